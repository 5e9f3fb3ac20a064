"""The placer core: seed + world + zebra library -> a deterministic sequence of scenes.

Randomness: every step's draws come from generators seeded by ``[seed, placement]`` (zebras) and
``[seed, placement, reroll]`` (time of day, strategy, cameras); the pool from ``[seed, 0x9001]``. So the
same seed gives the same sequence bit for bit, and any step can be regenerated alone from (seed, step).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.messages import Datum, Scene, WorldRef
from zebra_sim_ros.placement.cameras import STRATEGIES, CameraRanges, Surroundings, sample_cameras
from zebra_sim_ros.placement.config import PlacerConfig
from zebra_sim_ros.placement.ground import sample_ground_look
from zebra_sim_ros.placement.herd import Herd, HerdPlacer, PlacementError, make_pool
from zebra_sim_ros.placement.scene import build_scene, scene_zebras
from zebra_sim_ros.placement.sun import lighting_for, sample_time_and_day
from zebra_sim_ros.placement.weather import WEATHER_STREAM, rotate_sun, sample_weather
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.skeleton import MORPHS, OTHER_SPECIES, ZEBRA_MORPHS

OTHER_CLIPS = ("idle", "graze", "walk", "look_around", "tail_swish")
"""The clips animals of other species are shown in: standing, grazing and walking."""


class Placer:
    """Generates :class:`Scene` objects for steps 0, 1, 2, ... of one experiment."""

    def __init__(self, cfg: PlacerConfig, world: World, library: ZebraLibrary) -> None:
        self.cfg = cfg
        self.world = world
        self.library = library
        others = OTHER_SPECIES if cfg.other_species == ("all",) else cfg.other_species
        self.other_morphs = tuple(library.morphs.index(n) for n in others if n in library.morphs)
        self.pool = make_pool(cfg.seed, cfg.pool_size, cfg.morph_weights, len(ZEBRA_MORPHS),
                              self.other_morphs if cfg.other_animals_max > 0 else ())
        self.species = tuple(MORPHS[n].species if n in MORPHS else "zebra" for n in library.morphs)
        other_clips = [library.clip_names.index(c) for c in OTHER_CLIPS if c in library.clip_names]
        self.other_clip_ids = np.array(other_clips or [0])
        if cfg.clips == ("all",):
            self.clip_ids = np.arange(len(library.clip_names))
        else:
            unknown = [c for c in cfg.clips if c not in library.clip_names]
            if unknown:
                raise ParameterError("clips", list(cfg.clips), f"names among {list(library.clip_names)} or [all]")
            self.clip_ids = np.array([library.clip_names.index(c) for c in cfg.clips])
        max_slope = world.max_slope_deg if cfg.max_slope_deg < 0 else cfg.max_slope_deg
        self.herds = HerdPlacer(world.terrain, world.placeable, max_slope, world.obstacles.positions[:, :2],
                                world.obstacles.radii, library, world.water)
        self.camera = cfg.camera
        self.ranges = CameraRanges(
            height_min=cfg.camera_height_min, height_max=cfg.camera_height_max, far_radius=cfg.far_radius,
            closeby_margin=cfg.closeby_margin, roll_max_deg=cfg.roll_max_deg,
            far_yaw_jitter_deg=cfg.far_yaw_jitter_deg, closeby_yaw_jitter_deg=cfg.closeby_yaw_jitter_deg,
            pitch_offset_deg=cfg.pitch_offset_deg, min_separation=cfg.min_camera_separation,
            min_clearance=cfg.min_camera_clearance, low_height_min=cfg.low_height_min,
            low_height_max=cfg.low_height_max, low_distance_min=cfg.low_distance_min,
            low_distance_max=cfg.low_distance_max, low_yaw_jitter_deg=cfg.low_yaw_jitter_deg,
            low_roll_max_deg=cfg.low_roll_max_deg, low_other_target=cfg.low_other_target,
            nadir_height_min=cfg.nadir_height_min, nadir_height_max=cfg.nadir_height_max,
            nadir_tilt_max_deg=cfg.nadir_tilt_max_deg)
        self.camera_names = [f"drone_{i}" for i in range(cfg.num_cameras)]
        self._cache: tuple[int, Herd] | None = None
        self._world_info = WorldRef(world.name, world.source, world.seed, cfg.terrain_prim)
        self._datum = Datum(cfg.latitude_deg, cfg.longitude_deg, cfg.origin_altitude_m)  # where map is on the Earth

    def herd_for(self, placement: int) -> Herd:
        """The herd of ``placement`` (kept while its camera re-rolls are generated).

        If every zebra of a draw was dropped (rare: steep or crowded ground), the placement is drawn again
        from ``[seed, placement, 0, attempt]``, up to 10 times.
        """
        if self._cache is not None and self._cache[0] == placement:
            return self._cache[1]
        c = self.cfg
        for attempt in range(10):
            rng = np.random.default_rng([c.seed, placement] + ([0, attempt] if attempt else []))
            others = (np.random.default_rng([c.seed, placement, 0x07E5] + ([attempt] if attempt else [])),
                      c.other_animals_max, self.other_clip_ids)
            herd = self.herds.place(rng, self.pool, (c.count_min, c.count_max), (c.scale_min, c.scale_max),
                                    (c.rect_min, c.rect_max), self.clip_ids, c.max_attempts, others)
            if np.any(herd.ids < self.pool.zebras):
                self._cache = (placement, herd)
                return herd
        raise PlacementError("world", self.world.name,
                             "ground where at least one zebra can stand (10 draws placed none)")

    def _strategy(self, rng: np.random.Generator) -> str:
        """The step's camera strategy: the configured one, or drawn (``mixed``: far/closeby, ``any``: all four)."""
        if self.cfg.strategy == "mixed":
            return "far" if rng.uniform() < 0.5 else "closeby"
        if self.cfg.strategy == "any":
            return STRATEGIES[int(rng.integers(len(STRATEGIES)))]
        return self.cfg.strategy

    def scene(self, step: int) -> Scene:
        """The scene of step ``step`` (any step, in any order)."""
        if step < 0:
            raise ParameterError("step", step, ">= 0")
        c = self.cfg
        placement, reroll = divmod(step, c.camera_rerolls)
        herd = self.herd_for(placement)
        rng = np.random.default_rng([c.seed, placement, reroll + 1])
        tod, doy = sample_time_and_day(rng, c.night_fraction, c.day_window, c.day_start_h, c.day_end_h,
                                       c.latitude_deg)
        strategy = self._strategy(rng)
        lib = self.library
        boxes = np.asarray(lib.boxes()[herd.morph, herd.global_frame], dtype=np.float64)  # (N, 2, 3)
        centre_local = boxes.mean(axis=1) * herd.scale[:, None]
        box_center = np.einsum("nij,nj->ni", herd.rotation, centre_local) + herd.position
        box_size = (boxes[:, 1] - boxes[:, 0]) * herd.scale[:, None]
        obstacles = self.world.obstacles
        zeb = herd.ids < self.pool.zebras  # the cameras look at the zebras and keep out of every animal
        env = Surroundings(self.world.terrain, herd.position[zeb], box_center[zeb], obstacles.positions[:, :2],
                           obstacles.radii, herd.position[~zeb, :2], box_center[~zeb])
        cams = sample_cameras(rng, env, strategy, self.camera_names, self.ranges, self.camera)
        ground = sample_ground_look(rng, c.ground_recolor)  # drawn last: the draws above do not depend on it
        weather, veg_tint, sun_turn = sample_weather(np.random.default_rng([c.seed, placement, reroll + 1,
                                                                            WEATHER_STREAM]),
                                                     c.cloud_cover_max, c.look_randomise)
        ground = replace(ground, vegetation_tint=veg_tint)
        stamp_ns = int(round(step * 1e9 / c.rate_hz))
        zebras = scene_zebras(herd, lib.morphs, lib.clip_names, self.pool.coat_seed[herd.ids], box_center, box_size,
                              self.species)
        return build_scene(step, placement, reroll, c.seed, stamp_ns, self._world_info, str(lib.manifest["digest"]),
                           zebras, herd, rotate_sun(lighting_for(tod, doy, c.latitude_deg), sun_turn), cams, ground,
                           weather, self._datum)
