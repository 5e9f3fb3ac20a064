"""The labeller core: exact ground truth of one camera frame.

For every zebra with at least one pixel in the instance mask:

- ``box_visible``: tight box of its visible mask pixels;
- ``box_full``: amodal box of its projected posed, skinned mesh (the level of detail the camera drew), clipped
  to the image (``box_full_unclipped`` as well);
- ``visible_pixels``, ``silhouette_pixels`` (what it would cover unoccluded, inside the image),
  ``visible_fraction`` = visible / silhouette, ``in_frame_fraction`` = silhouette inside / whole silhouette;
- the 3D oriented box of the posed mesh in ``map`` and in the camera's optical frame;
- every keypoint in pixels with COCO visibility: 2 = in the image and not occluded (depth test against the
  depth image with a tolerance of ``keypoint_depth_tolerance_m`` times the zebra's scale, since keypoints such
  as joints lie inside the body), 1 = in the image but occluded, 0 = outside the image;
- scene id, morph, clip, frame, scale and distance from the camera to the box centre.

Boxes are ``[x_min, y_min, x_max, y_max]`` in pixel-edge coordinates: the top-left corner of the image is
(0, 0) and a pixel (col, row) spans [col, col + 1] x [row, row + 1] (COCO's convention); keypoint pixel
coordinates are the same edge coordinates. Instance ids in the mask are scene id + 1.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical
from zebra_sim_ros.geometry.rotations import matrix_to_quat, quat_to_matrix
from zebra_sim_ros.labels.config import LabelFilters
from zebra_sim_ros.labels.silhouettes import SilhouetteCounter
from zebra_sim_ros.rendering.views import views_from_scene, zebras_from_scene
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_NAMES

SCHEMA = "zebra_sim_ros/labels"
VERSION = 1


def tight_boxes(mask: NDArray[np.integer], ids: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Tight boxes (N, 4) xyxy (pixel edges) and pixel counts of the instances ``ids`` in ``mask``.

    An id with no pixel gets a box of NaNs and a count of 0.
    """
    ids = np.asarray(ids, dtype=np.int64)
    boxes = np.full((len(ids), 4), np.nan)
    counts = np.zeros(len(ids), dtype=np.int64)
    rows, cols = np.nonzero(mask)
    if len(rows) == 0 or len(ids) == 0:
        return boxes, counts
    vals = mask[rows, cols].astype(np.int64)
    order = np.argsort(vals, kind="stable")
    vals, rows, cols = vals[order], rows[order], cols[order]
    uniq, start, cnt = np.unique(vals, return_index=True, return_counts=True)
    pos = {int(u): k for k, u in enumerate(uniq)}
    for i, idv in enumerate(ids):
        k = pos.get(int(idv))
        if k is None:
            continue
        r = rows[start[k]:start[k] + cnt[k]]
        c = cols[start[k]:start[k] + cnt[k]]
        boxes[i] = (c.min(), r.min(), c.max() + 1, r.max() + 1)
        counts[i] = cnt[k]
    return boxes, counts


def project_edges(points_optical: NDArray[np.float64], camera: PinholeCamera) -> tuple[NDArray[np.float64],
                                                                                        NDArray[np.bool_]]:
    """Pixel-edge coordinates (..., 2) of optical-frame points and whether each is in front of the camera."""
    uv, front = camera.project(points_optical)
    return uv + 0.5, front


def full_boxes(points_optical: NDArray[np.float64], camera: PinholeCamera) -> tuple[NDArray[np.float64],
                                                                                     NDArray[np.float64]]:
    """Amodal boxes of point sets (N, P, 3) in the optical frame: (clipped to the image, unclipped), xyxy edges.

    Points behind the camera are ignored (their zebra is then only partly in front of it).
    """
    uv, front = project_edges(points_optical, camera)
    u = np.where(front, uv[..., 0], np.nan)
    v = np.where(front, uv[..., 1], np.nan)
    with warnings.catch_warnings():  # an all-behind row gives NaN, which is what it should give
        warnings.simplefilter("ignore", RuntimeWarning)
        raw = np.stack([np.nanmin(u, 1), np.nanmin(v, 1), np.nanmax(u, 1), np.nanmax(v, 1)], axis=1)
    clipped = raw.copy()
    clipped[:, [0, 2]] = np.clip(raw[:, [0, 2]], 0, camera.width)
    clipped[:, [1, 3]] = np.clip(raw[:, [1, 3]], 0, camera.height)
    return clipped, raw


