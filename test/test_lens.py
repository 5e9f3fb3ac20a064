"""Lens distortion: the plumb_bob model against OpenCV's, the renderer's distorted images against known geometry,
and labels that stay exact through the lens."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from render_helpers import cube_mesh, flat_world

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import PinholeCamera, depth_points, map_to_optical, optical_rotation, pixel_rays
from zebra_sim_ros.geometry.lens import Distortion, lens_canvas
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.rendering.config import lens_text, parse_lens
from zebra_sim_ros.rendering.renderer import CameraView, RenderedView, Renderer, RenderOptions, ZebraSet
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary

WIDE = Distortion(-0.3, 0.1, 0.002, -0.001, -0.01)  # a wide-angle drone camera's barrel distortion, tangential too


def _points_in_view(cam: PinholeCamera, n: int, seed: int) -> np.ndarray:
    """``n`` optical-frame points, 3-80 m deep, whose distorted pixels lie in the image (drawn as pixels, made ideal
    by OpenCV)."""
    rng = np.random.default_rng(seed)
    px = rng.uniform([0, 0], [cam.width - 1, cam.height - 1], (n, 2))
    ideal = cv2.undistortPoints(px.reshape(-1, 1, 2), cam.K, np.array(cam.D),
                                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)).reshape(-1, 2)
    depth = rng.uniform(3.0, 80.0, n)
    return np.c_[ideal * depth[:, None], depth]


@pytest.mark.parametrize("lens", [WIDE, Distortion(0.15, -0.05), Distortion(k1=-0.1), Distortion(p1=0.01, p2=-0.01)])
def test_projection_and_its_inverse_are_opencvs(lens: Distortion) -> None:
    """Barrel, pincushion, radial only, tangential only: ``PinholeCamera.project`` is ``cv2.projectPoints`` and
    ``Distortion.remove`` is ``cv2.undistortPoints``, to a millionth of a pixel, over the image."""
    cam = PinholeCamera(1280, 720, 80.0, lens)
    pts = _points_in_view(cam, 2000, 3)
    mine, front = cam.project(pts)
    theirs, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), cam.K, np.array(cam.D))
    assert front.all() and np.abs(mine - theirs.reshape(-1, 2)).max() < 1e-6
    x, y = lens.remove((mine[:, 0] - cam.K[0, 2]) / cam.fx, (mine[:, 1] - cam.K[1, 2]) / cam.fx)
    assert np.abs(np.c_[x, y] - pts[:, :2] / pts[:, 2:]).max() * cam.fx < 1e-6
    # the Jacobian is the model's derivative (central differences)
    h = 1e-6
    xi, yi = pts[:50, 0] / pts[:50, 2], pts[:50, 1] / pts[:50, 2]
    a, b, c, d = lens.jacobian(xi, yi)
    (xp, yp), (xm, ym) = lens.apply(xi + h, yi), lens.apply(xi - h, yi)
    (xq, yq), (xn, yn) = lens.apply(xi, yi + h), lens.apply(xi, yi - h)
    numeric = np.stack([(xp - xm), (xq - xn), (yp - ym), (yq - yn)]) / (2 * h)
    assert np.abs(np.stack([a, b, c, d]) - numeric).max() < 1e-6


def test_a_point_beyond_the_image_stays_outside_where_the_polynomial_folds_back() -> None:
    """A barrel lens's r (1 + k1 r^2) turns back at r^2 = -1 / (3 k1): OpenCV's projection puts a point far off the
    axis back inside the image; ours keeps it outside, in its direction."""
    cam = PinholeCamera(640, 360, 80.0, Distortion(k1=-0.15))
    far = np.array([[2.45, 0.5, 1.0], [-2.0, -1.5, 1.0], [0.3, 2.5, 1.0]])  # r 2.5: 2.5 (1 - 0.15 r^2) = 0.16
    theirs, _ = cv2.projectPoints(far, np.zeros(3), np.zeros(3), cam.K, np.array(cam.D))
    theirs = theirs.reshape(-1, 2)
    assert cam.in_image(far).tolist() == [False] * 3
    inside = (theirs >= 0).all(axis=1) & (theirs[:, 0] < 640) & (theirs[:, 1] < 360)
    assert inside.any(), theirs  # the model itself folds: the case this guards against
    uv, _ = cam.project(far)
    centre = np.array([(cam.width - 1) / 2, (cam.height - 1) / 2])
    assert np.all(np.sign(uv - centre) == np.sign(far[:, :2]))


def test_the_canvas_maps_each_pixel_to_the_ideal_point_it_shows() -> None:
    """Every image pixel's canvas coordinates, distorted again, land on that pixel (to 1e-3 px); a barrel lens needs
    a larger canvas, a pincushion one none (the 2 px margin); the nearest canvas pixel is the rounded map."""
    for lens, bigger in ((WIDE, True), (Distortion(0.2), False)):
        cam = PinholeCamera(320, 180, 70.0, lens)
        c = lens_canvas(cam.width, cam.height, cam.fx, lens)
        assert c is cam.canvas  # made once per camera model
        cx, cy = (c.canvas_width - 1) / 2, (c.canvas_height - 1) / 2
        xd, yd = lens.apply((c.map_x - cx) / cam.fx, (c.map_y - cy) / cam.fx)
        cols, rows = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
        assert np.abs(xd * cam.fx + (cam.width - 1) / 2 - cols).max() < 1e-3
        assert np.abs(yd * cam.fx + (cam.height - 1) / 2 - rows).max() < 1e-3
        assert (c.pad[0] > 10 and c.pad[1] > 5) if bigger else c.pad == (2, 2)
        assert c.canvas_width == cam.width + 2 * c.pad[0] and cam.ideal.fx == pytest.approx(cam.fx, rel=1e-12)
        near = np.unravel_index(c.nearest, (c.canvas_height, c.canvas_width))
        assert np.abs(near[1] - c.map_x).max() <= 0.5 + 1e-6 and np.abs(near[0] - c.map_y).max() <= 0.5 + 1e-6
        assert c.multiplicity().sum() == cam.width * cam.height
    assert PinholeCamera(320, 180, 70.0).canvas is None


def test_a_lens_that_cannot_be_undone_and_a_bad_lens_option_are_refused_by_name() -> None:
    with pytest.raises(ParameterError, match=r"lens distortion.*-1.*fold"):
        _ = PinholeCamera(640, 360, 120.0, Distortion(k1=-1.0)).canvas
    with pytest.raises(ParameterError, match="lens distortion"):
        RenderOptions(width=640, height=360, hfov_deg=120.0, distortion=Distortion(k1=-1.0)).check()
    with pytest.raises(ParameterError, match="distortion"):
        Distortion(k1=float("nan"))
    with pytest.raises(ValueError, match="rational_polynomial"):
        Distortion.from_d([0.1] * 8, "rational_polynomial")
    assert Distortion.from_d([0.0] * 8, "rational_polynomial").none and Distortion.from_d([]).none
    assert Distortion.from_d([-0.2, 0.05, 0, 0, 0]).coefficients == pytest.approx((-0.2, 0.05, 0, 0, 0), abs=1e-15)
    assert parse_lens([-0.2, 0.05]).coefficients == pytest.approx((-0.2, 0.05, 0, 0, 0), abs=1e-15)
    assert parse_lens([]).none
    assert parse_lens([float(v) for v in lens_text(WIDE).split()]).coefficients == pytest.approx(WIDE.coefficients,
                                                                                              rel=0, abs=1e-15)
    for values, what in (([0.0] * 6, "up to five numbers"), ([-2.0], "k1 -1..1"), ([0, 0, 0.2], "p1 -0.05..0.05")):
        with pytest.raises(ParameterError, match=f"--lens.*{what}"):
            parse_lens(values)


def _cube_world() -> World:
    return flat_world({"cube": (cube_mesh(2.0), [(11.0, -3.5, 1.0)])})  # its near face 10 m east, 2.5-4.5 m south


CUBE_CAMERA = PinholeCamera(320, 240, 60.0, Distortion(-0.3, 0.1))  # a level camera 3.5 m up, looking east
CUBE_VIEW = CameraView("cam", np.array([0.0, 0.0, 3.5]), optical_rotation(0.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def cube_render(library: ZebraLibrary) -> RenderedView:
    """The cube world through ``CUBE_CAMERA``'s barrel lens from ``CUBE_VIEW``."""
    cam = CUBE_CAMERA
    r = Renderer(_cube_world(), library, RenderOptions(width=cam.width, height=cam.height, hfov_deg=cam.hfov_deg,
                                                        coat_size=64, max_coats=16, distortion=cam.distortion))
    empty = ZebraSet(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0),
                     np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0, np.int64))
    try:
        return r.render(empty, lighting_for(12.0, 80, -2.3), [CUBE_VIEW])[0]
    finally:
        r.release()


