"""The renderer against known geometry: metric depth, exact masks, CameraInfo's projection, occlusion."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from render_helpers import cube_mesh, flat_world

from zebra_sim_ros.errors import DependencyError
from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical, optical_rotation
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.rendering.effects import CameraEffects
from zebra_sim_ros.rendering.renderer import CameraView, Renderer, RenderOptions, ZebraSet
from zebra_sim_ros.zebra.asset import ZebraLibrary

W, H, HFOV = 320, 240, 60.0
NOON = lighting_for(12.0, 80, -2.3)


def _zebras(library: ZebraLibrary, positions: list[tuple[float, float]], yaw: float = 0.0) -> ZebraSet:
    n = len(positions)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.tile(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), (n, 1, 1))
    return ZebraSet(ids=np.arange(n, dtype=np.int64) + 10,  # masks hold id + 1: 11, 12, ...
                    morph=np.zeros(n, dtype=np.int64),
                    global_frame=np.full(n, library.frame_index("idle", 0), dtype=np.int64), scale=np.ones(n),
                    rotation=rot, position=np.array([[x, y, 0.0] for x, y in positions]),
                    coat_seed=np.arange(n, dtype=np.int64))


def _view(pos: tuple[float, float, float], yaw_deg: float, pitch_deg: float) -> CameraView:
    return CameraView("cam", np.array(pos, dtype=np.float64),
                      optical_rotation(np.radians(yaw_deg), np.radians(pitch_deg), 0.0))


@pytest.fixture(scope="module")
def options() -> RenderOptions:
    return RenderOptions(width=W, height=H, hfov_deg=HFOV, coat_size=64, max_coats=16)


def test_cube_depth_silhouette_and_projection(library: ZebraLibrary, options: RenderOptions) -> None:
    # A 2 m cube whose near face is 20 m in front of a level camera at 1 m height, looking east.
    world = flat_world({"cube": (cube_mesh(2.0), [(21.0, 0.0, 1.0)])})
    r = Renderer(world, library, options)
    try:
        view = _view((0.0, 0.0, 1.0), 0.0, 0.0)
        out = r.render(_zebras(library, []), NOON, [view])[0]
    finally:
        r.release()
    cam = PinholeCamera(W, H, HFOV)
    np.testing.assert_allclose(out.K, cam.K)
    # Depth along the optical axis of the near face (x = 20) is 20 m everywhere on it.
    corners = np.array([[20.0, y, z] for y in (-1.0, 1.0) for z in (0.0, 2.0)])
    uv, _ = cam.project(map_to_optical(corners, view.position, view.r_optical))
    poly = cv2.convexHull(uv.astype(np.float32))
    expected = np.zeros((H, W), np.uint8)
    # Pixel centres inside the projected face: that is the silhouette a perfect rasteriser draws.
    ys, xs = np.mgrid[0:H, 0:W]
    inside = np.array([cv2.pointPolygonTest(poly, (float(x), float(y)), False) >= 0
                       for x, y in zip(xs.ravel(), ys.ravel(), strict=True)]).reshape(H, W)
    expected[inside] = 1
    got = (np.abs(out.depth - 20.0) < 0.2).astype(np.uint8)
    assert expected.sum() > 500
    iou = (expected & got).sum() / (expected | got).sum()
    assert iou > 0.95, iou
    face = out.depth[inside]
    np.testing.assert_allclose(np.median(face), 20.0, rtol=0.01)
    assert np.abs(face - 20.0).max() < 0.2  # within 1% everywhere inside
    # The ground's depth is metric too: the ray through pixel row v hits z = 0 at a known distance.
    v_row = int(H * 0.9)
    z_expected = 1.0 / ((v_row - (H - 1) / 2) / cam.fx)
    assert out.depth[v_row, 5] == pytest.approx(z_expected, rel=0.01)
    assert np.all(out.instances == 0)  # no zebra, no mask
    assert np.isinf(out.depth[0, 0])  # sky


def _one_zebra(library: ZebraLibrary, options: RenderOptions, looks: list[tuple[Any, Any]]) -> tuple[Any, Any, list]:
    """One zebra (id 10, yaw 0.4) on flat ground seen from 12 m south and 6 m up, rendered under each
    (lighting, ground look); returns the view, the zebras and the renders."""
    r = Renderer(flat_world(), library, options)
    try:
        view = _view((0.0, -12.0, 6.0), 90.0, -25.0)
        zebras = _zebras(library, [(0.0, 0.0)], yaw=0.4)
        return view, zebras, [r.render(zebras, light, [view], ground)[0] for light, ground in looks]
    finally:
        r.release()


def test_zebra_mask_is_the_projected_posed_mesh(library: ZebraLibrary, options: RenderOptions) -> None:
    view, zebras, (a, b) = _one_zebra(library, options, [(NOON, None), (lighting_for(19.5, 80, -2.3), None)])
    cam = PinholeCamera(W, H, HFOV)
    posed = library.pose(zebras.morph, zebras.global_frame, zebras.scale, zebras.rotation, zebras.position)
    uv, _ = cam.project(map_to_optical(posed.vertices[0].astype(np.float64), view.position, view.r_optical))
    faces = library.faces(0)
    # Rasterise every projected triangle at 8x, then average to pixels: the mesh's exact coverage.
    k = 8
    big = np.zeros((H * k, W * k), np.uint8)
    pts = np.round((uv[faces] + 0.5) * k - 0.5).astype(np.int32)
    for tri in pts:  # one by one: fillPoly on many polygons at once is not a union
        cv2.fillConvexPoly(big, tri, 1)
    coverage = big.reshape(H, k, W, k).mean(axis=(1, 3))
    mask = a.instances == 11
    assert mask.sum() > 400
    core, outside = coverage > 0.75, coverage < 0.25
    assert mask[core].mean() > 0.99  # pixels mostly covered by the zebra are labelled
    assert not mask[outside].any()  # pixels mostly not covered are not
    # Same geometry, other light: the same mask, pixel for pixel; and a different image.
    assert np.array_equal(a.instances, b.instances)
    assert not np.array_equal(a.rgb, b.rgb)
    # Depth on the zebra agrees with the mesh: nearest and farthest labelled depths bracket the vertices.
    z = map_to_optical(posed.vertices[0].astype(np.float64), view.position, view.r_optical)[:, 2]
    assert a.depth[mask].min() >= z.min() - 0.05 and a.depth[mask].max() <= z.max() + 0.05


def test_a_zebra_behind_a_tree_has_no_mask_where_the_tree_is(library: ZebraLibrary, options: RenderOptions) -> None:
    view = _view((0.0, -15.0, 1.5), 90.0, 0.0)
    zebras = _zebras(library, [(0.0, 0.0)])
    renders = {}
    for name, things in (("open", None), ("tree", {"trunk": (cube_mesh(0.5, height=4.0), [(0.3, -6.0, 1.0)])})):
        r = Renderer(flat_world(things), library, options)
        try:
            renders[name] = r.render(zebras, NOON, [view])[0]
        finally:
            r.release()
    open_, tree = renders["open"], renders["tree"]
    hidden = (open_.instances == 11) & (tree.depth < open_.depth - 0.5)  # the trunk is in front of the zebra
    assert hidden.sum() > 100
    assert not (tree.instances[hidden] > 0).any()
    assert np.all(tree.instances[tree.instances > 0] == 11)
    assert ((tree.instances == 11) <= (open_.instances == 11)).all()
    assert (tree.instances == 11).sum() < (open_.instances == 11).sum()


def test_same_scene_renders_the_same_twice(library: ZebraLibrary, options: RenderOptions) -> None:
    world = flat_world({"cube": (cube_mesh(1.0), [(5.0, 5.0, 1.0)])})
    zebras = _zebras(library, [(0.0, 0.0), (3.0, 1.0), (-2.0, 2.0)], yaw=1.0)
    view = _view((0.0, -20.0, 15.0), 90.0, -35.0)
    outs = []
    for _ in range(2):
        r = Renderer(world, library, options)
        try:
            outs.append(r.render(zebras, NOON, [view])[0])
        finally:
            r.release()
    assert np.array_equal(outs[0].instances, outs[1].instances)
    assert np.array_equal(outs[0].depth, outs[1].depth)
    assert set(np.unique(outs[0].instances)) == {0, 11, 12, 13}


def test_effects_touch_rgb_only_and_are_seeded() -> None:
    rgb = np.full((40, 60, 3), 128, np.uint8)
    fx = CameraEffects(blur_sigma_px=1.0, noise_std=5.0, jpeg_quality=70)
    a = fx.apply(rgb, np.random.default_rng(1))
    assert np.array_equal(a, fx.apply(rgb, np.random.default_rng(1)))
    assert not np.array_equal(a, rgb) and a.shape == rgb.shape and a.dtype == np.uint8
    assert abs(float(a.mean()) - 128) < 3


def test_missing_egl_names_the_debian_packages(monkeypatch: pytest.MonkeyPatch) -> None:
    import ctypes.util

    from zebra_sim_ros.rendering import gl

    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(DependencyError, match="libegl1"):
        gl.create_context()


def test_a_recoloured_ground_changes_the_terrain_only(library: ZebraLibrary, options: RenderOptions) -> None:
    from zebra_sim_ros.placement.ground import GroundLook

    snow = GroundLook((4.0, 4.0, 4.0), 1.0)
    _, _, (authored, snowy, again) = _one_zebra(library, options, [(NOON, None), (NOON, snow), (NOON, GroundLook())])
    assert np.array_equal(authored.instances, snowy.instances) and np.array_equal(authored.depth, snowy.depth)
    assert np.array_equal(authored.rgb, again.rgb)  # the identity look is the world as authored
    zebra = cv2.erode((authored.instances == 11).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    ground = (authored.instances == 0) & np.isfinite(authored.depth)
    ground &= cv2.dilate((authored.instances > 0).astype(np.uint8), np.ones((9, 9), np.uint8)) == 0
    assert zebra.sum() > 100 and ground.sum() > 10000
    assert np.array_equal(authored.rgb[zebra], snowy.rgb[zebra])  # the zebra keeps its coat and light
    a, s = authored.rgb[ground].astype(np.float64), snowy.rgb[ground].astype(np.float64)
    assert s.mean() > a.mean() + 40  # brighter ground
    assert np.abs(s - s.mean(axis=1, keepdims=True)).mean() < 0.3 * np.abs(a - a.mean(axis=1, keepdims=True)).mean()


def test_the_coat_array_grows_without_changing_a_pixel(library: ZebraLibrary, options: RenderOptions,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Twelve individuals rendered with a coat array that starts at two layers (doubled to 16 at once, for the frame's
    twelve coats) look exactly as with one of all sixteen layers from the start."""
    import zebra_sim_ros.rendering.renderer as renderer_module

    zebras = _zebras(library, [(float(x), float(y)) for x in (-3, 0, 3) for y in (-2, 0, 2, 4)], yaw=0.7)
    view = _view((0.0, -14.0, 10.0), 90.0, -35.0)
    rgb = {}
    for first in (2, 16):
        monkeypatch.setattr(renderer_module, "COAT_LAYERS_FIRST", first)
        r = Renderer(flat_world(), library, options)
        try:
            out = r.render(zebras, NOON, [view])[0]
            rgb[first] = out.rgb
            assert r.coats.size[2] == 16 and len(set(np.unique(out.instances)) - {0}) == 12
        finally:
            r.release()
    assert np.array_equal(rgb[2], rgb[16])


