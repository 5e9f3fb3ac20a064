"""Worlds as USD stages: write one (:func:`export_world_usd`), read any (:func:`read_world_usd`).

Written layout (z up, metersPerUnit 1, default prim ``/World``):

- ``/World`` (Xform) with customData ``zebra_sim:{name,preset,seed,placeable,max_slope_deg}`` and the
  sky ``zebra_sim:sky_{zenith_rgb,horizon_rgb,haze_per_m,ambient,sun}``
- ``/World/Terrain`` a Mesh of the full heightfield grid, per-vertex ``displayColor`` = ground colours
- ``/World/Vegetation/<prototype>`` a PointInstancer per prototype (positions, orientations from yaw,
  uniform scales) whose one prototype is the child Mesh ``<prototype>`` with ``displayColor``; tree and
  rock prototypes carry customData ``zebra_sim:footprint_radius`` (m at scale 1), ``zebra_sim:clearance``
  (m added after scaling) and ``zebra_sim:kind``.

Reading accepts any stage: Y-up stages are turned z-up, ``metersPerUnit`` applied, prim transforms
composed, polygons fan-triangulated.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import DependencyError
from zebra_sim_ros.world.model import OBSTACLE_KINDS, Instances, World, WorldError, build_obstacles
from zebra_sim_ros.world.presets import PRESETS, Sky
from zebra_sim_ros.world.terrain import Heightfield, TerrainError
from zebra_sim_ros.world.vegetation import PrototypeMesh

FloatArray = NDArray[np.float64]
VEGETATION_ROOT = "/World/Vegetation"
DEFAULT_MARGIN_M = 30.0
DEFAULT_MAX_SLOPE_DEG = 25.0


def _pxr() -> Any:
    try:
        import pxr
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt  # noqa: F401
    except ImportError as exc:  # pragma: no cover - usd-core is a declared dependency
        raise DependencyError("usd-core is needed for USD worlds: pip install usd-core") from exc
    return pxr


def _set_mesh(stage: Any, path: str, verts: NDArray[np.float32], faces: NDArray[np.int32],
              rgb: NDArray[np.float32]) -> Any:
    from pxr import Gf, UsdGeom, Vt

    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(verts, dtype=np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces, dtype=np.int32).ravel()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    pv = mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
    pv.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(rgb, dtype=np.float32)))
    return mesh


def export_world_usd(world: World, path: Path) -> Path:
    """Write ``world`` to ``path`` (.usd/.usdc binary, .usda text); returns the path.

    :func:`zebra_sim_ros.world.world.load_world` reads it back to the same heights (1 m grid), obstacles,
    instances and ground colours.
    """
    _pxr()
    from pxr import Gf, Usd, UsdGeom, Vt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(root.GetPrim())
    rp = root.GetPrim()
    rp.SetCustomDataByKey("zebra_sim:name", world.name)
    rp.SetCustomDataByKey("zebra_sim:source", world.source)
    if world.source.startswith("preset:"):
        rp.SetCustomDataByKey("zebra_sim:preset", world.source.removeprefix("preset:"))
    if world.seed is not None:
        rp.SetCustomDataByKey("zebra_sim:seed", int(world.seed))
    rp.SetCustomDataByKey("zebra_sim:placeable", Gf.Vec4d(*map(float, world.placeable)))
    rp.SetCustomDataByKey("zebra_sim:max_slope_deg", float(world.max_slope_deg))
    rp.SetCustomDataByKey("zebra_sim:sky_zenith_rgb", Gf.Vec3d(*world.sky.zenith_rgb))
    rp.SetCustomDataByKey("zebra_sim:sky_horizon_rgb", Gf.Vec3d(*world.sky.horizon_rgb))
    rp.SetCustomDataByKey("zebra_sim:sky_haze_per_m", float(world.sky.haze_per_m))
    rp.SetCustomDataByKey("zebra_sim:sky_ambient", float(world.sky.ambient))
    rp.SetCustomDataByKey("zebra_sim:sky_sun", float(world.sky.sun))

    verts, faces = world.terrain.to_mesh(1)
    colors = world.ground_colors().reshape(-1, 3)
    _set_mesh(stage, "/World/Terrain", verts, faces, colors)

    radius_at = world.footprints
    if world.vegetation:
        UsdGeom.Scope.Define(stage, VEGETATION_ROOT)
    for name in sorted(world.vegetation):
        inst = world.vegetation[name]
        ipath = f"{VEGETATION_ROOT}/{name}"
        pi = UsdGeom.PointInstancer.Define(stage, ipath)
        v, f, c = world.prototypes[name]
        proto = _set_mesh(stage, f"{ipath}/{name}", v, f, c).GetPrim()
        proto.SetCustomDataByKey("zebra_sim:kind", inst.kind)
        if name in radius_at:
            proto.SetCustomDataByKey("zebra_sim:footprint_radius", float(radius_at[name][0]))
            proto.SetCustomDataByKey("zebra_sim:clearance", float(radius_at[name][1]))
        pi.CreatePrototypesRel().SetTargets([proto.GetPath()])
        m = len(inst)
        pi.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(np.zeros(m, dtype=np.int32)))
        pi.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(inst.positions.astype(np.float32)))
        half = inst.yaw / 2
        q = np.stack([np.zeros(m), np.zeros(m), np.sin(half), np.cos(half)], 1)  # (i, j, k, real)
        pi.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(q.astype(np.float16)))
        pi.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(np.repeat(inst.scale[:, None], 3, 1).astype(np.float32)))
    stage.GetRootLayer().Save()
    return path


# --- reading ----------------------------------------------------------------------------------------

def _triangulate(counts: NDArray[np.int64], indices: NDArray[np.int64], left_handed: bool) -> NDArray[np.int64]:
    """Fan-triangulate polygons (faceVertexCounts, faceVertexIndices) into (F, 3) CCW triangles."""
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if counts.size == 0 or counts.sum() != indices.size:
        raise WorldError(f"mesh face arrays disagree: {counts.sum()} face-vertex counts, {indices.size} indices")
    starts = np.cumsum(counts) - counts
    ntri = np.maximum(counts - 2, 0)
    poly = np.repeat(np.arange(len(counts)), ntri)
    k = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = starts[poly]
    tri = np.stack([indices[s], indices[s + k], indices[s + k + 1]], 1)
    return tri[:, ::-1].copy() if left_handed else tri


def _stage_to_map(stage: Any) -> FloatArray:
    """4x4 (row-vector convention) taking stage units and up axis to map metres, z up."""
    from pxr import UsdGeom

    m = np.eye(4) * float(UsdGeom.GetStageMetersPerUnit(stage) or 0.01)
    m[3, 3] = 1.0
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y:
        # (x, y, z)_yup -> (x, -z, y)_zup, a proper rotation about +x
        rot = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
        m = m @ rot
    return m


def _world_xf(prim: Any) -> FloatArray:
    from pxr import Usd, UsdGeom

    return np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()), dtype=np.float64)


def _apply(points: FloatArray, xf: FloatArray) -> FloatArray:
    return np.asarray(points @ xf[:3, :3] + xf[3, :3])


def _mesh_arrays(prim: Any, to_map: FloatArray, relative_to: FloatArray | None = None) -> tuple[
        FloatArray, NDArray[np.int64], FloatArray | None]:
    """Vertices (map metres, or relative to an instancer prototype root), triangles and per-vertex RGB."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(prim)
    pts = np.asarray(mesh.GetPointsAttr().Get() or [], dtype=np.float64).reshape(-1, 3)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    if len(pts) == 0:
        raise WorldError(f"mesh {prim.GetPath()} has no points")
    tri = _triangulate(counts, idx, mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded)
    xf = _world_xf(prim)
    if relative_to is not None:
        xf = xf @ np.linalg.inv(relative_to)
    v = _apply(pts, xf @ to_map)
    rgb = None
    pv = mesh.GetDisplayColorPrimvar()
    if pv and pv.HasValue():
        c = np.asarray(pv.Get(), dtype=np.float64).reshape(-1, 3)
        interp = pv.GetInterpolation()
        if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying) and len(c) == len(pts):
            rgb = c
        elif len(c) == 1:
            rgb = np.repeat(c, len(pts), 0)
    return v, tri, rgb


