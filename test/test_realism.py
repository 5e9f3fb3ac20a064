"""Image formation that looks like a photograph: procedural ground detail, contact shadows, the per-frame camera
model. Each is checked for what it must do to the RGB image, and for what it must never do: move a mask or a depth
value (labels stay exact)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from render_helpers import flat_world

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import optical_rotation
from zebra_sim_ros.messages import SensorDraw
from zebra_sim_ros.placement.sun import lighting_for
from zebra_sim_ros.rendering.effects import SensorModel
from zebra_sim_ros.rendering.ground import contact_map, surface_from_colours
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
