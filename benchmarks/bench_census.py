"""Benchmark: one herd counted once across the drones (``geometry.census.join_views``), and how fast.

Renders ``--steps`` steps of the default world (the placer's defaults, its three cameras, ``--size``, the camera
node's photographic sensor) and places
on the map (``geometry.locate.locate_boxes``, the rendered depth, each camera's pose) two kinds of boxes:

- perfect ones: every labelled zebra's visible box (each knows its zebra);
- with ``--detector``, the shipped weights' zebra boxes at the detector node's defaults (conf 0.25, the checkpoint's
  scale rule), each given the zebra
  whose visible box it overlaps most (IoU 0.5 or more; any zebra seen, labelled or not), or none (a false box).

With ``--gnss``, the same boxes are placed again from each camera's pose as the drone's navigation gives it (the
placer's ``camera/pose_nav``: the camera moved by the GNSS error of the scene's seed and step,
``geodesy.NavNoise``; each ``SIGMA[:COMMON]`` a horizontal sigma in m, twice it up, and the share of its variance
common to the drones), which moves every point of a camera by its error; with ``--attitude``, from each camera
turned by its navigation's attitude error (``TILT:HEADING`` in degrees, the placer's ``nav_*``), which turns its
points about it. The census of each is scored alike.

Per step the three views' points are joined into animals at each ``--gates`` (standard deviations) and
``--separations`` (one camera's points closer than this on the ground are one animal; 0: never), and scored against
the zebras the boxes came from: the animals counted against the distinct zebras among them (the true count); the
zebras split over two or more animals (counted twice); the animals that join two zebras (one lost); and for the
detector the animals made of false boxes only. The sum of the three cameras' boxes is the count without joining.
Also the milliseconds a step's joining takes, against its three renders, measured in the same run.

    python benchmarks/bench_census.py [--steps 10] [--first 0] [--size 1280x720] [--detector] [--gates 4]
        [--separations 0 0.5] [--gnss 0.5 2.5 2.5:0.9] [--attitude 0.2:0.5 0.5:2] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np

from zebra_sim_ros.geometry.census import CENSUS_GATE, CENSUS_SEPARATION_M, join_views
from zebra_sim_ros.geometry.geodesy import NavNoise
from zebra_sim_ros.geometry.locate import locate_boxes
from zebra_sim_ros.messages import Scene, SceneCamera
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.placer import Placer
from zebra_sim_ros.rendering.config import CameraConfig
from zebra_sim_ros.simulation import Frame, Simulator
from zebra_sim_ros.world.world import load_world
from zebra_sim_ros.zebra.asset import load_library

# (N, 3) points on the map, (N,) zebra ids (-1: none), the camera's position, (N,) scores (the labels' all 1)
View = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class RenderedCamera(NamedTuple):
    """One camera of one step of the default world, rendered (with :func:`rendered_cameras`)."""

    step: int
    scene: Scene
    cam: SceneCamera
    frame: Frame
    k: np.ndarray  # the camera's 3x3 intrinsics
    render_ms: float


def rendered_cameras(size: str, steps: int, first: int = 0, strategy: str | None = None) -> Iterator[RenderedCamera]:
    """Steps ``first`` .. ``first + steps - 1`` of the default world (the placer's defaults, or its ``strategy``; its
    three cameras), each camera rendered at ``size`` ("1280x720") as the camera node renders it (its photographic
    sensor): the render loop of this benchmark and of ``bench_locate.py``."""
    w, h = (int(v) for v in size.split("x"))
    pc = PlacerConfig.from_params({"strategy": strategy} if strategy else {})
    cc = CameraConfig(width=w, height=h)
    world = load_world(pc.world, pc.terrain_prim, pc.world_seed)
    lib = load_library()
    placer = Placer(pc, world, lib)
    sim = Simulator(world, lib, cc.render_options(), sensor=cc.sensor_model())  # as the camera node renders
    try:
        for step in range(first, first + steps):
            scene = placer.scene(step)
            for cam in scene.cameras:
                t0 = time.perf_counter()
                frame = sim.simulate(scene, [cam.name])[0]
                yield RenderedCamera(step, scene, cam, frame, sim.renderer.camera.K, (time.perf_counter() - t0) * 1e3)
    finally:
        sim.release()


def shipped_detector() -> Any:
    """The shipped weights on the CPU, at the detector node's defaults."""
    from zebra_sim_ros.detection.checkpoint import load_model, select_device

    return load_model(None, select_device("cpu"))[0]