def _grid_colors(hf: Heightfield, verts: FloatArray, rgb: FloatArray) -> NDArray[np.float32]:
    """Per-vertex colours averaged onto the heightfield grid; empty samples take a neighbour's colour."""
    ny, nx = hf.shape
    i = np.clip(np.rint((verts[:, 0] - hf.origin[0]) / hf.resolution).astype(np.int64), 0, nx - 1)
    j = np.clip(np.rint((verts[:, 1] - hf.origin[1]) / hf.resolution).astype(np.int64), 0, ny - 1)
    acc = np.zeros((ny, nx, 3))
    cnt = np.zeros((ny, nx))
    np.add.at(acc, (j, i), rgb)
    np.add.at(cnt, (j, i), 1.0)
    known = cnt > 0
    acc[known] /= cnt[known, None]
    for _ in range(max(ny, nx)):
        if known.all():
            break
        for axis in (0, 1):
            for shift in (1, -1):
                src = np.roll(acc, shift, axis=axis)
                sk = np.roll(known, shift, axis=axis)
                edge = (0 if shift == 1 else -1)
                if axis == 0:
                    sk[edge, :] = False
                else:
                    sk[:, edge] = False
                take = ~known & sk
                acc[take] = src[take]
                known = known | take
    return np.clip(acc, 0, 1).astype(np.float32)


