"""Image formation that looks like a photograph: procedural ground detail, contact shadows, the per-frame camera
model. Each is checked for what it must do to the RGB image, and for what it must never do: move a mask or a depth
value (labels stay exact)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from render_helpers import cube_mesh, flat_world

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import optical_rotation
from zebra_sim_ros.messages import GroundLook, MessageFormatError, SensorDraw, Weather
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.placement.weather import rotate_sun, sample_weather
from zebra_sim_ros.rendering.effects import SensorModel
from zebra_sim_ros.rendering.ground import contact_map, surface_from_colours, vegetation_occlusion
from zebra_sim_ros.rendering.renderer import CameraView, Renderer, RenderOptions, ZebraSet
from zebra_sim_ros.zebra.asset import ZebraLibrary

NOON = lighting_for(12.0, 80, -2.3)


def _detail(rgb: np.ndarray, mask: np.ndarray) -> float:
    """Median |Laplacian| of the grey image after a 1 px blur, over ``mask`` (as the detail-energy tool)."""
    grey = cv2.GaussianBlur(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 1.0)
    return float(np.median(np.abs(cv2.Laplacian(grey, cv2.CV_32F))[mask]))


def test_contact_map_darkens_under_each_animal_along_its_body() -> None:
    cmap = contact_map(np.array([[10.0, 5.0, 0.0]]), np.array([[1.0, 0.0]]), np.array([1.0]), strength=0.5)
    v = cmap.values
    assert v.min() == pytest.approx(0.5, abs=0.02) and v.max() == pytest.approx(1.0, abs=1e-3)

    def at(x: float, y: float) -> float:
        i = int((x - cmap.origin[0]) / cmap.resolution)
        j = int((y - cmap.origin[1]) / cmap.resolution)
        return float(v[j, i])

    assert at(10.0, 5.0) < 0.55
    assert at(11.0, 5.0) < at(10.0, 6.0)  # darker 1 m along the body (x) than 1 m beside it
    assert at(10.0, 5.0 + 2.5) > 0.99
    u0, v0, su, sv = cmap.xform
    assert (u0, v0) == cmap.origin and su == pytest.approx(1 / (v.shape[1] * cmap.resolution))
    empty = contact_map(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0))
    assert empty.values.shape == (1, 1) and empty.values[0, 0] == 1.0


def test_surface_weights_from_colours_sum_to_one() -> None:
    rgb = np.array([[[0.10, 0.25, 0.05], [0.30, 0.26, 0.22], [0.005, 0.005, 0.004]]], dtype=np.float32)
    w = surface_from_colours(rgb)
    assert w.shape == (1, 3, 4)
    np.testing.assert_allclose(w.sum(axis=-1), 1.0, atol=1e-5)
    assert w[0, 0, 0] > 0.9  # green: grass
    assert w[0, 1, 1] > 0.6  # grey-brown: soil
    assert w[0, 2, 3] > 0.5  # near black: wet


def _ground_render(library: ZebraLibrary, detail: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    opts = RenderOptions(width=320, height=240, hfov_deg=60.0, coat_size=64, max_coats=16, detail=detail)
    r = Renderer(flat_world(), library, opts)
    try:
        n = 1
        zebras = ZebraSet(ids=np.array([4]), morph=np.zeros(n, dtype=np.int64),
                          global_frame=np.full(n, library.frame_index("idle", 0), dtype=np.int64), scale=np.ones(n),
                          rotation=np.eye(3)[None], position=np.array([[0.0, 0.0, 0.0]]),
                          coat_seed=np.zeros(n, dtype=np.int64))
        view = CameraView("cam", np.array([0.0, -8.0, 3.0]), optical_rotation(np.radians(90.0), np.radians(-20.0), 0.0))
        out = r.render(zebras, NOON, [view])[0]
    finally:
        r.release()
    return out.rgb, out.depth, out.instances


def test_ground_detail_adds_structure_and_never_moves_labels(library: ZebraLibrary) -> None:
    flat_rgb, flat_depth, flat_ids = _ground_render(library, detail=False)
    rgb, depth, ids = _ground_render(library, detail=True)
    assert np.array_equal(ids, flat_ids) and np.array_equal(depth, flat_depth)
    ground = (ids == 0) & np.isfinite(depth)
    ground[: ground.shape[0] // 2] = False
    assert ground.sum() > 10000
    assert _detail(rgb, ground) > 2.0 * _detail(flat_rgb, ground) + 0.2


def test_sensor_draws_are_seeded_in_range_and_recorded() -> None:
    model = SensorModel()
    a = model.draw(np.random.default_rng(3))
    assert a == model.draw(np.random.default_rng(3)) and a != model.draw(np.random.default_rng(4))
    draws = [model.draw(np.random.default_rng(s)) for s in range(200)]
    assert all(abs(d.exposure_ev) <= model.exposure_ev and 0 <= d.vignetting <= model.vignetting_max for d in draws)
    assert all(model.jpeg_quality[0] <= d.jpeg_quality <= model.jpeg_quality[1] for d in draws)
    assert 0.1 < np.mean([d.motion_px > 0 for d in draws]) < 0.5
    assert SensorDraw.from_dict(a.to_dict()) == a and SensorDraw.from_dict(None) is None
    off = SensorModel(0.0).draw(np.random.default_rng(3))
    assert off == SensorDraw()
    with pytest.raises(ParameterError, match="strength"):
        SensorModel(-1.0)


def test_sensor_apply_vignettes_and_adds_signal_dependent_noise() -> None:
    rng = np.random.default_rng(0)
    grey = np.full((180, 320, 3), 128, dtype=np.uint8)
    vig = SensorModel.apply(grey, SensorDraw(vignetting=0.3), rng)
    assert vig[90, 160].mean() > vig[2, 2].mean() + 15 and abs(int(vig[90, 160, 0]) - 128) <= 1
    assert np.array_equal(SensorModel.apply(grey, SensorDraw(), rng), grey)  # the perfect camera changes nothing
    shot = SensorDraw(shot_noise=0.004)
    dark = SensorModel.apply(np.full((180, 320, 3), 40, dtype=np.uint8), shot, rng)
    bright = SensorModel.apply(np.full((180, 320, 3), 200, dtype=np.uint8), shot, rng)
    # Poisson-Gaussian: variance grows with the signal (in linear light; 8-bit sRGB compresses the bright end).
    lin = lambda x: (x.astype(np.float64) / 255) ** 2.2  # noqa: E731
    assert lin(bright).var() > 2.0 * lin(dark).var()
    warm = SensorModel.apply(grey, SensorDraw(wb_gain=(1.1, 1.0, 0.9)), rng)
    assert warm[..., 0].mean() > grey[..., 0].mean() + 5 > warm[..., 2].mean() + 10


# -- the sky, clouds and structured domain randomisation ---------------------------------------------------------

def _sky_render(library: ZebraLibrary, weather: Weather | None, tree: bool = False,
                ground: GroundLook | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A flat world (a box, and with ``tree`` a green crown), one zebra, a camera 3 m up looking a little down so
    that the upper third of the image is sky."""
    opts = RenderOptions(width=320, height=240, hfov_deg=70.0, coat_size=64, max_coats=16)
    things = {"box": (cube_mesh(2.0), [(4.0, 6.0, 1.0)])}
    if tree:
        things["crown"] = (cube_mesh(4.0, (0.05, 0.2, 0.02)), [(-3.0, 8.0, 1.0)])
    r = Renderer(flat_world(things), library, opts)
    try:
        zebras = ZebraSet(ids=np.array([4]), morph=np.zeros(1, dtype=np.int64),
                          global_frame=np.full(1, library.frame_index("idle", 0), dtype=np.int64), scale=np.ones(1),
                          rotation=np.eye(3)[None], position=np.array([[0.0, 0.0, 0.0]]),
                          coat_seed=np.zeros(1, dtype=np.int64))
        view = CameraView("cam", np.array([0.0, -10.0, 3.0]), optical_rotation(np.radians(90.0), np.radians(-5.0), 0.0))
        out = r.render(zebras, NOON, [view], ground, weather)[0]
    finally:
        r.release()
    return out.rgb, out.depth, out.instances


