"""``zebra-sim generate``: YOLO and COCO that agree, deterministic, resumable, shardable, split by placement."""

from __future__ import annotations

import argparse
import json
import re
import shlex
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from cli_helpers import CliRun
from pycocotools.coco import COCO

from zebra_sim_ros.dataset.generate import GenerateConfig, Job, frame_name, generate, plan, stream_seed
from zebra_sim_ros.errors import ParameterError

SMALL = {"frames": 12, "strategy": "both", "worlds": ("savanna",), "seed": 5, "width": 320, "height": 180,
         "placer": {"count_max": 60}}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "a"
    stats = generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    assert stats["frames_written"] == 12
    return out


def test_layout_and_yaml(dataset: Path) -> None:
    y = yaml.safe_load((dataset / "dataset.yaml").read_text())
    assert y["names"] == {0: "zebra"} and y["nc"] == 1
    images = sorted((dataset / y["train"]).glob("*.jpg")) + sorted((dataset / y["val"]).glob("*.jpg"))
    assert len(images) == 12
    for img in images:
        split = img.parent.name
        assert (dataset / "labels" / split / f"{img.stem}.txt").exists()
        assert (dataset / "masks" / f"{img.stem}.png").exists()
        assert np.load(dataset / "depth" / f"{img.stem}.npz")["depth"].dtype == np.float32
        assert cv2.imread(str(img)).shape == (180, 320, 3)


def test_a_generated_folder_is_read_through_its_yaml(dataset: Path) -> None:
    from zebra_sim_ros.detection.data import YoloDataset, resolve_split

    for split in ("train", "val"):
        assert resolve_split(dataset, split) == dataset / "images" / split  # not the root, masks and all
    files = YoloDataset(resolve_split(dataset, "train")).files
    assert files and files == sorted((dataset / "images" / "train").glob("*.jpg"))


def test_a_world_named_twice_and_finalizing_a_folder_never_generated_are_refused_by_name(tmp_path: Path,
                                                                                      cli: CliRun) -> None:
    """``--worlds savanna,savanna`` planned every savanna step twice (two jobs for one frame); ``--finalize-only`` on a
    folder that generate never wrote ended in a traceback about coco/train.json. Both are refused, naming the
    option."""
    from zebra_sim_ros.dataset.generate import finalize
    from zebra_sim_ros.errors import ParameterError

    with pytest.raises(ParameterError, match=r"'--worlds' = 'savanna,zoo,savanna'.*each world once"):
        GenerateConfig(out=str(tmp_path / "x"), frames=6, worlds=("savanna", "zoo", "savanna")).check()
    with pytest.raises(ParameterError, match=r"'--out'.*nope.*annotations/"):
        finalize(tmp_path / "nope")
    r = cli(["generate", "--out", tmp_path / "nope", "--finalize-only"])  # --frames: not needed to finalize
    assert r.returncode == 2 and "annotations/" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "nope").exists()
    r = cli(["generate", "--out", tmp_path / "nope"])
    assert r.returncode == 2 and "'--frames'" in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_folder_is_continued_only_with_the_settings_its_frames_were_written_with(dataset: Path,
                                                                                    tmp_path: Path) -> None:
    """Continuing a folder with another frame size (or split, or placer setting) would mix two kinds of frame in
    one dataset: refused, naming the setting, every file left as it was. More frames and other workers continue
    it. The settings are recorded when a run starts, so a run cut short is checked as well; a record from before a
    setting existed is read as having had its old value (no lens, the pinhole's aim)."""
    import shutil

    from zebra_sim_ros.dataset.generate import _config_json
    from zebra_sim_ros.errors import ParameterError

    out = tmp_path / "more"
    shutil.copytree(dataset, out)
    before = {q: q.read_bytes() for q in out.rglob("*") if q.is_file()}
    for change, named in (({"width": 352}, "width 320 there, 352 now"), ({"val_fraction": 0.5}, "val_fraction"),
                          ({"placer": {"count_max": 61}}, "placer")):
        with pytest.raises(ParameterError, match=rf"'--out'.*{named}"):
            generate(GenerateConfig(out=str(out), **{**SMALL, **change}), progress=lambda *a: None)
        assert {q: q.read_bytes() for q in out.rglob("*") if q.is_file()} == before
    stats = generate(GenerateConfig(out=str(out), **{**SMALL, "frames": 15, "workers": 2}), progress=lambda *a: None)
    assert stats["frames_skipped_complete"] == 12 and stats["frames_written"] > 0  # the twelve kept, more added
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / "generate.json").write_text(json.dumps({"config": {"width": 640, "seed": 5}, "stats": None}))
    with pytest.raises(ParameterError, match="width 640 there, 320 now"):  # a run cut short left only this
        generate(GenerateConfig(out=str(cut), **SMALL), progress=lambda *a: None)
    # a record from before the lens was a setting had none: continued without one, refused with one
    old = tmp_path / "old"
    shutil.copytree(dataset, old)
    record = json.loads((old / "generate.json").read_text())
    assert record["config"]["aim"] == "pinhole"  # no lens: the placer's aim is the pinhole's
    del record["config"]["lens"], record["config"]["aim"]
    (old / "generate.json").write_text(json.dumps(record))
    assert generate(GenerateConfig(out=str(old), **SMALL), progress=lambda *a: None)["frames_written"] == 0
    # a lens folder from before the placer aimed through the lens (its record has the lens, not the aim): refused
    lens = {**SMALL, "lens": (-0.1, 0.0, 0.0, 0.0, 0.0)}
    settings = _config_json(GenerateConfig(out=str(cut), **lens))
    assert settings["aim"] == "lens"
    del settings["aim"]
    (cut / "generate.json").write_text(json.dumps({"config": settings, "stats": None}))
    with pytest.raises(ParameterError, match="aim 'pinhole' there, 'lens' now .not recorded there"):
        generate(GenerateConfig(out=str(cut), **lens), progress=lambda *a: None)
    (cut / "generate.json").write_text(json.dumps({"config": {"width": 320, "seed": 5}, "stats": None}))
    with pytest.raises(ParameterError, match=r"lens \[0.0, 0.0, 0.0, 0.0, 0.0\] there, \[-0.1, 0.0"):
        generate(GenerateConfig(out=str(cut), **{**SMALL, "lens": (-0.1, 0.0, 0.0, 0.0, 0.0)}),
                 progress=lambda *a: None)


