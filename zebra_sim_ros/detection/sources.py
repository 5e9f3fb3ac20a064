"""Frames to run the detector on, from a file, a folder or a video (``zebra-sim predict``): each with a name that
is unique within the source, a stamp where one is known (video: position in ns) and its RGB pixels.
Bags are read by :mod:`zebra_sim_ros.recording.images`, which yields the same :class:`Frame`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.detection.data import IMAGE_EXTS
from zebra_sim_ros.errors import ParameterError

VIDEO_EXTS = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")


@dataclass
class Frame:
    """One image to detect on: ``name`` (file-safe, unique in its source), ``stamp_ns`` (None if unknown),
    ``frame_id`` (the camera frame where known), RGB uint8 (H, W, 3)."""

    name: str
    rgb: NDArray[np.uint8]
    stamp_ns: int | None = None
    frame_id: str = ""


def source_kind(path: Path) -> str:
    """``image``, ``folder``, ``video`` or ``bag``; ParameterError naming ``SOURCE`` for anything else."""
    if path.is_dir():
        return "folder"
    if not path.is_file():
        raise ParameterError("SOURCE", str(path), "an image, a folder of images, a video or a .mcap bag that exists")
    suffix = path.suffix.lower()
    if suffix in IMAGE_EXTS:
        return "image"
    if suffix in VIDEO_EXTS:
        return "video"
    if suffix == ".mcap":
        return "bag"
    raise ParameterError("SOURCE", str(path), f"an image ({', '.join(IMAGE_EXTS)}), a video "
                         f"({', '.join(VIDEO_EXTS)}), a .mcap bag or a folder")


def image_frames(path: Path) -> Iterator[Frame]:
    """One image, or every image of a folder (recursively, sorted); an unreadable file stops with its name."""
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.suffix.lower() in IMAGE_EXTS)
    if not files:
        raise ParameterError("SOURCE", str(path), "a folder that holds images")
    for f in files:
        bgr = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if bgr is None:
            raise ParameterError("SOURCE", str(f), "a readable image")
        rel = f.relative_to(path).with_suffix("") if path.is_dir() else Path(f.stem)
        yield Frame("_".join(rel.parts), np.ascontiguousarray(bgr[..., ::-1]))


def video_frames(path: Path) -> tuple[Iterator[Frame], int, float]:
    """The frames of a video, the number OpenCV reports (0 if unknown) and its frame rate (0 if unknown)."""
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ParameterError("SOURCE", str(path), "a video OpenCV can open")
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)

    def frames() -> Iterator[Frame]:
        k = 0
        try:
            while True:
                ok, bgr = cap.read()
                if not ok:
                    return
                t = int(round(k * 1e9 / fps)) if fps > 0 else None
                yield Frame(f"{path.stem}_{k:06d}", np.ascontiguousarray(bgr[..., ::-1]), t)
                k += 1
        finally:
            cap.release()
    return frames(), count, fps


def yolo_lines(dets: NDArray[np.float32], width: int, height: int) -> list[str]:
    """YOLO label lines ``class cx cy w h`` (normalised) of detections (n, 6) [x0, y0, x1, y1, score, class]."""
    out = []
    for d in dets:
        x0, y0, x1, y1 = (float(v) for v in d[:4])
        out.append(f"{int(d[5])} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} "
                   f"{(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")
    return out
