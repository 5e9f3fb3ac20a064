"""The zebra's mesh, skeleton and skinning: closed parts, plausible size, exact rest pose."""

from __future__ import annotations

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.rotations import rigid
from zebra_sim_ros.geometry.winding import winding_numbers
from zebra_sim_ros.zebra.mesh import PART_NAMES, build_mesh
from zebra_sim_ros.zebra.skeleton import (
    BUFFALO,
    ELEPHANT,
    FOAL,
    GREVY,
    JOINT_NAMES,
    MORPHS,
    PLAINS,
    RHINO,
    ZEBRA_MORPHS,
    Morph,
    bind_positions,
    forward_kinematics,
)
from zebra_sim_ros.zebra.skinning import skin, skinning_matrices


def test_skeleton_has_the_joints_a_zebra_needs() -> None:
    assert len(JOINT_NAMES) >= 25
    for needed in ("spine_1", "neck_1", "head", "jaw", "ear_l", "ear_r", "tail_1", "hoof_fl", "hoof_hr"):
        assert needed in JOINT_NAMES


@pytest.mark.parametrize("morph", list(MORPHS.values()), ids=list(MORPHS))
@pytest.mark.parametrize("lod", [0, 1])
def test_every_part_is_closed_and_wound_outwards(morph: Morph, lod: int) -> None:
    m = build_mesh(morph, lod)
    for i, name in enumerate(PART_NAMES):
        faces = m.faces[m.face_part == i]
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        assert np.all(counts == 2), f"{name}: open or non-manifold edges"
        tri = m.vertices[faces]
        volume = np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
        assert volume > 0, f"{name}: faces wound inwards (signed volume {volume})"


def test_detail_levels() -> None:
    full, far = build_mesh(PLAINS, 0), build_mesh(PLAINS, 1)
    assert len(full.faces) >= 4000
    assert len(far.faces) < len(full.faces) / 2
    assert full.uv.shape == (len(full.faces), 3, 2)
    assert full.uv.min() >= 0.0 and full.uv.max() <= 1.0
    np.testing.assert_allclose(full.joint_weights.sum(axis=1), 1.0, atol=1e-9)
    assert full.joint_weights.min() >= 0.0
    with pytest.raises(ParameterError, match="lod"):
        build_mesh(PLAINS, 7)


@pytest.mark.parametrize(("morph", "withers", "length"), [
    (PLAINS, (1.2, 1.5), (2.2, 2.5)),
    (GREVY, (1.35, 1.6), (2.4, 2.8)),
    (FOAL, (0.8, 1.1), (1.3, 1.8)),
])
def test_proportions(morph: Morph, withers: tuple[float, float], length: tuple[float, float]) -> None:
    m = build_mesh(morph, 0)
    barrel = m.vertices[np.unique(m.faces[m.face_part == PART_NAMES.index("barrel")])]
    head = m.vertices[np.unique(m.faces[m.face_part == PART_NAMES.index("head")])]
    shoulder_x = bind_positions(morph)[JOINT_NAMES.index("chest"), 0]
    near = np.abs(barrel[:, 0] - shoulder_x) < 0.1
    assert withers[0] <= barrel[near, 2].max() <= withers[1]
    head_and_body = head[:, 0].max() - barrel[:, 0].min()
    assert length[0] <= head_and_body <= length[1]
    assert abs(m.vertices[:, 2].min()) < 0.01  # hooves on the ground


@pytest.mark.parametrize("morph", [PLAINS, FOAL], ids=["plains", "foal"])
def test_skinning_reproduces_the_rest_pose_at_bind(morph: Morph) -> None:
    m = build_mesh(morph, 0)
    bind = bind_positions(morph)
    g = forward_kinematics(bind, np.tile(np.eye(3), (len(JOINT_NAMES), 1, 1)), np.eye(4))
    np.testing.assert_allclose(g[:, :3, 3], bind, atol=1e-12)
    posed = skin(m.vertices, m.joint_indices, m.joint_weights, skinning_matrices(g, bind))
    np.testing.assert_allclose(posed, m.vertices, atol=1e-12)


def test_skinning_moves_rigidly_with_the_root() -> None:
    m = build_mesh(PLAINS, 1)
    bind = bind_positions(PLAINS)
    ang = np.radians(30)
    root = rigid(np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]]),
                 np.array([1.0, 2.0, 0.5]))
    g = forward_kinematics(bind, np.tile(np.eye(3), (len(JOINT_NAMES), 1, 1)), root)
    posed = skin(m.vertices, m.joint_indices, m.joint_weights, skinning_matrices(g, bind))
    expected = m.vertices @ root[:3, :3].T + root[:3, 3]
    np.testing.assert_allclose(posed, expected, atol=1e-9)


