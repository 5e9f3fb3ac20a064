"""Clips: enough of them, looping without jumps, hooves where a real zebra's would be."""

from __future__ import annotations

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.winding import winding_numbers
from zebra_sim_ros.zebra.animation import CLIPS, GAIT_CLIPS, STANDING_CLIPS, get_clip
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_EDGES, KEYPOINT_FLIP, KEYPOINT_NAMES
from zebra_sim_ros.zebra.mesh import PART_NAMES
from zebra_sim_ros.zebra.skeleton import MORPHS, PLAINS

LEG_PARTS = {"fl": "leg_fl", "fr": "leg_fr", "hl": "leg_hl", "hr": "leg_hr"}


def _clip_vertices(lib: ZebraLibrary, clip: str, morph: int = 0) -> np.ndarray:
    c = lib.clip_names.index(clip)
    s, n = int(lib.clip_start[c]), int(lib.clip_frames[c])
    return np.asarray(lib.vertices(morph, np.arange(s, s + n)), dtype=np.float64)


def _sole_heights(lib: ZebraLibrary, clip: str, morph: int = 0) -> dict[str, np.ndarray]:
    """Lowest point of each leg, per frame of the clip."""
    verts = _clip_vertices(lib, clip, morph)
    faces, part = lib.faces(0), lib.face_part(0)
    out = {}
    for leg, name in LEG_PARTS.items():
        idx = np.unique(faces[part == PART_NAMES.index(name)])
        out[leg] = verts[:, idx, 2].min(axis=1)
    return out


def test_clip_inventory() -> None:
    names = {c.name for c in CLIPS}
    assert len(CLIPS) >= 10
    assert sum(c.frames for c in CLIPS) >= 600
    for needed in ("idle", "graze", "walk", "trot", "gallop", "look_around", "tail_swish", "head_shake",
                   "lie_down", "rest", "drink"):
        assert needed in names
    with pytest.raises(ParameterError, match="clip"):
        get_clip("moonwalk")
    with pytest.raises(ParameterError, match="frame"):
        get_clip("walk").pose(36)


@pytest.mark.parametrize("clip", [c.name for c in CLIPS if c.loop])
def test_looping_clips_have_no_jump_at_the_seam(library: ZebraLibrary, clip: str) -> None:
    v = _clip_vertices(library, clip)
    steps = np.linalg.norm(np.diff(v, axis=0), axis=2).max(axis=1)  # worst vertex move per frame
    seam = np.linalg.norm(v[0] - v[-1], axis=1).max()
    assert steps.max() > 0, "a clip that never moves"
    assert seam <= 1.5 * steps.max() + 1e-4, f"seam {seam:.4f} m vs largest in-clip step {steps.max():.4f} m"


def test_every_clip_moves_the_body(library: ZebraLibrary) -> None:
    for clip in library.clip_names:
        v = _clip_vertices(library, clip)
        assert np.linalg.norm(v - v[:1], axis=2).max() > 0.02, clip


@pytest.mark.parametrize("morph", ["plains", "grevy", "foal", "buffalo", "elephant", "rhino"])
@pytest.mark.parametrize("clip", STANDING_CLIPS)
def test_hooves_stay_on_the_ground_in_standing_clips(library: ZebraLibrary, clip: str, morph: str) -> None:
    """The hooves carry the animal: no trunk, tusk or horn reaches below them, even with the head down to graze."""
    size = MORPHS[morph].withers_height / PLAINS.withers_height  # a clip's small steps scale with the animal
    for leg, z in _sole_heights(library, clip, library.morphs.index(morph)).items():
        assert z.min() >= -1e-4, f"{leg} hoof below the ground by {-z.min():.4f} m"
        assert z.max() <= 0.03 * size, f"{leg} hoof {z.max():.3f} m above the ground"


