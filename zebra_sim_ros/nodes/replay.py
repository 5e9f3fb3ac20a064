"""The ``replay`` node: plays MCAP bags back as recorded (``ros2 run zebra_sim_ros replay``).

Publishes every message as recorded (raw CDR, no deserialisation) on its topic (plus ``remap_prefix``), with the QoS
its publishers offered when recorded (reliable and transient local only if they all were; ``qos_overrides_path``
sets policies per topic over that, as ``ros2 bag play --qos-profile-overrides-path``), keeping the recorded
spacing of log times divided by ``rate``. ``start_offset_s`` and ``duration_s`` select a window,
``topics``/``topic_regex``/``exclude_regex`` select topics, ``loop`` plays again, ``clock`` publishes ``/clock``
with the bag's time for ``use_sim_time`` consumers. ``paused`` (runtime; the ``~/pause``, ``~/resume`` and
``~/toggle_paused`` services set it) holds playback at the bag time reached and goes on from there; while paused,
``~/play_next`` plays the next message alone (/clock moves to its time; the log names its topic and bag time);
``rate`` changes apply at once. Setting ``start_offset_s`` while playing seeks there, as ``ros2 bag play``'s seek: the
next message played is the first at or after that bag time (back or forth; a pause holds there; one past the bags'
last message is refused, as it is at start). Every service is ``ros2 bag play``'s, with rosbag2_interfaces' types
(Jazzy's), so its clients work unchanged: ``~/pause``, ``~/resume``, ``~/toggle_paused``, ``~/is_paused``,
``~/play_next``, ``~/burst`` (while paused, the next N messages at once; 0: the rest of the pass), ``~/seek`` (a
bag stamp), ``~/set_rate``, ``~/get_rate`` and ``~/stop`` (playback ends, and the node with it). A truncated or
corrupt bag plays everything intact, then the node logs where and why it stopped. The node exits when done (unless
looping).
"""

from __future__ import annotations

import functools
import math
import re
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.parameter import Parameter
from rosbag2_interfaces.srv import Burst, GetRate, PlayNext, Seek, SetRate, Stop
from rosgraph_msgs.msg import Clock

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.health import Activity
from zebra_sim_ros.nodes.ros_adapter import (
    DIAGNOSTICS_TOPIC,
    ZebraNode,
    flush,
    help_text,
    message_class,
    profile_qos,
    run_node,
    stamp,
    stamp_ns,
)
from zebra_sim_ros.recording.config import REPLAY_PARAMS, ReplayConfig
from zebra_sim_ros.recording.qos import from_yaml, load_overrides, overridden, replay_profile
from zebra_sim_ros.recording.reader import BagReader, first_log_time, last_log_time, topic_filter
from zebra_sim_ros.recording.stamps import stamp_text

_STEP_WAIT_S = 5.0  # how long ~/play_next (~/burst: each message) waits to be played before it withdraws the request
_BURST_ALL = 2**64 - 1  # ~/burst's 0: every message to the end of the pass (a uint64 cannot ask for more)

# After waiting for subscribers, before the first message: the publisher sees a new subscriber before that
# subscriber's side knows the publisher (discovery runs both ways), and what the subscriber drops meanwhile is lost
# once it leaves the recorded history depth (10 messages at 2 ms apart: 20 ms). A cut-bag test lost 1 of 245 so.
MATCH_SETTLE_S = 0.3


class _Seek(Exception):
    """Ends a pass to play again from bag time ``to`` (a seek back, or onto messages already played)."""

    def __init__(self, to: float) -> None:
        super().__init__(to)
        self.to = to


