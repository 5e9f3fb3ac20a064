"""Typed messages: the data that crosses a boundary (a topic, a file, a process), defined once.

A :class:`Scene` is what the placer draws for one step (``zebra_sim/scene``); :class:`Labels` the exact ground
truth of one camera frame (``<drone>/labels`` and the ``labels`` of a dataset's annotation files);
:class:`Detections` what the detector found in one image (``<drone>/detections``); :class:`FrameAnnotation` one
frame of a generated dataset (``annotations/<frame>.json``). Each is a frozen dataclass with ``to_json`` /
``from_json`` (and ``to_dict`` / ``from_dict``), carries a schema name and version, and refuses a message of
another schema or version with :class:`MessageFormatError` naming what is wrong. The JSON texts are those the
package has always written (same keys, same order), so recorded bags and datasets read back unchanged.

Conventions: lengths in metres, angles in degrees, frame ``map`` is ENU (REP 103); quaternions ``[x, y, z, w]``;
image boxes ``[x0, y0, x1, y1]`` in pixel-edge coordinates (COCO's); stamps are simulated time
(:class:`Stamp`, nanoseconds since the epoch of the run). This module imports nothing of the package but
errors, so every layer can use it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Self

from zebra_sim_ros.errors import ZebraSimError

SCENE_SCHEMA, SCENE_VERSION = "zebra_sim_ros/scene", 1
LABELS_SCHEMA, LABELS_VERSION = "zebra_sim_ros/labels", 1
DETECTIONS_SCHEMA, DETECTIONS_VERSION = "zebra_sim_ros/detections", 1

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Box = tuple[float, float, float, float]
NS_PER_S = 1_000_000_000


class MessageFormatError(ZebraSimError):
    """A message is not valid JSON of a schema and version this build reads, or lacks a field."""


# -- time --------------------------------------------------------------------------------------------------------

def stamp_ns(sec: int, nanosec: int) -> int:
    """Nanoseconds of a ROS-style (sec, nanosec) stamp: the one conversion the package uses."""
    return int(sec) * NS_PER_S + int(nanosec)


@dataclass(frozen=True, order=True)
class Stamp:
    """A time stamp: ``sec`` and ``nanosec`` as in builtin_interfaces/Time."""

    sec: int = 0
    nanosec: int = 0

    @property
    def ns(self) -> int:
        """Nanoseconds."""
        return stamp_ns(self.sec, self.nanosec)

    @classmethod
    def from_ns(cls, ns: int) -> Stamp:
        """The stamp of ``ns`` nanoseconds."""
        sec, nanosec = divmod(int(ns), NS_PER_S)
        return cls(sec, nanosec)

    def to_dict(self) -> dict[str, int]:
        return {"sec": self.sec, "nanosec": self.nanosec}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Stamp:
        return cls(int(d["sec"]), int(d["nanosec"]))


# -- parsing helpers ---------------------------------------------------------------------------------------------

def _json(text: str | bytes, what: str) -> Any:
    try:
        return json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise MessageFormatError(f"{what} is not JSON: {exc}") from exc


class _Message:
    """JSON text of a message with a ``to_dict`` / ``from_dict`` pair (``KIND`` names it in errors)."""

    KIND: ClassVar[str] = "message"

    def to_dict(self) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def from_dict(cls, d: Any) -> Self:
        raise NotImplementedError

    def to_json(self) -> str:
        """Compact JSON text."""
        return json.dumps(self.to_dict(), separators=(",", ":"))

    @classmethod
    def from_json(cls, text: str | bytes) -> Self:
        """Parse and check a message; :class:`MessageFormatError` says what is wrong."""
        return cls.from_dict(_json(text, cls.KIND))


def _checked(d: Any, schema: str, version: int, required: Sequence[str]) -> dict[str, Any]:
    what = schema.rsplit("/", 1)[-1]
    if not isinstance(d, dict) or d.get("schema") != schema:
        got = d.get("schema") if isinstance(d, dict) else None
        raise MessageFormatError(f"not a {schema} message (schema={got!r})")
    if d.get("version") != version:
        raise MessageFormatError(f"{what} schema version {d.get('version')!r}; this build reads {version}")
    for key in required:
        if key not in d:
            raise MessageFormatError(f"{what} lacks '{key}'")
    return d


def _parse(kind: str, build: Any, d: Any) -> Any:
    """``build(d)``, with a missing key or a wrong type reported as :class:`MessageFormatError` (a field that is not
    the object it should be, an infinite number where an integer belongs)."""
    try:
        return build(d)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, ArithmeticError) as exc:
        raise MessageFormatError(f"{kind} is malformed: {type(exc).__name__} {exc}") from exc


def _vec(v: Sequence[Any], n: int) -> list[float]:
    if len(v) != n:
        raise ValueError(f"{list(v)!r} has {len(v)} values, not {n}")
    return [float(x) for x in v]


def _v2(v: Sequence[Any]) -> tuple[float, float]:
    a = _vec(v, 2)
    return a[0], a[1]


def _v3(v: Sequence[Any]) -> Vec3:
    a = _vec(v, 3)
    return a[0], a[1], a[2]


def _v4(v: Sequence[Any]) -> Quat:
    a = _vec(v, 4)
    return a[0], a[1], a[2], a[3]


# -- the scene ---------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Lighting:
    """The lighting of one frame. Directions are unit vectors in ``map`` pointing towards the light; intensities
    are relative (1.0 = clear noon sun)."""

    time_of_day_h: float
    day_of_year: int
    latitude_deg: float
    sun_direction: Vec3  # towards the sun, ENU
    sun_elevation_deg: float
    sun_azimuth_deg: float  # clockwise from north
    light_direction: Vec3  # towards the key light (sun by day, moon by night)
    light_rgb: Vec3
    light_intensity: float
    ambient_rgb: Vec3
    ambient_intensity: float
    is_night: bool

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (see the scene schema)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Lighting:
        return cls(float(d["time_of_day_h"]), int(d["day_of_year"]), float(d["latitude_deg"]),
                   _v3(d["sun_direction"]), float(d["sun_elevation_deg"]),
                   float(d["sun_azimuth_deg"]), _v3(d["light_direction"]), _v3(d["light_rgb"]),
                   float(d["light_intensity"]), _v3(d["ambient_rgb"]), float(d["ambient_intensity"]),
                   bool(d["is_night"]))


@dataclass(frozen=True)
class SensorDraw:
    """One frame's drawn camera (:class:`~zebra_sim_ros.rendering.effects.SensorModel`), recorded in its annotation:
    exposure in EV, white-balance gains (r, g, b), corner vignetting (brightness lost), chromatic aberration,
    defocus sigma and motion-blur length in px at 1280 px wide, motion direction in degrees, shot-noise variance per
    unit signal and read-noise standard deviation (signal 0..1), JPEG quality (0 = none)."""

    exposure_ev: float = 0.0
    wb_gain: Vec3 = (1.0, 1.0, 1.0)
    vignetting: float = 0.0
    chromatic_px: float = 0.0
    defocus_px: float = 0.0
    motion_px: float = 0.0
    motion_angle_deg: float = 0.0
    shot_noise: float = 0.0
    read_noise: float = 0.0
    jpeg_quality: int = 0

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (an annotation's ``sensor``)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> SensorDraw | None:
        """From an annotation's ``sensor`` (None: no camera model was applied)."""
        if d is None:
            return None
        try:
            values = {k: (_v3(v) if k == "wb_gain" else int(v) if k == "jpeg_quality" else float(v))
                      for k, v in d.items()}
            return cls(**values)  # type: ignore[arg-type]
        except (TypeError, ValueError) as exc:
            raise MessageFormatError(f"sensor {dict(d)!r} is not a SensorDraw ({exc})") from exc