def label_view(scene: dict[str, Any], camera_name: str, mask: NDArray[np.integer], depth: NDArray[np.float32],
               camera: PinholeCamera, library: ZebraLibrary, silhouettes: SilhouetteCounter,
               filters: LabelFilters | None = None, detail_distance_m: float = 35.0) -> dict[str, Any]:
    """The labels of one camera frame as the versioned JSON-ready dictionary (module docstring)."""
    filters = filters or LabelFilters()
    view = views_from_scene(scene, [camera_name])
    if not view:
        raise KeyError(f"scene {scene.get('step')} has no camera {camera_name}")
    pos, r_opt = view[0].position, view[0].r_optical
    zebras = zebras_from_scene(scene, library)
    present = np.unique(mask)
    present = present[present > 0]
    index_of = {int(z) + 1: i for i, z in enumerate(zebras.ids)}
    sel = np.array([index_of[int(p)] for p in present if int(p) in index_of], dtype=np.int64)
    unknown = [int(p) for p in present if int(p) not in index_of]
    labels: list[dict[str, Any]] = []
    if len(sel):
        tight, counts = tight_boxes(mask, zebras.ids[sel] + 1)
        cover = silhouettes.count(zebras, pos, r_opt, sel)
        dist_cam = np.linalg.norm(zebras.position[sel] - pos, axis=1)
        lod = np.where(dist_cam < detail_distance_m, 0, 1)
        scene_z = [scene["zebras"][int(i)] for i in sel]
        full_c = np.zeros((len(sel), 4))
        full_u = np.zeros((len(sel), 4))
        for level in (0, 1):
            pick = np.flatnonzero(lod == level)
            if len(pick):
                s = sel[pick]
                posed = library.pose(zebras.morph[s], zebras.global_frame[s], zebras.scale[s], zebras.rotation[s],
                                     zebras.position[s], lod=level)
                p_opt = map_to_optical(posed.vertices.astype(np.float64), pos, r_opt)
                full_c[pick], full_u[pick] = full_boxes(p_opt, camera)
        posed0 = library.pose(zebras.morph[sel], zebras.global_frame[sel], zebras.scale[sel], zebras.rotation[sel],
                              zebras.position[sel], lod=0)
        kp_opt = map_to_optical(posed0.keypoints, pos, r_opt)  # (N, K, 3)
        kp_uv, kp_front = project_edges(kp_opt, camera)
        h, w = mask.shape
        inside = kp_front & (kp_uv[..., 0] >= 0) & (kp_uv[..., 0] < w) & (kp_uv[..., 1] >= 0) & (kp_uv[..., 1] < h)
        col = np.clip(np.floor(kp_uv[..., 0]).astype(np.int64), 0, w - 1)
        row = np.clip(np.floor(kp_uv[..., 1]).astype(np.int64), 0, h - 1)
        seen_depth = depth[row, col].astype(np.float64)
        tol = filters.keypoint_depth_tolerance_m * zebras.scale[sel][:, None]
        unoccluded = seen_depth >= kp_opt[..., 2] - tol
        vis = np.where(inside, np.where(unoccluded, 2, 1), 0)
        for k, i in enumerate(sel):
            z = scene_z[k]
            b = z["box"]
            r_box = quat_to_matrix(np.array([b["orientation_xyzw"][3], *b["orientation_xyzw"][:3]]))
            c_cam = (np.array(b["center"]) - pos) @ r_opt
            q_cam = matrix_to_quat(r_opt.T @ r_box)
            vis_px, sil = int(counts[k]), int(cover.in_image[k])
            tb = tight[k]
            bw, bh = tb[2] - tb[0], tb[3] - tb[1]
            reason = None
            if vis_px < filters.min_visible_pixels:
                reason = "min_visible_pixels"
            elif sil and vis_px / sil < filters.min_visible_fraction:
                reason = "min_visible_fraction"
            elif min(bw, bh) < filters.min_box_px:
                reason = "min_box_px"
            elif max(bw, bh) / max(min(bw, bh), 1e-9) > filters.max_aspect_ratio:
                reason = "max_aspect_ratio"
            kps = [[round(float(kp_uv[k, j, 0]), 2), round(float(kp_uv[k, j, 1]), 2), int(vis[k, j])]
                   for j in range(len(KEYPOINT_NAMES))]
            labels.append({
                "id": int(zebras.ids[i]), "instance": int(zebras.ids[i]) + 1, "morph": z["morph"], "clip": z["clip"],
                "frame": int(z["frame"]), "scale": float(z["scale"]), "distance_m": round(float(dist_cam[k]), 3),
                "box_visible": [float(v) for v in tb], "box_full": [round(float(v), 2) for v in full_c[k]],
                "box_full_unclipped": [round(float(v), 2) for v in full_u[k]],
                "visible_pixels": vis_px, "silhouette_pixels": sil,
                "visible_fraction": round(min(1.0, vis_px / sil), 4) if sil else 0.0,
                "in_frame_fraction": round(sil / int(cover.total[k]), 4) if cover.total[k] else 0.0,
                "box3d_map": b,
                "box3d_camera": {"center": [round(float(v), 4) for v in c_cam], "size": b["size"],
                                 "orientation_xyzw": [float(q_cam[1]), float(q_cam[2]), float(q_cam[3]),
                                                      float(q_cam[0])]},
                "keypoints": kps, "kept": reason is None, "drop_reason": reason,
            })
    return {
        "schema": SCHEMA, "version": VERSION, "stamp": scene["stamp"], "step": scene["step"], "seed": scene["seed"],
        "camera": camera_name, "frame_id": f"{camera_name}_camera_optical", "width": int(camera.width),
        "height": int(camera.height), "K": [float(v) for v in camera.K.ravel()],
        "keypoint_names": list(KEYPOINT_NAMES), "filters": filters.to_dict(),
        "zebras": labels, "in_view": len(labels), "kept": sum(1 for x in labels if x["kept"]),
        "unknown_instances": unknown,
    }
