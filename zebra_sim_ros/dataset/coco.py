"""COCO export: images, zebra annotations with boxes, keypoints (with skeleton), visibility and RLE masks.

Boxes are ``[x, y, w, h]`` in pixel-edge coordinates (COCO's). Segmentation is uncompressed RLE
(``{"counts": [...], "size": [h, w]}``, column-major runs starting with background), which pycocotools
reads. Extra per-annotation fields: ``zebra_id``, ``bbox_full`` (amodal, clipped), ``visible_fraction``,
``in_frame_fraction``, ``distance_m``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.messages import LabelledZebra, Labels
from zebra_sim_ros.zebra.keypoints import KEYPOINT_EDGES, KEYPOINT_NAMES
from zebra_sim_ros.zebra.skeleton import OTHER_SPECIES

CATEGORY = {
    "id": 1, "name": "zebra", "supercategory": "animal", "keypoints": list(KEYPOINT_NAMES),
    "skeleton": [[a + 1, b + 1] for a, b in KEYPOINT_EDGES],
}
SPECIES_CATEGORIES = [{"id": 2 + k, "name": name, "supercategory": "other_species", "keypoints": list(KEYPOINT_NAMES),
                       "skeleton": CATEGORY["skeleton"]} for k, name in enumerate(OTHER_SPECIES)]
"""The second category set: the other species, ids 2 and up (zebra stays 1, so a zebra-only reader filtering
on category 1 sees exactly the zebra labels)."""
SPECIES_CATEGORY_ID = {c["name"]: c["id"] for c in SPECIES_CATEGORIES}


def rle_encode(binary: NDArray[np.bool_]) -> dict[str, Any]:
    """Uncompressed COCO RLE of a binary mask (column-major, first run counts zeros)."""
    flat = np.asarray(binary, dtype=np.uint8).ravel(order="F")
    change = np.flatnonzero(np.diff(flat)) + 1
    bounds = np.concatenate([[0], change, [flat.size]])
    runs = np.diff(bounds).tolist()
    if flat.size and flat[0] == 1:
        runs = [0] + runs
    return {"counts": runs, "size": [int(binary.shape[0]), int(binary.shape[1])]}


def rle_encode_all(mask: NDArray[np.integer], ids: list[int]) -> dict[int, dict[str, Any]]:
    """Uncompressed COCO RLEs of ``mask == id`` for every id, in one pass over the mask.

    Equal to ``rle_encode(mask == id)`` for each id (a test checks it), without a full-image comparison per id.
    """
    h, w = mask.shape
    flat = np.asarray(mask).ravel(order="F")
    starts = np.concatenate([[0], np.flatnonzero(np.diff(flat)) + 1])
    ends = np.concatenate([starts[1:], [flat.size]])
    values = flat[starts]
    out = {}
    for i in ids:
        sel = np.flatnonzero(values == i)
        s, e = starts[sel], ends[sel]
        gaps = s - np.concatenate([[0], e[:-1]])
        runs = np.empty(2 * len(sel) + 1, dtype=np.int64)
        runs[0:-1:2] = gaps
        runs[1::2] = e - s
        runs[-1] = flat.size - (e[-1] if len(e) else 0)
        counts = runs.tolist()
        if counts and counts[-1] == 0:
            counts.pop()
        out[int(i)] = {"counts": counts, "size": [int(h), int(w)]}
    return out


def xyxy_to_xywh(box: Sequence[float]) -> list[float]:
    """[x0, y0, x1, y1] to COCO [x, y, w, h]."""
    return [box[0], box[1], box[2] - box[0], box[3] - box[1]]


def _rle(z: LabelledZebra) -> dict[str, Any]:
    if z.rle is None:
        raise ValueError(f"zebra {z.id} has no outline (rle): the dataset writer outlines kept and don't-care zebras")
    return z.rle.to_dict()


def zebra_annotation(z: LabelledZebra, image_id: int, ann_id: int) -> dict[str, Any]:
    """The COCO annotation of one kept, labelled zebra (its ``rle`` computed when the frame was written)."""
    return {
        "id": ann_id, "image_id": image_id, "category_id": 1, "iscrowd": 0,
        "bbox": xyxy_to_xywh(z.box_visible), "area": z.visible_pixels, "segmentation": _rle(z),
        "keypoints": [v for k in z.keypoints for v in (k[0], k[1], k[2])],
        "num_keypoints": sum(1 for k in z.keypoints if k[2] > 0),
        "zebra_id": z.id, "bbox_full": xyxy_to_xywh(z.box_full),
        "visible_fraction": z.visible_fraction, "in_frame_fraction": z.in_frame_fraction,
        "distance_m": z.distance_m,
    }


def species_annotation(z: LabelledZebra, image_id: int, ann_id: int) -> dict[str, Any]:
    """The COCO annotation of an animal of another species (its category from :data:`SPECIES_CATEGORIES`): the same
    fields as a zebra's, so the data can train a multi-species detector."""
    return {**zebra_annotation(z, image_id, ann_id), "category_id": SPECIES_CATEGORY_ID[z.species],
            "species": z.species}


def crowd_annotation(z: LabelledZebra, image_id: int, ann_id: int) -> dict[str, Any]:
    """The COCO annotation of a zebra seen but not labelled (:attr:`LabelledZebra.dont_care`): ``iscrowd`` 1, so
    COCO's evaluation ignores detections on it and trainers that honour ``iscrowd`` do not learn it as
    background."""
    return {"id": ann_id, "image_id": image_id, "category_id": 1, "iscrowd": 1,
            "bbox": xyxy_to_xywh(z.box_visible), "area": z.visible_pixels, "segmentation": _rle(z),
            "zebra_id": z.id, "drop_reason": z.drop_reason}


def yolo_lines(labels: Labels, box: str = "visible", dont_care: bool = False) -> list[str]:
    """YOLO detection lines (``0 cx cy w h``, normalised) of the kept zebras, or with ``dont_care`` of the
    zebras seen but not kept; ``box`` visible or full."""
    w, h = labels.width, labels.height
    lines = []
    for z in labels.dont_care if dont_care else labels.kept:
        x0, y0, x1, y1 = z.box_visible if box == "visible" else z.box_full
        lines.append(f"0 {(x0 + x1) / 2 / w:.6f} {(y0 + y1) / 2 / h:.6f} {(x1 - x0) / w:.6f} {(y1 - y0) / h:.6f}")
    return lines


def encode_frame(rgb: NDArray[np.uint8], image_format: str, jpeg_quality: int) -> bytes | None:
    """An RGB frame as a dataset's image file: ``jpg`` at ``jpeg_quality``, or ``png`` at OpenCV's default level
    (``generate`` and ``bag export`` write the same bytes for the same pixels); None where OpenCV cannot."""
    import cv2

    params = [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality] if image_format == "jpg" else []
    ok, buf = cv2.imencode(f".{image_format}", np.ascontiguousarray(rgb[..., ::-1]), params)
    return buf.tobytes() if ok else None


def write_dataset_yaml(out: Path, comment: str, val: str = "images/val") -> None:
    """A YOLO dataset's ``dataset.yaml`` in ``out``: its absolute path (quoted: a folder named "set #2" or "a: b"
    is still one YAML string), the train and ``val`` image folders, one class, zebra."""
    quoted = json.dumps(str(out.resolve()))
    (out / "dataset.yaml").write_text(f"# {comment}\npath: {quoted}\ntrain: images/train\nval: {val}\nnc: 1\n"
                                      "names:\n  0: zebra\n")
