"""``zebra-sim generate``: the whole pipeline in process (place, render, label, write), fast, resumable.

Layout of the output folder::

    images/{train,val}/<frame>.jpg|png   RGB
    labels/{train,val}/<frame>.txt       YOLO: "0 cx cy w h" normalised, one line per kept zebra
    ignore/{train,val}/<frame>.txt       the same for zebras seen but dropped by the label filters (only where
                                         there are some): don't-care regions, which evaluation neither counts
                                         as missed nor holds against a detection (COCO's iscrowd; coco/ has them)
                                         and training leaves out of the classification loss
    masks/<frame>.png                    uint16 instance mask (zebra id + 1, 0 = not a zebra)
    depth/<frame>.npz                    metres along the optical axis, key "depth" (inf = sky); float32 by
                                         default (--depth float16 halves the size, --depth none skips it)
    annotations/<frame>.json             everything about the frame: the labeller's labels, the scene's seed,
                                         step, world, lighting, camera pose and intrinsics, split, COCO RLEs
    coco/{train,val}.json                COCO (boxes, keypoints with skeleton, visibility, RLE masks)
    dataset.yaml                         for YOLO trainers (path, train, val, names)
    generate.json                        the settings (from a run's start) and the last run's statistics

A frame is ``<world>_<strategy>_<seed>_<step>_<camera>``. The split is by placement (a placement's steps
and cameras never straddle train and val): about 20% of placements go to val, chosen by a hash of world, seed
and placement. A frame is complete when its annotation file exists (written last, atomically); a rerun skips
complete steps, so an interrupted run continues where it stopped and writes no frame twice. ``--shard i/n``
takes the steps with ``step % n == i``, so machines can share a run without overlap. COCO and the YAML are
rebuilt from the annotation files at the end of every run (``--finalize-only`` does just that).
"""

from __future__ import annotations

import contextlib
import io
import json
import multiprocessing as mp
import multiprocessing.connection as mp_connection
import os
import shlex
import signal
import sys
import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from zebra_sim_ros.dataset.coco import (
    CATEGORY,
    SPECIES_CATEGORIES,
    crowd_annotation,
    encode_frame,
    rle_encode_all,
    species_annotation,
    write_dataset_yaml,
    yolo_lines,
    zebra_annotation,
)
from zebra_sim_ros.errors import ParameterError, WorkerError
from zebra_sim_ros.labels.config import LabelFilters
from zebra_sim_ros.messages import FrameAnnotation, Labels, Rle, Scene

if TYPE_CHECKING:
    from zebra_sim_ros.rendering.renderer import RenderedView

STRATEGY_SETS = {"both": ("far", "closeby"), "all": ("far", "closeby", "low", "nadir")}
"""Named sets of camera strategies: the run's frames are split evenly over the set's members."""
STRATEGIES = ("far", "closeby", "low", "nadir", *STRATEGY_SETS)
# The paper's two training sets by name.
NAMED_SETS = {"SF": "both", "SC": "closeby"}