class _Pace:
    """When each bag time is due on the wall clock, at a ``rate`` that may change while playing: after a change
    the bag goes on from where it is, at the new speed; at rate 0 (paused) it stands where it is and nothing is due.
    Times in seconds from the bag's first message."""

    def __init__(self, offset_s: float, rate: float) -> None:
        self.offset, self.start, self.rate = offset_s, time.monotonic(), rate  # bag time ``offset`` at ``start``
        self.last_clock = 0.0  # wall time /clock was last published
        self.clock_ns = 0  # the last /clock published (bag ns): it never goes back within a pass but by a seek

    def position(self, now: float) -> float:
        """The bag time reached at wall time ``now``."""
        return self.offset + (now - self.start) * self.rate

    def jump(self, rel: float, now: float, clock_ns: int | None = None) -> None:
        """Stand at bag time ``rel`` from ``now`` (a message played alone while paused, a seek); /clock is due at
        once, and with ``clock_ns`` (a seek) goes there, back too."""
        self.offset, self.start, self.last_clock = rel, now, 0.0
        if clock_ns is not None:
            self.clock_ns = clock_ns

    def set_rate(self, rate: float, now: float) -> None:
        """Play on at ``rate`` from ``now``."""
        if rate != self.rate:
            self.offset, self.start, self.rate = self.position(now), now, rate

    def due(self, rel: float) -> float:
        """The wall time at which bag time ``rel`` is due; while paused (rate 0) none is."""
        return self.start + (rel - self.offset) / self.rate if self.rate > 0 else math.inf


