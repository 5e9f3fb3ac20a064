"""Drawing detections on images (for the annotated image topic and previews)."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray


def draw_boxes(rgb: NDArray[np.uint8], dets: NDArray[np.float32], colour: tuple[int, int, int] = (255, 60, 0),
               label: bool = True) -> NDArray[np.uint8]:
    """A copy of ``rgb`` with boxes (n, >=5: x0, y0, x1, y1, score, ...) drawn, scores written above them."""
    out = np.ascontiguousarray(rgb).copy()
    for d in dets:
        x0, y0, x1, y1 = (int(round(float(v))) for v in d[:4])
        cv2.rectangle(out, (x0, y0), (max(x1 - 1, x0), max(y1 - 1, y0)), colour, 1, cv2.LINE_AA)
        if label and len(d) > 4:
            cv2.putText(out, f"{float(d[4]):.2f}", (x0, max(y0 - 2, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1,
                        cv2.LINE_AA)
    return out
