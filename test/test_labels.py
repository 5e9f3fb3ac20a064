"""The labeller core against known geometry: boxes, visibility, occluded keypoints."""

from __future__ import annotations

import numpy as np
import pytest
from render_helpers import cube_mesh, flat_world

from zebra_sim_ros.dataset.coco import rle_encode, rle_encode_all
from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical, optical_rotation
from zebra_sim_ros.geometry.rotations import matrix_to_quat
from zebra_sim_ros.labels.labeller import full_boxes, label_view, tight_boxes
from zebra_sim_ros.labels.silhouettes import SilhouetteCounter
from zebra_sim_ros.messages import Labels, OrientedBox, Scene, SceneCamera, SceneZebra, Stamp, WorldRef
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.rendering.renderer import Renderer, RenderOptions
from zebra_sim_ros.rendering.views import zebras_from_scene
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_NAMES

W, H, HFOV = 320, 240, 60.0
NOON = lighting_for(12.0, 80, -2.3)


def test_tight_and_full_boxes_of_a_cube() -> None:
    cam = PinholeCamera(W, H, HFOV)
    # A 2 m cube centred 20 m ahead of a level camera looking east: corners at x = 19, 21.
    r = optical_rotation(0.0, 0.0, 0.0)
    pos = np.array([0.0, 0.0, 0.0])
    corners = np.array([[x, y, z] for x in (19.0, 21.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    clipped, raw = full_boxes(map_to_optical(corners, pos, r)[None], cam)
    half = cam.fx * 1.0 / 19.0  # the near face spans +-1 m at 19 m
    expected = [W / 2 - half, H / 2 - half, W / 2 + half, H / 2 + half]
    np.testing.assert_allclose(raw[0], expected, atol=1e-9)
    np.testing.assert_allclose(clipped[0], expected, atol=1e-9)
    # Moved left until it leaves the image: the clipped box stops at the border, the raw one does not.
    shifted = corners + np.array([0.0, 12.0, 0.0])
    clipped, raw = full_boxes(map_to_optical(shifted, pos, r)[None], cam)
    assert raw[0, 0] < 0 and clipped[0, 0] == 0.0 and clipped[0, 2] == raw[0, 2]
    # Tight box of the mask pixels: columns 10..19 and rows 30..44 give [10, 30, 20, 45] in pixel edges.
    mask = np.zeros((H, W), np.uint16)
    mask[30:45, 10:20] = 7
    mask[100, 200] = 9
    boxes, counts = tight_boxes(mask, np.array([7, 9, 11]))
    np.testing.assert_array_equal(boxes[0], [10, 30, 20, 45])
    np.testing.assert_array_equal(boxes[1], [200, 100, 201, 101])
    assert np.isnan(boxes[2]).all() and counts.tolist() == [150, 1, 0]


def _scene(library: ZebraLibrary, cam_pos: np.ndarray, r_opt: np.ndarray, yaw: float = 0.0) -> Scene:
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    q = matrix_to_quat(rot)
    qc = matrix_to_quat(r_opt)
    box = library.boxes()[0, library.frame_index("idle", 0)].astype(float)
    centre = rot @ box.mean(axis=0)
    xyzw = (float(q[1]), float(q[2]), float(q[3]), float(q[0]))
    zebra = SceneZebra(4, "plains", 1, "idle", 0, 1.0, float(np.degrees(yaw)), (0.0, 0.0, 0.0), xyzw,
                       OrientedBox(tuple(centre.tolist()), tuple((box[1] - box[0]).tolist()), xyzw))
    qc_xyzw = (float(qc[1]), float(qc[2]), float(qc[3]), float(qc[0]))
    camera = SceneCamera("drone_0", "far", tuple(cam_pos.tolist()), qc_xyzw, 0.0, 0.0, 0.0, "drone_0/camera_optical")
    return Scene(Stamp(1, 0), 0, 0, 0, 0, library.manifest["digest"], WorldRef("flat", "test", None), NOON,
                 (0.0, 0.0), (10.0, 10.0), 1, (zebra,), (camera,))


def _label(library: ZebraLibrary, things: dict | None, cam_pos: np.ndarray, r_opt: np.ndarray) -> Labels:
    r = Renderer(flat_world(things), library, RenderOptions(width=W, height=H, hfov_deg=HFOV, coat_size=64,
                                                            max_coats=4))
    try:
        scene = _scene(library, cam_pos, r_opt)
        from zebra_sim_ros.rendering.views import views_from_scene

        view = r.render(zebras_from_scene(scene, library), NOON, views_from_scene(scene))[0]
        counter = SilhouetteCounter(library, r.camera, ctx=r.ctx)
        return label_view(scene, "drone_0", view.instances, view.depth, r.camera, library, counter)
    finally:
        r.release()


def test_a_half_hidden_zebra(library: ZebraLibrary) -> None:
    cam_pos = np.array([0.0, -14.0, 1.2])
    r_opt = optical_rotation(np.pi / 2, 0.0, 0.0)
    open_ = _label(library, None, cam_pos, r_opt).zebras[0]
    # A wall 4 m in front of the camera hiding the zebra's rear half (x < 0 side, seen from the south).
    wall = {"wall": (cube_mesh(0.8, height=3.0), [(-0.33, -10.0, 1.0)])}  # right edge: x = +0.25 m at the zebra
    half = _label(library, wall, cam_pos, r_opt).zebras[0]
    assert open_.visible_fraction > 0.97 and open_.in_frame_fraction == 1.0
    assert 0.3 < half.visible_fraction < 0.7, half.visible_fraction
    assert half.silhouette_pixels == pytest.approx(open_.silhouette_pixels, rel=0.01)
    tb, fb = half.box_visible, half.box_full
    assert (fb[2] - fb[0]) > 1.4 * (tb[2] - tb[0])  # the amodal box is the whole animal
    assert fb[0] <= tb[0] + 0.5 and fb[2] >= tb[2] - 0.5 and fb[1] <= tb[1] + 0.5 and fb[3] >= tb[3] - 0.5
    np.testing.assert_allclose(half.box_full, open_.box_full, atol=1e-6)  # the amodal box ignores the wall
    assert half.kept and half.drop_reason is None


def test_a_keypoint_behind_a_tree_is_occluded(library: ZebraLibrary) -> None:
    cam_pos = np.array([0.0, -14.0, 1.2])
    r_opt = optical_rotation(np.pi / 2, 0.0, 0.0)
    open_ = _label(library, None, cam_pos, r_opt).zebras[0]
    nose = KEYPOINT_NAMES.index("nose")
    tail = KEYPOINT_NAMES.index("tail_base")
    assert open_.keypoints[nose][2] == 2 and open_.keypoints[tail][2] == 2
    # A trunk between the camera and the head (the zebra faces east: the head is at x ~ +1.3 m).
    head_x = 1.3
    trunk = {"trunk": (cube_mesh(0.45, height=4.0), [(head_x * 6 / 14 + 0.05, -8.0, 1.0)])}
    hidden = _label(library, trunk, cam_pos, r_opt).zebras[0]
    assert hidden.keypoints[nose][2] == 1  # labelled, in the image, but occluded
    assert hidden.keypoints[tail][2] == 2
    # Out of the image: flagged 0.
    # Seen from the right side, the left legs are hidden by the body itself: also flagged 1.
    assert open_.keypoints[KEYPOINT_NAMES.index("left_hock")][2] == 1
    assert open_.keypoints[KEYPOINT_NAMES.index("right_hock")][2] == 2
    # Turned so the zebra straddles the image border: keypoints outside are 0, the in-frame fraction drops.
    away = _label(library, None, cam_pos, optical_rotation(np.pi / 2 + np.radians(30), 0.0, 0.0)).zebras[0]
    assert any(k[2] == 0 for k in away.keypoints) and any(k[2] == 2 for k in away.keypoints)
    assert 0.1 < away.in_frame_fraction < 0.9


def test_rle_of_all_instances_equals_one_by_one() -> None:
    rng = np.random.default_rng(0)
    mask = rng.integers(0, 5, size=(37, 23)).astype(np.uint16)
    mask[:, -1] = 3
    all_ = rle_encode_all(mask, [1, 2, 3, 4, 9])
    for i in (1, 2, 3, 4, 9):
        assert all_[i] == rle_encode(mask == i)


def test_shipped_yaml_files_match_the_defaults() -> None:
    from pathlib import Path

    from zebra_sim_ros.labels.config import LabellerConfig
    from zebra_sim_ros.params import load_params_file
    from zebra_sim_ros.rendering.config import CameraConfig

    config = Path(__file__).resolve().parents[1] / "config"
    assert LabellerConfig.from_params(load_params_file(str(config / "labeller.yaml"), "labeller")) == LabellerConfig()
    assert CameraConfig.from_params(load_params_file(str(config / "camera.yaml"), "camera")) == CameraConfig()


def test_renderers_and_labellers_each_with_its_own_context_share_a_process(library: ZebraLibrary,
                                                                           savanna: World) -> None:
    """Two camera models in one process (a labeller node whose cameras differ, a benchmark comparing two renderers),
    each with a GL context of its own, created one after the other: each draws in its own context, so the first
    renderer's frame and the first labeller's silhouettes are what they are alone. Before, a renderer drew into the
    latest context made (a crash) and a labeller counted empty silhouettes."""
    from zebra_sim_ros.labels.labeller import Labeller
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.simulation import Simulator

    scene = Placer(PlacerConfig(), savanna, library).scene(0)
    alone = Simulator(savanna, library, RenderOptions(width=320, height=180))
    try:
        want = alone.simulate(scene)
    finally:
        alone.release()
    first = Simulator(savanna, library, RenderOptions(width=320, height=180))
    labeller = Labeller(library, PinholeCamera(320, 180, 80.0))  # a context of its own
    second = Simulator(savanna, library, RenderOptions(width=160, height=90))  # made last: its context is current
    try:
        views = first.render(scene)
        second.render(scene)
        got = [labeller.label(scene, v.name, v.instances, v.depth) for v in views]
    finally:
        second.release()
        labeller.release()
        first.release()
    assert sum(z.silhouette_pixels for lab in got for z in lab.zebras) > 300
    for frame, view, labels in zip(want, views, got, strict=True):
        assert np.array_equal(frame.view.instances, view.instances)
        assert labels.to_dict() == frame.labels.to_dict()
