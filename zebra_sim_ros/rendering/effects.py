"""Optional camera effects on the RGB image only (never on depth or the instance mask).

Applied in this order, as a real camera chain would: optics blur, sensor noise, JPEG compression.
Every draw comes from the generator passed in, so effects are as reproducible as everything else.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError


@dataclass(frozen=True)
class CameraEffects:
    """``blur_sigma_px``: Gaussian blur (0 = off); ``noise_std``: Gaussian noise in 8-bit levels (0 = off);
    ``jpeg_quality``: 1..100 re-encodes as JPEG (0 = off)."""

    blur_sigma_px: float = 0.0
    noise_std: float = 0.0
    jpeg_quality: int = 0

    def __post_init__(self) -> None:
        if not 0.0 <= self.blur_sigma_px <= 20.0:
            raise ParameterError("blur_sigma_px", self.blur_sigma_px, "0..20 pixels")
        if not 0.0 <= self.noise_std <= 64.0:
            raise ParameterError("noise_std", self.noise_std, "0..64 levels")
        if not 0 <= self.jpeg_quality <= 100:
            raise ParameterError("jpeg_quality", self.jpeg_quality, "0 (off) or 1..100")

    @property
    def active(self) -> bool:
        """Whether any effect is on."""
        return self.blur_sigma_px > 0 or self.noise_std > 0 or self.jpeg_quality > 0

    def apply(self, rgb: NDArray[np.uint8], rng: np.random.Generator) -> NDArray[np.uint8]:
        """The RGB image with the effects applied (a new array)."""
        out: NDArray[np.uint8] = rgb
        if self.blur_sigma_px > 0:
            out = np.asarray(cv2.GaussianBlur(out, (0, 0), self.blur_sigma_px), dtype=np.uint8)
        if self.noise_std > 0:
            noisy = out.astype(np.float32) + rng.normal(0.0, self.noise_std, out.shape).astype(np.float32)
            out = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        if self.jpeg_quality > 0:
            ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(self.jpeg_quality)])
            if not ok:  # pragma: no cover - OpenCV always encodes uint8 RGB
                raise ParameterError("jpeg_quality", self.jpeg_quality, "a quality OpenCV can encode")
            decoded = cv2.imdecode(buf, cv2.IMREAD_COLOR)
            if decoded is None:  # pragma: no cover
                raise ParameterError("jpeg_quality", self.jpeg_quality, "a quality OpenCV can decode")
            out = np.asarray(decoded[..., ::-1], dtype=np.uint8)
        return np.ascontiguousarray(out, dtype=np.uint8)
