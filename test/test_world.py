"""Worlds: preset generation (deterministic, sane terrain and vegetation), USD export/import, CLI."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import CliRun

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.world.noise import derive_rng, spectral_noise, value_noise
from zebra_sim_ros.world.presets import PRESETS
from zebra_sim_ros.world.usd_io import export_world_usd
from zebra_sim_ros.world.vegetation import MAX_GRASS_TUFTS, build_prototype, thin_min_distance
from zebra_sim_ros.world.world import World, WorldError, generate_world, load_world

_CACHE: dict[tuple[str, int], World] = {}


def _world(name: str, seed: int = 0) -> World:
    """One generated world per (preset, seed) for the read-only checks of this module."""
    if (name, seed) not in _CACHE:
        _CACHE[name, seed] = generate_world(name, seed)
    return _CACHE[name, seed]


def test_at_least_twelve_presets_with_savanna_default() -> None:
    assert len(PRESETS) >= 12
    for name in ("savanna", "grassland", "meadow", "woodland", "moorland", "snowy_highland", "scrubland",
                 "farmland"):
        assert name in PRESETS
        assert PRESETS[name].terrain.size_m >= 512 and PRESETS[name].terrain.resolution == 1.0
    assert generate_world().name == "savanna"


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_is_deterministic_per_seed(name: str) -> None:
    a, b, c = _world(name, 0), generate_world(name, 0), generate_world(name, 1)
    assert np.array_equal(a.terrain.heights, b.terrain.heights)
    assert a.vegetation.keys() == b.vegetation.keys()
    for k in a.vegetation:
        for field in ("positions", "yaw", "scale"):
            assert np.array_equal(getattr(a.vegetation[k], field), getattr(b.vegetation[k], field)), (k, field)
    assert np.array_equal(a.obstacles.radii, b.obstacles.radii)
    assert not np.allclose(a.terrain.heights, c.terrain.heights)
    assert a.vegetation.keys() != c.vegetation.keys() or any(
        len(a.vegetation[k]) != len(c.vegetation[k]) or not np.allclose(a.vegetation[k].positions,
                                                                         c.vegetation[k].positions)
        for k in a.vegetation)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_terrain_placeable_and_obstacles(name: str) -> None:
    w = _world(name)
    hf = w.terrain
    x0, y0, x1, y1 = hf.bounds
    assert x1 - x0 >= 500 and y1 - y0 >= 500
    assert hf.resolution == pytest.approx(1.0)
    assert w.source == f"preset:{name}" and w.seed == 0
    px0, py0, px1, py1 = w.placeable
    assert x0 < px0 < px1 < x1 and y0 < py0 < py1 < y1
    assert px1 - px0 >= 120 and py1 - py0 >= 120  # the paper's largest placement rectangle fits
    gx, gy = np.meshgrid(np.linspace(px0, px1, 150), np.linspace(py0, py1, 150))
    steep = np.mean(hf.slope_deg(gx, gy) > w.max_slope_deg)
    assert steep < 0.05, f"{steep:.1%} of the placeable area is steeper than {w.max_slope_deg} deg"
    ob = w.obstacles
    assert len(ob) > 0 and ob.positions.shape == (len(ob), 3) and len(ob.kinds) == len(ob)
    assert np.all(ob.radii > 0) and np.all(ob.radii < 5)
    assert set(ob.kinds) <= {"tree", "rock", "prop"}
    assert np.all(hf.contains(ob.positions[:, 0], ob.positions[:, 1]))


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_vegetation_matches_its_declaration(name: str) -> None:
    w, preset = _world(name), PRESETS[name]
    kinds = {inst.kind for inst in w.vegetation.values() if len(inst)}
    declared = {v.kind for v in preset.vegetation if v.per_hectare > 0 or v.pattern == "hedgerow"}
    assert declared <= kinds, f"declared {declared}, got {kinds}"
    n_grass = sum(len(i) for i in w.vegetation.values() if i.kind == "grass")
    assert 0 < n_grass <= MAX_GRASS_TUFTS
    n_obstacles = 0
    for proto, inst in w.vegetation.items():
        m = len(inst)
        assert inst.prototype == proto and inst.positions.shape == (m, 3)
        assert inst.yaw.shape == (m,) and inst.scale.shape == (m,) and np.all(inst.scale > 0)
        assert np.all(w.terrain.contains(inst.positions[:, 0], inst.positions[:, 1]))
        z = w.terrain.height_at(inst.positions[:, 0], inst.positions[:, 1])
        assert np.allclose(inst.positions[:, 2], z, atol=1e-6)
        v, f, c = w.prototypes[proto]
        assert v.dtype == np.float32 and f.dtype == np.int32 and c.dtype == np.float32
        assert v.shape[1] == 3 and c.shape == v.shape and f.min() >= 0 and f.max() < len(v)
        assert 0 <= c.min() and c.max() <= 1
        if inst.kind in ("tree", "rock", "prop"):
            n_obstacles += m
    assert n_obstacles == len(w.obstacles)
    for layer in preset.vegetation:  # instances of one layer keep its spacing
        if layer.min_spacing_m > 0 and layer.pattern != "hedgerow" and \
                sum(1 for v in preset.vegetation if v.style == layer.style) == 1:
            xy = np.concatenate([i.positions[:, :2] for k, i in w.vegetation.items() if k.startswith(layer.style)])
            if len(xy) > 1:
                d = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(xy)) * 1e9
                assert d.min() >= layer.min_spacing_m - 1e-9, (layer.style, d.min())


@pytest.mark.parametrize("name", ["savanna", "snowy_highland", "farmland"])
def test_ground_colors(name: str) -> None:
    w = _world(name)
    g = w.ground_colors()
    assert g.shape == (*w.terrain.shape, 3) and g.dtype == np.float32
    assert 0 <= g.min() and g.max() <= 1 and g.std() > 0.005
    assert np.array_equal(g, generate_world(name, 0).ground_colors())
    if name == "snowy_highland":  # snow up high, not down low
        h = w.terrain.heights
        assert g[h > np.percentile(h, 95)].mean() > g[h < np.percentile(h, 5)].mean() + 0.1


def test_unknown_preset_names_world_and_lists_presets() -> None:
    with pytest.raises(ParameterError) as exc:
        generate_world("atlantis")
    assert "'world'" in str(exc.value) and "savanna" in str(exc.value) and "farmland" in str(exc.value)
    with pytest.raises(ParameterError):
        load_world("atlantis")
    with pytest.raises(ParameterError, match="seed"):
        generate_world("savanna", -1)


def test_noise_is_seeded_and_normalised() -> None:
    a = spectral_noise((200, 300), 1.0, derive_rng(3, "t"), 3.5, 4.0, 200.0)
    b = spectral_noise((200, 300), 1.0, derive_rng(3, "t"), 3.5, 4.0, 200.0)
    c = spectral_noise((200, 300), 1.0, derive_rng(4, "t"), 3.5, 4.0, 200.0)
    assert a.shape == (200, 300) and np.array_equal(a, b) and not np.allclose(a, c)
    assert abs(a.mean()) < 1e-9 and a.std() == pytest.approx(1.0)
    v = value_noise((64, 80), 8.0, derive_rng(0, "v"), octaves=3)
    assert v.shape == (64, 80) and v.min() == pytest.approx(0.0) and v.max() == pytest.approx(1.0)


def test_thin_min_distance_never_keeps_a_close_pair() -> None:
    xy = np.random.default_rng(0).uniform(0, 50, (3000, 2))
    keep = thin_min_distance(xy, 2.0)
    k = xy[keep]
    d = np.linalg.norm(k[:, None] - k[None], axis=-1) + np.eye(len(k)) * 1e9
    assert d.min() >= 2.0 and 100 < len(k) < 3000


def test_prototypes_stand_on_the_ground() -> None:
    for style in ("acacia", "deciduous", "conifer", "bush", "rock", "mound", "tuft", "fence", "wall", "trough", "hut",
                  "vehicle", "person"):
        p = build_prototype(style, 1)
        v = p.mesh[0]
        assert -0.6 < v[:, 2].min() <= 0.05 and v[:, 2].max() > 0.2, style
        assert (p.footprint_m > 0) == (p.kind in ("tree", "rock", "prop")), style
    sizes = {s: np.ptp(build_prototype(s, 0).mesh[0], axis=0) for s in ("fence", "wall", "hut", "vehicle", "person")}
    assert 2.9 < sizes["fence"][0] < 3.2 and 1.3 < sizes["fence"][2] < 1.9  # a 3 m panel, 1.45 m above ground
    assert 4.5 < sizes["vehicle"][0] < 5.0 and 1.5 < sizes["vehicle"][2] < 2.2
    assert 1.6 < sizes["person"][2] < 2.0 and sizes["person"][0] < 0.5
    assert 3.5 < sizes["hut"][2] < 4.2


def test_waterhole_has_flat_open_water_where_nothing_stands() -> None:
    """The waterhole's basin is filled to a flat surface: the terrain there is level at the water line, the world
    says how deep the water is, no tree, bush, rock or tuft stands in it and no zebra is placed in it."""
    from zebra_sim_ros.placement.config import PlacerConfig
    from zebra_sim_ros.placement.placer import Placer
    from zebra_sim_ros.zebra.asset import load_library

    w = _world("waterhole")
    assert w.water is not None and w.water.shape == w.terrain.shape
    wet = w.water > 0
    area_m2 = float(wet.sum()) * w.terrain.resolution ** 2
    assert 2000 < area_m2 < 20000, area_m2  # a pond some 50-160 m across
    surface = w.terrain.heights[wet]
    assert float(np.ptp(surface)) < 1e-5  # flat
    assert w.water.max() > 1.0  # deep in the middle
    for inst in w.vegetation.values():
        depth = _sample(w.water, w, inst.positions[:, :2])
        assert np.all(depth <= -0.3 + 1e-6), inst.prototype
    placer = Placer(PlacerConfig.from_params({"world": "waterhole", "seed": 2, "count_min": 150}), w, load_library())
    for step in range(0, 12, 3):
        feet = np.array([z.position for z in placer.scene(step).zebras])
        assert np.all(_sample(w.water, w, feet[:, :2]) < 0.0)
    assert _world("savanna").water is None


def _sample(grid: np.ndarray, w: World, xy: np.ndarray) -> np.ndarray:
    t = w.terrain
    i = np.clip(np.rint((xy[:, 0] - t.origin[0]) / t.resolution).astype(int), 0, t.shape[1] - 1)
    j = np.clip(np.rint((xy[:, 1] - t.origin[1]) / t.resolution).astype(int), 0, t.shape[0] - 1)
    return grid[j, i]


def test_zoo_fences_run_along_the_paddock_lines_and_tracks_are_painted() -> None:
    """Fence and wall panels stand end to end along the paddock boundaries, turned along them; people, vehicles,
    huts and troughs are obstacles no zebra stands in; tracks darken or lighten thin lines of the ground."""
    w = _world("zoo")
    fences = [i for k, i in w.vegetation.items() if k.startswith(("fence", "wall"))]
    assert sum(len(i) for i in fences) > 100
    xy = np.concatenate([i.positions[:, :2] for i in fences])
    yaw = np.concatenate([i.yaw for i in fences])
    nearest = np.linalg.norm(xy[:, None] - xy[None], axis=-1) + np.eye(len(xy)) * 1e9
    j = nearest.argmin(axis=1)
    assert np.median(nearest.min(axis=1)) < 3.2  # panels meet end to end
    d = xy[j] - xy
    along = np.abs(np.cos(np.arctan2(d[:, 1], d[:, 0]) - yaw))
    assert np.median(along) > 0.95  # each panel is turned along its line
    assert "prop" in set(w.obstacles.kinds)
    plain = generate_world(replace(PRESETS["dusty_plain"], materials=PRESETS["dusty_plain"].materials[:3]), 0)
    diff = np.abs(_world("dusty_plain").ground_colors() - plain.ground_colors()).sum(axis=-1)
    share = float((diff > 0.01).mean())
    assert 0.01 < share < 0.5, share  # thin lines, not a wash over everything
    assert build_prototype("acacia", 0).mesh[0][:, 2].max() > 4.0  # a tree, not a shrub


def test_usd_round_trip(tmp_path: Path) -> None:
    w = _world("woodland")
    path = export_world_usd(w, tmp_path / "woodland.usdc")
    back = load_world(path)
    assert back.source == str(path) and back.name == "woodland" and back.seed == 0
    assert back.terrain.origin == w.terrain.origin and back.terrain.shape == w.terrain.shape
    assert np.abs(back.terrain.heights - w.terrain.heights).max() < 1e-3
    assert len(back.obstacles) == len(w.obstacles)
    assert np.allclose(np.sort(back.obstacles.radii), np.sort(w.obstacles.radii), atol=1e-5)
    assert back.placeable == pytest.approx(w.placeable) and back.max_slope_deg == w.max_slope_deg
    assert back.sky == w.sky and back.materials == w.materials
    assert back.instance_count() == w.instance_count()
    for k, inst in w.vegetation.items():
        assert back.vegetation[k].kind == inst.kind
        assert np.allclose(back.vegetation[k].positions, inst.positions, atol=1e-4)
        dyaw = np.angle(np.exp(1j * (back.vegetation[k].yaw - inst.yaw)))
        assert np.abs(dyaw).max() < 3e-3  # orientations are half-precision quaternions in USD
        assert np.allclose(back.prototypes[k][0], w.prototypes[k][0], atol=1e-5)
    assert np.abs(back.ground_colors() - w.ground_colors()).max() < 1e-3


def _stage(path: Path, up: str = "Z", mpu: float = 1.0):  # type: ignore[no-untyped-def]
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    UsdGeom.Xform.Define(stage, "/World")
    return stage


def _quad_grid(stage, path: str, n: int, size: float, height) -> None:  # type: ignore[no-untyped-def]
    """An n x n vertex grid of quads over (x, z) in [0, size]^2 (y up) with y = height(x)."""
    from pxr import UsdGeom, Vt

    c = np.linspace(0, size, n)
    gx, gz = np.meshgrid(c, c)
    pts = np.stack([gx, height(gx), gz], -1).reshape(-1, 3)
    idx = np.arange(n * n).reshape(n, n)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4] * ((n - 1) * (n - 1))))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(quads.tolist()))


def test_missing_terrain_prim_names_it_and_lists_meshes(tmp_path: Path) -> None:
    stage = _stage(tmp_path / "a.usda", up="Y")
    _quad_grid(stage, "/World/Ground", 4, 10.0, lambda x: 0 * x)
    stage.GetRootLayer().Save()
    with pytest.raises(WorldError) as exc:
        load_world(tmp_path / "a.usda")
    assert "/World/Terrain" in str(exc.value) and "/World/Ground" in str(exc.value)
    w = load_world(tmp_path / "a.usda", terrain_prim="/World/Ground")
    assert w.terrain.bounds[2] - w.terrain.bounds[0] == pytest.approx(10.0)
    assert w.seed is None and len(w.obstacles) == 0 and w.ground_colors().shape == (*w.terrain.shape, 3)


def test_terrain_prim_that_is_not_a_mesh(tmp_path: Path) -> None:
    from pxr import UsdGeom

    stage = _stage(tmp_path / "b.usda", up="Y")
    UsdGeom.Xform.Define(stage, "/World/Terrain")
    _quad_grid(stage, "/World/Terrain/Mesh", 4, 10.0, lambda x: 0 * x)
    stage.GetRootLayer().Save()
    with pytest.raises(WorldError) as exc:
        load_world(str(tmp_path / "b.usda"))
    assert "/World/Terrain" in str(exc.value) and "Xform" in str(exc.value)


def test_missing_usd_file_names_the_path(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="nowhere.usd"):
        load_world(tmp_path / "nowhere.usd")


def test_y_up_centimetre_quad_mesh_loads_in_metres(tmp_path: Path) -> None:
    from pxr import Gf, UsdGeom

    stage = _stage(tmp_path / "cm.usda", up="Y", mpu=0.01)
    _quad_grid(stage, "/World/Terrain", 11, 2000.0, lambda x: 50.0 + 0.1 * x)  # 20 m square, cm
    UsdGeom.Xformable(stage.GetPrimAtPath("/World/Terrain")).AddTranslateOp().Set(Gf.Vec3d(0, 100, 0))
    stage.GetRootLayer().Save()
    w = load_world(tmp_path / "cm.usda")
    x0, y0, x1, y1 = w.terrain.bounds
    # y-up (x, y, z) -> z-up (x, -z, y): the stage's +z depth becomes map -y
    assert (x0, y0, x1, y1) == pytest.approx((0.0, -20.0, 20.0, 0.0), abs=1e-4)
    assert w.terrain.shape == (21, 21)
    for x, y in ((0.0, -20.0), (10.0, -5.0), (17.5, -12.0), (20.0, 0.0)):
        assert float(w.terrain.height_at(x, y)) == pytest.approx(1.5 + 0.1 * x, abs=1e-4)
    assert float(w.terrain.slope_deg(10.0, -10.0)) == pytest.approx(np.degrees(np.arctan(0.1)), abs=0.01)


def test_cli_world_list_json(cli: CliRun) -> None:
    proc = cli(["world", "list", "--json"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert [w["name"] for w in summary["worlds"]] == list(PRESETS)
    assert summary["default"] == "savanna" and all(w["description"] for w in summary["worlds"])
    assert "savanna" in proc.stdout.splitlines()[0]


def test_cli_world_export_and_bad_preset(tmp_path: Path, cli: CliRun) -> None:
    out = tmp_path / "scrub.usd"
    proc = cli(["world", "export", "--preset", "scrubland", "--seed", "2", out, "--json"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["path"] == str(out) and summary["bytes"] == out.stat().st_size > 1_000_000
    assert summary["preset"] == "scrubland" and summary["seed"] == 2 and summary["triangles"] == 2 * 512 * 512
    assert summary["instances"] == generate_world("scrubland", 2).instance_count()
    bad = cli(["world", "export", "--preset", "atlantis", tmp_path / "x.usd"])
    assert bad.returncode == 2
    assert "--preset" in bad.stderr and "savanna" in bad.stderr and "atlantis" in bad.stderr


def test_cli_world_preview(tmp_path: Path, cli: CliRun) -> None:
    import cv2

    out = tmp_path / "m.png"
    proc = cli(["world", "preview", "--preset", "moorland", "--px-per-m", "1", out, "--json"])
    assert proc.returncode == 0, proc.stderr
    img = cv2.imread(str(out))
    assert img.shape == (512, 512, 3) and img.std() > 5