class ReplayNode(ZebraNode[ReplayConfig]):
    """Plays bags from a thread of its own; the executor only serves the graph. ``rate`` and ``paused`` may change
    while it plays, and a new ``start_offset_s`` seeks. ``~/play_next`` and ``~/burst`` wait for the messages they
    play in a callback group of their own, on the second of the executor's two threads: /diagnostics, parameters and
    the other services are served meanwhile (a ``~/resume`` ends a burst)."""

    executor_threads = 2

    def __init__(self) -> None:
        super().__init__("replay", ReplayConfig)

    def start(self) -> None:
        """Open the bags, make every publisher, and start playing."""
        c = self.cfg
        self.bags: list[str | Path] = [b for b in c.bags if b]
        self.reader = BagReader.open(self.bags, name="bags")  # missing files stop the node here, naming them
        self.t0_bag: int | None = None  # log time of the first message played (bag time 0), once a pass has read it
        if why := self._past_end(c.start_offset_s):  # a window that holds no message stops the node here too
            raise ParameterError("start_offset_s", c.start_offset_s, f"a bag time the bags reach ({why})")
        self.overrides = load_overrides(c.qos_overrides_path)  # so does a bad overrides file
        self.regex = re.compile(c.topic_regex)  # checked by its ParamSpec
        self.exclude = re.compile(c.exclude_regex) if c.exclude_regex else None
        self.topics = {t for t in c.topics if t}
        self.wanted = topic_filter(self.topics, self.regex, self.exclude)  # the topics played
        self.pubs: dict[str, Any] = {}
        self.clock_pub = self.create_publisher(Clock, "/clock", 10) if c.clock else None
        self.published = 0
        # ~/play_next: steps asked for and not yet taken (the play thread takes them while paused), messages played
        # by a step and the last of them (topic and bag time); the condition guards all three
        self.steps, self.stepped, self.step_note = 0, 0, ""
        self.passes = 0  # passes ended (a ~/burst of the whole pass stops at the end of its pass)
        self.pause_changes = 0  # pauses and resumes so far: one that comes while a ~/burst waits ends it
        self.burst_all = False  # a ~/burst of the whole pass runs: its steps not taken end with the pass
        self.step_cond = threading.Condition()
        self.seek_to: float | None = None  # a seek asked for and not yet taken (bag seconds); under step_cond
        self.seeks = 0  # seeks taken
        self.error = ""  # why playing failed
        self.stop_asked = False  # ~/stop ended playback
        self.damaged_before = 0  # damaged parts skipped in earlier passes (looping reopens the reader)
        self.damaged_pass: set[str] = set()  # this pass's, from readers a seek back replaced (the same parts again)
        self.pass_lock = threading.Lock()  # a report never sees a pass counted twice, or not at all
        self.waiting = ""  # what the play thread waits for before it plays
        self.reading = ""  # the bag time it reads on to, past what it does not play (an offset, a seek)
        for topic, type_name, metadata in self.reader.channel_list():  # publishers up front: subscribers match
            self._publisher(topic, type_name, metadata)                    # before the first message is played
        self.serve_pause()
        steps = MutuallyExclusiveCallbackGroup()  # one step or burst at a time; the rest served beside it
        self.create_service(PlayNext, "~/play_next", self._on_play_next, callback_group=steps)
        self.create_service(Burst, "~/burst", self._on_burst, callback_group=steps)
        self.create_service(Seek, "~/seek", self._on_seek)
        self.create_service(SetRate, "~/set_rate", self._on_set_rate)
        self.create_service(GetRate, "~/get_rate", self._on_get_rate)
        self.create_service(Stop, "~/stop", self._on_stop)
        self.get_logger().info(f"playing {[str(p) for p in self.reader.paths]} at rate {c.rate}, "
                               f"offset {c.start_offset_s} s, duration {c.duration_s or 'all'}, "
                               f"loop {c.loop}, clock {c.clock}, remap prefix '{c.remap_prefix}'"
                               + (" (paused: ~/resume plays)" if c.paused else ""))
        self.thread = threading.Thread(target=self._play_all, name="replay", daemon=True)
        self.thread.start()

    def on_config(self, cfg: ReplayConfig) -> None:
        """A new rate or pause applies at once, also to the wait for the next message (the play thread reads
        ``cfg``)."""
        if changed := cfg.paused != self.cfg.paused:
            self.get_logger().info("paused" if cfg.paused else "playing again")
        with self.step_cond:  # a step asked for in the last pause is not carried into the next one, and a
            if changed:  # ~/burst waiting for its messages hears that the pause has ended (also where it has
                self.steps = 0  # begun again before the burst's thread woke: the count says so)
                self.pause_changes += 1
            self.cfg = cfg
            self.step_cond.notify_all()

    def refuse_config(self, cfg: ReplayConfig, changes: Mapping[str, Any]) -> str:
        """A seek (``start_offset_s`` set) once the bags have been played, or to a time past their last message."""
        if "start_offset_s" not in changes:
            return ""
        if self._ending():  # the play thread has ended: nothing takes a seek
            return "the bags have been played: no seek (loop:=true keeps the replay playing)"
        why = self._past_end(cfg.start_offset_s)
        return f"start_offset_s {cfg.start_offset_s:g} s: {why}" if why else ""

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """As every node's, and every accepted set of ``start_offset_s`` seeks, even to the value it has (as a
        repeated ``ros2 bag play`` seek plays again from there)."""
        result = super()._on_set_parameters(params)
        if result.successful and any(p.name == "start_offset_s" for p in params):  # after start(): the service's
            to = self.cfg.start_offset_s
            with self.step_cond:
                self.seek_to = to
            self.get_logger().info(f"seeking to {to:g} s of the bag")
        return result

    def _past_end(self, offset_s: float) -> str:
        """Why bag time ``offset_s`` (seconds after the first message played) is past the bags' last message, or ""
        where it is not or the bags' summaries do not say where they end (a cut file). Before a message is played
        the bags' first message stands for the first played one, which is never earlier, so nothing the bags reach
        is refused."""
        end = last_log_time(self.reader.paths)
        if end is None:
            return ""
        base = self.t0_bag if self.t0_bag is not None else first_log_time(self.reader.paths)
        if base is None or base + round(offset_s * 1e9) <= end:
            return ""
        first = "the first message played" if self.t0_bag is not None else "their first message"
        return f"past the bags' last message at {stamp_text(end)}, {(end - base) / 1e9:g} s after {first}"

    def _take_seek(self) -> float | None:
        """The seek asked for, if any (taken and counted: asked once, done once)."""
        with self.step_cond:
            to, self.seek_to = self.seek_to, None
            self.seeks += to is not None
            return to

    def _publisher(self, topic: str, type_name: str, metadata: dict[str, str]) -> Any:
        """The topic's publisher with its recorded QoS (and overrides), made once; None for a topic not played or
        not playable (type not installed, no schema, unreadable QoS metadata: logged once, and the rest of the bag
        plays)."""
        if topic in self.pubs:
            return self.pubs[topic]
        pub = None
        if self.cfg.clock and type_name == "rosgraph_msgs/msg/Clock":
            self.get_logger().info(f"not playing the recorded {topic}: this node publishes /clock from the bag's "
                                   "log times (the same times)")
        elif topic == DIAGNOSTICS_TOPIC and not self.cfg.remap_prefix and topic not in self.topics:
            self.get_logger().info(f"not playing the recorded {topic} under its own name: live nodes report there "
                                   "(name it in topics, or give a remap_prefix, to play it)")
        elif self.wanted(topic):
            try:
                p = replay_profile(from_yaml(metadata.get("offered_qos_profiles", "")))
                q = profile_qos(overridden(p, self.overrides.get(topic)))  # keyed by the topic as recorded
                pub = self.create_publisher(message_class(type_name), self.cfg.remap_prefix + topic, q)
            except (ImportError, AttributeError, ValueError, yaml.YAMLError) as exc:
                self.get_logger().error(f"cannot play {topic} ({type_name or 'no schema'}): {exc}; skipping it")
        self.pubs[topic] = pub
        return pub

    def _play_all(self) -> None:
        try:
            origin: float | None = None  # where a seek back restarts the pass (None: at start_offset_s)
            while True:
                try:
                    self._play_once(origin)
                    origin = None
                except _Seek as seek:  # read the bags again from their start, up to the bag time sought
                    origin = seek.to
                if self._ending() or (origin is None and not self.cfg.loop):
                    break
                # the bags listed again (a folder may have new files), knowing what the last reader learnt of the
                # files unchanged since: a seek passes over the chunks read before, even without a summary
                reader = BagReader.open(self.bags).carry_from(self.reader)
                with self.pass_lock:
                    if origin is None:  # a new pass
                        self.damaged_before += len(self.damaged_pass | set(self.reader.stopped))
                        self.damaged_pass = set()
                    else:  # the same pass again from the bag time sought: its damaged parts are not new ones
                        self.damaged_pass |= set(self.reader.stopped)
                    self.reader = reader
        except Exception as exc:  # noqa: BLE001 - reported, and the node ends with an error status
            if self._ending() or not self.context.ok():  # Ctrl-C: rclpy's handler ended the context under it
                return
            self.error = f"replay failed: {type(exc).__name__}: {exc}"
            self.get_logger().error(self.error)
            self.exit_code = 1
        finally:
            if self.stop_asked and self.context.ok():  # ~/stop: what was published reaches subscribers; the count
                flush(self, [p for p in self.pubs.values() if p is not None])
                self.get_logger().info(f"~/stop: playback stopped after {self.published} messages")
            self.done = True
            with self.step_cond:  # a ~/play_next waiting for its message hears that none will come
                self.step_cond.notify_all()

    def _play_once(self, origin: float | None) -> None:
        """One pass over the bags, from ``start_offset_s`` or, after a seek back, from bag time ``origin`` (the
        spacing from it kept); raises :class:`_Seek` for a seek to a bag time at or before a message this pass has
        already played or skipped, and for one that comes as the pass ends. A seek forward goes on in this pass."""
        c = self.cfg  # what may change while playing (rate) is read from self.cfg where it is used
        # a seek back reads the bags again with every subscriber matched already: no second wait for them
        wait_until = time.monotonic() + (c.wait_for_subscribers_s if origin is None else 0.0)
        t0_bag = self.t0_bag  # known after a first pass (the same bags, the same topics played)
        pace: _Pace | None = None
        begin = c.start_offset_s if origin is None else origin  # the window: [begin, begin + duration_s]
        anchor = origin  # the bag time the pacing starts from: a seek's, else (None) the first message played
        consumed = -math.inf  # bag time of the last message this pass has played or skipped
        from_ns = None  # chunks wholly before it are passed over unread
        if t0_bag is not None and begin > 0:
            from_ns = t0_bag + int(begin * 1e9)
            consumed = begin - 1e-9  # what came before may have been passed over: a seek to it reads again
        ended = False  # past the window's end
        n = 0
        self.reading = f"reading the bags to {begin:g} s" if begin > 0 else ""
        for m in self.reader.messages(from_ns=from_ns):
            if self._ending():
                return
            pub = self._publisher(m.topic, m.type_name, m.metadata)
            if pub is None:  # not played: its log time does not set the start (a report on another clock, say)
                continue
            if t0_bag is None:
                t0_bag = self.t0_bag = m.log_time
            rel = (m.log_time - t0_bag) / 1e9
            while True:  # until this message is played or skipped: a seek while it waits judges it again
                to = self._take_seek()
                if to is not None:
                    if to <= consumed:  # what it wants has been played or skipped: read the bags again
                        raise _Seek(to)
                    begin = anchor = to
                    if rel < to:  # read on to it: the pacing starts again there, not while the bags are read
                        pace = None
                        self.reading = f"reading the bags to {to:g} s"
                        self.reader.pass_before_ns = t0_bag + int(to * 1e9)  # chunks wholly before it: unread
                        consumed = max(consumed, to - 1e-9)
                    elif pace is not None:  # into the gap before this message: the bag (and /clock) stand at ``to``
                        pace.jump(to, time.monotonic(), t0_bag + int(to * 1e9))
                if rel < begin:
                    consumed = max(consumed, rel)  # bag times may go back (bags in turn, stamps out of order)
                    break
                if c.duration_s and rel > begin + c.duration_s:
                    ended = True
                    break
                self.reading = ""
                if pace is None:  # every publisher known so far should have a subscriber (up to wait_for_subscribers_s)
                    self._wait_for_subscribers(wait_until, c.wait_for_subscribers_s)
                    c_now = self.cfg  # paused: the bag stands at its start from the first instant
                    pace = _Pace(rel if anchor is None else anchor, 0.0 if c_now.paused else c_now.rate)
                waited = self._wait(pace, rel, t0_bag, m.log_time)
                if self._ending():
                    return
                if waited == "seek":
                    continue
                self._publish_clock(pace, m.log_time)
                pub.publish(m.data)
                n += 1
                self.published += 1
                consumed = max(consumed, rel)
                if waited == "step":  # played for ~/play_next: its answer names it
                    with self.step_cond:
                        self.stepped += 1
                        self.step_note = f"{m.topic} at {rel:.3f} s of the bag"
                        self.step_cond.notify_all()
                break
            if ended:
                break
        self.reading = ""
        self._seek_now()  # one that came as the pass ended ...
        self._end_pass(n)
        self._seek_now()  # ... or while its publishers flushed: taken, not lost

    def _seek_now(self) -> None:
        """Raise :class:`_Seek` for a seek asked for and not yet taken (at a pass's end: the bags are read again)."""
        if (to := self._take_seek()) is not None:
            raise _Seek(to)

    def _wait_for_subscribers(self, until: float, wait_s: float) -> None:
        """Before the first message: until every publisher known so far has a subscriber, or wall time ``until``."""
        waited = False
        while not self._ending() and time.monotonic() < until and any(
                p is not None and p.get_subscription_count() == 0 for p in self.pubs.values()):
            self.waiting = f"waiting up to {wait_s:g} s for subscribers"
            waited = True
            time.sleep(0.01)
        if waited:  # a match just made: let the subscriber's side know this publisher too
            time.sleep(MATCH_SETTLE_S)
        self.waiting = ""

    def _end_pass(self, n: int) -> None:
        for note in self.reader.stopped:
            self.get_logger().warning(f"bag damaged, played everything intact: {note}")
        flush(self, [p for p in self.pubs.values() if p is not None])
        self.get_logger().info(f"played {n} messages" + (f" ({self.seeks} seeks)" if self.seeks else ""))
        with self.step_cond:  # a ~/burst of the whole pass ends here: the next pass takes none of its steps
            self.passes += 1
            if self.burst_all:
                self.steps, self.burst_all = 0, False
            self.step_cond.notify_all()

    def _on_play_next(self, request: Any, response: Any) -> Any:
        """``~/play_next`` (rosbag2_interfaces/srv/PlayNext): while paused, the next message is played alone;
        answered once it is (``success``; the log names its topic and bag time), or refused (the log says why: see
        :meth:`_play_steps`)."""
        played, why = self._play_steps(1, "~/play_next")
        response.success = self.log_service("~/play_next", played == 1, f"played {self.step_note}" if played else why)
        return response

    def _on_burst(self, request: Any, response: Any) -> Any:
        """``~/burst`` (rosbag2_interfaces/Burst): while paused, the next ``num_messages`` play at once, each as
        soon as the one before (0: to the end of the pass); answers how many were (``actually_burst``), and logs
        why where fewer were."""
        n = int(request.num_messages) or _BURST_ALL
        played, why = self._play_steps(n, "~/burst")
        response.actually_burst = played
        if played:
            self.get_logger().info(f"burst {played} messages, the last {self.step_note}")
        if why:
            self.get_logger().warning(f"burst {played} of {request.num_messages or 'the pass'} messages: {why}")
        return response

    def _play_steps(self, n: int, service: str) -> tuple[int, str]:
        """Play the next ``n`` messages alone while paused, each as soon as the one before (the play thread takes
        them as steps; ``_BURST_ALL``: to the end of this pass, which is then no shortfall); returns how many were
        played and, where fewer, why: not paused (or resumed meanwhile), the bag played to its end or failed, at once
        while the replay waits for subscribers or reads the bags on to a time sought, or no message played within
        ``_STEP_WAIT_S`` (the steps not taken are withdrawn; one the play thread has just taken plays after the
        answer)."""
        def ended() -> str:
            return self.error or ("playback was stopped (~/stop)" if self.stop_asked else "the bag has been played")

        if self._ending() or not self.cfg.paused:
            return 0, ended() if self._ending() else f"not paused: {service} plays while paused"
        if busy := self.waiting or self.reading:  # no message is near: refused at once, not holding the executor
            return 0, f"nothing to play yet ({busy})"
        whole = n == _BURST_ALL
        with self.step_cond:
            before, passes, pause = self.stepped, self.passes, self.pause_changes
            self.steps += n
            self.burst_all = whole
            while self.stepped - before < n and (not whole or self.passes == passes):
                last = self.stepped
                self.step_cond.wait_for(
                    functools.partial(self._stepped_since, last, passes if whole else None, pause),
                    timeout=_STEP_WAIT_S)
                if self.stepped == last:
                    break
            played = self.stepped - before
            self.burst_all = False
            if played >= n:
                return played, ""
            withdrawn = min(self.steps, n - played)
            self.steps -= withdrawn
            if whole and played and not self.error and not self.stop_asked and (self.done or self.passes != passes):
                return played, ""  # the whole pass, as asked
            if self._ending():
                return played, ended()
            if whole and self.passes != passes:
                return played, "the pass ended"
            if self.pause_changes != pause or not self.cfg.paused:  # resumed (maybe paused again): its burst ended
                return played, "resumed while it played"
            if withdrawn == n - played:
                busy = self.waiting or self.reading
                return played, f"nothing played within {_STEP_WAIT_S:g} s" + (f" ({busy})" if busy else "")
            return played, f"the next message is playing (not within {_STEP_WAIT_S:g} s)"

    def _stepped_since(self, stepped: int, passes: int | None, pause: int) -> bool:
        """A message played after ``stepped`` had been, the pass ``passes`` ended (where given), the pause did (its
        count of changes is no longer ``pause``), or the replay did (under ``step_cond``)."""
        return (self.stepped > stepped or (passes is not None and self.passes != passes) or self._ending()
                or self.pause_changes != pause or not self.cfg.paused or not self.context.ok())

    def _on_seek(self, request: Any, response: Any) -> Any:
        """``~/seek`` (rosbag2_interfaces/Seek): seek to a bag stamp, as setting ``start_offset_s`` to its seconds
        after the first message played (a stamp before it seeks there). Refused (success false, the reason logged)
        before a message is read, past the bags' last message where their summaries give it, and where setting the
        offset is (the replay has ended)."""
        ns = stamp_ns(request.time)
        t0 = self.t0_bag
        if t0 is None:
            why = "no message read yet: the bags' first played stamp is not known"
        else:  # past the bags' last message, setting the offset refuses it
            why = self.set_param("start_offset_s", max(0.0, (ns - t0) / 1e9))
        response.success = not why
        if why:
            self.get_logger().warning(f"seek to {stamp_text(ns)} refused: {why}")
        return response

    def _on_set_rate(self, request: Any, response: Any) -> Any:
        """``~/set_rate`` (rosbag2_interfaces/SetRate): sets ``rate`` (its bounds hold; a refusal is logged)."""
        refused = self.set_param("rate", float(request.rate))
        response.success = not refused
        if refused:
            self.get_logger().warning(f"set_rate to {request.rate:g} refused: {refused}")
        return response

    def _on_get_rate(self, request: Any, response: Any) -> Any:
        """``~/get_rate`` (rosbag2_interfaces/GetRate): the ``rate`` played at (paused or not)."""
        response.rate = float(self.cfg.rate)
        return response

    def _on_stop(self, request: Any, response: Any) -> Any:
        """``~/stop`` (rosbag2_interfaces/srv/Stop), as ``ros2 bag play``'s: playback ends where it is, paused or not
        (looping too), and the node ends as it does when the bags have been played: the play thread flushes what it
        published, logs the count and sets ``done`` (so the answer goes out before the node ends)."""
        if self._ending():
            self.get_logger().info("~/stop: playback has ended already")
            return response
        with self.step_cond:  # a ~/burst or ~/play_next waiting on the other executor thread answers now
            self.stop_asked = True
            self.step_cond.notify_all()
        return response

    def _take_step(self) -> bool:
        """One of ~/play_next's requests, if any is waiting."""
        with self.step_cond:
            if self.steps <= 0:
                return False
            self.steps -= 1
            return True

    def _wait(self, pace: _Pace, rel: float, t0_bag: int, log_time: int) -> str:
        """Sleep in slices until bag time ``rel`` is due, publishing /clock on the way; a new rate applies at once,
        and a pause holds the wait (and /clock) where the bag is until it ends. Returns "due", or "step" where
        ``~/play_next`` took this message while paused (it plays alone), or "seek" where a seek came first (the
        message is judged again)."""
        period = 1.0 / self.cfg.clock_rate_hz
        while not self._ending():  # stop() ends the wait too
            if self.seek_to is not None:
                return "seek"
            now, c = time.monotonic(), self.cfg  # one config a pass: the executor may swap it meanwhile
            pace.set_rate(0.0 if c.paused else c.rate, now)
            if self.clock_pub is not None and now - pace.last_clock >= period:  # first: a seek's time is sent
                self._publish_clock(pace, min(t0_bag + int(pace.position(now) * 1e9), log_time))
                pace.last_clock = now
            if c.paused and self._take_step():  # ~/play_next: this message alone, /clock moved to it
                pace.jump(rel, now)
                return "step"
            target = pace.due(rel)
            if now >= target:
                return "due"
            time.sleep(min(target - now, period / 2 if self.clock_pub else 0.05))
        return "due"

    def _publish_clock(self, pace: _Pace, ns: int) -> None:
        """/clock at bag time ``ns`` (with ``clock``), never under the last one this pass sent (the paced time, a
        float, may fall a nanosecond under a message's stamp)."""
        if self.clock_pub is not None:
            pace.clock_ns = max(pace.clock_ns, ns)
            self.clock_pub.publish(Clock(clock=stamp(pace.clock_ns)))

    def activity(self) -> Activity:
        """Messages played; damaged parts of the bags skipped (everything intact is played); an error ends it."""
        with self.pass_lock:
            damaged = self.damaged_before + len(self.damaged_pass | set(self.reader.stopped))
        return Activity({"messages": self.published, "damaged": damaged, "seeks": self.seeks}, "messages",
                        ("damaged",),
                        error=self.error,
                        waiting=self.waiting or self.reading or ("paused" if self.cfg.paused else ""),
                        info={"bags": ", ".join(str(p) for p in self.reader.paths), "rate": f"{self.cfg.rate:g}",
                              "paused": str(self.cfg.paused).lower()})

    def _ending(self) -> bool:
        """The play thread has ended (``done``) or is asked to end by ``~/stop``."""
        return self.done or self.stop_asked

    def stop(self) -> None:
        """End the play thread before the node's publishers go (it would publish through destroyed ones)."""
        self.done = True
        with self.step_cond:  # a ~/burst or ~/play_next waiting on the other executor thread answers now
            self.step_cond.notify_all()
        thread = getattr(self, "thread", None)
        if thread is not None:
            thread.join(timeout=5.0)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run zebra_sim_ros replay``; returns the exit status."""
    return run_node("replay", ReplayNode, argv, help_text("replay", __doc__ or "", REPLAY_PARAMS))


if __name__ == "__main__":
    raise SystemExit(main())