def detected_zebras(model: Any, rgb: np.ndarray) -> np.ndarray:
    """The detector's zebra boxes of one image: (N, 6) float64 rows x0, y0, x1, y1, score, class."""
    from zebra_sim_ros.detection.predict import detect

    found = detect(model, [rgb])[0]
    return found[found[:, 5] == 0].astype(np.float64)


def box_owners(boxes: np.ndarray, seen: Sequence[Any]) -> np.ndarray:
    """For each box (N, 4), the index in ``seen`` (labelled zebras) of the one whose visible box it overlaps most,
    IoU 0.5 or more; -1 for none (a false box)."""
    from zebra_sim_ros.detection.metrics import iou_matrix

    owner = np.full(len(boxes), -1, np.int64)
    if seen and len(boxes):
        iou = iou_matrix(boxes, np.array([z.box_visible for z in seen], np.float64).reshape(-1, 4))
        hit = iou.max(axis=1) >= 0.5
        owner[hit] = iou.argmax(axis=1)[hit]
    return owner


def views_of_steps(steps: int, size: str, detector: bool, first: int = 0) -> tuple[list[dict[str, list[View]]],
                                                                                 list[float], list[tuple[int, int]]]:
    """Per step, per kind of box ("labels", and "detector" with it), the three cameras' placed points and ids;
    the milliseconds of each render; and each step's scene seed and step."""
    model = shipped_detector() if detector else None
    out: list[dict[str, list[View]]] = []
    render_ms: list[float] = []
    at: list[tuple[int, int]] = []
    current = -1
    for r in rendered_cameras(size, steps, first):
        if r.step != current:
            current = r.step
            out.append({"labels": [], "detector": []})
            at.append((r.scene.seed, r.scene.step))
        kinds = out[-1]
        render_ms.append(r.render_ms)
        pose = (r.k, np.array(r.cam.position), np.array(r.cam.orientation_xyzw))
        kept = r.frame.labels.kept
        boxes = np.array([z.box_visible for z in kept], np.float64).reshape(-1, 4)
        got = locate_boxes(boxes, r.frame.view.depth, *pose)
        ids = np.array([z.id for z in kept], np.int64)
        kinds["labels"].append((got.points[got.valid], ids[got.valid], pose[1], np.ones(int(got.valid.sum()))))
        if model is not None:
            found = detected_zebras(model, r.frame.view.rgb)
            seen = [z for z in r.frame.labels.zebras if z.is_zebra]
            owner = box_owners(found[:, :4], seen)
            ids = np.array([seen[int(j)].id if j >= 0 else -1 for j in owner], np.int64)
            placed = locate_boxes(found[:, :4], r.frame.view.depth, *pose)
            ok = placed.valid
            kinds["detector"].append((placed.points[ok], ids[ok], pose[1], found[ok, 4]))
    return out, render_ms, at


def navigated(views_by_step: list[list[View]], at: list[tuple[int, int]], gnss: NavNoise,
              attitude: NavNoise) -> list[list[View]]:
    """The views placed from the cameras' navigated poses instead (the placer's ``camera/pose_nav``): a box's
    point lies on its ray at its depth from the camera, so turning the camera by its attitude error turns its
    points about it, and moving it by its GNSS error moves them by as much."""
    out = []
    for views, (seed, step) in zip(views_by_step, at, strict=True):
        err = gnss.errors(len(views), seed, step)
        turn = attitude.rotations(len(views), seed, step)
        out.append([(v[2] + err[i] + (v[0] - v[2]) @ turn[i].T, v[1], v[2] + err[i], v[3])
                    for i, v in enumerate(views)])
    return out


def gnss_setting(text: str) -> NavNoise:
    """``SIGMA[:COMMON]``: a horizontal sigma in m (twice it up), white, with that share common to the drones."""
    sigma, _, common = text.partition(":")
    try:
        return NavNoise(float(sigma), 2.0 * float(sigma), 0.0, float(common or 0.0))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--gnss {text!r}: want SIGMA[:COMMON] ({exc})") from None


