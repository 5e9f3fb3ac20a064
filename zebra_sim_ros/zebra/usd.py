"""Write the zebra as a UsdSkel asset that opens in any USD tool.

Layout of ``zebra_<morph>.usd`` (z up, metres, 30 time codes per second):

- ``/Zebra`` (SkelRoot, default prim) with a variant set ``clip`` choosing the bound animation
- ``/Zebra/Skeleton`` the joints, bind and rest transforms; keypoint definitions as custom
  ``zebra:keypoint*`` attributes (vertex indices and weights into the full-detail mesh)
- ``/Zebra/Mesh_LOD0`` (purpose render) and ``/Zebra/Mesh_LOD1`` (purpose proxy), skinned with
  four influences per vertex, face-varying ``st`` UVs, bound to a UsdPreviewSurface coat
- ``/Zebra/Animations/<clip>`` one SkelAnimation per clip, time samples at frames 0..n-1

USD matrices use row vectors (``p' = p * M``), so our column-vector matrices are transposed here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import DependencyError
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_NAMES, keypoint_weights
from zebra_sim_ros.zebra.mesh import LODS, build_mesh
from zebra_sim_ros.zebra.skeleton import JOINT_NAMES, MORPHS, PARENTS, bind_positions

FloatArray = NDArray[np.float64]


def joint_paths() -> list[str]:
    """UsdSkel joint paths ("root/pelvis/spine_1", ...) in skeleton order."""
    paths: list[str] = []
    for j, name in enumerate(JOINT_NAMES):
        p = PARENTS[j]
        paths.append(name if p < 0 else f"{paths[p]}/{name}")
    return paths


def local_transforms(global_xf: FloatArray) -> FloatArray:
    """(..., J, 4, 4) parent-relative transforms from joint-to-asset transforms."""
    out = np.array(global_xf, dtype=np.float64, copy=True)
    for j in range(len(JOINT_NAMES)):
        if PARENTS[j] >= 0:
            out[..., j, :, :] = np.linalg.inv(global_xf[..., PARENTS[j], :, :]) @ global_xf[..., j, :, :]
    return out


def write_usd(lib: ZebraLibrary, morph: str, path: Path, coat_png: str | None = None) -> Path:
    """Write morph ``morph`` of ``lib`` with all its clips to ``path`` (.usd, .usda or .usdc)."""
    try:
        from pxr import Usd, UsdGeom, UsdSkel
    except ImportError as exc:  # pragma: no cover - usd-core is a declared dependency
        raise DependencyError("usd-core is needed to write USD: pip install usd-core") from exc

    m = lib.morphs.index(morph)
    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(float(lib.manifest["fps"]))  # type: ignore[arg-type]
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(int(lib.clip_frames.max()) - 1)
    root = UsdSkel.Root.Define(stage, "/Zebra")
    stage.SetDefaultPrim(root.GetPrim())
    root.GetPrim().SetCustomDataByKey("zebra_sim_ros:morph", morph)
    root.GetPrim().SetCustomDataByKey("zebra_sim_ros:asset_digest", str(lib.manifest["digest"]))

    skel = _define_skeleton(stage, morph)
    material = _coat_material(stage, coat_png) if coat_png else None
    for lod in LODS:
        _define_mesh(stage, morph, lod, skel, material)
    _define_animations(stage, lib, m)
    UsdSkel.BindingAPI.Apply(skel.GetPrim())
    _clip_variants(root.GetPrim(), skel.GetPrim(), lib.clip_names)
    stage.GetRootLayer().Save()
    return path


def _matrices(xf: FloatArray) -> Any:
    """(N, 4, 4) column-vector matrices as a USD (row-vector) matrix array."""
    from pxr import Gf, Vt

    return Vt.Matrix4dArray([Gf.Matrix4d(*x.T.ravel().tolist()) for x in xf])


def _define_skeleton(stage: Any, morph: str) -> Any:
    """``/Zebra/Skeleton``: joints, bind and rest transforms, and the keypoint definitions as custom attributes."""
    from pxr import Sdf, UsdSkel, Vt

    paths = joint_paths()
    bind_xf = np.tile(np.eye(4), (len(paths), 1, 1))
    bind_xf[:, :3, 3] = bind_positions(MORPHS[morph])
    skel = UsdSkel.Skeleton.Define(stage, "/Zebra/Skeleton")
    skel.CreateJointsAttr(paths)
    skel.CreateJointNamesAttr(list(JOINT_NAMES))
    skel.CreateBindTransformsAttr(_matrices(bind_xf))
    skel.CreateRestTransformsAttr(_matrices(local_transforms(bind_xf)))
    kp_idx, kp_w = keypoint_weights(build_mesh(MORPHS[morph], 0))
    sp = skel.GetPrim()
    sp.CreateAttribute("zebra:keypointNames", Sdf.ValueTypeNames.TokenArray).Set(list(KEYPOINT_NAMES))
    sp.CreateAttribute("zebra:keypointVertexIndices", Sdf.ValueTypeNames.IntArray).Set(
        Vt.IntArray(kp_idx.ravel().tolist()))
    sp.CreateAttribute("zebra:keypointVertexWeights", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray(kp_w.ravel().tolist()))
    sp.CreateAttribute("zebra:keypointElementSize", Sdf.ValueTypeNames.Int).Set(int(kp_idx.shape[1]))
    return skel


def _define_mesh(stage: Any, morph: str, lod: int, skel: Any, material: Any) -> None:
    """``/Zebra/Mesh_LOD<lod>`` (purpose render for LOD 0, proxy otherwise): skinned, face-varying ``st``."""
    from pxr import Gf, Sdf, UsdGeom, UsdShade, UsdSkel, Vt

    msh = build_mesh(MORPHS[morph], lod)
    geom = UsdGeom.Mesh.Define(stage, f"/Zebra/Mesh_LOD{lod}")
    geom.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(msh.vertices.astype(np.float32)))
    geom.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(msh.faces)))
    geom.CreateFaceVertexIndicesAttr(Vt.IntArray(msh.faces.ravel().tolist()))
    geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    geom.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    geom.CreatePurposeAttr(UsdGeom.Tokens.render if lod == 0 else UsdGeom.Tokens.proxy)
    lo, hi = msh.vertices.min(axis=0), msh.vertices.max(axis=0)
    geom.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
    st = UsdGeom.PrimvarsAPI(geom.GetPrim()).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st.Set(Vt.Vec2fArray.FromNumpy(msh.uv.reshape(-1, 2)))
    binding = UsdSkel.BindingAPI.Apply(geom.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(False, 4).Set(Vt.IntArray(msh.joint_indices.ravel().tolist()))
    binding.CreateJointWeightsPrimvar(False, 4).Set(
        Vt.FloatArray(msh.joint_weights.astype(np.float32).ravel().tolist()))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(geom.GetPrim()).Bind(material)


def _define_animations(stage: Any, lib: ZebraLibrary, m: int) -> None:
    """``/Zebra/Animations/<clip>``: one SkelAnimation per clip of morph index ``m``, a time sample per frame."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

    from zebra_sim_ros.geometry.rotations import matrix_to_quat

    paths = joint_paths()
    UsdGeom.Scope.Define(stage, "/Zebra/Animations")
    for c, name in enumerate(lib.clip_names):
        anim = UsdSkel.Animation.Define(stage, f"/Zebra/Animations/{name}")
        anim.CreateJointsAttr(paths)
        start, n = int(lib.clip_start[c]), int(lib.clip_frames[c])
        anim.GetPrim().SetCustomDataByKey("zebra_sim_ros:frames", n)
        anim.GetPrim().SetCustomDataByKey("zebra_sim_ros:loop", bool(lib.clip_loop[c]))
        xf = local_transforms(np.asarray(lib.joint_transforms(m, np.arange(start, start + n)), dtype=np.float64))
        quats = matrix_to_quat(xf[..., :3, :3])
        t_attr, r_attr, s_attr = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(), anim.CreateScalesAttr()
        s_attr.Set(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * len(paths)))
        for f in range(n):
            t_attr.Set(Vt.Vec3fArray.FromNumpy(xf[f, :, :3, 3].astype(np.float32)), Usd.TimeCode(f))
            r_attr.Set(Vt.QuatfArray([Gf.Quatf(*q.tolist()) for q in quats[f]]), Usd.TimeCode(f))