def test_a_folder_whose_name_yaml_would_misread_is_still_the_yaml_path(dataset: Path, tmp_path: Path) -> None:
    """dataset.yaml quotes its path: a folder named with " #" (a YAML comment) or ": " (a mapping) is read back
    whole, and the trainer's loader finds its images through it."""
    import shutil

    from zebra_sim_ros.dataset.generate import finalize
    from zebra_sim_ros.detection.data import YoloDataset, resolve_split

    for name in ("set #2", "a: b"):
        out = tmp_path / name
        shutil.copytree(dataset, out)
        finalize(out)
        assert yaml.safe_load((out / "dataset.yaml").read_text())["path"] == str(out.resolve())
        assert YoloDataset(resolve_split(out / "dataset.yaml", "train")).files == sorted(
            (out / "images" / "train").glob("*.jpg"))


def test_coco_loads_and_equals_yolo(dataset: Path) -> None:
    """Kept zebras: COCO annotations = labels/; zebras seen but dropped by the filters: COCO crowds = ignore/."""
    checked = {0: 0, 1: 0}
    for split in ("train", "val"):
        coco = COCO(str(dataset / "coco" / f"{split}.json"))
        cat = coco.loadCats(1)[0]
        assert cat["name"] == "zebra" and len(cat["keypoints"]) == 26 and cat["skeleton"]
        for img in coco.loadImgs(coco.getImgIds()):
            stem = Path(img["file_name"]).stem
            mask = cv2.imread(str(dataset / "masks" / f"{stem}.png"), cv2.IMREAD_UNCHANGED)
            for crowd, folder in ((0, "labels"), (1, "ignore")):
                anns = coco.loadAnns(coco.getAnnIds(imgIds=img["id"], catIds=[1], iscrowd=None))  # zebras
                anns = [a for a in anns if a["iscrowd"] == crowd]
                path = dataset / folder / split / f"{stem}.txt"
                lines = path.read_text().split() if path.exists() else []
                yolo = np.array(lines, dtype=float).reshape(-1, 5) if lines else np.zeros((0, 5))
                assert len(yolo) == len(anns)
                for a, row in zip(anns, yolo, strict=True):
                    x, y, w, h = a["bbox"]
                    np.testing.assert_allclose(row[1:], [(x + w / 2) / 320, (y + h / 2) / 180, w / 320, h / 180],
                                               atol=1e-6)
                    m = coco.annToMask(a)
                    assert np.array_equal(m.astype(bool), mask == a["zebra_id"] + 1)
                    assert m.sum() == a["area"]
                    if crowd:
                        assert a["area"] > 0 and a["drop_reason"] in (
                            "min_visible_pixels", "min_visible_fraction", "min_box_px", "max_aspect_ratio")
                    else:
                        assert len(a["keypoints"]) == 78
                    checked[crowd] += 1
    assert checked[0] > 20 and checked[1] > 0