def test_a_distorted_render_shows_a_cube_where_opencvs_lens_puts_it(cube_render: RenderedView) -> None:
    """A 2 m cube towards the image's lower right corner, 10 m in front of a level camera 3.5 m up with a barrel
    lens: its face is where the pixels' rays, made ideal by OpenCV, meet it, at 10 m depth; the ground's depth
    follows the same rays. The ideal pinhole's silhouette, 7 px away there, does not match."""
    cam, out = CUBE_CAMERA, cube_render
    width, height = cam.width, cam.height
    assert out.rgb.shape == (height, width, 3) and out.depth.shape == (height, width)
    assert out.D == pytest.approx(cam.D, abs=1e-12) and np.allclose(out.K, cam.K)
    cols, rows = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    px = np.stack([cols.ravel(), rows.ravel()], axis=1).reshape(-1, 1, 2)
    ideal = cv2.undistortPoints(px, cam.K, np.array(cam.D),
                                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    x, y = ideal.reshape(height, width, 2).transpose(2, 0, 1)  # optical: x right (map -y), y down (map -z)

    def face(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Pixels whose ray (x, y, 1) meets the cube's near face: x = 10 m east, y in -4.5..-2.5, z in 0..2."""
        return (np.abs(-10.0 * x - (-3.5)) < 1.0) & (np.abs(3.5 - 10.0 * y - 1.0) < 1.0)

    apart = np.abs(3.5 / np.maximum(y, 1e-6) - 10.0) > 0.25  # not the ground 10 m away (where the face meets it)
    want = face(x, y) & apart
    pinhole = face((cols - cam.K[0, 2]) / cam.fx, (rows - cam.K[1, 2]) / cam.fx) & apart
    got = (np.abs(out.depth - 10.0) < 0.1) & apart
    assert want.sum() > 400

    def iou(a: np.ndarray, b: np.ndarray) -> float:
        return float((a & b).sum() / (a | b).sum())

    def centre(mask: np.ndarray) -> np.ndarray:
        return np.array([cols[mask].mean(), rows[mask].mean()])

    assert iou(want, got) > 0.95 and iou(pinhole, got) < 0.8, (iou(want, got), iou(pinhole, got))
    assert np.linalg.norm(centre(got) - centre(want)) < 0.5 and np.linalg.norm(centre(got) - centre(pinhole)) > 3
    assert np.abs(out.depth[want & got] - 10.0).max() < 0.1
    # the ground 3.5 m down, nearer than the cube: depth 3.5 / y along OpenCV's ray (the nearest canvas pixel's
    # depth: half a pixel off at most), 8% off along the pinhole's
    ground = (y > 0.05) & (out.depth < 9.5)
    assert ground.sum() > 5000
    assert np.median(np.abs(out.depth[ground] * y[ground] / 3.5 - 1.0)) < 0.005
    y_pinhole = (rows - cam.K[1, 2]) / cam.fx
    assert np.median(np.abs(out.depth[ground] * y_pinhole[ground] / 3.5 - 1.0)) > 0.04


def test_a_depth_images_points_lie_on_the_geometry_it_shows(cube_render: RenderedView) -> None:
    """The points of the cube render's depth image through its barrel lens, in ``map``: the ground's on z = 0, the
    cube's near face's at x = 10 m; each projects back onto its own pixel. The pinhole's rays, which ignore the lens,
    put the ground off z = 0 towards the image's edges."""
    cam, out = CUBE_CAMERA, cube_render
    stride = 3
    pts = depth_points(out.depth, cam, stride)
    h, w = -(-cam.height // stride), -(-cam.width // stride)
    assert pts.shape == (h, w, 3) and pts.dtype == np.float32
    sky = ~np.isfinite(out.depth[::stride, ::stride])
    assert sky.any() and np.isnan(pts[sky]).all() and np.isfinite(pts[~sky]).all()
    in_map = pts.astype(np.float64) @ CUBE_VIEW.r_optical.T + CUBE_VIEW.position
    depth = out.depth[::stride, ::stride]
    face = (np.abs(depth - 10.0) < 0.1) & (in_map[..., 2] > 0.2)  # 10 m deep and off the ground: the face
    ground = ~sky & (depth < 9.5)  # nearer than the cube: only ground
    assert face.sum() > 100 and ground.sum() > 500
    # on the face: 10 m east, 2.5-4.5 m south, up to 2 m (the pinhole's rays spread them 5 m either side)
    assert np.abs(in_map[face][:, 0] - 10.0).max() < 0.05
    assert np.abs(in_map[face][:, 1] + 3.5).max() < 1.05 and in_map[face][:, 2].max() < 2.05
    assert np.median(np.abs(in_map[ground][:, 2])) < 0.01  # the nearest canvas pixel's depth: within 1 cm
    rows, cols = np.mgrid[0:cam.height:stride, 0:cam.width:stride]
    uv, front = cam.project(pts[~sky].astype(np.float64))
    assert front.all()
    assert np.abs(uv - np.stack([cols[~sky], rows[~sky]], axis=-1)).max() < 1e-3
    # the pinhole's rays: the same depths, the ground well off z = 0 at the image's lower corners
    pinhole = depth_points(out.depth, PinholeCamera(cam.width, cam.height, cam.hfov_deg), stride)
    off = (pinhole.astype(np.float64) @ CUBE_VIEW.r_optical.T + CUBE_VIEW.position)[ground][:, 2]
    assert np.percentile(np.abs(off), 90) > 0.1


def test_pixel_rays_and_depth_points_refuse_what_they_cannot_use() -> None:
    ideal = PinholeCamera(64, 48, 80.0)
    rays = pixel_rays(ideal, 5)
    assert rays.shape == (10, 13, 2) and not rays.flags.writeable
    assert rays[0, 0] == pytest.approx([-31.5 / ideal.fx, -23.5 / ideal.fx])
    assert rays[-1, -1] == pytest.approx([(60 - 31.5) / ideal.fx, (45 - 23.5) / ideal.fx])
    assert pixel_rays(ideal, 5) is rays  # made once
    with pytest.raises(ParameterError, match="stride"):
        pixel_rays(ideal, 0)
    with pytest.raises(ValueError, match="48x64"):
        depth_points(np.ones((64, 48), np.float32), ideal)
    depth = np.full((48, 64), 2.0, np.float32)
    depth[0, 0], depth[0, 1], depth[0, 2] = np.inf, 0.0, np.nan
    pts = depth_points(depth, ideal)
    assert np.isnan(pts[0, :3]).all() and np.isfinite(pts[0, 3:]).all()
    assert pts[1, 1] == pytest.approx([2 * (1 - 31.5) / ideal.fx, 2 * (1 - 23.5) / ideal.fx, 2.0])


@pytest.fixture(scope="module")
def step_through_a_lens(library: ZebraLibrary, savanna: World) -> tuple[Any, list[Any], list[Any]]:
    """The default world's first step at 640x360: its scene, its frames through ``WIDE`` and through the pinhole."""
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.simulation import Simulator

    scene = Placer(PlacerConfig(), savanna, library).scene(0)
    frames = []
    for lens in (WIDE, Distortion()):
        sim = Simulator(savanna, library, RenderOptions(width=640, height=360, distortion=lens))
        try:
            frames.append(sim.simulate(scene))
        finally:
            sim.release()
    return scene, frames[0], frames[1]


def test_labels_through_a_lens_stay_exact(step_through_a_lens: tuple[Any, list[Any], list[Any]]) -> None:
    """Every animal's visible pixels are a subset of its silhouette (both counted in the image's pixels); one that
    nothing hides and the image holds whole, through the lens and through the pinhole, has as many visible pixels as
    its silhouette, which is the pinhole's scaled by the lens's area factor there (within 15%, for 30 px or more).
    Its visible box lies in its full box, the labels carry the lens, and nine visible keypoints in ten show their
    own animal within a pixel (as without a lens: 94% at 640x360; a thin leg or tail tip can miss), where the ideal
    pinhole's pixels for them would show it for about 28%."""
    scene, frames, pinhole_frames = step_through_a_lens
    cam = PinholeCamera(640, 360, 80.0, WIDE)
    checked = shown = shown_pinhole = whole = 0

    def shows(image: np.ndarray, u: float, v: float, instance: int) -> bool:
        r0, c0 = int(np.floor(v)), int(np.floor(u))
        return bool((image[max(r0 - 1, 0):r0 + 2, max(c0 - 1, 0):c0 + 2] == instance).any())

    def in_frame(z: Any, f: Any) -> bool:
        """The zebra's whole amodal box in the image (its in_frame_fraction is rounded: 1.0 may miss a pixel)."""
        x0, y0, x1, y1 = z.box_full_unclipped
        h, w = f.view.depth.shape
        return bool(x0 >= 0 and y0 >= 0 and x1 <= w and y1 <= h)

    for f, ideal, c in zip(frames, pinhole_frames, scene.cameras, strict=True):
        assert f.labels.D == pytest.approx(WIDE.coefficients, abs=1e-12)
        plain = {z.id: z for z in ideal.labels.zebras}
        pose = np.array(c.position), optical_rotation(np.radians(c.yaw_deg), np.radians(c.pitch_deg),
                                                      np.radians(c.roll_deg))
        for z in f.labels.zebras:
            assert 0 < z.visible_pixels <= z.silhouette_pixels, (z.visible_pixels, z.silhouette_pixels)
            vb, fb = np.array(z.box_visible), np.array(z.box_full)
            assert (vb[:2] >= fb[:2] - 1.0).all() and (vb[2:] <= fb[2:] + 1.0).all(), (vb, fb)
            p = plain.get(z.id)
            if p is not None and p.visible_pixels == p.silhouette_pixels and in_frame(p, ideal) and in_frame(z, f):
                assert z.visible_pixels == z.silhouette_pixels, (z.id, z.visible_pixels, z.silhouette_pixels)
                if p.silhouette_pixels >= 30:
                    centre = map_to_optical(np.array(z.box3d_map.center), *pose)
                    factor = float(WIDE.area_factor(centre[0] / centre[2], centre[1] / centre[2]))
                    assert z.silhouette_pixels / p.silhouette_pixels == pytest.approx(factor, rel=0.15), z.id
                    whole += 1
            for u, v, vis in z.keypoints:
                if vis == 2:
                    checked += 1
                    shown += shows(f.view.instances, u, v, z.instance)
                    x, y = WIDE.remove((u - 0.5 - cam.K[0, 2]) / cam.fx, (v - 0.5 - cam.K[1, 2]) / cam.fx)
                    shown_pinhole += shows(f.view.instances, x * cam.fx + cam.K[0, 2] + 0.5,
                                           y * cam.fx + cam.K[1, 2] + 0.5, z.instance)
    assert checked > 500 and shown >= 0.9 * checked and shown_pinhole < 0.5 * checked, (checked, shown, shown_pinhole)
    assert whole >= 10, whole


def test_a_scene_in_the_image_through_a_lens_is_where_projection_puts_it(
        step_through_a_lens: tuple[Any, list[Any], list[Any]]) -> None:
    """Each labelled animal's 3D box centre, projected through the lens, falls in its visible box (or within two
    pixels of it); projected by the ideal pinhole of the same K, several fall outside theirs."""
    scene, frames, _ = step_through_a_lens
    cam = PinholeCamera(640, 360, 80.0, WIDE)
    pinhole = PinholeCamera(cam.width, cam.height, cam.hfov_deg)
    inside = total = pinhole_inside = 0
    for f, c in zip(frames, scene.cameras, strict=True):
        pose = np.array(c.position), optical_rotation(np.radians(c.yaw_deg), np.radians(c.pitch_deg),
                                                      np.radians(c.roll_deg))
        for z in f.labels.kept:
            if z.visible_fraction < 0.9 or z.visible_pixels < 30:
                continue
            x0, y0, x1, y1 = z.box_visible
            total += 1
            for camera in (cam, pinhole):
                uv, _ = camera.project(map_to_optical(np.array(z.box3d_map.center), *pose)[None])
                u, v = uv[0] + 0.5  # pixel edges, as boxes are
                hit = x0 - 2 <= u <= x1 + 2 and y0 - 2 <= v <= y1 + 2
                inside += hit and camera is cam
                pinhole_inside += hit and camera is pinhole
    assert total >= 10 and inside == total, (inside, total)
    assert pinhole_inside <= total - 3, (pinhole_inside, total)


def test_locating_a_box_undoes_the_lens_for_its_ray_and_its_size() -> None:
    """A 0.6 m square 20 m deep near the image's corner, boxed through a wide-angle lens: its point and its size come
    back through the lens (to 2 cm and 3%); the pinhole's reading is off by more. A lens that folds over inside the
    image gives no point for a box where it cannot be undone, rather than a wrong one."""
    from zebra_sim_ros.geometry.locate import locate_boxes

    cam = PinholeCamera(640, 360, 80.0, WIDE)
    centre = np.array([13.0, 6.5, 20.0])  # optical frame: right, down, deep
    edges = centre + np.array([[-0.3, 0, 0], [0.3, 0, 0], [0, -0.3, 0], [0, 0.3, 0]])
    uv, _ = cam.project(edges)
    box = np.array([[uv[0, 0], uv[2, 1], uv[1, 0], uv[3, 1]]]) + 0.5  # pixel edges
    assert 0 < box[0, 0] and box[0, 2] < 640 and box[0, 3] < 360
    depth = np.full((360, 640), 20.0, np.float32)
    ident = np.array([0.0, 0.0, 0.0, 1.0])  # the optical frame is map
    got = locate_boxes(box, depth, cam.K, np.zeros(3), ident, distortion=WIDE)
    plain = locate_boxes(box, depth, cam.K, np.zeros(3), ident)
    assert np.linalg.norm(got.points[0] - centre) < 0.02 and np.linalg.norm(plain.points[0] - centre) > 1.0
    assert got.size[0] == pytest.approx([0.6, 0.6], rel=0.03)
    assert abs(plain.size[0, 0] - 0.6) > 0.06
    folding = Distortion(k1=-0.5)  # turns back at r 0.82, inside this camera's corners (0.96)
    xd = (630.0 - cam.K[0, 2]) / cam.fx, (350.0 - cam.K[1, 2]) / cam.fx
    assert np.isnan(folding.remove(*xd)).all()  # the polynomial has a solution, on its far branch: not a ray
    corner = np.array([[620.0, 340, 640, 360], [310.0, 170, 330, 190]])
    far = locate_boxes(corner, depth, cam.K, np.zeros(3), ident, distortion=folding)
    assert far.valid.tolist() == [False, True]


def test_the_area_factor_beyond_the_image_follows_the_projection() -> None:
    """Off the image the camera keeps the corner's radial factor, so the silhouette estimate's area factor there is
    its square, not the polynomial's (which falls to 0 at the fold and grows as r^4 past it)."""
    cam = PinholeCamera(1280, 720, 90.0, Distortion(k1=-0.1))
    lens = cam.canvas
    assert lens is not None
    factor = float(cam.distortion.radial(lens.max_radius)) ** 2
    far = lens.area_factor(np.array([2.5, 10.0, 0.0]), np.array([0.0, 0.0, 25.0]))
    assert far == pytest.approx([factor] * 3, rel=1e-12)
    assert float(cam.distortion.area_factor(10.0, 0.0)) > 100  # the raw polynomial's, guarded against
    near = lens.area_factor(np.array([0.1]), np.array([0.2]))
    assert float(near[0]) == pytest.approx(float(cam.distortion.area_factor(0.1, 0.2)), rel=1e-12)