def test_a_frame_of_new_animals_starts_the_coat_array_again(library: ZebraLibrary, options: RenderOptions,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A frame that shows none of the coats held and would grow the array (``generate``: new animals every frame)
    puts its coats at layer 0 again, in the array as it is; a frame that shows some of them keeps them and grows it,
    copying them over. Either way its pixels are those of a fresh renderer's."""
    from dataclasses import replace

    import zebra_sim_ros.rendering.renderer as renderer_module

    monkeypatch.setattr(renderer_module, "COAT_LAYERS_FIRST", 16)
    opts = replace(options, max_coats=64)
    spots = [(float(x), float(y)) for x in (-3, 0, 3) for y in (-2, 0, 2, 4)]
    first = _zebras(library, spots, yaw=0.7)
    fresh_animals = replace(first, coat_seed=first.coat_seed + 100)  # twelve other individuals
    mixed = replace(first, coat_seed=first.coat_seed + np.where(np.arange(12) < 6, 100, 200))  # 100-105 held
    view = _view((0.0, -14.0, 10.0), 90.0, -35.0)

    def alone(zebras: ZebraSet) -> np.ndarray:
        r = Renderer(flat_world(), library, opts)
        try:
            return r.render(zebras, NOON, [view])[0].rgb
        finally:
            r.release()

    r = Renderer(flat_world(), library, opts)
    try:
        r.render(first, NOON, [view])
        assert r.coats.size[2] == 16 and sorted(r._coat_layer.values()) == list(range(12))
        again = r.render(fresh_animals, NOON, [view])[0].rgb  # 24 coats would not fit: none of the 12 is shown
        assert r.coats.size[2] == 16 and set(r._coat_layer) == {(0, 100 + i) for i in range(12)}
        assert np.array_equal(again, alone(fresh_animals))
        # a frame that would grow the array but whose coats cannot be had (a morph the library lacks) changes nothing
        with pytest.raises(IndexError):
            r.render(replace(mixed, morph=np.where(np.arange(12) == 11, 99, mixed.morph)), NOON, [view])
        assert r.coats.size[2] == 16 and np.array_equal(r.render(fresh_animals, NOON, [view])[0].rgb, again)
        both = r.render(mixed, NOON, [view])[0].rgb  # six held, six new: 18 coats, the array doubled
        assert r.coats.size[2] == 32 and len(r._coat_layer) == 18 and r._coat_layer[(0, 100)] == 0
        assert np.array_equal(both, alone(mixed))
    finally:
        r.release()


def test_coats_from_the_store_render_as_baked_ones(library: ZebraLibrary, options: RenderOptions) -> None:
    """Twelve individuals rendered with coats baked in memory, then by a renderer whose options turn the coat
    store on (beside the library's cache: baked and written), then by another (read back): the same pixels each
    time, and the last renderer baked none. Cameras turn the store on; a renderer alone (``generate``, whose
    streams bring new animals) does not."""
    import shutil
    from dataclasses import replace

    from zebra_sim_ros.rendering.config import CameraConfig

    assert CameraConfig().render_options().coat_store and not options.coat_store
    zebras = _zebras(library, [(float(x), float(y)) for x in (-3, 0, 3) for y in (-2, 0, 2, 4)], yaw=0.7)
    view = _view((0.0, -14.0, 10.0), 90.0, -35.0)
    rgb, counts = [], []
    for i, opts in enumerate((options, replace(options, coat_store=True), replace(options, coat_store=True))):
        r = Renderer(flat_world(), library, opts)
        try:
            store = r.coat_store
            assert store.on == (i > 0) and store.dir.parent == library.root.parent
            if i == 1:
                shutil.rmtree(store.dir)  # empty, whatever other tests left there
                store.dir.mkdir()
            rgb.append(r.render(zebras, NOON, [view])[0].rgb)
            counts.append((store.baked, store.read))
        finally:
            r.release()
    assert counts == [(12, 0), (12, 0), (0, 12)]
    assert np.array_equal(rgb[0], rgb[1]) and np.array_equal(rgb[0], rgb[2])


def test_only_the_animals_a_view_sees_get_a_coat(library: ZebraLibrary, options: RenderOptions) -> None:
    """Coats are baked for the animals some view of the frame can see, no others: a view of part of a herd bakes
    only its animals' coats and renders exactly as when the frame's other view, which sees them all, has every coat
    baked (the animals out of view are culled from every pass, shadows included)."""
    zebras = _zebras(library, [(float(x), float(y)) for x in (-30, -27, 0, 3, 30, 33) for y in (0, 3)], yaw=0.7)
    close = _view((0.0, -10.0, 6.0), 90.0, -30.0)  # the two zebras at x = 0 and 3 wide, not those 30 m off
    whole = _view((0.0, -60.0, 40.0), 90.0, -35.0)
    seen, baked, coats = [], [], []
    for views in ([close], [close, whole]):
        r = Renderer(flat_world(), library, options)
        try:
            out = r.render(zebras, NOON, views)
            seen.append(out[0])
            baked.append(r.coat_store.baked)
            coats.append(len(r._coat_layer))
            if len(views) == 2:
                assert set(np.unique(out[1].instances)) - {0} == set(zebras.ids + 1)  # the whole herd in view
        finally:
            r.release()
    in_close = set(np.unique(seen[0].instances)) - {0}
    assert in_close == {15, 16, 17, 18}  # ids + 1 of the four zebras at x = 0 and 3
    assert baked[0] == coats[0] == 4, (baked, coats)  # the far ones' coats were never baked
    assert baked[1] == coats[1] == 12
    for a, b in ((seen[0].rgb, seen[1].rgb), (seen[0].depth, seen[1].depth), (seen[0].instances, seen[1].instances)):
        assert np.array_equal(a, b)