def test_weather_changes_the_image_never_the_labels(library: ZebraLibrary) -> None:
    clear_rgb, clear_depth, clear_ids = _sky_render(library, None)
    over_rgb, over_depth, over_ids = _sky_render(library, Weather(1.0, (10.0, 20.0)))
    assert np.array_equal(over_ids, clear_ids) and np.array_equal(over_depth, clear_depth)
    sky = ~np.isfinite(clear_depth)
    assert sky.sum() > 5000
    # A clear sky is blue; an overcast one is grey.
    c, o = clear_rgb[sky].astype(float), over_rgb[sky].astype(float)
    assert (c[:, 2] - c[:, 0]).mean() > 20 > (o[:, 2] - o[:, 0]).mean() + 10
    # Under an overcast sky the box casts no hard shadow: the ground beside it is as bright as the ground in the sun.
    ground = np.isfinite(clear_depth) & (clear_ids == 0)
    g_clear = cv2.cvtColor(clear_rgb, cv2.COLOR_RGB2GRAY)[ground].astype(float)
    g_over = cv2.cvtColor(over_rgb, cv2.COLOR_RGB2GRAY)[ground].astype(float)
    assert np.percentile(g_over, 95) - np.percentile(g_over, 5) < np.percentile(g_clear, 95) - np.percentile(
        g_clear, 5)


def test_broken_clouds_show_in_the_sky(library: ZebraLibrary) -> None:
    clear_rgb, depth, _ = _sky_render(library, None)
    broken_rgb, _, _ = _sky_render(library, Weather(0.5, (0.0, 0.0)))
    sky = ~np.isfinite(depth)
    grey = lambda im: cv2.cvtColor(im, cv2.COLOR_RGB2GRAY).astype(float)  # noqa: E731
    # Clouds are white and grey patches: the sky's brightness varies far more than a clear gradient's row to row.
    assert grey(broken_rgb)[sky].std() > 1.5 * grey(clear_rgb)[sky].std()


