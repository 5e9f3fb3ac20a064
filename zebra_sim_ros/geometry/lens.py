"""Lens distortion: the ``plumb_bob`` model of ``sensor_msgs/CameraInfo`` and OpenCV (k1, k2, p1, p2, k3).

A real drone camera's lens bends straight lines: a wide-angle one shows barrel distortion (k1 < 0), which grows
towards the image corners. The model maps a point's ideal normalised image coordinates (x, y) = (X / Z, Y / Z) in
the optical frame to distorted ones::

    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y

and the pixel is (fx xd + cx, fy yd + cy) with the camera's K. CameraInfo's ``d`` carries the five coefficients in
that order, and ``image_proc``'s rectification or ``cv2.undistortPoints`` undo them.

The renderer draws an ideal pinhole image on a :class:`LensCanvas` (the same focal length, larger where the lens
sees more) and resamples it through the canvas's maps: RGB bilinearly, depth and instance ids at the nearest canvas
pixel, so a distorted mask and depth stay exact values of the scene. Pure numpy, no ROS.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.params import param

FloatArray = NDArray[np.float64]
PLUMB_BOB = "plumb_bob"
LENS_ERROR = "lens distortion"  # what a ParameterError of a lens that cannot be used names (lens_k1.., --lens)
_CANVAS_MAX = 3.0  # the ideal canvas at most this many times the image's width or height
_TAN_85 = float(np.tan(np.radians(85.0)))  # the canvas's half field of view at most 85 deg (a pinhole's limit)


@dataclass(frozen=True)
class Lens:
    """The declarations of the lens distortion parameters, made once: the camera node, ``generate`` and
    ``zebra-sim render`` declare them with ``same_as``. All zero (the default) is an ideal pinhole."""

    lens_k1: float = param(0.0, "lens distortion k1 (plumb_bob, as CameraInfo d[0] and OpenCV; negative: barrel, "
                           "a wide-angle drone camera's -0.05..-0.3; 0: no distortion)", lo=-1.0, hi=1.0)
    lens_k2: float = param(0.0, "lens distortion k2 (plumb_bob d[1], radial r^4)", lo=-1.0, hi=1.0)
    lens_p1: float = param(0.0, "lens distortion p1 (plumb_bob d[2], tangential)", lo=-0.05, hi=0.05)
    lens_p2: float = param(0.0, "lens distortion p2 (plumb_bob d[3], tangential)", lo=-0.05, hi=0.05)
    lens_k3: float = param(0.0, "lens distortion k3 (plumb_bob d[4], radial r^6)", lo=-1.0, hi=1.0)


@dataclass(frozen=True)
class Distortion:
    """Plumb-bob distortion coefficients; all zero is none."""

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def __post_init__(self) -> None:
        if not all(np.isfinite(self.coefficients)):
            raise ParameterError("distortion", list(self.coefficients), "finite k1, k2, p1, p2, k3")

    @classmethod
    def from_d(cls, d: ArrayLike, model: str = PLUMB_BOB) -> Distortion:
        """From CameraInfo's ``distortion_model`` and ``d``: plumb_bob with 5 coefficients, or no coefficients (or all
        zero) of any model; ValueError naming the values otherwise (a model this package does not undo)."""
        values = [float(v) for v in np.asarray(d, dtype=np.float64).ravel()]
        if not any(values):
            return cls()
        if model != PLUMB_BOB or len(values) != 5:
            raise ValueError(f"distortion model {model!r} with d = {values}: want plumb_bob with 5 coefficients "
                             "(k1, k2, p1, p2, k3), or none")
        return cls(*values)  # ParameterError (a ValueError) for one that is not finite

    @property
    def coefficients(self) -> tuple[float, float, float, float, float]:
        """(k1, k2, p1, p2, k3): CameraInfo's ``d``."""
        return self.k1, self.k2, self.p1, self.p2, self.k3

    @property
    def none(self) -> bool:
        """Whether this is no distortion at all."""
        return not any(self.coefficients)

    def apply(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Distorted normalised coordinates of ideal ones (the model above)."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        if self.none:
            return x, y
        r2 = x * x + y * y
        radial = self._radial(r2)
        xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return xd, yd

    def remove(self, xd: ArrayLike, yd: ArrayLike, iterations: int = 50) -> tuple[FloatArray, FloatArray]:
        """Ideal normalised coordinates of distorted ones: Newton's method on :meth:`apply` from the distorted point
        (OpenCV's ``undistortPoints`` iterates a fixed point instead; both converge where the lens does not fold).
        NaN where the lens cannot be undone: no solution within 1e-9 (a millionth of a pixel at a focal length of
        1000 px), or one past the radial map's first turn (:meth:`on_first_branch`: a solution of the polynomial,
        not a ray)."""
        xd, yd = np.asarray(xd, dtype=np.float64), np.asarray(yd, dtype=np.float64)
        if self.none:
            return xd, yd
        x, y = xd.copy(), yd.copy()
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for _ in range(iterations):
                fx, fy = self.apply(x, y)
                ex, ey = fx - xd, fy - yd
                a, b, c, d = self.jacobian(x, y)
                det = a * d - b * c
                det = np.where(np.abs(det) > 1e-12, det, 1e-12)
                dx, dy = (d * ex - b * ey) / det, (a * ey - c * ex) / det
                x, y = x - dx, y - dy
                if float(np.max(np.abs(dx), initial=0.0)) < 1e-14 and float(np.max(np.abs(dy), initial=0.0)) < 1e-14:
                    break
            fx, fy = self.apply(x, y)
            good = (np.hypot(fx - xd, fy - yd) <= 1e-9) & self.on_first_branch(x, y)
        return np.where(good, x, np.nan), np.where(good, y, np.nan)

    def jacobian(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The partial derivatives (dxd/dx, dxd/dy, dyd/dx, dyd/dy) of :meth:`apply` at ideal coordinates."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        r2 = x * x + y * y
        radial, dradial = self._radial(r2), self._slope(r2)
        a = radial + 2.0 * x * x * dradial + 2.0 * self.p1 * y + 6.0 * self.p2 * x
        b = 2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y  # dxd/dy and dyd/dx are equal
        d = radial + 2.0 * y * y * dradial + 6.0 * self.p1 * y + 2.0 * self.p2 * x
        return a, b, b, d

    def _radial(self, r2: FloatArray) -> FloatArray:
        return np.asarray(1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3)))

    def _slope(self, r2: FloatArray) -> FloatArray:
        """d radial / d r2."""
        return np.asarray(self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2))

    def on_first_branch(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
        """Whether ideal coordinates lie where the radial map r -> r (1 + k1 r^2 + ...) still rises from the axis:
        its factor and its derivative positive. Past its first turn the model images a point again, mirrored or
        nearer the axis, and undoing a distorted point may land there (a solution of the polynomial, not a ray)."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        r2 = x * x + y * y
        radial = self._radial(r2)
        return np.asarray((radial > 0) & (radial + 2.0 * r2 * self._slope(r2) > 0))

    def radial(self, r: ArrayLike) -> FloatArray:
        """The radial factor 1 + k1 r^2 + k2 r^4 + k3 r^6 at ideal radius ``r``."""
        return self._radial(np.square(np.asarray(r, dtype=np.float64)))

    def area_factor(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """How much the lens scales a small area at ideal coordinates (the Jacobian's determinant, 0 where the lens
        folds over)."""
        a, b, c, d = self.jacobian(x, y)
        return np.asarray(np.maximum(a * d - b * c, 0.0))


LENS_KEYS = tuple(f.name for f in fields(Distortion))  # plumb_bob's order: CameraInfo's d, the lens_<key> parameters


def lens_distortion(cfg: object, prefix: str = "lens_") -> Distortion:
    """The :class:`Distortion` of a config that declares the :class:`Lens` parameters (``lens_k1`` ..., or under
    another ``prefix``)."""
    return Distortion(*(float(getattr(cfg, f"{prefix}{k}")) for k in LENS_KEYS))


def lens_params(distortion: Distortion, prefix: str = "lens_") -> dict[str, float]:
    """A distortion as the :class:`Lens` parameters' values (``lens_k1`` ..., or under another ``prefix``): the
    inverse of :func:`lens_distortion`."""
    return {f"{prefix}{k}": v for k, v in zip(LENS_KEYS, distortion.coefficients, strict=True)}


def lens_names(prefix: str = "lens_") -> str:
    """The lens parameters' names as an error about them gives them: ``lens_k1, lens_k2, lens_p1, lens_p2, lens_k3``
    (or under another ``prefix``)."""
    return ", ".join(f"{prefix}{k}" for k in LENS_KEYS)


@contextmanager
def lens_named(name: str, source: str = LENS_ERROR) -> Iterator[None]:
    """Raise a :class:`ParameterError` about a lens that cannot be used (named ``source``: :data:`LENS_ERROR`, or the
    parameters that gave it) again naming ``name``: the parameters or the option that gave the lens."""
    try:
        yield
    except ParameterError as exc:
        if exc.name != source:
            raise
        raise ParameterError(name, exc.value, exc.allowed) from None


@dataclass(frozen=True)
class LensCanvas:
    """Where a distorted camera's image comes from: an ideal pinhole canvas of the same focal length, ``pad`` pixels
    wider on each side (x, y), and per image pixel the canvas pixel it shows.

    ``map_x``, ``map_y``: float32 (H, W) canvas pixel-centre coordinates of each image pixel's centre (for
    ``cv2.remap``); ``nearest``: int64 (H, W) flat canvas index of the canvas pixel nearest to it (depth and masks);
    ``max_radius``: the largest ideal normalised radius the image shows (its outer corners'); ``fx``: the focal
    length, px.
    """

    width: int
    height: int
    canvas_width: int
    canvas_height: int
    pad: tuple[int, int]
    max_radius: float
    fx: float
    distortion: Distortion
    map_x: NDArray[np.float32] = field(repr=False)
    map_y: NDArray[np.float32] = field(repr=False)
    nearest: NDArray[np.int64] = field(repr=False)

    def resample_nearest(self, canvas_image: NDArray[np.generic]) -> NDArray[np.generic]:
        """An (H', W', ...) canvas image as the distorted (H, W, ...) image, each pixel the nearest canvas pixel's."""
        flat = canvas_image.reshape(self.canvas_height * self.canvas_width, *canvas_image.shape[2:])
        return flat[self.nearest]

    def normalised(self, cols: ArrayLike, rows: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Ideal normalised coordinates of canvas pixel coordinates (on the canvas or off it)."""
        return ((np.asarray(cols, dtype=np.float64) - (self.canvas_width - 1) / 2) / self.fx,
                (np.asarray(rows, dtype=np.float64) - (self.canvas_height - 1) / 2) / self.fx)

    def area_factor(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """The lens's area factor at ideal coordinates, as the camera projects: beyond the image's farthest radius a
        point keeps the radial factor there (:meth:`PinholeCamera.project`), so the factor is its square."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        beyond = np.hypot(x, y) > self.max_radius
        return np.where(beyond, float(self.distortion.radial(self.max_radius)) ** 2,
                        self.distortion.area_factor(x, y))

    def multiplicity(self) -> NDArray[np.int64]:
        """(H', W') how many image pixels show each canvas pixel (their nearest)."""
        counts = np.bincount(self.nearest.ravel(), minlength=self.canvas_width * self.canvas_height)
        return counts.reshape(self.canvas_height, self.canvas_width)


@lru_cache(maxsize=8)
def lens_canvas(width: int, height: int, fx: float, distortion: Distortion) -> LensCanvas:
    """The :class:`LensCanvas` of a ``width`` x ``height`` camera with focal length ``fx`` (square pixels, principal
    point at the centre) and ``distortion``; :class:`ParameterError` naming the coefficients where the model cannot
    be undone inside the image (the lens folds over there), or where the ideal image it needs is over three times
    the image, over 16384 px or over 170 deg wide. Made once per camera model in a process (its arrays are
    read-only), and refused once: a refused model is refused again without solving it again."""
    if (refused := _REFUSED.get((width, height, fx, distortion))) is not None:
        raise refused
    try:
        return _canvas(width, height, fx, distortion)
    except ParameterError as exc:
        _REFUSED[(width, height, fx, distortion)] = exc
        raise


_REFUSED: dict[tuple[int, int, float, Distortion], ParameterError] = {}  # camera models lens_canvas refused


def _canvas(width: int, height: int, fx: float, distortion: Distortion) -> LensCanvas:
    cx, cy = (width - 1) / 2, (height - 1) / 2
    cols, rows = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    # the pixel centres, and the image's outer corners (pixel edges), made ideal
    xd = np.concatenate([((cols - cx) / fx).ravel(), np.array([-0.5 - cx, width - 0.5 - cx] * 2) / fx])
    yd = np.concatenate([((rows - cy) / fx).ravel(), np.array([-0.5 - cy] * 2 + [height - 0.5 - cy] * 2) / fx])
    x, y = distortion.remove(xd, yd)  # NaN where it cannot be undone
    with np.errstate(invalid="ignore", over="ignore"):
        a, b, c, d = distortion.jacobian(x, y)
        bad = int(np.count_nonzero(~(a * d - b * c > 0)))  # NaN counts too
    if bad:
        raise ParameterError(LENS_ERROR, list(distortion.coefficients),
                             f"a lens that does not fold over inside the {width}x{height} image (the model cannot be "
                             f"undone at {bad} of its pixels and corners: its polynomial turns back there)")
    max_radius = float(np.max(np.hypot(x, y)))
    x, y = x[:-4].reshape(height, width), y[:-4].reshape(height, width)
    u, v = x * fx, y * fx  # canvas pixels from the principal point
    pad_x = max(0, int(np.ceil(float(np.max(np.abs(u))) - cx - 1e-6))) + 2
    pad_y = max(0, int(np.ceil(float(np.max(np.abs(v))) - cy - 1e-6))) + 2
    cw, ch = width + 2 * pad_x, height + 2 * pad_y
    if cw > _CANVAS_MAX * width or ch > _CANVAS_MAX * height or max(cw, ch) > 16384 or cw / 2 / fx > _TAN_85:
        raise ParameterError(LENS_ERROR, list(distortion.coefficients),
                             f"a lens whose ideal image fits in {_CANVAS_MAX:g} times the {width}x{height} image, "
                             f"16384 px and 170 deg (it needs {cw}x{ch}, "
                             f"{np.degrees(2 * np.arctan(cw / 2 / fx)):.1f} deg)")
    map_x, map_y = u + cx + pad_x, v + cy + pad_y
    near_c = np.clip(np.floor(map_x + 0.5), 0, cw - 1).astype(np.int64)
    near_r = np.clip(np.floor(map_y + 0.5), 0, ch - 1).astype(np.int64)
    arrays = map_x.astype(np.float32), map_y.astype(np.float32), near_r * cw + near_c
    for array in arrays:
        array.flags.writeable = False
    return LensCanvas(width, height, cw, ch, (pad_x, pad_y), max_radius, fx, distortion, *arrays)