def _custom(prim: Any, key: str, default: Any = None) -> Any:
    v = prim.GetCustomDataByKey(key)
    return default if v is None else v


def _rgb(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _mesh_prims(stage: Any, limit: int = 10) -> list[str]:
    from pxr import UsdGeom

    out = []
    for p in stage.Traverse():
        if p.IsA(UsdGeom.Mesh):
            out.append(str(p.GetPath()))
            if len(out) >= limit:
                break
    return out


def _guess_kind(name: str) -> str:
    n = name.lower()
    for kind, words in (("rock", ("rock", "stone", "boulder", "mound")), ("grass", ("grass", "tuft")),
                        ("bush", ("bush", "shrub", "hedge")), ("tree", ("tree", "acacia", "conifer", "pine",
                                                                          "oak", "birch", "deciduous"))):
        if any(w in n for w in words):
            return kind
    return "other"


def _open_terrain(path: Path, terrain_prim: str) -> tuple[Any, Any]:
    """The stage at ``path`` and its terrain prim, or :class:`WorldError` saying what is missing."""
    from pxr import Usd, UsdGeom

    if not path.is_file():
        raise WorldError(f"USD world file not found: {path}")
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException
        raise WorldError(f"cannot open USD stage {path}: {exc}") from exc
    prim = stage.GetPrimAtPath(terrain_prim)
    if not prim or not prim.IsValid():
        meshes = _mesh_prims(stage)
        raise WorldError(f"terrain prim {terrain_prim} not found in {path}; mesh prims in the stage: "
                         f"{meshes if meshes else 'none'}")
    if not prim.IsA(UsdGeom.Mesh):
        raise WorldError(f"terrain prim {terrain_prim} in {path} is a {prim.GetTypeName() or 'typeless prim'}, "
                         f"not a Mesh")
    return stage, prim


def _read_vegetation(stage: Any, to_map: FloatArray) -> tuple[
        dict[str, Instances], dict[str, PrototypeMesh], dict[str, tuple[float, float]]]:
    """Instances, prototype meshes and footprints of every PointInstancer under :data:`VEGETATION_ROOT`."""
    from pxr import Usd, UsdGeom

    vegetation: dict[str, Instances] = {}
    prototypes: dict[str, PrototypeMesh] = {}
    radius_at: dict[str, tuple[float, float]] = {}
    veg_root = stage.GetPrimAtPath(VEGETATION_ROOT)
    if veg_root and veg_root.IsValid():
        for p in Usd.PrimRange(veg_root):
            if not p.IsA(UsdGeom.PointInstancer):
                continue
            _read_instancer(p, to_map, vegetation, prototypes, radius_at)
    return vegetation, prototypes, radius_at


def _read_sky(get: Any) -> Sky:
    """The sky from the root's ``zebra_sim:sky_*`` customData, :class:`Sky`'s defaults where absent."""
    d = Sky()
    return Sky(
        _rgb(get("zebra_sim:sky_zenith_rgb", d.zenith_rgb)),
        _rgb(get("zebra_sim:sky_horizon_rgb", d.horizon_rgb)),
        float(get("zebra_sim:sky_haze_per_m", d.haze_per_m)),
        float(get("zebra_sim:sky_ambient", d.ambient)),
        float(get("zebra_sim:sky_sun", d.sun)),
    )


def _read_placeable(get: Any, terrain: Heightfield) -> tuple[float, float, float, float]:
    """The stored placeable rectangle, or the terrain kept a margin (30 m, at most a tenth of a side) inside."""
    x0, y0, x1, y1 = terrain.bounds
    margin = min(DEFAULT_MARGIN_M, 0.1 * min(x1 - x0, y1 - y0))
    placeable_cd = get("zebra_sim:placeable")
    placeable = (tuple(float(a) for a in placeable_cd) if placeable_cd is not None
                 else (x0 + margin, y0 + margin, x1 - margin, y1 - margin))
    return (placeable[0], placeable[1], placeable[2], placeable[3])


def read_world_usd(path: Path, terrain_prim: str = "/World/Terrain") -> World:
    """Read a world from a USD stage (see the module docstring); heights sampled on a 1 m grid.

    Raises :class:`WorldError` when the stage cannot be opened, ``terrain_prim`` is missing (listing up
    to 10 mesh prims the stage has) or is not a ``UsdGeom.Mesh`` (naming its type).
    """
    _pxr()
    path = Path(path)
    stage, prim = _open_terrain(path, terrain_prim)
    to_map = _stage_to_map(stage)
    verts, tri, rgb = _mesh_arrays(prim, to_map)
    try:
        terrain = Heightfield.from_mesh(verts, tri, 1.0)
    except TerrainError as exc:
        raise WorldError(f"terrain prim {terrain_prim} in {path}: {exc}") from exc
    ground = _grid_colors(terrain, verts, rgb) if rgb is not None else None
    vegetation, prototypes, radius_at = _read_vegetation(stage, to_map)

    root = stage.GetDefaultPrim() or stage.GetPrimAtPath("/World")
    get = (lambda k, d=None: _custom(root, k, d)) if root and root.IsValid() else (lambda k, d=None: d)
    preset = get("zebra_sim:preset")
    seed = get("zebra_sim:seed")
    return World(
        name=str(get("zebra_sim:name", path.stem)),
        source=str(path),
        seed=int(seed) if seed is not None else None,
        terrain=terrain,
        placeable=_read_placeable(get, terrain),
        max_slope_deg=float(get("zebra_sim:max_slope_deg", DEFAULT_MAX_SLOPE_DEG)),
        obstacles=build_obstacles(vegetation, radius_at),
        vegetation=vegetation,
        prototypes=prototypes,
        materials=PRESETS[preset].materials if preset in PRESETS else (),
        sky=_read_sky(get),
        description=PRESETS[preset].description if preset in PRESETS else f"USD stage {path.name}",
        footprints=radius_at,
        ground_rgb=ground,
    )


def _instance_frames(pi_prim: Any, to_map: FloatArray) -> tuple[
        NDArray[np.int64], FloatArray, FloatArray, FloatArray, float] | None:
    """A PointInstancer's prototype index, map position (M, 3) m, yaw (M,) rad and scale (M,) per instance, and the
    stage's metres per unit; None when it has no instances or no prototypes."""
    from pxr import UsdGeom

    pi = UsdGeom.PointInstancer(pi_prim)
    pos = np.asarray(pi.GetPositionsAttr().Get() or [], dtype=np.float64).reshape(-1, 3)
    if len(pos) == 0 or not pi.GetPrototypesRel().GetTargets():
        return None
    ids = np.asarray(pi.GetProtoIndicesAttr().Get() or np.zeros(len(pos), dtype=np.int32), dtype=np.int64)
    ori = pi.GetOrientationsAttr().Get()
    q = np.asarray(ori, dtype=np.float64).reshape(-1, 4) if ori else np.tile([0.0, 0, 0, 1], (len(pos), 1))
    sc = pi.GetScalesAttr().Get()
    s = np.asarray(sc, dtype=np.float64).reshape(-1, 3) if sc else np.ones((len(pos), 3))
    xf = _world_xf(pi_prim) @ to_map
    lin = xf[:3, :3]
    unit = abs(float(np.linalg.det(lin))) ** (1 / 3)  # stage units -> metres, times any instancer scale
    mpu = float(np.linalg.norm(to_map[0, :3]))
    world_pos = _apply(pos, xf)
    # heading: the instance's +x axis, rotated, taken to the map frame (row vectors: v @ R^T for quats)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    ax = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], 1)
    ax_map = (ax @ lin) / unit
    yaw = np.arctan2(ax_map[:, 1], ax_map[:, 0])
    scale = s.mean(axis=1) * (unit / mpu)  # prototypes are read in metres, so only the instancer's own scale
    return ids, world_pos, yaw, scale, mpu


def _prototype_mesh(proto: Any, to_map: FloatArray) -> PrototypeMesh | None:
    """Every Mesh under a prototype prim as one mesh in its own frame (z up, metres); None when it has none."""
    from pxr import Usd, UsdGeom

    root_xf = _world_xf(proto)
    vs, fs, cs = [], [], []
    n = 0
    for mp in Usd.PrimRange(proto):
        if not mp.IsA(UsdGeom.Mesh):
            continue
        v, f, c = _mesh_arrays(mp, np.eye(4), relative_to=root_xf)
        v = v @ to_map[:3, :3]  # prototype frame, z up, metres
        vs.append(v)
        fs.append(f + n)
        cs.append(c if c is not None else np.full((len(v), 3), 0.5))
        n += len(v)
    if not vs:
        return None
    return (np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int32),
            np.clip(np.concatenate(cs), 0, 1).astype(np.float32))


