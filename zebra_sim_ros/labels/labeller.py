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

A camera with a lens (:class:`~zebra_sim_ros.geometry.camera.PinholeCamera`'s ``distortion``, from CameraInfo's
``d``) is labelled through it: full boxes and keypoints are projected through the lens, silhouettes are counted in
the image's pixels (:mod:`~zebra_sim_ros.labels.silhouettes`), and the labels carry its coefficients as ``D``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical
from zebra_sim_ros.geometry.frames import matrix_to_xyzw, optical_frame, xyzw_to_matrix
from zebra_sim_ros.labels.config import LabelFilters
from zebra_sim_ros.labels.silhouettes import SilhouetteCounter
from zebra_sim_ros.messages import LabelledZebra, Labels, OrientedBox, Scene
from zebra_sim_ros.rendering.renderer import ZebraSet
from zebra_sim_ros.rendering.views import views_from_scene, zebras_from_scene
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.keypoints import KEYPOINT_NAMES
from zebra_sim_ros.zebra.lod import DETAIL_DISTANCE_M, lod_of


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


@dataclass(frozen=True)
class _Present:
    """The scene zebras a frame shows: their indices into the scene, the arrays, the camera pose."""

    sel: NDArray[np.int64]
    zebras: ZebraSet
    pos: NDArray[np.float64]
    r_opt: NDArray[np.float64]


