"""The camera node's parameters: one frozen dataclass, each parameter declared once (see ``CAMERA_PARAMS``).

Its intrinsics (width, height, hfov_deg) are declared once in :class:`~zebra_sim_ros.geometry.camera.Intrinsics`:
one default, unit and range for the cameras the placer aims and the cameras that render; its lens (``lens_k1`` ..
``lens_k3``) in :class:`~zebra_sim_ros.geometry.lens.Lens`, for the camera node, ``generate`` and ``render``.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import MAX_CAMERAS, Intrinsics
from zebra_sim_ros.geometry.lens import LENS_KEYS, Distortion, Lens, lens_distortion, lens_named, lens_names
from zebra_sim_ros.params import ParamSpec, StageConfig, diagnostics_param, param, reliability_param, same_as, spec_of
from zebra_sim_ros.rendering.effects import CameraEffects, SensorModel
from zebra_sim_ros.rendering.renderer import RenderOptions

LOOKS = ("photo", "plain")


def look_options(look: str) -> dict[str, bool]:
    """The :class:`RenderOptions` switches of a look (``LOOKS``)."""
    photo = look == "photo"
    return {"detail": photo, "contact_shadows": photo}


LENS_HELP = ("the lens's plumb_bob distortion, CameraInfo's d: K1 [K2 [P1 [P2 [K3]]]] (the rest 0; e.g. -0.2 0.05 "
             "for a wide-angle drone camera's barrel distortion); default none, an ideal pinhole")


def add_lens_option(p: argparse.ArgumentParser) -> None:
    """The ``--lens K1 [K2 [P1 [P2 [K3]]]]`` option of ``generate`` and ``render`` (read with :func:`parse_lens`)."""
    p.add_argument("--lens", nargs="+", type=float, default=[], metavar="K", help=LENS_HELP)


def parse_lens(values: Sequence[float], name: str = "--lens") -> Distortion:
    """k1 [k2 [p1 [p2 [k3]]]] as a :class:`Distortion`, each value in its :class:`Lens` parameter's range;
    :class:`ParameterError` naming ``name`` otherwise."""
    if len(values) > len(LENS_KEYS):
        raise ParameterError(name, list(values), "K1 [K2 [P1 [P2 [K3]]]]: up to five numbers")
    for key, value in zip(LENS_KEYS, values, strict=False):
        spec = spec_of(Lens, f"lens_{key}")
        if not spec.check(value):
            raise ParameterError(name, list(values), f"{key} {spec.allowed}")
    return Distortion(*(float(v) for v in values))


def check_render_options(options: RenderOptions, lens_name: str) -> RenderOptions:
    """``options`` once :meth:`RenderOptions.check` accepts them; a lens it refuses is named ``lens_name`` (the
    parameters or option that gave it)."""
    with lens_named(lens_name):
        options.check()
    return options


def lens_text(distortion: Distortion) -> str:
    """A distortion as ``--lens`` takes it, each value exactly: ``-0.2 0.05 0.0 0.0 0.0``."""
    return " ".join(repr(float(v)) for v in distortion.coefficients)


@dataclass(frozen=True)
class CameraConfig(StageConfig):
    """Validated camera parameters."""

    drone_index: int = param(0, "which drone this camera is: drone_{index} in the scene", lo=0, hi=MAX_CAMERAS - 1)
    width: int = same_as(Intrinsics, "width", help="image width (the paper used 1920)")
    height: int = same_as(Intrinsics, "height", help="image height (the paper used 1080)")
    hfov_deg: float = same_as(Intrinsics, "hfov_deg",
                              help="horizontal field of view (the placer's camera_hfov_deg: up and the launch file "
                              "give it the first camera's; keep them equal where you start nodes yourself)")
    lens_k1: float = same_as(Lens, "lens_k1")
    lens_k2: float = same_as(Lens, "lens_k2")
    lens_p1: float = same_as(Lens, "lens_p1")
    lens_p2: float = same_as(Lens, "lens_p2")
    lens_k3: float = same_as(Lens, "lens_k3")
    shadows: bool = param(True, "render sun shadows")
    shadow_size: int = param(2048, "shadow map size", "px", lo=256, hi=8192)
    antialias: bool = param(True, "FXAA on the RGB image (never on depth or mask)")
    blur_sigma_px: float = param(0.0, "camera effect: Gaussian blur sigma (0 = off)", "px", lo=0.0, hi=20.0)
    noise_std: float = param(0.0, "camera effect: Gaussian noise (0 = off)", "8-bit levels", lo=0.0, hi=64.0)
    jpeg_quality: int = param(0, "camera effect: JPEG re-encode quality (0 = off)", lo=0, hi=100)
    look: str = param("photo", "photo: procedural ground detail, contact shadows and photographic coat shading; "
                      "plain: flat ground colours and the bare coat texture (the look before photographic "
                      "rendering, which the shipped weights were trained on)", choices=LOOKS)
    sensor_strength: float = param(1.0, "the photograph's camera drawn per frame (exposure, white balance, "
                                   "vignetting, chromatic aberration, defocus and motion blur, Poisson-Gaussian "
                                   "noise, JPEG) as a multiple of its default ranges (0 = a perfect camera)",
                                   lo=0.0, hi=3.0)
    compressed: str = param("off", "also publish image_raw/compressed (sensor_msgs/CompressedImage, as "
                            "image_transport's compressed transport): jpeg (lossy, compressed_quality), png "
                            "(lossless) or off", choices=("off", "jpeg", "png"))
    compressed_quality: int = param(90, "JPEG quality of image_raw/compressed", lo=1, hi=100)
    points_stride: int = param(0, "also publish points (sensor_msgs/PointCloud2 in the optical frame: x, y, z and "
                               "packed rgb from the depth and colour images, organised, NaN where only sky) at every "
                               "points_stride-th pixel of each row and column; 0 = off", "px", lo=0, hi=64)
    qos_reliability: str = reliability_param("QoS reliability of the image topics")
    qos_depth: int = param(5, "history depth of the image topics", lo=1, hi=1000)
    diagnostics_period_s: float = diagnostics_param()
    ack: bool = param(True, "acknowledge each published frame on zebra_sim/frame_done (placer lockstep)")
    coat_store: bool = param(True, "share baked coats with the other cameras through the cache's coat store "
                             "(each coat baked by one process, read by the rest and by later runs); false: bake "
                             "every coat in this process")

    def check(self) -> None:
        """The renderer's and the effects' own rules (the lens with this image size and field of view)."""
        check_render_options(self.render_options(), lens_names())
        self.effects()

    @property
    def name(self) -> str:
        """The drone's name in scenes and frames: ``drone_{index}``."""
        return f"drone_{self.drone_index}"

    def render_options(self) -> RenderOptions:
        """Renderer settings from these parameters."""
        return RenderOptions(width=self.width, height=self.height, hfov_deg=self.hfov_deg, shadows=self.shadows,
                             shadow_size=self.shadow_size, antialias=self.antialias, coat_store=self.coat_store,
                             distortion=lens_distortion(self), **look_options(self.look))

    def sensor_model(self) -> SensorModel | None:
        """The per-frame camera model (None when ``sensor_strength`` is 0)."""
        return SensorModel(self.sensor_strength) if self.sensor_strength > 0 else None

    def effects(self) -> CameraEffects:
        """Camera effects from these parameters."""
        return CameraEffects(self.blur_sigma_px, self.noise_std, self.jpeg_quality)


CAMERA_PARAMS: tuple[ParamSpec, ...] = CameraConfig.specs()