def test_winding_numbers_tell_inside_from_outside() -> None:
    m = build_mesh(PLAINS, 1)
    barrel = m.faces[m.face_part == PART_NAMES.index("barrel")]
    inside = np.array([[0.0, 0.0, 0.85]])
    outside = np.array([[0.0, 0.0, 2.5], [0.0, 1.0, 0.85]])
    w = winding_numbers(np.concatenate([inside, outside]), m.vertices, barrel)
    assert w[0] == pytest.approx(1.0, abs=1e-6)
    np.testing.assert_allclose(w[1:], 0.0, atol=1e-6)


def _part_vertices(m: Morph, name: str) -> np.ndarray:
    msh = build_mesh(m, 0)
    return msh.vertices[np.unique(msh.faces[msh.face_part == PART_NAMES.index(name)])]


@pytest.mark.parametrize("name", ZEBRA_MORPHS)
def test_a_zebras_horns_and_snout_are_hidden_inside_its_head(name: str) -> None:
    m = MORPHS[name]
    msh = build_mesh(m, 0)
    head = msh.faces[msh.face_part == PART_NAMES.index("head")]
    for part in ("horn_l", "horn_r", "snout"):
        v = _part_vertices(m, part)
        assert np.ptp(v, axis=0).max() < 0.03, part  # a sliver, not a shape
        w = winding_numbers(v, msh.vertices, head)
        np.testing.assert_allclose(w, 1.0, atol=1e-3, err_msg=part)  # wholly inside the head


def test_other_species_carry_their_horns_trunk_and_tusks() -> None:
    head_top = {n: _part_vertices(MORPHS[n], "head")[:, 2].max() for n in ("buffalo", "elephant", "rhino")}
    # A buffalo's horns sweep out far beyond its head on both sides.
    head_w = np.ptp(_part_vertices(BUFFALO, "head")[:, 1])
    left, right = _part_vertices(BUFFALO, "horn_l"), _part_vertices(BUFFALO, "horn_r")
    assert left[:, 1].max() > 0.45 and right[:, 1].min() < -0.45 and left[:, 1].max() > 2 * head_w / 2
    # An elephant's trunk hangs from its face most of the way to the ground, in front of its forelegs.
    trunk = _part_vertices(ELEPHANT, "snout")
    assert np.ptp(trunk[:, 2]) > 1.2
    assert 0.3 < trunk[:, 2].min() < 1.2 and trunk[:, 2].max() < head_top["elephant"]
    legs = _part_vertices(ELEPHANT, "leg_fl")
    assert trunk[:, 0].mean() > legs[:, 0].max()
    # Its tusks reach forward of the trunk's root and its legs are columns: a zebra's lower leg is 4-5 cm across
    # at the cannon, an elephant's over 20 cm.
    assert _part_vertices(ELEPHANT, "horn_l")[:, 0].max() > trunk[:, 0].min()
    def cannon(m: Morph) -> float:  # the leg's width across, 15-25 cm above the ground
        leg = _part_vertices(m, "leg_fl")
        return float(np.ptp(leg[np.abs(leg[:, 2] - 0.2) < 0.05, 1]))

    assert cannon(ELEPHANT) > 0.2 > 0.08 > cannon(PLAINS)
    # A rhino's front horn stands on its nose, its tip above the nose and forward of the head's back.
    horn = _part_vertices(RHINO, "snout")
    nose = _part_vertices(RHINO, "head")
    assert horn[:, 2].max() > nose[nose[:, 0].argmax(), 2] + 0.3
    assert np.ptp(horn, axis=0).max() > 0.4


@pytest.mark.parametrize(("field", "value", "match"), [
    ("horn", "antlers", "morph.plains.horn"),
    ("snout", "beak", "morph.plains.snout"),
    ("horn_length", 0.3, "morph.plains.horn_length"),
    ("ear_droop", 1.5, "morph.plains.ear_droop"),
])
def test_a_bad_shape_is_named(field: str, value: object, match: str) -> None:
    from dataclasses import replace

    with pytest.raises(ParameterError, match=match):
        replace(PLAINS, **{field: value}).validate()
    with pytest.raises(ParameterError, match="morph.plains.horn"):  # zebras carry no horns
        replace(PLAINS, horn="curved", horn_length=0.3).validate()
    replace(BUFFALO, horn="lyre").validate()  # any style fits another species