def amodal_boxes(present: _Present, camera: PinholeCamera, library: ZebraLibrary,
                 detail_distance_m: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per present zebra: the full box clipped and unclipped (of the level of detail the camera drew: full detail
    nearer than ``detail_distance_m``) and its distance from the camera, m."""
    z, sel = present.zebras, present.sel
    dist_cam = np.linalg.norm(z.position[sel] - present.pos, axis=1)
    lod = lod_of(dist_cam, detail_distance_m)
    full_c = np.zeros((len(sel), 4))
    full_u = np.zeros((len(sel), 4))
    for level in (0, 1):
        pick = np.flatnonzero(lod == level)
        if len(pick):
            s = sel[pick]
            posed = library.pose(z.morph[s], z.global_frame[s], z.scale[s], z.rotation[s], z.position[s], lod=level)
            p_opt = map_to_optical(posed.vertices.astype(np.float64), present.pos, present.r_opt)
            full_c[pick], full_u[pick] = full_boxes(p_opt, camera)
    return full_c, full_u, dist_cam


def keypoint_visibility(present: _Present, camera: PinholeCamera, library: ZebraLibrary,
                        depth: NDArray[np.float32], tolerance_m: float) -> tuple[NDArray[np.float64],
                                                                                NDArray[np.int64]]:
    """Keypoints (N, K, 2) in pixel edges and their COCO visibility (N, K): 2 in the image and not occluded (the
    depth image is not nearer than the keypoint by more than ``tolerance_m`` times the zebra's scale), 1 in the
    image but occluded, 0 outside."""
    z, sel = present.zebras, present.sel
    posed0 = library.pose(z.morph[sel], z.global_frame[sel], z.scale[sel], z.rotation[sel], z.position[sel], lod=0)
    kp_opt = map_to_optical(posed0.keypoints, present.pos, present.r_opt)  # (N, K, 3)
    kp_uv, kp_front = project_edges(kp_opt, camera)
    h, w = depth.shape
    inside = kp_front & (kp_uv[..., 0] >= 0) & (kp_uv[..., 0] < w) & (kp_uv[..., 1] >= 0) & (kp_uv[..., 1] < h)
    col = np.clip(np.floor(kp_uv[..., 0]).astype(np.int64), 0, w - 1)
    row = np.clip(np.floor(kp_uv[..., 1]).astype(np.int64), 0, h - 1)
    seen_depth = depth[row, col].astype(np.float64)
    unoccluded = seen_depth >= kp_opt[..., 2] - tolerance_m * z.scale[sel][:, None]
    return kp_uv, np.where(inside, np.where(unoccluded, 2, 1), 0)


OTHER_SPECIES_REASON = "other_species"
"""The drop reason of an animal of another species: labelled with its species, never as a zebra."""


def drop_reason(visible_px: int, silhouette_px: int, box: NDArray[np.float64], filters: LabelFilters) -> str | None:
    """Which label filter drops a zebra (None: kept)."""
    bw, bh = box[2] - box[0], box[3] - box[1]
    if visible_px < filters.min_visible_pixels:
        return "min_visible_pixels"
    if silhouette_px and visible_px / silhouette_px < filters.min_visible_fraction:
        return "min_visible_fraction"
    if min(bw, bh) < filters.min_box_px:
        return "min_box_px"
    if max(bw, bh) / max(min(bw, bh), 1e-9) > filters.max_aspect_ratio:
        return "max_aspect_ratio"
    return None


def camera_box(box: OrientedBox, pos: NDArray[np.float64], r_opt: NDArray[np.float64]) -> OrientedBox:
    """A box in ``map`` expressed in a camera's optical frame (centre rounded to 0.1 mm)."""
    c = (np.array(box.center) - pos) @ r_opt
    return OrientedBox((round(float(c[0]), 4), round(float(c[1]), 4), round(float(c[2]), 4)), box.size,
                       matrix_to_xyzw(r_opt.T @ xyzw_to_matrix(box.orientation_xyzw)))


def _present(scene: Scene, camera_name: str, mask: NDArray[np.integer],
             library: ZebraLibrary) -> tuple[_Present, list[int]]:
    view = views_from_scene(scene, [camera_name])
    if not view:
        raise KeyError(f"scene {scene.step} has no camera {camera_name}")
    zebras = zebras_from_scene(scene, library)
    present = np.unique(mask)
    present = present[present > 0]
    index_of = {int(z) + 1: i for i, z in enumerate(zebras.ids)}
    sel = np.array([index_of[int(p)] for p in present if int(p) in index_of], dtype=np.int64)
    unknown = [int(p) for p in present if int(p) not in index_of]
    return _Present(sel, zebras, view[0].position, view[0].r_optical), unknown


def label_view(scene: Scene, camera_name: str, mask: NDArray[np.integer], depth: NDArray[np.float32],
               camera: PinholeCamera, library: ZebraLibrary, silhouettes: SilhouetteCounter,
               filters: LabelFilters | None = None, detail_distance_m: float = DETAIL_DISTANCE_M) -> Labels:
    """The labels of one camera frame (module docstring): every zebra with a pixel in ``mask``."""
    filters = filters or LabelFilters()
    p, unknown = _present(scene, camera_name, mask, library)
    labels: list[LabelledZebra] = []
    if len(p.sel):
        tight, counts = tight_boxes(mask, p.zebras.ids[p.sel] + 1)
        cover = silhouettes.count(p.zebras, p.pos, p.r_opt, p.sel)
        full_c, full_u, dist_cam = amodal_boxes(p, camera, library, detail_distance_m)
        kp_uv, vis = keypoint_visibility(p, camera, library, depth, filters.keypoint_depth_tolerance_m)
        for k, i in enumerate(p.sel):
            z = scene.zebras[int(i)]
            vis_px, sil, total = int(counts[k]), int(cover.in_image[k]), int(cover.total[k])
            reason = drop_reason(vis_px, sil, tight[k], filters) if z.is_zebra else OTHER_SPECIES_REASON
            labels.append(LabelledZebra(
                z.id, z.id + 1, z.morph, z.clip, z.frame, z.scale, round(float(dist_cam[k]), 3),
                _box(tight[k]), _box(full_c[k], 2), _box(full_u[k], 2), vis_px, sil,
                round(min(1.0, vis_px / sil), 4) if sil else 0.0, round(sil / total, 4) if total else 0.0,
                z.box, camera_box(z.box, p.pos, p.r_opt),
                tuple((round(float(kp_uv[k, j, 0]), 2), round(float(kp_uv[k, j, 1]), 2), int(vis[k, j]))
                      for j in range(len(KEYPOINT_NAMES))), reason is None, reason, species=z.species))
    return Labels(scene.stamp, scene.step, scene.seed, camera_name, optical_frame(camera_name),
                  int(camera.width), int(camera.height), tuple(float(v) for v in camera.K.ravel()),
                  tuple(KEYPOINT_NAMES), filters.to_dict(), tuple(labels), tuple(unknown), camera.D)


def _box(b: NDArray[np.float64], digits: int | None = None) -> tuple[float, float, float, float]:
    v = [float(x) if digits is None else round(float(x), digits) for x in b]
    return v[0], v[1], v[2], v[3]


class Labeller:
    """Labels frames of one camera model: the silhouette counter (a GL context) and the label filters, kept
    between frames. What the labeller node runs per camera size, and :class:`~zebra_sim_ros.simulation.Simulator`
    after each render."""

    def __init__(self, library: ZebraLibrary, camera: PinholeCamera, filters: LabelFilters | None = None,
                 detail_distance_m: float = DETAIL_DISTANCE_M, ctx: Any = None) -> None:
        self.library, self.camera = library, camera
        self.filters = filters or LabelFilters()
        self.detail_distance_m = detail_distance_m
        self.silhouettes = SilhouetteCounter(library, camera, detail_distance_m, ctx=ctx)

    def label(self, scene: Scene, camera_name: str, mask: NDArray[np.integer], depth: NDArray[np.float32]) -> Labels:
        """:func:`label_view` of one frame."""
        return label_view(scene, camera_name, mask, depth, self.camera, self.library, self.silhouettes, self.filters,
                          self.detail_distance_m)

    def release(self) -> None:
        """Release the GL resources."""
        self.silhouettes.release()
