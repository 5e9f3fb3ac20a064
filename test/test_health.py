"""A node's health for /diagnostics, without ROS: levels, messages and values from its counters, period by period."""

from __future__ import annotations

import pytest

from zebra_sim_ros.health import Activity, HealthMonitor, Level


def _camera(frames: int, skipped: int = 0, busy: float | None = None, **kw: object) -> Activity:
    return Activity({"frames": frames, "skipped": skipped}, "frames", ("skipped",), busy_s=busy, **kw)  # type: ignore[arg-type]


def test_work_in_a_period_is_ok_with_its_rate_and_time_per_unit() -> None:
    mon = HealthMonitor(start_s=100.0)
    h = mon.report(102.0, _camera(5, busy=1.5, hardware="drone_0", info={"world": "savanna"}))
    assert h.level is Level.OK and h.message == "5 frames in the last 2.0 s (2.5/s)"
    assert h.value("frames") == "5" and h.value("skipped") == "0" and h.value("world") == "savanna"
    assert float(h.value("frames per second")) == pytest.approx(2.5)
    assert float(h.value("seconds per frame")) == pytest.approx(0.3)
    # the next period counts from this report: 3 more frames in 0.5 s, 0.6 s more work
    h = mon.report(102.5, _camera(8, busy=2.1))
    assert h.message == "3 frames in the last 0.5 s (6/s)" and h.value("frames") == "8"
    assert float(h.value("seconds per frame")) == pytest.approx(0.2)


def test_a_problem_warns_for_the_period_it_rose_in_only() -> None:
    mon = HealthMonitor(start_s=0.0)
    assert mon.report(1.0, _camera(4)).level is Level.OK
    h = mon.report(2.0, _camera(6, skipped=2))
    assert h.level is Level.WARN and h.message == "2 skipped in the last 1.0 s; 2 frames in the last 1.0 s (2/s)"
    assert h.value("skipped") == "2"
    h = mon.report(3.0, _camera(7, skipped=2))  # no new problem: OK again, the total still shown
    assert h.level is Level.OK and h.value("skipped") == "2"


def test_an_error_outranks_a_warning_and_waiting_is_said() -> None:
    mon = HealthMonitor(start_s=0.0)
    h = mon.report(1.0, _camera(1, skipped=1, error="recording ended: disk full"))
    assert h.level is Level.ERROR and h.message == "recording ended: disk full"
    h = mon.report(2.0, _camera(1, skipped=1, waiting="waiting for subscribers"))
    assert h.level is Level.OK and h.message == "waiting for subscribers"


def test_idle_says_since_when() -> None:
    mon = HealthMonitor(start_s=0.0)
    assert mon.report(1.0, _camera(0)).message == "no frames yet"
    mon.report(2.0, _camera(3))  # the last work seen in the report at 2.0 s
    mon.report(3.0, _camera(3))
    h = mon.report(4.5, _camera(3))
    assert h.level is Level.OK and h.message == "no frames for 2.5 s; 3 in all"
    assert float(h.value("frames per second")) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(KeyError, match="seconds per frame"):
        h.value("seconds per frame")  # no work in the period: no time per frame to give
    assert mon.report(300.0, _camera(3)).message == "no frames for 5.0 min; 3 in all"


def test_an_activity_must_hold_the_counters_it_names() -> None:
    with pytest.raises(KeyError, match=r"lack \['dropped'\]"):
        Activity({"messages": 1}, "messages", ("dropped",))


def test_a_note_follows_the_message_unless_the_node_failed() -> None:
    mon = HealthMonitor(start_s=0.0)
    assert mon.report(1.0, _camera(2, note="mAP50 0.7")).message == "2 frames in the last 1.0 s (2/s); mAP50 0.7"
    assert mon.report(2.0, _camera(2, note="mAP50 0.7", error="bad")).message == "bad"