def _clip_variants(root: Any, skel: Any, clip_names: tuple[str, ...]) -> None:
    """The variant set ``clip`` on the root: each variant binds the skeleton to that clip; the first is selected."""
    from pxr import Sdf, UsdSkel

    vset = root.GetVariantSets().AddVariantSet("clip")
    for name in clip_names:
        vset.AddVariant(name)
        vset.SetVariantSelection(name)
        with vset.GetVariantEditContext():
            UsdSkel.BindingAPI(skel).CreateAnimationSourceRel().SetTargets([Sdf.Path(f"/Zebra/Animations/{name}")])
    vset.SetVariantSelection(clip_names[0])


def _coat_material(stage: object, coat_png: str) -> object:
    from pxr import Sdf, UsdShade

    mat = UsdShade.Material.Define(stage, "/Zebra/Looks/Coat")
    pbr = UsdShade.Shader.Define(stage, "/Zebra/Looks/Coat/PreviewSurface")
    pbr.CreateIdAttr("UsdPreviewSurface")
    pbr.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.85)
    pbr.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    reader = UsdShade.Shader.Define(stage, "/Zebra/Looks/Coat/stReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
    tex = UsdShade.Shader.Define(stage, "/Zebra/Looks/Coat/CoatTexture")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(coat_png)
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    pbr.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(pbr.ConnectableAPI(), "surface")
    return mat