@dataclass(frozen=True)
class GroundLook:
    """How the renderer recolours the landscape: ``albedo' = min(mix(albedo, luma(albedo), desaturation) * tint,
    0.95)`` in linear RGB for the terrain, and ``albedo * vegetation_tint`` for plants. The default is the world
    as authored."""

    tint: Vec3 = (1.0, 1.0, 1.0)
    desaturation: float = 0.0
    vegetation_tint: Vec3 = (1.0, 1.0, 1.0)

    @property
    def is_identity(self) -> bool:
        return self == GroundLook()

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (the scene's ``ground``; ``vegetation_tint`` only when it is not identity)."""
        d: dict[str, object] = {"tint": list(self.tint), "desaturation": self.desaturation}
        return d if self.vegetation_tint == (1.0, 1.0, 1.0) else {**d, "vegetation_tint": list(self.vegetation_tint)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> GroundLook:
        """From a scene's ``ground`` (None or absent: as authored); raises :class:`MessageFormatError` on bad
        values."""
        if not d:
            return cls()
        try:
            tint = _v3(d["tint"])
            desat = float(d["desaturation"])
            veg = _v3(d.get("vegetation_tint", (1.0, 1.0, 1.0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise MessageFormatError(f"scene ground {dict(d)!r} is not {{'tint': [r, g, b], 'desaturation': "
                                     "0..1, 'vegetation_tint': [r, g, b]}") from exc
        if not all(0.0 <= t <= 100.0 for t in tint + veg) or not 0.0 <= desat <= 1.0:
            raise MessageFormatError(f"scene ground {dict(d)!r}: want tints of three factors in 0..100 and "
                                     "desaturation in 0..1")
        return cls(tint, desat, veg)


@dataclass(frozen=True)
class Weather:
    """The sky of one step: ``cloud_cover`` 0 (clear) .. 1 (overcast), the cloud field's offset in ``map`` (m; a
    different sky each step), and the structured domain randomisation of the sky's and the light's colours (linear
    factors, 1 = as the world and the sun's position give them). Clouds shade the ground where they hide the
    sun; an overcast sky hides it everywhere and the light is the sky's."""

    cloud_cover: float = 0.0
    cloud_offset: tuple[float, float] = (0.0, 0.0)
    sky_tint: Vec3 = (1.0, 1.0, 1.0)
    light_tint: Vec3 = (1.0, 1.0, 1.0)

    @property
    def is_clear(self) -> bool:
        return self == Weather()

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (the scene's ``weather``)."""
        return {"cloud_cover": self.cloud_cover, "cloud_offset": list(self.cloud_offset),
                "sky_tint": list(self.sky_tint), "light_tint": list(self.light_tint)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> Weather:
        """From a scene's ``weather`` (None or absent: a clear sky); :class:`MessageFormatError` on bad values."""
        if not d:
            return cls()
        try:
            w = cls(float(d["cloud_cover"]), _v2(d["cloud_offset"]), _v3(d["sky_tint"]), _v3(d["light_tint"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise MessageFormatError(f"scene weather {dict(d)!r} is not {{'cloud_cover': 0..1, 'cloud_offset': "
                                     "[x, y], 'sky_tint': [r, g, b], 'light_tint': [r, g, b]}") from exc
        if not 0.0 <= w.cloud_cover <= 1.0 or not all(0.0 <= t <= 100.0 for t in w.sky_tint + w.light_tint):
            raise MessageFormatError(f"scene weather {dict(d)!r}: want cloud_cover in 0..1 and tints in 0..100")
        return w


@dataclass(frozen=True)
class OrientedBox:
    """A 3D box: centre (m), size (length, width, height in m) and orientation ``[x, y, z, w]``."""

    center: Vec3
    size: Vec3
    orientation_xyzw: Quat

    def to_dict(self) -> dict[str, Any]:
        return {"center": list(self.center), "size": list(self.size), "orientation_xyzw": list(self.orientation_xyzw)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> OrientedBox:
        return cls(_v3(d["center"]), _v3(d["size"]), _v4(d["orientation_xyzw"]))


@dataclass(frozen=True)
class SceneZebra:
    """One placed zebra, or an animal of another species (``species``): ``id`` is its pool index (instance masks
    use id + 1); ``position`` the asset origin (the ground under the body); asset frame x forward, y left, z up."""

    id: int
    morph: str
    coat_seed: int
    clip: str
    frame: int
    scale: float
    yaw_deg: float
    position: Vec3
    orientation_xyzw: Quat
    box: OrientedBox
    species: str = "zebra"  # another species (a distractor: never a zebra label) when not "zebra"

    @property
    def is_zebra(self) -> bool:
        """Whether this animal is a zebra (only zebras are ever labelled as zebra)."""
        return self.species == "zebra"

    def to_dict(self) -> dict[str, Any]:
        d = {"id": self.id, "morph": self.morph, "coat_seed": self.coat_seed, "clip": self.clip,
             "frame": self.frame, "scale": self.scale, "yaw_deg": self.yaw_deg, "position": list(self.position),
             "orientation_xyzw": list(self.orientation_xyzw), "box": self.box.to_dict()}
        return d if self.is_zebra else {**d, "species": self.species}  # zebras' scenes read as before

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SceneZebra:
        return cls(int(d["id"]), str(d["morph"]), int(d["coat_seed"]), str(d["clip"]), int(d["frame"]),
                   float(d["scale"]), float(d["yaw_deg"]), _v3(d["position"]),
                   _v4(d["orientation_xyzw"]), OrientedBox.from_dict(d["box"]), str(d.get("species", "zebra")))


@dataclass(frozen=True)
class SceneCamera:
    """One drone camera: its optical frame (z forward, x right, y down) in ``map``; pitch is the optical axis'
    elevation (negative looks down), yaw counter-clockwise from east."""

    name: str
    strategy: str
    position: Vec3
    orientation_xyzw: Quat
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    frame_id: str

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "strategy": self.strategy, "position": list(self.position),
                "orientation_xyzw": list(self.orientation_xyzw), "yaw_deg": self.yaw_deg,
                "pitch_deg": self.pitch_deg, "roll_deg": self.roll_deg, "frame_id": self.frame_id}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SceneCamera:
        return cls(str(d["name"]), str(d["strategy"]), _v3(d["position"]),
                   _v4(d["orientation_xyzw"]), float(d["yaw_deg"]), float(d["pitch_deg"]),
                   float(d["roll_deg"]), str(d["frame_id"]))


@dataclass(frozen=True)
class Datum:
    """Where ``map``'s origin is on the Earth: WGS84 latitude and longitude (deg) and height above the ellipsoid
    (m); ``map`` is the local tangent plane there (x east, y north, z up; :mod:`zebra_sim_ros.geometry.geodesy`)."""

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0

    def __post_init__(self) -> None:
        if not -90.0 <= self.latitude_deg <= 90.0:
            raise ValueError(f"datum latitude {self.latitude_deg!r} deg: want -90..90")
        if not -180.0 <= self.longitude_deg <= 180.0:
            raise ValueError(f"datum longitude {self.longitude_deg!r} deg: want -180..180")
        if not math.isfinite(self.altitude_m):
            raise ValueError(f"datum altitude {self.altitude_m!r} m: want a finite height")

    def to_dict(self) -> dict[str, float]:
        return {"latitude_deg": self.latitude_deg, "longitude_deg": self.longitude_deg, "altitude_m": self.altitude_m}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> Datum | None:
        """None for a scene written before scenes carried their datum."""
        if d is None:
            return None
        return cls(float(d["latitude_deg"]), float(d["longitude_deg"]), float(d["altitude_m"]))


@dataclass(frozen=True)
class WorldRef:
    """Which world a scene is in: enough for ``load_world`` to rebuild it."""

    name: str
    source: str  # "preset:<name>" or a USD path
    seed: int | None
    terrain_prim: str = "/World/Terrain"

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "source": self.source, "seed": self.seed, "terrain_prim": self.terrain_prim}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> WorldRef:
        seed = d.get("seed")
        return cls(str(d["name"]), str(d["source"]), None if seed is None else int(seed),
                   str(d.get("terrain_prim", "/World/Terrain")))

    def load_args(self) -> tuple[str, str, int]:
        """(source, terrain_prim, seed) for ``load_world``."""
        source = self.source.split(":", 1)[1] if self.source.startswith("preset:") else self.source
        return source, self.terrain_prim, int(self.seed or 0)


@dataclass(frozen=True)
class Scene(_Message):
    """Everything drawn for one step (``zebra_sim/scene``). ``step = placement * camera_rerolls + reroll``;
    ``seed`` and ``step`` are enough to regenerate the scene alone."""

    KIND: ClassVar[str] = "scene"

    stamp: Stamp
    step: int
    placement: int
    reroll: int
    seed: int
    asset_digest: str  # the zebra asset the clip frames refer to
    world: WorldRef
    lighting: Lighting
    rectangle_center: tuple[float, float]  # the placement rectangle, m
    rectangle_size: tuple[float, float]
    requested: int  # zebras asked for
    zebras: tuple[SceneZebra, ...]
    cameras: tuple[SceneCamera, ...]
    ground: GroundLook = field(default_factory=GroundLook)
    weather: Weather = field(default_factory=Weather)
    datum: Datum | None = None  # where map is on the Earth (None: a scene from before scenes carried it)

    def __post_init__(self) -> None:
        # the sun's path is drawn for the lighting's latitude: a map put elsewhere on the Earth would disagree with it
        if self.datum is not None and not abs(self.datum.latitude_deg - self.lighting.latitude_deg) <= 1e-9:  # NaN too
            raise ValueError(f"datum latitude {self.datum.latitude_deg!r} deg is not the lighting's "
                             f"{self.lighting.latitude_deg!r} deg (the sun's path is drawn for it)")

    @property
    def placed(self) -> int:
        """Zebras actually placed."""
        return len(self.zebras)

    def camera(self, name: str) -> SceneCamera:
        """The camera ``name``; :class:`MessageFormatError` if the scene has none."""
        for c in self.cameras:
            if c.name == name:
                return c
        raise MessageFormatError(f"scene {self.step} has no camera {name!r} (it has {[c.name for c in self.cameras]})")

    def with_lighting(self, lighting: Lighting) -> Scene:
        """The same scene under other light."""
        return replace(self, lighting=lighting)

    def to_dict(self) -> dict[str, Any]:
        """The versioned JSON structure (the ``ground`` only when it differs from the world as authored, the
        ``weather`` only when the sky is not clear)."""
        return {
            "schema": SCENE_SCHEMA, "version": SCENE_VERSION, "stamp": self.stamp.to_dict(), "step": self.step,
            "placement": self.placement, "reroll": self.reroll, "seed": self.seed, "asset_digest": self.asset_digest,
            "world": self.world.to_dict(), "lighting": self.lighting.to_dict(),
            "rectangle": {"center": list(self.rectangle_center), "size": list(self.rectangle_size)},
            "requested": self.requested, "placed": self.placed, "zebras": [z.to_dict() for z in self.zebras],
            "cameras": [c.to_dict() for c in self.cameras],
            **({} if self.ground.is_identity else {"ground": self.ground.to_dict()}),
            **({} if self.weather.is_clear else {"weather": self.weather.to_dict()}),
            **({} if self.datum is None else {"datum": self.datum.to_dict()}),
        }

    @classmethod
    def from_dict(cls, d: Any) -> Scene:
        d = _checked(d, SCENE_SCHEMA, SCENE_VERSION, ("stamp", "step", "seed", "world", "lighting", "zebras",
                                                      "cameras"))
        return _parse("scene", lambda d: cls(
            Stamp.from_dict(d["stamp"]), int(d["step"]), int(d.get("placement", 0)), int(d.get("reroll", 0)),
            int(d["seed"]), str(d.get("asset_digest", "")), WorldRef.from_dict(d["world"]),
            Lighting.from_dict(d["lighting"]), _v2(d.get("rectangle", {}).get("center", (0, 0))),
            _v2(d.get("rectangle", {}).get("size", (0, 0))), int(d.get("requested", len(d["zebras"]))),
            tuple(SceneZebra.from_dict(z) for z in d["zebras"]), tuple(SceneCamera.from_dict(c) for c in d["cameras"]),
            GroundLook.from_dict(d.get("ground")), Weather.from_dict(d.get("weather")),
            Datum.from_dict(d.get("datum"))), d)


# -- labels ------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Rle:
    """An uncompressed COCO run-length mask: column-major runs starting with background, ``size`` [h, w]."""

    counts: tuple[int, ...]
    size: tuple[int, int]

    def to_dict(self) -> dict[str, Any]:
        return {"counts": list(self.counts), "size": list(self.size)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Rle:
        return cls(tuple(int(c) for c in d["counts"]), (int(d["size"][0]), int(d["size"][1])))


@dataclass(frozen=True)
class LabelledZebra:
    """The ground truth of one zebra with at least one pixel in a frame (see ``labels/labeller.py``): tight
    (visible) and amodal (full) boxes, pixel counts and fractions, 3D boxes, keypoints ``(u, v, visibility)``
    with COCO's visibility (2 seen, 1 occluded, 0 outside), and whether the label filters kept it."""

    id: int
    instance: int  # the value in the instance mask: id + 1
    morph: str
    clip: str
    frame: int
    scale: float
    distance_m: float
    box_visible: Box
    box_full: Box
    box_full_unclipped: Box
    visible_pixels: int
    silhouette_pixels: int
    visible_fraction: float
    in_frame_fraction: float
    box3d_map: OrientedBox
    box3d_camera: OrientedBox
    keypoints: tuple[tuple[float, float, int], ...]
    kept: bool
    drop_reason: str | None
    rle: Rle | None = None  # its mask, where a dataset writer outlined it
    species: str = "zebra"  # another species is never kept: it is labelled with its species, not as a zebra

    @property
    def is_zebra(self) -> bool:
        """Whether this animal is a zebra."""
        return self.species == "zebra"

    @property
    def dont_care(self) -> bool:
        """A zebra seen (visible pixels) but not labelled (the filters dropped it): a don't-care region for
        evaluation, as COCO's crowd boxes are. Other species are never don't-care: a detection on one is false."""
        return self.is_zebra and not self.kept and self.visible_pixels > 0

    def to_dict(self) -> dict[str, Any]:
        d = {"id": self.id, "instance": self.instance, "morph": self.morph, "clip": self.clip, "frame": self.frame,
             "scale": self.scale, "distance_m": self.distance_m, "box_visible": list(self.box_visible),
             "box_full": list(self.box_full), "box_full_unclipped": list(self.box_full_unclipped),
             "visible_pixels": self.visible_pixels, "silhouette_pixels": self.silhouette_pixels,
             "visible_fraction": self.visible_fraction, "in_frame_fraction": self.in_frame_fraction,
             "box3d_map": self.box3d_map.to_dict(), "box3d_camera": self.box3d_camera.to_dict(),
             "keypoints": [list(k) for k in self.keypoints], "kept": self.kept, "drop_reason": self.drop_reason}
        if self.rle is not None:
            d["rle"] = self.rle.to_dict()
        if not self.is_zebra:
            d["species"] = self.species
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LabelledZebra:
        return cls(int(d["id"]), int(d.get("instance", int(d["id"]) + 1)), str(d.get("morph", "")),
                   str(d.get("clip", "")), int(d.get("frame", 0)), float(d.get("scale", 1.0)),
                   float(d.get("distance_m", math.nan)), _v4(d["box_visible"]),
                   _v4(d.get("box_full", d["box_visible"])),
                   _v4(d.get("box_full_unclipped", d.get("box_full", d["box_visible"]))),
                   int(d.get("visible_pixels", 0)), int(d.get("silhouette_pixels", 0)),
                   float(d.get("visible_fraction", 0.0)), float(d.get("in_frame_fraction", 0.0)),
                   _box_or_empty(d.get("box3d_map")), _box_or_empty(d.get("box3d_camera")),
                   tuple((float(k[0]), float(k[1]), int(k[2])) for k in d.get("keypoints", ())),
                   bool(d["kept"]), d.get("drop_reason"), Rle.from_dict(d["rle"]) if "rle" in d else None,
                   str(d.get("species", "zebra")))


def _box_or_empty(d: Mapping[str, Any] | None) -> OrientedBox:
    return OrientedBox.from_dict(d) if d else OrientedBox((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


@dataclass(frozen=True)
class Labels(_Message):
    """The labels of one camera frame (``<drone>/labels``): every zebra seen, kept or not, and the camera."""

    KIND: ClassVar[str] = "labels"

    stamp: Stamp
    step: int
    seed: int
    camera: str
    frame_id: str
    width: int
    height: int
    K: tuple[float, ...]  # row-major 3x3 intrinsics
    keypoint_names: tuple[str, ...]
    filters: Mapping[str, float]  # the label filters in force (labels/config.LabelFilters)
    zebras: tuple[LabelledZebra, ...]
    unknown_instances: tuple[int, ...] = ()  # mask values no scene zebra has
    D: tuple[float, ...] = ()  # the lens's plumb_bob distortion (k1, k2, p1, p2, k3); empty or zeros: none

    @property
    def kept(self) -> tuple[LabelledZebra, ...]:
        """The labelled zebras (kept by the filters)."""
        return tuple(z for z in self.zebras if z.kept)

    @property
    def others(self) -> tuple[LabelledZebra, ...]:
        """The animals of other species seen in the frame (never zebra labels)."""
        return tuple(z for z in self.zebras if not z.is_zebra)

    @property
    def dont_care(self) -> tuple[LabelledZebra, ...]:
        """The zebras seen but not labelled (:attr:`LabelledZebra.dont_care`)."""
        return tuple(z for z in self.zebras if z.dont_care)

    def with_zebras(self, zebras: Sequence[LabelledZebra]) -> Labels:
        return replace(self, zebras=tuple(zebras))

    def ground_truth(self) -> tuple[Detections, tuple[int, ...]]:
        """The labels as detections with score 1 (``<drone>/labels/boxes2d``) and each one's scene id: every
        kept zebra (class 0, ``zebra``; the boxes a dataset's labels hold), then every animal of another species
        seen (class -1, named by its species: no class of the detector). Zebras seen but not labelled
        (:attr:`dont_care`) are left out. Boxes are the visible ones."""
        animals = self.kept + self.others
        dets = tuple(Detection(z.box_visible, 1.0, 0 if z.is_zebra else -1, z.species) for z in animals)
        return Detections(self.stamp, self.frame_id, self.width, self.height, dets), tuple(z.id for z in animals)

    def to_dict(self) -> dict[str, Any]:
        return {"schema": LABELS_SCHEMA, "version": LABELS_VERSION, "stamp": self.stamp.to_dict(), "step": self.step,
                "seed": self.seed, "camera": self.camera, "frame_id": self.frame_id, "width": self.width,
                "height": self.height, "K": list(self.K), "keypoint_names": list(self.keypoint_names),
                "filters": dict(self.filters), "zebras": [z.to_dict() for z in self.zebras],
                "in_view": len(self.zebras), "kept": len(self.kept), "unknown_instances": list(self.unknown_instances),
                "D": list(self.D)}

    @classmethod
    def from_dict(cls, d: Any) -> Labels:
        d = _checked(d, LABELS_SCHEMA, LABELS_VERSION, ("stamp", "zebras"))
        return _parse("labels", lambda d: cls(
            Stamp.from_dict(d["stamp"]), int(d.get("step", 0)), int(d.get("seed", 0)), str(d.get("camera", "")),
            str(d.get("frame_id", "")), int(d.get("width", 0)), int(d.get("height", 0)),
            tuple(float(v) for v in d.get("K", ())), tuple(str(n) for n in d.get("keypoint_names", ())),
            dict(d.get("filters", {})), tuple(LabelledZebra.from_dict(z) for z in d["zebras"]),
            tuple(int(i) for i in d.get("unknown_instances", ())), tuple(float(v) for v in d.get("D", ()))), d)


# -- detections --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Detection:
    """One detected object: box in the image's pixel-edge coordinates, confidence, class."""

    box_xyxy: Box
    score: float
    class_id: int = 0
    class_name: str = "zebra"

    def to_dict(self) -> dict[str, Any]:
        return {"box_xyxy": list(self.box_xyxy), "score": self.score, "class": self.class_id,
                "class_name": self.class_name}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Detection:
        return cls(_v4(d["box_xyxy"]), float(d["score"]), int(d.get("class", 0)),
                   str(d.get("class_name", "zebra")))


@dataclass(frozen=True)
class Detections(_Message):
    """What the detector found in one image (``<drone>/detections``), with the image's stamp and frame."""

    KIND: ClassVar[str] = "detections"

    stamp: Stamp
    frame_id: str
    width: int
    height: int
    detections: tuple[Detection, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"schema": DETECTIONS_SCHEMA, "version": DETECTIONS_VERSION, "stamp": self.stamp.to_dict(),
                "frame_id": self.frame_id, "width": self.width, "height": self.height,
                "detections": [x.to_dict() for x in self.detections]}

    @classmethod
    def from_dict(cls, d: Any) -> Detections:
        d = _checked(d, DETECTIONS_SCHEMA, DETECTIONS_VERSION, ("stamp", "detections"))
        return _parse("detections", lambda d: cls(
            Stamp.from_dict(d["stamp"]), str(d.get("frame_id", "")), int(d.get("width", 0)), int(d.get("height", 0)),
            tuple(Detection.from_dict(x) for x in d["detections"])), d)


# -- dataset annotation files ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FrameAnnotation(_Message):
    """One frame of a generated dataset (``annotations/<frame>.json``): where its files are, the scene facts it
    came from, the command that renders it again alone, and its labels (kept and don't-care zebras outlined)."""

    KIND: ClassVar[str] = "annotation"

    frame: str
    split: str
    image: str
    mask: str
    depth: str | None
    world: WorldRef
    seed: int
    step: int
    placement: int
    reroll: int
    strategy: str
    asset_digest: str
    lighting: Lighting
    camera: SceneCamera
    regenerate: str
    labels: Labels
    sensor: SensorDraw | None = None  # the camera drawn for this frame; None: a perfect camera
    weather: Weather = field(default_factory=Weather)  # the step's sky and its randomised colours
    ground: GroundLook = field(default_factory=GroundLook)  # the step's landscape colours
    appearance_digest: str = ""  # the animals' look (asset and coats); "" in files written before it was recorded

    def to_dict(self) -> dict[str, Any]:
        return {"weather": self.weather.to_dict(), "ground": self.ground.to_dict(),
                "appearance_digest": self.appearance_digest,
                "frame": self.frame, "split": self.split, "image": self.image, "mask": self.mask, "depth": self.depth,
                "world": self.world.to_dict(), "seed": self.seed, "step": self.step, "placement": self.placement,
                "reroll": self.reroll, "strategy": self.strategy, "asset_digest": self.asset_digest,
                "lighting": self.lighting.to_dict(), "camera": self.camera.to_dict(), "regenerate": self.regenerate,
                "labels": self.labels.to_dict(), "sensor": self.sensor.to_dict() if self.sensor else None}

    def to_json(self) -> str:
        """Compact JSON with sorted keys (the file format)."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))

    @classmethod
    def from_dict(cls, d: Any) -> FrameAnnotation:
        return _parse("annotation", lambda d: cls(
            str(d["frame"]), str(d["split"]), str(d["image"]), str(d["mask"]), d.get("depth"),
            WorldRef.from_dict(d["world"]), int(d["seed"]), int(d["step"]), int(d["placement"]), int(d["reroll"]),
            str(d["strategy"]), str(d["asset_digest"]), Lighting.from_dict(d["lighting"]),
            SceneCamera.from_dict(d["camera"]), str(d["regenerate"]), Labels.from_dict(d["labels"]),
            SensorDraw.from_dict(d.get("sensor")), Weather.from_dict(d.get("weather")),
            GroundLook.from_dict(d.get("ground")), str(d.get("appearance_digest", ""))), d)