def test_look_randomisation_tints_plants_and_sky(library: ZebraLibrary) -> None:
    base, depth, ids = _sky_render(library, None, tree=True)
    tinted, depth2, ids2 = _sky_render(library, Weather(0.0, (0.0, 0.0), sky_tint=(1.2, 0.9, 0.8)), tree=True,
                                       ground=GroundLook(vegetation_tint=(2.0, 1.0, 0.5)))
    assert np.array_equal(ids, ids2) and np.array_equal(depth, depth2)
    sky = ~np.isfinite(depth)
    assert tinted[sky][:, 0].mean() > base[sky][:, 0].mean() + 5  # redder sky
    crown = (np.abs(depth - np.hypot(3.0, 18.0)) < 4.0) & (base[..., 1] > base[..., 0] + 5)
    assert crown.sum() > 100
    assert tinted[crown][:, 0].mean() > base[crown][:, 0].mean() + 5  # the plants' red channel doubled


def test_vegetation_occlusion_darkens_the_ground_under_a_crown() -> None:
    world = flat_world({"tree": (cube_mesh(6.0, (0.1, 0.3, 0.05)), [(10.0, -5.0, 1.0)])})
    world.vegetation["tree"] = replace(world.vegetation["tree"], kind="tree")
    occl = vegetation_occlusion(world, strength=0.5)
    t = world.terrain
    at = lambda x, y: float(occl[int(round(y - t.origin[1])), int(round(x - t.origin[0]))])  # noqa: E731
    assert at(10.0, -5.0) == pytest.approx(0.5, abs=0.01)
    assert at(10.0, -5.0) < at(13.0, -5.0) < at(20.0, -5.0)
    assert at(40.0, 40.0) == 1.0
    rocks = flat_world({"rock": (cube_mesh(6.0), [(10.0, -5.0, 1.0)])})  # rocks are not crowns
    assert vegetation_occlusion(rocks).min() == 1.0


def test_weather_is_seeded_bounded_and_its_own_stream() -> None:
    draws = [sample_weather(np.random.default_rng(s), 1.0, 0.0) for s in range(300)]
    covers = np.array([w.cloud_cover for w, _, _ in draws])
    assert 0.0 <= covers.min() and covers.max() <= 1.0
    assert 0.1 < np.mean(covers > 0.7) < 0.3 and 0.3 < np.mean(covers < 0.15) < 0.6  # overcast and clear days
    assert all(w.sky_tint == (1.0, 1.0, 1.0) and v == (1.0, 1.0, 1.0) and t == 0.0 for w, v, t in draws)
    half = [sample_weather(np.random.default_rng(s), 0.5, 1.0) for s in range(300)]
    assert max(w.cloud_cover for w, _, _ in half) <= 0.5
    # The same draws whatever the settings: cover scales, the cloud field stays where it was.
    assert all(a.cloud_offset == b.cloud_offset for (a, _, _), (b, _, _) in zip(draws, half, strict=True))
    assert np.mean([t != 0.0 for _, _, t in half]) == 1.0
    assert sample_weather(np.random.default_rng(7), 1.0, 0.5) == sample_weather(np.random.default_rng(7), 1.0, 0.5)
    with pytest.raises(ParameterError, match="cloud_cover_max"):
        sample_weather(np.random.default_rng(0), 1.5, 0.0)
    with pytest.raises(ParameterError, match="look_randomise"):
        sample_weather(np.random.default_rng(0), 1.0, -0.1)


def test_rotate_sun_keeps_elevation_and_turns_azimuth_and_shadows() -> None:
    turned = rotate_sun(NOON, 90.0)
    assert turned.sun_elevation_deg == NOON.sun_elevation_deg
    assert turned.sun_azimuth_deg == pytest.approx((NOON.sun_azimuth_deg + 90.0) % 360.0)
    sx, sy, sz = turned.sun_direction
    assert np.degrees(np.arctan2(sx, sy)) % 360.0 == pytest.approx(turned.sun_azimuth_deg, abs=1e-9)
    assert sz == pytest.approx(NOON.sun_direction[2]) and turned.light_direction == turned.sun_direction
    assert rotate_sun(NOON, 0.0) is NOON


def test_weather_and_look_round_trip_and_old_scenes_read_clear() -> None:
    w = Weather(0.42, (12.5, -3.0), (1.1, 1.0, 0.9), (1.2, 1.0, 0.8))
    assert Weather.from_dict(w.to_dict()) == w and Weather.from_dict(None) == Weather()
    g = GroundLook((1.0, 2.0, 0.5), 0.3, (0.8, 1.2, 0.7))
    assert GroundLook.from_dict(g.to_dict()) == g
    assert "vegetation_tint" not in GroundLook((2.0, 1.0, 1.0), 0.1).to_dict()  # scenes of before read the same
    with pytest.raises(MessageFormatError, match="cloud_cover"):
        Weather.from_dict({"cloud_cover": 1.5, "cloud_offset": [0, 0], "sky_tint": [1, 1, 1], "light_tint": [1, 1, 1]})
