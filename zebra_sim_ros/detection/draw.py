"""Drawing detections on images (for the annotated image topic and previews)."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

OTHER_COLOUR = (0, 170, 255)  # RGB: detections of a class other than zebra (class 0), e.g. other_animal


def draw_boxes(rgb: NDArray[np.uint8], dets: NDArray[np.floating[Any]], colour: tuple[int, int, int] = (255, 60, 0),
               label: bool = True) -> NDArray[np.uint8]:
    """A copy of ``rgb`` with boxes (n, >=5: x0, y0, x1, y1, score, [class]) drawn, scores written above them;
    a box of a class other than 0 (zebra) in :data:`OTHER_COLOUR`, its score marked with the class."""
    out = np.ascontiguousarray(rgb).copy()
    for d in dets:
        x0, y0, x1, y1 = (int(round(float(v))) for v in d[:4])
        other = len(d) > 5 and int(d[5]) != 0
        col = OTHER_COLOUR if other else colour
        cv2.rectangle(out, (x0, y0), (max(x1 - 1, x0), max(y1 - 1, y0)), col, 1, cv2.LINE_AA)
        if label and len(d) > 4:
            text = f"{float(d[4]):.2f}" + (f" c{int(d[5])}" if other else "")
            cv2.putText(out, text, (x0, max(y0 - 2, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.35, col, 1, cv2.LINE_AA)
    return out


def predictions_grid(items: list[tuple[NDArray[np.uint8], NDArray[np.float64], NDArray[np.float64]]],
                     tile: tuple[int, int] = (320, 180), columns: int = 4) -> NDArray[np.uint8]:
    """One RGB image of up to ``columns`` x n tiles: each image (RGB) with its ground truth (m, 4) in green and its
    detections (n, >=5) in red with their scores, scaled to ``tile`` (width, height) keeping the aspect."""
    tw, th = tile
    tiles = []
    for rgb, gt, dets in items:
        h, w = rgb.shape[:2]
        r = min(tw / w, th / h)
        out = draw_boxes(rgb, np.asarray(gt, np.float64).reshape(-1, 4), (40, 220, 40), label=False)
        out = draw_boxes(out, np.asarray(dets, np.float64).reshape(-1, 5), (255, 40, 0))
        small = cv2.resize(out, (max(1, round(w * r)), max(1, round(h * r))), interpolation=cv2.INTER_AREA)
        canvas = np.full((th, tw, 3), 30, np.uint8)
        canvas[: small.shape[0], : small.shape[1]] = small
        tiles.append(canvas)
    if not tiles:
        return np.full((th, tw, 3), 30, np.uint8)
    while len(tiles) % columns and len(tiles) > columns:
        tiles.append(np.full((th, tw, 3), 30, np.uint8))
    rows = [np.hstack(tiles[k:k + columns]) for k in range(0, len(tiles), columns)]
    return np.vstack(rows)