def test_validation_reads_the_dont_care_boxes(dataset: Path) -> None:
    from zebra_sim_ros.detection.data import YoloDataset, resolve_split
    from zebra_sim_ros.messages import FrameAnnotation

    seen = 0
    for split in ("train", "val"):
        if not any((dataset / "images" / split).iterdir()):
            continue
        ds = YoloDataset(resolve_split(dataset, split), 320)
        for i, f in enumerate(ds.files):
            meta = FrameAnnotation.from_json((dataset / "annotations" / f"{f.stem}.json").read_text())
            want = [z.box_visible for z in meta.labels.dont_care]
            got = ds[i][2].ignore[:, 1:]  # image pixels
            np.testing.assert_allclose(got, np.array(want).reshape(-1, 4), atol=0.01)
            seen += len(want)
    assert seen > 0


def test_split_is_by_placement(dataset: Path) -> None:
    splits: dict[tuple[str, int, int], set[str]] = {}
    for p in (dataset / "annotations").glob("*.json"):
        m = json.loads(p.read_text())
        splits.setdefault((m["strategy"], m["seed"], m["placement"]), set()).add(m["split"])
        assert m["labels"]["camera"] in m["frame"] and m["camera"]["name"] == m["labels"]["camera"]
    assert all(len(s) == 1 for s in splits.values())


