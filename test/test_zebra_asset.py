"""The baked cache and posing many zebras at once."""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from zebra_sim_ros.errors import AssetError, ParameterError
from zebra_sim_ros.geometry.rotations import rot_z
from zebra_sim_ros.zebra import coat
from zebra_sim_ros.zebra.asset import (
    CoatStore,
    ZebraLibrary,
    appearance_digest,
    asset_digest,
    build_library,
    load_library,
)
from zebra_sim_ros.zebra.skeleton import MORPHS


def test_manifest_and_frame_table(library: ZebraLibrary) -> None:
    assert library.n_frames == int(library.clip_frames.sum()) >= 600
    assert library.frame_index("walk", 0) == int(library.clip_start[library.clip_names.index("walk")])
    with pytest.raises(ParameterError, match="frame"):
        library.frame_index("walk", 10_000)
    # The zebra morphs first: the pool's morph_weights index them.
    assert library.morphs == ("plains", "grevy", "foal", "wildebeest", "impala", "giraffe", "buffalo", "cattle",
                              "donkey", "elephant", "rhino")
    assert library.manifest["digest"] in library.root.name


def test_load_reuses_the_cache_and_rejects_a_broken_one(library: ZebraLibrary, zebra_cache: Path,
                                                        tmp_path: Path) -> None:
    again = load_library(zebra_cache, build_if_missing=False)
    assert again.root == library.root
    assert np.array_equal(again.vertices(1, 100), library.vertices(1, 100))
    with pytest.raises(AssetError, match="asset build"):
        load_library(tmp_path / "empty", build_if_missing=False)
    broken = tmp_path / "broken" / library.root.name
    broken.mkdir(parents=True)
    (broken / "manifest.json").write_text(json.dumps(library.manifest))
    with pytest.raises(AssetError, match="lacks"):
        load_library(tmp_path / "broken", build_if_missing=False)


def test_rebuild_is_bit_identical(library: ZebraLibrary, tmp_path: Path) -> None:
    leftover = tmp_path / f"zebra-{asset_digest()}"  # an interrupted build: files but no manifest
    leftover.mkdir()
    (leftover / "joints.npy").write_bytes(b"junk")
    other = build_library(tmp_path)  # replaces it (it used to loop, rebuilding forever)
    for name in ("vertices_lod0", "vertices_lod1", "joints", "keypoints", "boxes"):
        assert np.array_equal(np.asarray(other._a[name]), np.asarray(library._a[name])), name