def _read_instancer(pi_prim: Any, to_map: FloatArray, vegetation: dict[str, Instances],
                    prototypes: dict[str, PrototypeMesh], radius_at: dict[str, tuple[float, float]]) -> None:
    """Add one PointInstancer's instances (grouped by prototype prim name) and prototype meshes."""
    from pxr import UsdGeom

    frames = _instance_frames(pi_prim, to_map)
    if frames is None:
        return
    ids, world_pos, yaw, scale, mpu = frames
    for k, target in enumerate(UsdGeom.PointInstancer(pi_prim).GetPrototypesRel().GetTargets()):
        sel = ids == k
        if not sel.any():
            continue
        proto = pi_prim.GetStage().GetPrimAtPath(target)
        if not proto or not proto.IsValid():
            continue
        name = proto.GetName()
        kind = str(_custom(proto, "zebra_sim:kind", _guess_kind(name)))
        if name not in prototypes:
            mesh = _prototype_mesh(proto, to_map)
            if mesh is None:
                continue
            prototypes[name] = mesh
            r1 = proto.GetCustomDataByKey("zebra_sim:footprint_radius")
            if r1 is not None and kind in OBSTACLE_KINDS:
                radius_at[name] = (float(r1) * mpu, float(_custom(proto, "zebra_sim:clearance", 0.0)))
        new = Instances(name, world_pos[sel], yaw[sel], scale[sel], kind)
        if name in vegetation:
            old = vegetation[name]
            new = Instances(name, np.concatenate([old.positions, new.positions]), np.concatenate([old.yaw, new.yaw]),
                            np.concatenate([old.scale, new.scale]), kind)
        vegetation[name] = new