def attitude_setting(text: str) -> NavNoise:
    """``TILT:HEADING``: the navigation's attitude sigmas in degrees (the placer's ``nav_*``), white."""
    tilt, _, heading = text.partition(":")
    try:
        return PlacerConfig.from_params({"nav_tilt_sigma_deg": float(tilt),
                                         "nav_heading_sigma_deg": float(heading or 0.0)}).attitude_noise()
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--attitude {text!r}: want TILT:HEADING ({exc})") from None


def score_census(views_by_step: list[list[View]], gate: float, separation: float) -> dict[str, Any]:
    """The census of every step at ``gate`` and ``separation`` against the zebras its boxes came from (module
    docstring)."""
    tally: Counter[str] = Counter()
    join_ms: list[float] = []
    for views in views_by_step:
        t0 = time.perf_counter()
        census = join_views([v[0] for v in views], [v[2] for v in views], gate=gate, separation_m=separation,
                            scores=[v[3] for v in views])
        join_ms.append((time.perf_counter() - t0) * 1e3)
        truth = {int(i) for v in views for i in v[1] if i >= 0}
        animal_ids = [{int(views[v][1][i]) for v, i in census.points_of(a) if views[v][1][i] >= 0}
                      for a in range(census.count)]
        holders = Counter(i for s in animal_ids for i in s)
        tally["boxes"] += sum(len(v[0]) for v in views)
        tally["animals"] += census.count
        tally["true"] += len(truth)
        tally["split"] += sum(n - 1 for n in holders.values())
        tally["merged"] += sum(len(s) - 1 for s in animal_ids if len(s) > 1)
        tally["false_only"] += sum(1 for s in animal_ids if not s)
    true = max(tally["true"], 1)
    return {"gate": gate, "separation_m": separation, **dict(tally),
            "error": round((tally["animals"] - tally["true"]) / true, 4),
            "summed_error": round((tally["boxes"] - tally["true"]) / true, 4),
            "join_ms_per_step": round(statistics.median(join_ms), 2) if join_ms else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--first", type=int, default=0, help="the first step (the defaults were chosen on steps 0-9)")
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--detector", action="store_true", help="also count the shipped detector's boxes")
    ap.add_argument("--gates", type=float, nargs="+", default=[CENSUS_GATE], help="in standard deviations")
    ap.add_argument("--separations", type=float, nargs="+", default=[0.0, CENSUS_SEPARATION_M],
                    help="one camera's points closer than this on the ground are one animal, m")
    ap.add_argument("--gnss", type=gnss_setting, nargs="*", default=[],
                    help="SIGMA[:COMMON]: the census again with the boxes placed from each drone's GNSS position")
    ap.add_argument("--attitude", type=attitude_setting, nargs="*", default=[],
                    help="TILT:HEADING (deg): the census again with the boxes placed from each camera turned by its "
                         "navigation's attitude error (positions exact)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    steps, render_ms, at = views_of_steps(args.steps, args.size, args.detector, args.first)
    out: dict[str, Any] = {
        "date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores", "steps": args.steps, "first": args.first, "size": args.size,
        "render_ms_per_step": round(statistics.median(render_ms) * 3, 1)}
    exact = NavNoise()
    for kind in ("labels", "detector") if args.detector else ("labels",):
        out[kind] = [score_census([s[kind] for s in steps], g, sep) for sep in args.separations for g in args.gates]
        for gnss, attitude in [(n, exact) for n in args.gnss] + [(exact, a) for a in args.attitude]:
            moved = navigated([s[kind] for s in steps], at, gnss, attitude)
            out[kind] += [{"gnss_sigma_m": gnss.sigma_h_m, "gnss_common": gnss.common_fraction,
                           "tilt_deg": attitude.sigma_h_m, "heading_deg": attitude.sigma_v_m,
                           **score_census(moved, g, sep)} for sep in args.separations for g in args.gates]
    if args.json:
        print(json.dumps(out, indent=1))
        return
    for k, v in out.items():
        if isinstance(v, list):
            print(f"{k}:")
            for row in v:
                print("  " + ", ".join(f"{a}={b}" for a, b in row.items()))
        else:
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