@dataclass(frozen=True)
class GenerateConfig:
    """Settings of a run. ``frames`` counts camera images over all worlds (the paper: 36K)."""

    out: str
    frames: int
    strategy: str = "both"
    worlds: tuple[str, ...] = ("savanna",)
    seed: int = 0
    world_seed: int = 0
    width: int = 1280
    height: int = 720
    hfov_deg: float = 80.0
    image_format: str = "jpg"
    jpeg_quality: int = 95
    workers: int = 1
    shard: tuple[int, int] = (0, 1)
    yolo_box: str = "visible"
    val_fraction: float = 0.2
    depth: str = "float32"
    placer: dict[str, Any] = field(default_factory=dict)
    filters: LabelFilters = field(default_factory=LabelFilters)
    sensor_strength: float = 1.0  # the photograph's camera (rendering.effects.SensorModel); 0 = a perfect camera
    look: str = "photo"  # rendering.config.LOOKS: photo, or plain (flat ground, bare coats)
    other_animals: int = 20  # the placer's other_animals_max: distractors of other species (0 = zebras only)
    randomise: float = 0.5  # the placer's look_randomise (and half of it as ground_recolor): domain randomisation
    lens: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)  # the lens's plumb_bob distortion (geometry.lens); 0: none

    @property
    def placer_params(self) -> dict[str, Any]:
        """What this run sets of the placer's parameters (``placer``, the ``--set`` overrides, win)."""
        return {"other_animals_max": self.other_animals, "look_randomise": self.randomise,
                "ground_recolor": round(self.randomise / 2, 6), **self.placer}

    def check(self) -> None:
        """Raise :class:`ParameterError` naming the first bad setting."""
        if self.frames < 1:
            raise ParameterError("--frames", self.frames, ">= 1")
        if self.strategy not in STRATEGIES:
            raise ParameterError("--strategy", self.strategy, f"one of {STRATEGIES} (or the sets SF, SC)")
        if not self.worlds:
            raise ParameterError("--worlds", "", "at least one world")
        if len(set(self.worlds)) != len(self.worlds):  # a world named twice would plan its steps twice
            raise ParameterError("--worlds", ",".join(self.worlds), "each world once")
        if self.image_format not in ("jpg", "png"):
            raise ParameterError("--format", self.image_format, "jpg or png")
        if not 1 <= self.jpeg_quality <= 100:
            raise ParameterError("--jpeg-quality", self.jpeg_quality, "1..100")
        if not 1 <= self.workers <= 64:
            raise ParameterError("--workers", self.workers, "1..64")
        i, n = self.shard
        if not (n >= 1 and 0 <= i < n):
            raise ParameterError("--shard", f"{i}/{n}", "i/n with 0 <= i < n")
        if self.yolo_box not in ("visible", "full"):
            raise ParameterError("--yolo-box", self.yolo_box, "visible or full")
        if self.depth not in ("float32", "float16", "none"):
            raise ParameterError("--depth", self.depth, "float32, float16 or none")
        if self.look not in ("photo", "plain"):
            raise ParameterError("--look", self.look, "photo or plain")
        if not 0.0 <= self.randomise <= 1.0:
            raise ParameterError("--randomise", self.randomise, "0..1")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ParameterError("--val-fraction", self.val_fraction, "0 <= f < 1")
        from zebra_sim_ros.rendering.config import check_render_options

        check_render_options(self.render_options(), "--lens")  # the lens, for this image size and field of view

    @property
    def distortion(self) -> Any:
        """The lens (:class:`~zebra_sim_ros.geometry.lens.Distortion`); ParameterError naming ``--lens`` unless it
        has its five coefficients."""
        from zebra_sim_ros.geometry.lens import Distortion

        if len(self.lens) != 5:
            raise ParameterError("--lens", list(self.lens), "k1, k2, p1, p2, k3")
        return Distortion(*self.lens)

    def render_options(self) -> Any:
        """The renderer's settings (:class:`~zebra_sim_ros.rendering.renderer.RenderOptions`)."""
        from zebra_sim_ros.rendering.config import look_options
        from zebra_sim_ros.rendering.renderer import RenderOptions

        return RenderOptions(width=self.width, height=self.height, hfov_deg=self.hfov_deg,
                             distortion=self.distortion, **look_options(self.look))


@dataclass(frozen=True)
class Job:
    """One step of one world and strategy: renders every camera of that step."""

    world: str
    strategy: str
    seed: int
    step: int


def frame_name(job: Job, camera: str) -> str:
    """File stem of one camera image."""
    return f"{job.world}_{job.strategy}_{job.seed}_{job.step:06d}_{camera}"


def split_of(world: str, seed: int, placement: int, val_fraction: float) -> str:
    """'train' or 'val' for a placement: a hash, so the same placement always lands in the same split."""
    h = zlib.crc32(f"{world}:{seed}:{placement}".encode()) / 2**32
    return "val" if h < val_fraction else "train"


