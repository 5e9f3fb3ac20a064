"""The camera node's parameters: one frozen dataclass, validated once (see ``CAMERA_PARAMS``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from zebra_sim_ros.params import ParamSpec, in_range, one_of, validate
from zebra_sim_ros.rendering.effects import CameraEffects
from zebra_sim_ros.rendering.renderer import RenderOptions

CAMERA_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("drone_index", 0, "which drone this camera is: drone_{index} in the scene", "0..15", in_range(0, 15)),
    ParamSpec("width", 1280, "image width, px (the paper used 1920)", "16..8192", in_range(16, 8192)),
    ParamSpec("height", 720, "image height, px (the paper used 1080)", "16..8192", in_range(16, 8192)),
    ParamSpec("hfov_deg", 80.0, "horizontal field of view, deg (keep equal to the placer's camera_hfov_deg)",
              "20..150", in_range(20.0, 150.0)),
    ParamSpec("shadows", True, "render sun shadows", "true or false", lambda v: isinstance(v, bool)),
    ParamSpec("shadow_size", 2048, "shadow map size, px", "256..8192", in_range(256, 8192)),
    ParamSpec("antialias", True, "FXAA on the RGB image (never on depth or mask)", "true or false",
              lambda v: isinstance(v, bool)),
    ParamSpec("blur_sigma_px", 0.0, "camera effect: Gaussian blur sigma, px (0 = off)", "0..20", in_range(0.0, 20.0)),
    ParamSpec("noise_std", 0.0, "camera effect: Gaussian noise, 8-bit levels (0 = off)", "0..64", in_range(0.0, 64.0)),
    ParamSpec("jpeg_quality", 0, "camera effect: JPEG re-encode quality (0 = off)", "0..100", in_range(0, 100)),
    ParamSpec("qos_reliability", "reliable", "QoS reliability of the image topics", "reliable or best_effort",
              one_of("reliable", "best_effort")),
    ParamSpec("qos_depth", 5, "history depth of the image topics", "1..1000", in_range(1, 1000)),
    ParamSpec("ack", True, "acknowledge each published frame on /zebra_sim/frame_done (placer lockstep)",
              "true or false", lambda v: isinstance(v, bool)),
)


@dataclass(frozen=True)
class CameraConfig:
    """Validated camera parameters."""

    drone_index: int = 0
    width: int = 1280
    height: int = 720
    hfov_deg: float = 80.0
    shadows: bool = True
    shadow_size: int = 2048
    antialias: bool = True
    blur_sigma_px: float = 0.0
    noise_std: float = 0.0
    jpeg_quality: int = 0
    qos_reliability: str = "reliable"
    qos_depth: int = 5
    ack: bool = True

    @classmethod
    def from_params(cls, values: dict[str, Any]) -> CameraConfig:
        """Validate raw parameter values (missing ones take their defaults)."""
        cfg = cls(**validate(CAMERA_PARAMS, values))
        cfg.render_options().check()
        cfg.effects()
        return cfg

    @property
    def name(self) -> str:
        """The drone's name in scenes and frames: ``drone_{index}``."""
        return f"drone_{self.drone_index}"

    def render_options(self) -> RenderOptions:
        """Renderer settings from these parameters."""
        return RenderOptions(width=self.width, height=self.height, hfov_deg=self.hfov_deg, shadows=self.shadows,
                             shadow_size=self.shadow_size, antialias=self.antialias)

    def effects(self) -> CameraEffects:
        """Camera effects from these parameters."""
        return CameraEffects(self.blur_sigma_px, self.noise_std, self.jpeg_quality)