def test_same_seed_same_bytes_and_resume(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "b"
    generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    for sub in ("annotations", "masks", "labels/train", "labels/val"):
        for p in (dataset / sub).glob("*"):
            assert p.read_bytes() == (out / sub / p.name).read_bytes(), p.name
    assert (dataset / "coco" / "train.json").read_bytes() == (out / "coco" / "train.json").read_bytes()
    # Interrupted run: one camera's frame is missing; a rerun redoes that step only and nothing else.
    victim = sorted((out / "annotations").glob("*.json"))[4]
    before = {p.name: p.stat().st_mtime_ns for p in (out / "annotations").glob("*.json")}
    victim.unlink()
    stats = generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    assert stats["frames_written"] == 3 and stats["frames_skipped_complete"] == 9
    assert victim.read_bytes() == (dataset / "annotations" / victim.name).read_bytes()
    after = {p.name: p.stat().st_mtime_ns for p in (out / "annotations").glob("*.json")}
    step = victim.name.rsplit("_drone_", 1)[0]
    untouched = [n for n in before if not n.startswith(step)]
    assert all(before[n] == after[n] for n in untouched)


@pytest.mark.parametrize(("sig", "said"), [
    ("SIGKILL", r"died with exit code -9 \(SIGKILL"),
    ("SIGSTOP", r"reported nothing for \d+ s \(over the 3 s allowed: taken as hung\)")])
def test_a_worker_killed_or_hung_mid_run_stops_generate_at_once_and_a_rerun_completes_it(
        dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sig: str, said: str) -> None:
    """A worker the OOM killer takes (SIGKILL, after the run's first frame) sends nothing more: generate stops within
    seconds with an error naming that worker, its exit code and signal (it once waited ten minutes for a report),
    and stops the other worker too. A worker that hangs (stopped by SIGSTOP; the silence allowed cut to 3 s once both
    run) is found while the other still reports, named, and ended although stopped. Nothing written is lost: a rerun
    writes only what is missing, the same bytes as an unbroken run."""
    import multiprocessing
    import os
    import signal
    import time

    from zebra_sim_ros.dataset import generate as generate_module
    from zebra_sim_ros.errors import WorkerError

    out = tmp_path / "broken"
    before = set(multiprocessing.active_children())
    hit: list[tuple[int, float]] = []

    def break_one(done: int, total: int, t0: float) -> None:
        if not hit:  # the run's first report (from either worker)
            workers = sorted(set(multiprocessing.active_children()) - before, key=lambda p: p.pid or 0)
            assert len(workers) == 2, workers
            assert workers[0].pid is not None
            os.kill(workers[0].pid, getattr(signal, sig))
            hit.append((workers[0].pid, time.monotonic()))
        elif len(hit) == 1:  # the next, from the other worker: it is past its pipeline's building (seconds) too,
            monkeypatch.setattr(generate_module, "_WORKER_STALL_S", 3.0)  # so the silence allowed can be cut
            hit.append((0, 0.0))  # (SMALL gives each worker two jobs: after the first report the other worker
            # always reports once more, whichever worker sent it; on its own pipe, so a worker stopped in the
            # middle of a report cannot hold that back, as a shared queue's write lock could)

    with pytest.raises(WorkerError) as err:
        generate(GenerateConfig(out=str(out), workers=2, **SMALL), progress=break_one)
    # a death is seen within a poll; a hang after the silence allowed, once the other worker has reported again
    assert hit and time.monotonic() - hit[0][1] < (20 if sig == "SIGKILL" else 60), "generate waited on a worker"
    message = str(err.value)
    assert re.search(rf"\(pid {hit[0][0]}\) {said}", message), message
    assert str(out) in message and "run the same command again" in message
    # the worker the parent stopped itself is not reported as a failure (its exit code -15; the folder's path, under
    # pytest's numbered temporary folders, may hold "-15" too: pytest-150)
    assert "code -15" not in message.replace(str(out), "") and "SIGTERM" not in message
    assert set(multiprocessing.active_children()) <= before  # every worker ended, the stopped one too
    with pytest.raises(ProcessLookupError):
        os.kill(hit[0][0], 0)  # reaped, not left stopped
    kept = len(list((out / "annotations").glob("*.json")))
    assert 0 < kept < 12
    stats = generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    assert stats["frames_written"] + stats["frames_skipped_complete"] == 12 and stats["frames_written"] < 12
    for p in (dataset / "annotations").glob("*.json"):
        assert p.read_bytes() == (out / "annotations" / p.name).read_bytes(), p.name


@pytest.mark.parametrize(("worker", "said"), [
    ("reports_then_returns", r"worker 0 \(pid \d+\) ended \(exit code 0\) before its last frame"),
    ("closes_its_pipe_and_stays", r"worker 0 \(pid \d+\) closed its pipe before its last frame and did not end")])
def test_a_worker_that_ends_its_pipe_before_it_is_done_is_named_at_once(tmp_path: Path, worker: str,
                                                                          said: str) -> None:
    """A worker whose pipe ends before it said it was done is a failure seen as the pipe ends, not after the ten
    minutes of silence allowed a hung one: whether it ended with exit code 0 (nothing else tells it from a worker
    that finished) or closed its pipe and went on running (then it is ended, not left behind)."""
    import multiprocessing
    import time

    import worker_helpers

    from zebra_sim_ros.dataset.generate import _run_workers
    from zebra_sim_ros.errors import WorkerError

    before = set(multiprocessing.active_children())
    cfg = GenerateConfig(out=str(tmp_path / "x"), workers=1, **SMALL)
    shown: list[int] = []
    t0 = time.monotonic()
    with pytest.raises(WorkerError) as err:
        _run_workers(cfg, plan(cfg, 3), 36, shown.append, worker=getattr(worker_helpers, worker))
    assert time.monotonic() - t0 < 60, "the parent waited out the silence allowed"
    message = str(err.value)
    assert re.search(said, message), message
    assert shown == ([1] if worker == "reports_then_returns" else [])  # what it reported still counts
    assert f"after {shown[-1] if shown else 0} of 36 frames" in message
    assert set(multiprocessing.active_children()) <= before  # the one that stayed was ended


def test_a_worker_that_cannot_be_started_stops_those_started(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The system refusing the second worker's process (EAGAIN) is an error naming that worker, and the first one,
    already running, is ended and reaped: no process is left behind and no pipe left open."""
    import errno
    import multiprocessing
    import multiprocessing.context as mp_context
    import os
    from multiprocessing import resource_tracker

    import worker_helpers

    from zebra_sim_ros.dataset.generate import _run_workers
    from zebra_sim_ros.errors import WorkerError

    started: list[int] = []
    start = mp_context.SpawnProcess.start

    def refuse_the_second(self: mp_context.SpawnProcess) -> None:
        if started:
            raise OSError(errno.EAGAIN, os.strerror(errno.EAGAIN))
        start(self)
        assert self.pid is not None
        started.append(self.pid)

    monkeypatch.setattr(mp_context.SpawnProcess, "start", refuse_the_second)
    before = set(multiprocessing.active_children())
    resource_tracker.ensure_running()  # its pipe stays open for the process's life: opened before counting
    fds = len(os.listdir("/proc/self/fd"))
    cfg = GenerateConfig(out=str(tmp_path / "x"), workers=3, **SMALL)
    with pytest.raises(WorkerError) as err:
        _run_workers(cfg, plan(cfg, 3), 36, lambda d: None, worker=worker_helpers.reports_then_waits)
    message = str(err.value)
    assert "worker 1 (of workers 0..2) could not be started" in message, message
    assert os.strerror(errno.EAGAIN) in message, message
    assert "run the same command again" in message
    assert len(started) == 1 and set(multiprocessing.active_children()) <= before
    with pytest.raises(ProcessLookupError):
        os.kill(started[0], 0)  # reaped
    assert len(os.listdir("/proc/self/fd")) <= fds  # the six pipe ends and the started one's sentinel closed


@pytest.mark.parametrize(("key", "what"), [("asset_digest", "animal asset"),
                                           ("appearance_digest", r"animal appearance \(asset and coats\)")])
def test_a_folder_of_other_animals_is_not_continued(dataset: Path, tmp_path: Path, key: str, what: str) -> None:
    """Frames rendered with another version of the animals (their asset, or only their coats) are never mixed with
    this one's: continuing such a folder stops with an error naming --out and both digests, and leaves every file as
    it was."""
    import shutil

    from zebra_sim_ros.zebra.asset import appearance_digest

    out = tmp_path / "old"
    shutil.copytree(dataset, out)
    first = sorted((out / "annotations").glob("*.json"))[0]
    (out / "annotations" / sorted((out / "annotations").glob("*.json"))[-1].name).unlink()  # an unfinished run
    ann = json.loads(first.read_text())
    assert ann["appearance_digest"] == appearance_digest()  # recorded with every frame
    ann[key] = "0123456789abcdef"
    first.write_text(json.dumps(ann))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    bad = rf"--out.*{what} 0123456789abcdef, this code renders {what} [0-9a-f]{{16}}"
    with pytest.raises(ParameterError, match=bad):
        generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_a_folder_written_before_the_appearance_was_recorded_is_continued(dataset: Path, tmp_path: Path) -> None:
    """Annotations from before the appearance digest was recorded carry only the asset's: such a folder of today's
    asset is continued, and the frames written now record the appearance."""
    import shutil

    from zebra_sim_ros.zebra.asset import appearance_digest

    out = tmp_path / "older"
    shutil.copytree(dataset, out)
    files = sorted((out / "annotations").glob("*.json"))
    for f in files:
        ann = json.loads(f.read_text())
        del ann["appearance_digest"]
        f.write_text(json.dumps(ann))
    files[-1].unlink()
    stats = generate(GenerateConfig(out=str(out), **SMALL), progress=lambda *a: None)
    assert stats["frames_written"] == 3
    assert json.loads(files[-1].read_text())["appearance_digest"] == appearance_digest()
    assert "appearance_digest" not in json.loads(files[0].read_text())


def test_shards_partition_the_steps() -> None:
    cfg = GenerateConfig(out="x", frames=90, worlds=("savanna", "meadow"))
    full = set(plan(cfg, 3))
    parts = [set(plan(GenerateConfig(out="x", frames=90, worlds=("savanna", "meadow"), shard=(i, 3)), 3))
             for i in range(3)]
    assert set().union(*parts) == full and sum(len(p) for p in parts) == len(full)
    assert frame_name(Job("savanna", "far", 0, 7), "drone_2") == "savanna_far_0_000007_drone_2"


def test_every_world_and_strategy_draws_its_own_stream() -> None:
    # With one seed for every world, step k of each world had the same time of day, herd size and camera jitter:
    # seven worlds held a seventh of the lighting they seemed to.
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.sun import sample_time_and_day

    worlds = ("savanna", "grassland", "meadow", "woodland", "moorland", "snowy_highland", "scrubland", "farmland")
    jobs = plan(GenerateConfig(out="x", frames=8 * 2 * 3 * 2, worlds=worlds), 3)
    seeds = {(j.world, j.strategy): j.seed for j in jobs}
    assert len(seeds) == 16 and len(set(seeds.values())) == 16
    assert all(seeds[(w, "closeby")] == stream_seed(0, w, 1) for w in worlds)
    alone = plan(GenerateConfig(out="x", frames=2 * 3 * 2, worlds=("meadow",)), 3)
    assert {j.seed for j in alone} == {seeds[("meadow", "far")], seeds[("meadow", "closeby")]}  # others don't matter
    c = PlacerConfig()
    hours = {round(sample_time_and_day(np.random.default_rng([s, 0, 1]), c.night_fraction)[0], 6)
             for s in seeds.values()}
    assert len(hours) == 16  # the placer's first draw of step 0 (its time of day) differs in every stream


def test_cli_summary_and_bad_arguments(tmp_path: Path, cli: CliRun) -> None:
    proc = cli(["generate", "--frames", "3", "--strategy", "SC", "--imgsz", "256x144", "--out", tmp_path / "c",
                "--set", "count_max=20", "--json", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["frames_written"] == 3
    assert all("closeby" in p.name for p in (tmp_path / "c" / "annotations").glob("*.json"))
    for args, needle in ((["--frames", "0"], "--frames"), (["--frames", "3", "--strategy", "sideways"], "--strategy"),
                         (["--frames", "3", "--imgsz", "big"], "--imgsz"), (["--frames", "3", "--shard", "3/2"],
                                                                            "--shard")):
        bad = cli(["generate", *args, "--out", tmp_path / "d"])
        assert bad.returncode == 2 and needle in bad.stderr, (args, bad.stderr)


def test_image_sizes_parse_or_name_the_bad_value() -> None:
    import argparse

    from zebra_sim_ros.cli import parse_size, size_arg
    from zebra_sim_ros.cli.generate import parse_imgsz
    from zebra_sim_ros.errors import ParameterError

    assert parse_size("1280x720") == (1280, 720) and parse_size("16X8192") == (16, 8192)
    assert parse_imgsz("1920") == (1920, 1080) and parse_imgsz("640x360") == (640, 360)
    for text, named, allowed in (("1280", "--size", "WxH"), ("1280x720x3", "--size", "WxH"), ("axb", "--size", "WxH"),
                                 ("15x720", "--size", "16..8192"), ("1280x8193", "--size", "16..8192")):
        with pytest.raises(ParameterError, match=f"'{named}' = '{text}'.*{allowed}"):
            parse_size(text)
    for text in ("10", "big", "10x10"):
        with pytest.raises(ParameterError, match=f"'--imgsz' = '{text}'"):
            parse_imgsz(text)
    with pytest.raises(argparse.ArgumentTypeError, match="'64'"):
        size_arg("64")


def test_regenerate_command_reproduces_the_frames_scene(dataset: Path) -> None:
    # The fixture overrides a placer parameter (count_max): the command must carry it, or the herd and with it the
    # cameras differ.
    from zebra_sim_ros.cli import build_parser
    from zebra_sim_ros.cli.place import placer_values
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.world.world import load_world
    from zebra_sim_ros.zebra.asset import load_library

    for path in sorted((dataset / "annotations").glob("*_drone_1.json"))[:2]:
        meta = json.loads(path.read_text())
        assert "--set count_max=60" in meta["regenerate"]
        args = build_parser().parse_args(shlex.split(meta["regenerate"])[1:] + ["--out", "unused"])
        values = {**placer_values(argparse.Namespace(**{**vars(args), "start_step": None})),
                  "camera_width": args.width, "camera_height": args.height, "camera_hfov_deg": args.hfov_deg}
        cfg = PlacerConfig.from_params(values)
        scene = Placer(cfg, load_world(cfg.world), load_library()).scene(args.step)
        assert scene.lighting.to_dict() == meta["lighting"]
        assert scene.camera("drone_1").position == pytest.approx(meta["camera"]["position"])


def test_each_frame_records_its_drawn_camera(dataset: Path) -> None:
    """generate applies the photograph's camera by default, drawn per frame from the frame's seed, step and camera,
    and records the draw in the annotation, so the frame can be made again exactly."""
    from zebra_sim_ros.messages import FrameAnnotation
    from zebra_sim_ros.rendering.effects import SensorModel

    draws = {}
    for p in sorted((dataset / "annotations").glob("*.json")):
        meta = FrameAnnotation.from_json(p.read_text())
        assert meta.sensor is not None and 55 <= meta.sensor.jpeg_quality <= 95
        assert "--sensor-strength 1.0" in meta.regenerate
        order = int(meta.camera.name.split("_")[1])
        again = SensorModel().draw(np.random.default_rng([meta.seed, meta.step, order, 0x5E50]))
        assert again == meta.sensor
        draws[p.stem] = meta.sensor
    assert len(set(draws.values())) == len(draws)  # every frame its own camera


def test_low_and_nadir_frames_and_the_box_size_histogram(tmp_path: Path) -> None:
    """``--strategy all`` splits the frames over far, closeby, low and nadir; the run reports the size histogram of
    the boxes it labelled, per strategy, and the ground-level camera sees bigger zebras than the survey drone."""
    from zebra_sim_ros.dataset.generate import box_size_histogram
    from zebra_sim_ros.messages import FrameAnnotation

    cfg = GenerateConfig(out=str(tmp_path / "all"), frames=24, strategy="all", seed=4, width=320, height=180,
                         depth="none")
    stats = generate(cfg, progress=lambda *a: None)
    metas = [FrameAnnotation.from_json(p.read_text()) for p in sorted((tmp_path / "all" / "annotations").glob("*"))]
    by: dict[str, list[float]] = {}
    for m in metas:
        assert m.camera.strategy == m.strategy
        by.setdefault(m.strategy, []).extend(
            float(np.sqrt((z.box_visible[2] - z.box_visible[0]) * (z.box_visible[3] - z.box_visible[1])))
            for z in m.labels.zebras if z.kept)
    assert sorted(by) == ["closeby", "far", "low", "nadir"] and len(metas) == 24
    assert sum(stats["box_sizes_px"].values()) == stats["zebras_labelled"] == sum(len(v) for v in by.values())
    for strategy, sizes in by.items():
        assert stats["box_sizes_px_by_strategy"].get(strategy, box_size_histogram([])) == box_size_histogram(sizes)
    assert max(by["low"]) > 3 * max(by["nadir"] or [1.0])  # the nearest zebra of a low view fills much of it
    hist = box_size_histogram([3.0, 8.0, 15.9, 300.0, 96.0])
    assert list(hist) == ["<8", "8-16", "16-32", "32-96", "96-256", ">=256"]
    assert list(hist.values()) == [1, 2, 0, 0, 1, 1]


def test_a_default_run_holds_other_species_never_as_zebras(tmp_path: Path) -> None:
    """A default generate of 24 frames places animals of other species with the zebras: the annotations and COCO
    list them under their own categories (ids 2 and up), and the YOLO labels, the don't-care boxes and COCO's
    zebra category hold zebras only."""
    from zebra_sim_ros.messages import FrameAnnotation

    cfg = GenerateConfig(out=str(tmp_path / "d"), frames=24, seed=2, width=320, height=180, depth="none")
    stats = generate(cfg, progress=lambda *a: None)
    assert len(stats["other_species_labelled"]) >= 2, stats["other_species_labelled"]
    coco = {split: json.loads((tmp_path / "d" / "coco" / f"{split}.json").read_text()) for split in ("train", "val")}
    names = {c["id"]: c["name"] for c in coco["train"]["categories"]}
    assert names[1] == "zebra" and set(stats["other_species_labelled"]) <= set(names.values())
    per_cat: dict[str, int] = {}
    for c in coco.values():
        for a in c["annotations"]:
            per_cat[names[a["category_id"]]] = per_cat.get(names[a["category_id"]], 0) + 1
    assert {k: v for k, v in per_cat.items() if k != "zebra"} == stats["other_species_labelled"]
    yolo_lines = 0
    skies = set()
    randomised = 0
    for path in (tmp_path / "d" / "annotations").glob("*.json"):
        meta = FrameAnnotation.from_json(path.read_text())
        skies.add(meta.weather.cloud_cover)
        randomised += meta.weather.sky_tint != (1.0, 1.0, 1.0)
        others = [z for z in meta.labels.zebras if not z.is_zebra]
        assert all(not z.kept and not z.dont_care and z.drop_reason == "other_species" for z in others)
        assert {z.morph for z in others} == {z.species for z in others}
        label = tmp_path / "d" / "labels" / meta.split / f"{meta.frame}.txt"
        lines = label.read_text().split()
        assert len(lines) == 5 * len(meta.labels.kept)
        yolo_lines += len(meta.labels.kept)
    crowd_and_zebras = sum(1 for c in coco.values() for a in c["annotations"] if a["category_id"] == 1)
    assert crowd_and_zebras >= yolo_lines == stats["zebras_labelled"]
    # every step draws its own sky, and generate's default randomises the look of about half the steps
    assert len(skies) >= 4 and 0 < randomised < 24
    settings = json.loads((tmp_path / "d" / "generate.json").read_text())
    assert "look_randomise=0.5" in FrameAnnotation.from_json(path.read_text()).regenerate, settings


def test_randomise_zero_renders_the_worlds_as_authored(tmp_path: Path) -> None:
    from zebra_sim_ros.messages import FrameAnnotation, GroundLook

    cfg = GenerateConfig(out=str(tmp_path / "d"), frames=6, seed=2, width=160, height=90, depth="none",
                         randomise=0.0)
    generate(cfg, progress=lambda *a: None)
    for path in (tmp_path / "d" / "annotations").glob("*.json"):
        meta = FrameAnnotation.from_json(path.read_text())
        assert meta.ground == GroundLook() and meta.weather.sky_tint == (1.0, 1.0, 1.0)
        assert meta.lighting.sun_azimuth_deg == pytest.approx(
            float(np.degrees(np.arctan2(meta.lighting.sun_direction[0], meta.lighting.sun_direction[1])) % 360))
    with pytest.raises(Exception, match="--randomise"):
        GenerateConfig(out="x", frames=6, randomise=1.5).check()


def test_a_lens_goes_into_the_frames_their_labels_and_the_command_that_renders_them_again(tmp_path: Path,
                                                                                         cli: CliRun) -> None:
    """``generate --lens``: the settings record it, each frame's labels carry it as D, and the frame's ``regenerate``
    command, run, renders the very instance mask the dataset holds; a lens that folds over in the image is refused
    by name before anything is written."""
    from zebra_sim_ros.messages import FrameAnnotation

    out = tmp_path / "lens"
    proc = cli(["generate", "--frames", "3", "--imgsz", "256x144", "--lens", "-0.2", "0.05", "--out", out,
                "--set", "count_max=20", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "generate.json").read_text())["config"]["lens"] == pytest.approx(
        [-0.2, 0.05, 0.0, 0.0, 0.0], abs=1e-12)
    path = sorted((out / "annotations").glob("*_drone_0.json"))[0]
    meta = FrameAnnotation.from_json(path.read_text())
    assert meta.labels.D == pytest.approx((-0.2, 0.05, 0.0, 0.0, 0.0), abs=1e-12)
    assert " --lens -0.2 0.05 0.0 0.0 0.0" in meta.regenerate, meta.regenerate
    again = cli([*shlex.split(meta.regenerate)[1:], "--out", tmp_path / "again"])
    assert again.returncode == 0, again.stderr
    mask = cv2.imread(str(out / meta.mask), cv2.IMREAD_UNCHANGED)
    assert mask.any() and np.array_equal(mask, cv2.imread(str(tmp_path / "again" / "drone_0_instances.png"),
                                                         cv2.IMREAD_UNCHANGED))
    bad = cli(["generate", "--frames", "3", "--imgsz", "256x144", "--hfov", "120", "--lens", "-1", "--out",
               tmp_path / "bad"])
    assert bad.returncode == 2 and "'--lens'" in bad.stderr and "fold" in bad.stderr, bad.stderr
    assert not (tmp_path / "bad").exists()