def test_the_body_rests_on_the_ground_in_every_frame(library: ZebraLibrary) -> None:
    boxes = library.boxes()
    gallop = library.clip_names.index("gallop")
    in_gallop = np.zeros(library.n_frames, dtype=bool)
    s = library.clip_start[gallop]
    in_gallop[s:s + library.clip_frames[gallop]] = True
    low = boxes[:, :, 0, 2]
    np.testing.assert_allclose(low[:, ~in_gallop], 0.0, atol=1e-5)
    assert low[:, in_gallop].max() < 0.1  # a gallop's moment of suspension, no more


def _swing_peak_phase(z: np.ndarray) -> float:
    return float(np.argmax(z) / len(z))


def _cyclic_gap(a: float, b: float) -> float:
    return (b - a) % 1.0


def test_walk_is_a_four_beat_lateral_sequence(library: ZebraLibrary) -> None:
    peak = {leg: _swing_peak_phase(z) for leg, z in _sole_heights(library, "walk").items()}
    order = ["hl", "fl", "hr", "fr"]
    for a, b in zip(order, order[1:] + order[:1], strict=True):
        assert _cyclic_gap(peak[a], peak[b]) == pytest.approx(0.25, abs=0.06), (a, b, peak)
    for z in _sole_heights(library, "walk").values():
        assert z.max() > 0.05  # the hoof really lifts
        assert z.min() < 0.02  # and really lands


def test_trot_moves_diagonal_pairs_together(library: ZebraLibrary) -> None:
    peak = {leg: _swing_peak_phase(z) for leg, z in _sole_heights(library, "trot").items()}
    assert min(_cyclic_gap(peak["fl"], peak["hr"]), _cyclic_gap(peak["hr"], peak["fl"])) <= 0.05
    assert min(_cyclic_gap(peak["fr"], peak["hl"]), _cyclic_gap(peak["hl"], peak["fr"])) <= 0.05
    assert _cyclic_gap(peak["fl"], peak["fr"]) == pytest.approx(0.5, abs=0.06)


def test_gallop_lands_hind_then_fore(library: ZebraLibrary) -> None:
    peak = {leg: _swing_peak_phase(z) for leg, z in _sole_heights(library, "gallop").items()}
    start = peak["hl"]
    rel = {leg: _cyclic_gap(start, p) for leg, p in peak.items()}
    assert rel["hl"] < rel["hr"] < rel["fl"] < rel["fr"], rel


def test_gait_offsets_are_the_documented_footfall_orders() -> None:
    walk = GAIT_CLIPS["walk"].offsets
    assert sorted(walk, key=walk.__getitem__) == ["hl", "fl", "hr", "fr"]


def test_keypoint_definitions() -> None:
    assert len(KEYPOINT_NAMES) >= 20
    assert len(set(KEYPOINT_NAMES)) == len(KEYPOINT_NAMES)
    for a, b in KEYPOINT_EDGES:
        assert 0 <= a < len(KEYPOINT_NAMES) and 0 <= b < len(KEYPOINT_NAMES) and a != b
    assert sorted(KEYPOINT_FLIP) == list(range(len(KEYPOINT_NAMES)))
    flipped = KEYPOINT_NAMES[KEYPOINT_FLIP[KEYPOINT_NAMES.index("left_hock")]]
    assert flipped == "right_hock"


@pytest.mark.parametrize("clip", ["idle", "graze", "gallop", "look_around", "lie_down", "rest"])
def test_keypoints_lie_on_or_in_the_posed_mesh(library: ZebraLibrary, clip: str) -> None:
    c = library.clip_names.index(clip)
    faces = library.faces(0)
    for f in (0, int(library.clip_frames[c]) // 2):
        g = library.frame_index(clip, f)
        verts = np.asarray(library.vertices(0, g), dtype=np.float64)
        kps = np.asarray(library.keypoints(0, g), dtype=np.float64)
        w = winding_numbers(kps, verts, faces)
        # 1 inside a part (more where parts overlap), 1/2 on the skin, 0 outside.
        bad = [KEYPOINT_NAMES[i] for i in np.nonzero(w < 0.45)[0]]
        assert not bad, f"{clip} frame {f}: outside the mesh: {bad} (winding {w[w < 0.45]})"
