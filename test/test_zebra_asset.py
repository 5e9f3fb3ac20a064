"""The baked cache and posing many zebras at once."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from zebra_sim_ros.errors import AssetError, ParameterError
from zebra_sim_ros.geometry.rotations import rot_z
from zebra_sim_ros.zebra import coat
from zebra_sim_ros.zebra.asset import ZebraLibrary, appearance_digest, asset_digest, build_library, load_library


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
