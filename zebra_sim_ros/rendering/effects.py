"""Camera effects on the RGB image only (never on depth or the instance mask): the simple fixed ones of the camera
node (:class:`CameraEffects`) and the photograph's camera drawn per frame (:class:`SensorModel`).

Applied in this order, as a real camera chain would: optics blur, sensor noise, JPEG compression.
Every draw comes from the generator passed in, so effects are as reproducible as everything else.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import SensorDraw


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


@dataclass(frozen=True)
class SensorModel:
    """A photograph's camera, drawn per frame (:meth:`draw`) and applied to the rendered sRGB image (:meth:`apply`).

    In the order a camera forms the image: exposure (EV about the renderer's metering), white balance (a
    colour-temperature and tint error), lens vignetting, lateral chromatic aberration, defocus and motion blur,
    Poisson-Gaussian sensor noise (shot noise grows with the signal, read noise does not), and JPEG. Ranges are
    uniform unless said; every draw comes from the generator handed in, and the draw is recorded
    (:class:`~zebra_sim_ros.messages.SensorDraw`) so a frame can be made again exactly. RGB only: depth and the
    instance mask stay exact. ``strength`` scales every range (0 = a perfect camera).
    """

    strength: float = 1.0
    exposure_ev: float = 0.5  # +- EV
    white_balance: float = 0.08  # +- relative red/blue gain error
    vignetting_max: float = 0.35  # brightness lost at the corners, up to
    chromatic_px_max: float = 1.0  # red/blue shift at the corners, px (at 1280 px wide; scales with width)
    defocus_px_max: float = 1.0  # Gaussian sigma, px (at 1280 px wide)
    motion_px_max: float = 3.0  # blur length, px (at 1280 px wide), in a random direction
    motion_probability: float = 0.3
    shot_noise_max: float = 0.002  # variance per unit signal (signal 0..1): std 0.03 at mid-grey at most
    read_noise_max: float = 0.006  # standard deviation (signal 0..1)
    jpeg_quality: tuple[int, int] = (55, 95)

    def __post_init__(self) -> None:
        if not 0.0 <= self.strength <= 3.0:
            raise ParameterError("sensor strength", self.strength, "0..3 (0 = a perfect camera)")
        lo, hi = self.jpeg_quality
        if not 1 <= lo <= hi <= 100:
            raise ParameterError("jpeg_quality", self.jpeg_quality, "(lo, hi) with 1 <= lo <= hi <= 100")

    def draw(self, rng: np.random.Generator) -> SensorDraw:
        """One frame's camera (a fixed number of draws, so later draws of ``rng`` do not depend on the values)."""
        s = self.strength
        u = rng.uniform(size=11)
        moving = u[7] < self.motion_probability
        temp = (u[1] * 2 - 1) * self.white_balance * s
        tint = (u[2] * 2 - 1) * self.white_balance * 0.5 * s
        q_lo, q_hi = self.jpeg_quality
        return SensorDraw(
            exposure_ev=float((u[0] * 2 - 1) * self.exposure_ev * s),
            wb_gain=(float(1 + temp), float(1 - tint), float(1 - temp)),
            vignetting=float(u[3] * self.vignetting_max * s),
            chromatic_px=float(u[4] * self.chromatic_px_max * s),
            defocus_px=float(u[5] * self.defocus_px_max * s),
            motion_px=float(u[6] * self.motion_px_max * s) if moving else 0.0,
            motion_angle_deg=float(u[8] * 180.0) if moving and s > 0 else 0.0,
            shot_noise=float(u[9] * self.shot_noise_max * s),
            read_noise=float(u[10] * self.read_noise_max * s),
            jpeg_quality=int(round(q_hi - (q_hi - q_lo) * min(s, 1.0) * rng.uniform())) if s > 0 else 0,
        )

    @staticmethod
    def apply(rgb: NDArray[np.uint8], d: SensorDraw, rng: np.random.Generator) -> NDArray[np.uint8]:
        """The image as the drawn camera would have taken it (a new array)."""
        h, w = rgb.shape[:2]
        k = w / 1280.0
        lin = _TO_LINEAR[rgb]
        lin *= np.float32(2.0 ** d.exposure_ev) * np.asarray(d.wb_gain, dtype=np.float32)
        xx, yy, r2 = _grid(h, w)
        if d.vignetting > 0:
            lin *= (1.0 - np.float32(d.vignetting) * r2 * np.sqrt(r2))[..., None]
        if d.chromatic_px > 0:
            lin = _chromatic(lin, d.chromatic_px * k, xx, yy)
        if d.defocus_px > 0.05:
            lin = np.asarray(cv2.GaussianBlur(lin, (0, 0), d.defocus_px * k), dtype=np.float32)
        if d.motion_px * k >= 1.0:
            lin = _motion_blur(lin, d.motion_px * k, d.motion_angle_deg)
        lin = np.clip(lin, 0.0, 1.0)
        if d.shot_noise > 0 or d.read_noise > 0:
            sd = np.sqrt(np.float32(d.shot_noise) * lin + np.float32(d.read_noise ** 2))
            lin += rng.standard_normal(lin.shape, dtype=np.float32) * sd
            np.clip(lin, 0.0, 1.0, out=lin)
        out = np.asarray(cv2.pow(lin, 1 / 2.2) * 255.0 + 0.5, dtype=np.float32).astype(np.uint8)
        if d.jpeg_quality > 0:
            out = CameraEffects(jpeg_quality=d.jpeg_quality).apply(out, rng)
        return np.ascontiguousarray(out)


_TO_LINEAR = ((np.arange(256, dtype=np.float64) / 255.0) ** 2.2).astype(np.float32)


@functools.lru_cache(maxsize=4)
def _grid(h: int, w: int) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """Pixel x, y and squared radius over the squared corner radius (0 at the centre, 1 at the corners)."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / np.float32((w / 2) ** 2 + (h / 2) ** 2)
    for a in (xx, yy, r2):
        a.setflags(write=False)
    return xx, yy, r2.astype(np.float32)


def _chromatic(lin: NDArray[np.float32], px: float, xx: NDArray[np.float32], yy: NDArray[np.float32]
               ) -> NDArray[np.float32]:
    """Lateral chromatic aberration: red magnified and blue shrunk about the centre, ``px`` at the corners."""
    h, w = lin.shape[:2]
    cx, cy = w / 2, h / 2
    corner = float(np.hypot(cx, cy))
    out = lin.copy()
    for ch, sign in ((0, 1.0), (2, -1.0)):
        f = 1.0 - sign * px / corner
        mx = (cx + (xx - cx) * f).astype(np.float32)
        my = (cy + (yy - cy) * f).astype(np.float32)
        out[..., ch] = cv2.remap(lin[..., ch], mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return out


def _motion_blur(lin: NDArray[np.float32], length_px: float, angle_deg: float) -> NDArray[np.float32]:
    """A straight line kernel of ``length_px`` at ``angle_deg``."""
    n = int(np.ceil(length_px)) | 1
    kernel = np.zeros((n, n), dtype=np.float32)
    c = n // 2
    a = np.radians(angle_deg)
    for t in np.linspace(-length_px / 2, length_px / 2, 4 * n):
        kernel[int(round(c + t * np.sin(a))), int(round(c + t * np.cos(a)))] += 1.0
    kernel /= kernel.sum()
    return np.asarray(cv2.filter2D(lin, -1, kernel, borderType=cv2.BORDER_REFLECT), dtype=np.float32)
