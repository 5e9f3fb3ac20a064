"""The USD asset re-opens with usd-core, holds every clip, and UsdSkel poses it as we do."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel

from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_NAMES
from zebra_sim_ros.zebra.skeleton import JOINT_NAMES
from zebra_sim_ros.zebra.usd import write_usd


@pytest.fixture(scope="module")
def usd_path(library: ZebraLibrary, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_usd(library, "grevy", tmp_path_factory.mktemp("usd") / "zebra_grevy.usd", "./coat.png")


def test_stage_reopens_with_every_clip(usd_path: Path, library: ZebraLibrary) -> None:
    stage = Usd.Stage.Open(str(usd_path))
    assert stage is not None
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert root.IsA(UsdSkel.Root)
    variants = root.GetVariantSets().GetVariantSet("clip").GetVariantNames()
    assert sorted(variants) == sorted(library.clip_names)
    for c, name in enumerate(library.clip_names):
        anim = UsdSkel.Animation(stage.GetPrimAtPath(f"/Zebra/Animations/{name}"))
        assert anim, name
        assert len(anim.GetRotationsAttr().GetTimeSamples()) == library.clip_frames[c]
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/Zebra/Skeleton"))
    assert len(skel.GetJointsAttr().Get()) == len(JOINT_NAMES)
    assert list(skel.GetPrim().GetAttribute("zebra:keypointNames").Get()) == list(KEYPOINT_NAMES)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Zebra/Mesh_LOD0"))
    assert len(mesh.GetFaceVertexCountsAttr().Get()) == len(library.faces(0))


@pytest.mark.parametrize(("clip", "frame"), [("idle", 0), ("walk", 9), ("gallop", 11), ("rest", 60)])
def test_usdskel_skinning_matches_the_baked_vertices(usd_path: Path, library: ZebraLibrary, clip: str,
                                                     frame: int) -> None:
    stage = Usd.Stage.Open(str(usd_path))
    root = stage.GetDefaultPrim()
    root.GetVariantSets().GetVariantSet("clip").SetVariantSelection(clip)
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(root), Usd.PrimDefaultPredicate)
    skel_query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Zebra/Skeleton")))
    mesh_prim = stage.GetPrimAtPath("/Zebra/Mesh_LOD0")
    skinning = cache.GetSkinningQuery(mesh_prim)
    xforms = skel_query.ComputeSkinningTransforms(frame)
    points = UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get()
    assert skinning.ComputeSkinnedPoints(xforms, points, frame)
    ours = library.vertices(library.morphs.index("grevy"), library.frame_index(clip, frame))
    bind = library.bind_vertices(library.morphs.index("grevy"))
    assert np.abs(ours - bind).max() > 0.01  # the comparison means something: the pose is not the bind pose
    np.testing.assert_allclose(np.asarray(points), ours, atol=1e-4)