def stream_seed(seed: int, world: str, strategy_index: int) -> int:
    """The placer seed of one world and strategy of a run with ``--seed seed``.

    Every world draws its own stream (offset by a hash of its name, so a world's frames do not depend on which
    other worlds share the run); with the bare seed for all, every world drew the same herd sizes, times of day
    and camera jitter at the same step, and a run of seven worlds held a seventh of the lighting it seemed to.
    Closeby (strategy index 1) draws its own placements too, as the paper's second set did; so do low and nadir
    (indices 2 and 3 in the set ``all``). A strategy run alone has index 0.
    """
    return seed + 1_000_003 * strategy_index + 1_009 * (zlib.crc32(world.encode()) % 9_973)


def plan(cfg: GenerateConfig, cameras: int) -> list[Job]:
    """The steps needed for ``cfg.frames`` images: split evenly over worlds (and strategies for 'both')."""
    strategies = STRATEGY_SETS.get(cfg.strategy, (cfg.strategy,))
    parts = len(cfg.worlds) * len(strategies)
    per_part = -(-cfg.frames // parts)  # images
    steps = -(-per_part // cameras)
    jobs = []
    for world in cfg.worlds:
        for k, strategy in enumerate(strategies):
            seed = stream_seed(cfg.seed, world, k)
            jobs += [Job(world, strategy, seed, s) for s in range(steps)]
    i, n = cfg.shard
    return [j for j in jobs if j.step % n == i]


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


class _Pipeline:
    """Per-process state: zebra library, a simulator per world, placers."""

    def __init__(self, cfg: GenerateConfig) -> None:
        from zebra_sim_ros.zebra.asset import appearance_digest, load_library

        self.cfg = cfg
        self.library = load_library()
        self.appearance = appearance_digest()
        self.world_name: str | None = None
        self.sim: Any = None
        self.placers: dict[tuple[str, int], Any] = {}
        self.times = {"place": 0.0, "render": 0.0, "label": 0.0, "write": 0.0}
        self.out = Path(cfg.out)

    def _world(self, name: str) -> None:
        if name == self.world_name:
            return
        from zebra_sim_ros.rendering.effects import SensorModel
        from zebra_sim_ros.simulation import Simulator
        from zebra_sim_ros.world.world import load_world

        if self.sim is not None:
            self.sim.release()
        c = self.cfg
        self.world = load_world(name, "/World/Terrain", c.world_seed)
        self.sim = Simulator(self.world, self.library, c.render_options(), c.filters,
                             SensorModel(c.sensor_strength) if c.sensor_strength > 0 else None)
        self.placers = {}
        self.world_name = name

    @property
    def lens_arg(self) -> str:
        """The lens as a ``render`` option (none without distortion)."""
        from zebra_sim_ros.rendering.config import lens_text

        lens = self.cfg.distortion
        return "" if lens.none else f" --lens {lens_text(lens)}"

    @property
    def set_args(self) -> str:
        """The placer overrides (and a non-default world seed) as ``render`` options, so a frame's
        ``regenerate`` command reproduces it alone."""
        over = {**self.cfg.placer_params, **({"world_seed": self.cfg.world_seed} if self.cfg.world_seed else {})}
        return "".join(f" --set {shlex.quote(f'{k}={v if isinstance(v, str) else json.dumps(v)}')}"
                       for k, v in sorted(over.items()))

    def placer(self, job: Job) -> Any:
        from zebra_sim_ros.geometry.lens import lens_params
        from zebra_sim_ros.placement.config import PlacerConfig
        from zebra_sim_ros.placement.placer import Placer

        self._world(job.world)
        key = (job.strategy, job.seed)
        if key not in self.placers:
            c = self.cfg
            params = {**c.placer_params, "seed": job.seed, "strategy": job.strategy,
                      "world": job.world,
                      "world_seed": c.world_seed, "camera_width": c.width, "camera_height": c.height,
                      "camera_hfov_deg": c.hfov_deg, **lens_params(c.distortion, "camera_lens_")}
            self.placers[key] = Placer(PlacerConfig.from_params(params), self.world, self.library)
        return self.placers[key]

    def run(self, job: Job) -> list[str]:
        """Place, render, label and write one step; returns the frame names written."""
        t0 = time.perf_counter()
        scene = self.placer(job).scene(job.step)
        t1 = time.perf_counter()
        views = self.sim.render(scene)
        t2 = time.perf_counter()
        labelled = [self.sim.labeller.label(scene, v.name, v.instances, v.depth) for v in views]
        t3 = time.perf_counter()
        split = split_of(job.world, job.seed, scene.placement, self.cfg.val_fraction)
        names = [self._write(job, scene, split, v, labels) for v, labels in zip(views, labelled, strict=True)]
        t4 = time.perf_counter()
        for k, dt in (("place", t1 - t0), ("render", t2 - t1), ("label", t3 - t2), ("write", t4 - t3)):
            self.times[k] += dt
        return names

    def _write(self, job: Job, scene: Scene, split: str, v: RenderedView, labels: Labels) -> str:
        """Write one frame's image, mask, depth, YOLO labels, don't-care boxes and annotation; returns its name."""
        import cv2

        c = self.cfg
        name = frame_name(job, v.name)
        img = encode_frame(v.rgb, c.image_format, c.jpeg_quality)
        ok_m, mask_png = cv2.imencode(".png", v.instances)
        if img is None or not ok_m:
            raise ParameterError("--format", c.image_format, "a format OpenCV can encode")
        _write_atomic(self.out / "images" / split / f"{name}.{c.image_format}", img)
        _write_atomic(self.out / "masks" / f"{name}.png", mask_png.tobytes())
        if c.depth != "none":
            buf = io.BytesIO()
            np.savez_compressed(buf, depth=v.depth.astype(c.depth))
            _write_atomic(self.out / "depth" / f"{name}.npz", buf.getvalue())
        _write_atomic(self.out / "labels" / split / f"{name}.txt",
                      ("\n".join(yolo_lines(labels, c.yolo_box)) + "\n").encode() if labels.kept else b"")
        dont_care = yolo_lines(labels, c.yolo_box, dont_care=True)
        if dont_care:
            _write_atomic(self.out / "ignore" / split / f"{name}.txt", ("\n".join(dont_care) + "\n").encode())
        outlined = [z.instance for z in labels.zebras if z.kept or z.dont_care or not z.is_zebra]
        rles = rle_encode_all(v.instances, outlined)
        labels = labels.with_zebras([replace(z, rle=Rle.from_dict(rles[z.instance])) if z.instance in rles else z
                                     for z in labels.zebras])
        meta = FrameAnnotation(
            name, split, f"images/{split}/{name}.{c.image_format}", f"masks/{name}.png",
            f"depth/{name}.npz" if c.depth != "none" else None, scene.world, scene.seed, scene.step, scene.placement,
            scene.reroll, job.strategy, scene.asset_digest, scene.lighting, scene.camera(v.name),
            f"zebra-sim render --seed {job.seed} --step {job.step} --world {job.world} --strategy {job.strategy} "
            f"--width {c.width} --height {c.height} --hfov {c.hfov_deg} --sensor-strength {c.sensor_strength} "
            f"--look {c.look}{self.lens_arg}"
            f"{self.set_args}", labels, v.sensor, scene.weather, scene.ground, self.appearance)
        _write_atomic(self.out / "annotations" / f"{name}.json", meta.to_json().encode())
        return name


def _worker(cfg: GenerateConfig, jobs: list[Job], conn: Any) -> None:
    """Render ``jobs``, reporting on ``conn``, this worker's own pipe: a worker stopped in the middle of a report
    (SIGSTOP, ^Z) holds no lock that the others need to report (a queue shared by all workers has one)."""
    conn.send(("started", None))  # before the pipeline is built (a GL context; the asset, if not cached)
    pipe = _Pipeline(cfg)
    for job in jobs:
        conn.send(("frames", len(pipe.run(job))))
    conn.send(("done", pipe.times))
    conn.close()


def _progress(done: int, total: int, t0: float, stream: Any) -> None:
    rate = done / max(time.perf_counter() - t0, 1e-9)
    eta = (total - done) / rate if rate > 0 else float("inf")
    eta_s = f"{int(eta // 60)}m{int(eta % 60):02d}s" if np.isfinite(eta) else "?"
    width = 30
    bar = "#" * int(width * done / max(total, 1))
    stream.write(f"\r[generate] [{bar:<{width}}] {done}/{total} frames, {rate:.2f} frames/s, ETA {eta_s}   ")
    stream.flush()


def _run_workers(cfg: GenerateConfig, todo: list[Job], total: int, show: Callable[[int], None],
                 worker: Callable[[GenerateConfig, list[Job], Any], None] = _worker) -> tuple[int, dict[str, float]]:
    """Run ``todo`` (``total`` frames) in ``cfg.workers`` spawned processes, each running ``worker`` (importable by
    a spawned process) on its share; returns the frames written and the summed stage times.

    Each worker reports on its own pipe (a worker stopped in the middle of a report holds up no other's). A worker
    that dies (an exception, the OOM killer) sends nothing more: the parent looks at the workers' exit codes
    every :data:`_WORKER_POLL_S` seconds, also while the others keep reporting, and at a pipe that ends before its
    worker said it was done; it stops the rest and raises :class:`WorkerError` naming the dead one. So it does for
    a live worker that has not finished and has reported nothing for :data:`_WORKER_STALL_S` (each worker's silence
    is timed apart, so one that hangs is found while the others still report). A worker that cannot be started
    (the system refuses a process) stops those already started, the same way."""
    ctx = mp.get_context("spawn")  # fresh processes: GL contexts do not survive fork
    chunks = [c for c in (todo[k::cfg.workers] for k in range(cfg.workers)) if c]
    pipes = [ctx.Pipe(duplex=False) for _ in chunks]  # (read end, write end): one per worker
    procs = [ctx.Process(target=worker, args=(cfg, ch, w), daemon=True)
             for ch, (_, w) in zip(chunks, pipes, strict=True)]
    reading = {r: k for k, (r, _) in enumerate(pipes)}
    ended: set[int] = set()  # the workers whose pipe has ended
    done = 0
    finished: set[int] = set()
    times = {"place": 0.0, "render": 0.0, "label": 0.0, "write": 0.0}
    failure = ""
    try:
        for k, p in enumerate(procs):
            try:
                p.start()
            except OSError as exc:  # no process to be had (EAGAIN, ENOMEM): those started are stopped below
                failure = f"worker {k} (of workers 0..{len(procs) - 1}) could not be started ({exc})"
                break
        for _, w in pipes:
            w.close()  # the worker holds its write end alone, so its pipe reads as ended when it dies
        looked = time.monotonic()
        heard = [looked] * len(procs)  # when each worker last reported
        while not failure and len(finished) < len(procs):
            ready = mp_connection.wait(list(reading), timeout=_WORKER_POLL_S)
            now = time.monotonic()
            for r, k in [(r, k) for r, k in reading.items() if r in ready]:
                try:
                    kind, val = r.recv()  # a report is one write of under PIPE_BUF bytes: never read in part
                except EOFError:  # the worker ended, every report of it read: its exit code, looked at below, says how
                    del reading[r]
                    ended.add(k)
                    if k not in finished:
                        procs[k].join(timeout=5)  # its exit code, without waiting for a poll
                    continue
                heard[k] = now
                if kind == "frames":
                    done += val
                    show(done)
                elif kind == "done":
                    finished.add(k)
                    for key in times:
                        times[key] += val[key]
            if ready and now - looked < _WORKER_POLL_S:
                continue
            looked = now
            # the latter: ended (its pipe read to the end) without saying it was done
            dead = [(k, p) for k, p in enumerate(procs) if p.exitcode not in (None, 0)
                    or (k in ended and k not in finished)]
            if dead:  # the exit codes as the workers died, before the others are stopped below
                failure = "; ".join(_death_note(k, p.pid, p.exitcode) for k, p in dead)
                break
            hung = [(k, p) for k, p in enumerate(procs) if k not in finished and now - heard[k] > _WORKER_STALL_S]
            if hung:
                failure = "; ".join(f"worker {k} (pid {p.pid}) reported nothing for {now - heard[k]:.0f} s (over "
                                    f"the {_WORKER_STALL_S:.0f} s allowed: taken as hung)" for k, p in hung)
                break
    finally:
        stop = len(finished) < len(procs)
        for p in procs:
            if p.pid is None:  # never started
                continue
            if stop and p.is_alive():  # the rest of a failed run is not waited for: a rerun resumes it
                p.terminate()
                with contextlib.suppress(OSError):  # a stopped worker (SIGSTOP, ^Z) takes its SIGTERM only
                    os.kill(p.pid, signal.SIGCONT)  # once continued
            p.join(timeout=30)
            if p.is_alive():
                p.kill()
                p.join(timeout=10)
        ends = [(p.pid, p.exitcode) for p in procs]  # read before close(), after which a Process says nothing
        for p in procs:
            with contextlib.suppress(ValueError):  # its sentinel's descriptor; still running after the kill: left
                p.close()
        for r, w in pipes:
            r.close()
            w.close()  # closed already, but where an exception came between the start and their closing
    if not failure:  # every worker said it was done: one that then failed on its way out
        failure = "; ".join(f"worker {k} (pid {pid}) ended with exit code {code}{_signal_name(code)} "
                            f"after its last frame" for k, (pid, code) in enumerate(ends) if code)
    if failure:
        raise WorkerError(f"generate into {cfg.out}: {failure}, after {done} of {total} frames; "
                          f"the other workers were stopped and every frame written is kept: run the same command "
                          f"again to write the rest")
    return done, times


def _death_note(k: int, pid: int | None, exitcode: int | None) -> str:
    """How worker ``k`` failed before its last frame: died (a non-zero exit code, and the signal), ended with 0, or
    closed its pipe and still runs (None: its join timed out)."""
    if exitcode:
        return f"worker {k} (pid {pid}) died with exit code {exitcode}{_signal_name(exitcode)}"
    if exitcode == 0:
        return f"worker {k} (pid {pid}) ended (exit code 0) before its last frame"
    return f"worker {k} (pid {pid}) closed its pipe before its last frame and did not end"


def _signal_name(exitcode: int | None) -> str:
    """`` (SIGKILL)`` for a process a signal ended (a negative exit code), else nothing."""
    if exitcode is None or exitcode >= 0:
        return ""
    try:
        return f" ({signal.Signals(-exitcode).name}{': killed, often for memory' if exitcode == -9 else ''})"
    except ValueError:
        return ""


_WORKER_POLL_S = 0.5  # how often the parent looks at the workers' exit codes
_WORKER_STALL_S = 600.0  # a live worker that reports nothing for this long is taken as hung


def _check_same_asset(out: Path, have: list[str]) -> None:
    """Refuse to continue a folder whose frames show the animals otherwise: a resumed run would mix two assets
    (another body, other species' shapes) or two sets of coats (the other species' hides, say) in one dataset. The
    first and last frames written are checked; frames written before the appearance was recorded are checked on
    their asset alone."""
    from zebra_sim_ros.zebra.asset import appearance_digest, asset_digest

    now = (("asset_digest", "animal asset", asset_digest()),
           ("appearance_digest", "animal appearance (asset and coats)", appearance_digest()))
    for name in {*have[:1], *have[-1:]}:
        try:
            ann = json.loads((out / "annotations" / f"{name}.json").read_text())
        except (OSError, ValueError):
            continue  # a frame cut off mid-write is written again
        for key, what, ours in now:
            then = ann.get(key) or None
            if then is not None and then != ours:
                raise ParameterError("--out", str(out), f"a new folder, or this one emptied: its frames (e.g. {name}) "
                                     f"were rendered with {what} {then}, this code renders {what} {ours}")


_RESUMABLE = ("frames", "workers", "shard", "out")  # settings a run may change when it continues a folder
# settings added since folders were first written: what a record without one had. ``aim``: how the placer aimed
# the cameras, through the lens ("lens") or with the pinhole of the same field of view ("pinhole", as before it
# followed the lens): a lens folder from before cannot go on with the new aim
_ADDED = {"lens": [0.0] * 5, "aim": "pinhole"}


def _check_same_settings(out: Path, settings: dict[str, Any]) -> None:
    """Refuse to continue a folder whose frames were written with other settings (another size, split, look,
    placer...): a resumed run would mix them in one dataset. ``generate.json`` holds them from the start of every
    run; more frames, other workers or another shard may continue it. A setting the record lacks (written by an
    older version) is not compared, but for those added since (``_ADDED``), which had the value given there."""
    try:
        then = json.loads((out / "generate.json").read_text())["config"]
    except (OSError, ValueError, KeyError, TypeError):
        return
    if not isinstance(then, dict):
        return
    ours = json.loads(json.dumps(settings))  # tuples as lists, as the record holds them
    recorded = set(then)
    then = {**_ADDED, **then}
    for key, value in ours.items():
        if key not in _RESUMABLE and key in then and then[key] != value:
            there = "" if key in recorded else " (not recorded there: read as what it was before it was recorded)"
            raise ParameterError("--out", str(out), f"a new folder, or the settings its frames were written with "
                                 f"({key} {then[key]!r} there, {value!r} now{there})")


def generate(cfg: GenerateConfig, progress: Callable[[int, int, float], None] | None = None) -> dict[str, Any]:
    """Run (or continue) a generation; returns statistics. Rebuilds COCO and the YAML at the end."""
    from zebra_sim_ros.placement.config import PlacerConfig

    cfg.check()
    pc = PlacerConfig.from_params({**cfg.placer, "seed": cfg.seed})
    out = Path(cfg.out)
    for sub in ("images/train", "images/val", "labels/train", "labels/val", "ignore/train", "ignore/val", "masks",
                "depth", "annotations", "coco"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    cameras = [f"drone_{i}" for i in range(pc.num_cameras)]
    jobs = plan(cfg, len(cameras))
    have = {p.stem for p in (out / "annotations").glob("*.json")}
    _check_same_asset(out, sorted(have))
    settings = _config_json(cfg)
    _check_same_settings(out, settings)
    if not (out / "generate.json").is_file():  # the settings from the start: an interrupted run is checked too
        (out / "generate.json").write_text(json.dumps({"config": settings, "stats": None}, indent=1))
    todo = [j for j in jobs if not all(frame_name(j, c) in have for c in cameras)]
    total = len(todo) * len(cameras)
    t0 = time.perf_counter()
    done = 0
    times = {"place": 0.0, "render": 0.0, "label": 0.0, "write": 0.0}
    show = progress or (lambda d, n, t: _progress(d, n, t, sys.stderr))
    if todo:
        if cfg.workers == 1:
            pipe = _Pipeline(cfg)
            for job in todo:
                done += len(pipe.run(job))
                show(done, total, t0)
            times = pipe.times
        else:
            done, times = _run_workers(cfg, todo, total, lambda d: show(d, total, t0))
        if progress is None:
            sys.stderr.write("\n")
    seconds = time.perf_counter() - t0
    counts = finalize(out, cfg)
    stats = {"frames_written": done, "frames_skipped_complete": len(jobs) * len(cameras) - total,
             "seconds": round(seconds, 2), "frames_per_s": round(done / seconds, 3) if done else None,
             "time_split_s": {k: round(v, 2) for k, v in times.items()}, **counts}
    (out / "generate.json").write_text(json.dumps({"config": settings, "stats": stats}, indent=1))
    return stats


def _config_json(cfg: GenerateConfig) -> dict[str, Any]:
    d = asdict(cfg)
    d["worlds"] = list(cfg.worlds)
    d["shard"] = f"{cfg.shard[0]}/{cfg.shard[1]}"
    d["aim"] = "pinhole" if cfg.distortion.none else "lens"  # the placer aims through the lens (without one: alike)
    return d


BOX_SIZE_BINS_PX = (8, 16, 32, 96, 256)
"""Edges of the box-size histogram, in pixels of sqrt(width x height) of the visible box: under 8, 8-16, 16-32
(COCO small ends at 32), 32-96 (COCO medium), 96-256 and 256 or more."""


def box_size_histogram(sizes: list[float]) -> dict[str, int]:
    """Counts of box sizes (sqrt of area, px) per :data:`BOX_SIZE_BINS_PX` bin, in order, keyed like ``"8-16"``."""
    edges = (0, *BOX_SIZE_BINS_PX, float("inf"))
    counts, _ = np.histogram(np.asarray(sizes, dtype=np.float64), bins=np.asarray(edges, dtype=np.float64))
    pairs = zip(BOX_SIZE_BINS_PX[:-1], BOX_SIZE_BINS_PX[1:], strict=True)
    keys = [f"<{BOX_SIZE_BINS_PX[0]}", *(f"{a}-{b}" for a, b in pairs), f">={BOX_SIZE_BINS_PX[-1]}"]
    return {k: int(c) for k, c in zip(keys, counts, strict=True)}


def format_histogram(hist: dict[str, int], width: int = 40) -> list[str]:
    """Text bars of a histogram, one line per bin."""
    top = max(max(hist.values(), default=0), 1)
    return [f"{k:>8} px {v:7d} {'#' * round(width * v / top)}" for k, v in hist.items()]


def finalize(out: Path, cfg: GenerateConfig | None = None) -> dict[str, Any]:
    """Rebuild coco/{train,val}.json, the split lists and dataset.yaml from the annotation files."""
    out = Path(out)
    if not (out / "annotations").is_dir():
        raise ParameterError("--out", str(out), "a folder generate has written (it holds annotations/)")
    images: dict[str, list[dict[str, Any]]] = {"train": [], "val": []}
    anns: dict[str, list[dict[str, Any]]] = {"train": [], "val": []}
    kept = 0
    others: dict[str, int] = {}
    sizes: dict[str, list[float]] = {}
    for path in sorted((out / "annotations").glob("*.json")):
        meta = FrameAnnotation.from_json(path.read_text())
        image_id = len(images[meta.split]) + 1
        lab = meta.labels
        images[meta.split].append({"id": image_id, "file_name": meta.image, "width": lab.width, "height": lab.height,
                                   "frame": meta.frame, "world": meta.world.name,
                                   "time_of_day_h": meta.lighting.time_of_day_h})
        split_anns = anns[meta.split]
        for z in lab.zebras:
            if not z.is_zebra:
                if z.rle is not None and z.visible_pixels > 0:
                    split_anns.append(species_annotation(z, image_id, len(split_anns) + 1))
                    others[z.species] = others.get(z.species, 0) + 1
            elif z.kept:
                split_anns.append(zebra_annotation(z, image_id, len(split_anns) + 1))
                kept += 1
                x0, y0, x1, y1 = z.box_visible
                sizes.setdefault(meta.strategy, []).append(float(np.sqrt(max(x1 - x0, 0.0) * max(y1 - y0, 0.0))))
            elif z.dont_care and z.rle is not None:  # sets written before don't-care regions have no outline
                split_anns.append(crowd_annotation(z, image_id, len(split_anns) + 1))
    for split in ("train", "val"):
        coco = {"info": {"description": "zebra_sim_ros synthetic zebras", "version": "1"}, "licenses": [],
                "categories": [CATEGORY, *SPECIES_CATEGORIES], "images": images[split], "annotations": anns[split]}
        (out / "coco" / f"{split}.json").write_text(json.dumps(coco, separators=(",", ":")))
        (out / f"{split}.txt").write_text("".join(f"./{im['file_name']}\n" for im in images[split]))
    write_dataset_yaml(out, "zebra_sim_ros synthetic dataset (YOLO format); COCO in coco/")
    return {"images_train": len(images["train"]), "images_val": len(images["val"]), "zebras_labelled": kept,
            "other_species_labelled": dict(sorted(others.items())),
            "box_sizes_px": box_size_histogram([v for vs in sizes.values() for v in vs]),
            "box_sizes_px_by_strategy": {k: box_size_histogram(v) for k, v in sorted(sizes.items())}}