def test_pose_places_scales_and_rotates(library: ZebraLibrary) -> None:
    n = 5
    rng = np.random.default_rng(0)
    morph = rng.integers(0, 3, n)
    frame = rng.integers(0, library.n_frames, n)
    scale = rng.uniform(0.4, 1.0, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    rot = rot_z(yaw)
    t = rng.uniform(-50, 50, (n, 3))
    posed = library.pose(morph, frame, scale, rot, t)
    for i in range(n):
        local = library.vertices(int(morph[i]), int(frame[i])).astype(np.float64)
        expected = (local * scale[i]) @ rot[i].T + t[i]
        np.testing.assert_allclose(posed.vertices[i], expected, atol=1e-4)
        # Every vertex lies in its oriented box.
        rel = (posed.vertices[i] - posed.box_center[i]) @ posed.box_rotation[i]
        assert np.all(np.abs(rel) <= posed.box_extent[i] / 2 + 1e-4)
        # And the box is tight: vertices touch every face.
        np.testing.assert_allclose(np.abs(rel).max(axis=0), posed.box_extent[i] / 2, atol=1e-4)
    corners = posed.box_corners()
    assert corners.shape == (n, 8, 3)
    assert posed.keypoints.shape == (n, 26, 3) and posed.joints.shape[2] == 3


def test_appearance_digest_follows_the_coats_source_as_well_as_the_asset(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Benchmarks key cached renders on the appearance digest: a coat source that differs by one byte gives another
    digest, the same source the same one, and the asset digest does not move with the coats."""
    today, asset = appearance_digest(), asset_digest()
    assert len(today) == 16 and today != asset
    copy = tmp_path / "coat.py"
    copy.write_bytes(Path(str(coat.__file__)).read_bytes())
    monkeypatch.setattr(coat, "__file__", str(copy))
    assert appearance_digest() == today
    copy.write_bytes(copy.read_bytes() + b"\n")
    assert appearance_digest() != today and asset_digest() == asset


def _share_coats(root: str, keys: list[tuple[str, int]], barrier: Any, out: Any) -> None:
    """A process of the coat store test: wait for the others, then ask the store for every coat."""
    from zebra_sim_ros.zebra.asset import CoatStore

    store = CoatStore(Path(root))
    barrier.wait(timeout=60)
    texs = store.coats(keys, 128)
    out.put((store.baked, store.read, [hashlib.md5(t.tobytes()).hexdigest() for t in texs]))


def test_three_processes_share_the_coat_store_and_each_coat_is_baked_once(tmp_path: Path) -> None:
    """Three processes that ask for the same 24 coats at the same moment (the three cameras of a graph) bake each of
    them once between them and all get the coats that bake_coat bakes; a later store reads them all."""
    keys = [(name, seed) for name in ("plains", "grevy", "buffalo") for seed in range(8)]
    ctx = multiprocessing.get_context("spawn")
    barrier, out = ctx.Barrier(3), ctx.Queue()
    procs = [ctx.Process(target=_share_coats, args=(str(tmp_path), keys, barrier, out)) for _ in range(3)]
    for p in procs:
        p.start()
    try:
        got = [out.get(timeout=120) for _ in procs]
    finally:
        for p in procs:
            p.join(timeout=30)
            if p.is_alive():
                p.kill()
    want = [hashlib.md5(coat.bake_coat(MORPHS[n], coat.random_coat(s, MORPHS[n]), 128).tobytes()).hexdigest()
            for n, s in keys]
    assert all(md5s == want for _, _, md5s in got)
    assert sum(baked for baked, _, _ in got) == len(keys), got  # not 3 x 24
    assert sum(read for _, read, _ in got) == 2 * len(keys)
    later = CoatStore(tmp_path)
    assert [hashlib.md5(t.tobytes()).hexdigest() for t in later.coats(keys, 128)] == want
    assert (later.baked, later.read) == (0, len(keys))
    assert not list(later.dir.glob("*.claim")) and not list(later.dir.glob("*.tmp"))


def test_a_broken_coat_file_a_dead_claim_and_an_unwritable_store_still_give_the_coat(tmp_path: Path) -> None:
    """A coat file cut short is baked again; a claim left by a process that died (older than ``stale_s``) is
    taken over; a store whose folder cannot be made names it, turns itself off and bakes in memory."""
    want = coat.bake_coat(MORPHS["plains"], coat.random_coat(3, MORPHS["plains"]), 64)
    store = CoatStore(tmp_path, stale_s=0.5)
    store.path("plains", 3, 64).write_bytes(b"x\x9c\x03")  # a truncated zlib stream
    assert np.array_equal(store.coats([("plains", 3)], 64)[0], want) and store.baked == 1
    assert np.array_equal(CoatStore(tmp_path).coats([("plains", 3)], 64)[0], want)  # rewritten whole
    claim = store.path("plains", 4, 64).with_suffix(".claim")
    claim.touch()
    os.utime(claim, (time.time() - 5, time.time() - 5))  # its process is gone
    t0 = time.monotonic()
    four = store.coats([("plains", 4), ("plains", 3)], 64)
    assert time.monotonic() - t0 < 5 and not claim.exists()
    assert np.array_equal(four[0], coat.bake_coat(MORPHS["plains"], coat.random_coat(4, MORPHS["plains"]), 64))
    (tmp_path / "file").write_text("not a folder")
    off = CoatStore(tmp_path / "file")
    assert not off.on and off.error is not None and str(tmp_path / "file") in off.error
    assert np.array_equal(off.coats([("plains", 3)], 64)[0], want) and off.baked == 1
