"""Zebra skeleton: joint hierarchy, body proportions and forward kinematics.

Every joint's bind orientation is the asset frame (x forward, y left, z up), so a joint's local
rotation is expressed in axes everyone can picture: rotation about +y swings a hanging leg backwards
and tips a head nose-down, rotation about +z turns left, rotation about +x rolls towards the right.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.rotations import rigid

FloatArray = NDArray[np.float64]

# (name, parent). Parents come before children, so forward kinematics is one pass in this order.
JOINTS: tuple[tuple[str, str | None], ...] = (
    ("root", None),
    ("pelvis", "root"),
    ("spine_1", "pelvis"),
    ("spine_2", "spine_1"),
    ("chest", "spine_2"),
    ("neck_1", "chest"),
    ("neck_2", "neck_1"),
    ("head", "neck_2"),
    ("jaw", "head"),
    ("ear_l", "head"),
    ("ear_r", "head"),
    ("tail_1", "pelvis"),
    ("tail_2", "tail_1"),
    ("tail_3", "tail_2"),
    ("shoulder_fl", "chest"),
    ("elbow_fl", "shoulder_fl"),
    ("knee_fl", "elbow_fl"),
    ("fetlock_fl", "knee_fl"),
    ("hoof_fl", "fetlock_fl"),
    ("shoulder_fr", "chest"),
    ("elbow_fr", "shoulder_fr"),
    ("knee_fr", "elbow_fr"),
    ("fetlock_fr", "knee_fr"),
    ("hoof_fr", "fetlock_fr"),
    ("hip_hl", "pelvis"),
    ("stifle_hl", "hip_hl"),
    ("hock_hl", "stifle_hl"),
    ("fetlock_hl", "hock_hl"),
    ("hoof_hl", "fetlock_hl"),
    ("hip_hr", "pelvis"),
    ("stifle_hr", "hip_hr"),
    ("hock_hr", "stifle_hr"),
    ("fetlock_hr", "hock_hr"),
    ("hoof_hr", "fetlock_hr"),
)
JOINT_NAMES: tuple[str, ...] = tuple(n for n, _ in JOINTS)
JOINT_INDEX: dict[str, int] = {n: i for i, n in enumerate(JOINT_NAMES)}
PARENTS: NDArray[np.int64] = np.array([-1 if p is None else JOINT_INDEX[p] for _, p in JOINTS])
LEGS: tuple[str, ...] = ("fl", "fr", "hl", "hr")
LEG_CHAINS: dict[str, tuple[str, ...]] = {
    "fl": ("shoulder_fl", "elbow_fl", "knee_fl", "fetlock_fl", "hoof_fl"),
    "fr": ("shoulder_fr", "elbow_fr", "knee_fr", "fetlock_fr", "hoof_fr"),
    "hl": ("hip_hl", "stifle_hl", "hock_hl", "fetlock_hl", "hoof_hl"),
    "hr": ("hip_hr", "stifle_hr", "hock_hr", "fetlock_hr", "hoof_hr"),
}


@dataclass(frozen=True)
class Morph:
    """Body proportions of one kind of zebra, in metres.

    ``withers_height`` is the shoulder height of a standing animal; ``body_length`` runs from the
    point of the shoulder to the point of the buttock (the head and neck come on top of it).
    """

    name: str
    withers_height: float = 1.30
    body_length: float = 1.45
    leg_fraction: float = 0.56  # elbow height over withers height: longer in foals
    girth_radius: float = 0.27  # half the body depth at the belly
    neck_length: float = 0.72
    head_length: float = 0.56
    ear_length: float = 0.17
    ear_width: float = 0.045
    tail_length: float = 0.62
    mane_height: float = 0.08
    stripe_period: float = 0.11  # metres between black stripes on the barrel
    white_belly: bool = False
    extra: dict[str, float] = field(default_factory=dict)
    species: str = "zebra"  # what the labels call it: only "zebra" is ever a zebra label
    coat: str = "stripes"  # stripes, brindle (faint bands), solid, network (giraffe) or patches (cattle)
    coat_rgb: tuple[float, float, float] = (0.9, 0.88, 0.82)  # base hair colour (other species)
    coat_alt_rgb: tuple[float, float, float] = (0.1, 0.1, 0.1)  # bands, patches, points (other species)
    # The shapes that tell other species from a zebra at a glance (a zebra has none of them: its horn and snout
    # parts are tucked inside its head, so every morph shares one mesh topology).
    neck_pitch_deg: float | None = None  # neck rise above horizontal; None = the zebra's (about 57 degrees)
    head_pitch_deg: float = 52.0  # face line below horizontal
    leg_girth: float = 1.0  # thickness of the legs against a zebra's, most below the elbow (elephant: columns)
    ear_droop: float = 0.0  # 0 = ears up, 1 = flaps hanging down the side of the head (elephant)
    horn: str = "none"  # a pair of horns or tusks, one of HORNS
    horn_length: float = 0.0  # along each horn's curve, metres
    horn_rgb: tuple[float, float, float] = (0.11, 0.10, 0.09)  # horns (dark keratin), tusks (ivory)
    snout: str = "none"  # a trunk or a nasal horn, one of SNOUTS
    snout_length: float = 0.0  # metres

    def validate(self) -> None:
        """Raise :class:`ParameterError` for proportions no animal of its species has."""
        if self.coat not in COATS:
            raise ParameterError(f"morph.{self.name}.coat", self.coat, f"one of {COATS}")
        if self.horn not in HORNS:
            raise ParameterError(f"morph.{self.name}.horn", self.horn, f"one of {HORNS}")
        if self.snout not in SNOUTS:
            raise ParameterError(f"morph.{self.name}.snout", self.snout, f"one of {SNOUTS}")
        shape = {"head_pitch_deg": (0.0, 90.0), "leg_girth": (0.5, 4.0), "ear_droop": (0.0, 1.0),
                 "horn_length": (0.0, 2.0), "snout_length": (0.0, 2.5)}
        if self.neck_pitch_deg is not None:
            shape["neck_pitch_deg"] = (0.0, 90.0)
        for name, (lo, hi) in shape.items():
            if not lo <= getattr(self, name) <= hi:
                raise ParameterError(f"morph.{self.name}.{name}", getattr(self, name), f"[{lo}, {hi}]")
        for name, style in (("horn", self.horn), ("snout", self.snout)):
            if (style == "none") != (getattr(self, f"{name}_length") == 0.0):
                raise ParameterError(f"morph.{self.name}.{name}_length", getattr(self, f"{name}_length"),
                                     f"0 exactly when {name} is 'none' (it is {style!r})")
        if self.species != "zebra":  # other species: any quadruped the skeleton can carry
            for name in ("withers_height", "body_length", "girth_radius", "neck_length", "head_length"):
                if not 0.1 <= getattr(self, name) <= 3.5:
                    raise ParameterError(f"morph.{self.name}.{name}", getattr(self, name), "[0.1, 3.5] m")
            return
        if self.horn != "none" or self.snout != "none":
            raise ParameterError(f"morph.{self.name}.horn", self.horn, "'none' with snout 'none' on a zebra")
        checks = {
            "withers_height": (0.5, 1.7),
            "body_length": (0.6, 2.0),
            "leg_fraction": (0.4, 0.7),
            "girth_radius": (0.1, 0.4),
            "neck_length": (0.3, 1.0),
            "head_length": (0.3, 0.8),
            "ear_length": (0.05, 0.35),
            "tail_length": (0.2, 1.0),
            "stripe_period": (0.03, 0.3),
        }
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise ParameterError(f"morph.{self.name}.{name}", v, f"[{lo}, {hi}] m")


# Plains zebra (Equus quagga): ~1.3 m at the withers, broad stripes, shadow stripes on the rump.
PLAINS = Morph(name="plains")
# Grévy's zebra (Equus grevyi): taller, longer head, big round ears, narrow stripes, white belly.
GREVY = Morph(
    name="grevy",
    withers_height=1.45,
    body_length=1.62,
    girth_radius=0.29,
    neck_length=0.80,
    head_length=0.66,
    ear_length=0.24,
    ear_width=0.07,
    tail_length=0.68,
    mane_height=0.10,
    stripe_period=0.065,
    white_belly=True,
)
# A foal of a few months: long legs, short body, big head and ears for its size.
FOAL = Morph(
    name="foal",
    withers_height=0.95,
    body_length=0.85,
    leg_fraction=0.64,
    girth_radius=0.17,
    neck_length=0.45,
    head_length=0.40,
    ear_length=0.14,
    ear_width=0.04,
    tail_length=0.38,
    mane_height=0.07,
    stripe_period=0.075,
)
ZEBRA_MORPHS: tuple[str, ...] = ("plains", "grevy", "foal")
"""The zebra morphs, first in the asset: their indices are the pool's ``morph_weights``."""
COATS = ("stripes", "brindle", "solid", "network", "patches")
HORNS = ("none", "boss", "curved", "lyre", "ossicone", "tusk", "nasal")
"""Horn pairs: none, boss (a buffalo's: out, down and up from a heavy base), curved (out and up: wildebeest,
cattle), lyre (up and back: impala), ossicone (a giraffe's short knobs), tusk (an elephant's, from the mouth),
nasal (a rhino's rear horn, on the face's midline)."""
SNOUTS = ("none", "trunk", "horn")
"""What grows from the muzzle: none, trunk (an elephant's, hanging down) or horn (a rhino's front horn)."""

# Other species of the savanna and farmland, on the same skeleton and clips: never labelled as zebra. Sizes from
# field guides (shoulder height, body length); coats as they read from a distance.
WILDEBEEST = Morph(name="wildebeest", species="wildebeest", withers_height=1.35, body_length=1.55, leg_fraction=0.55,
                   girth_radius=0.32, neck_length=0.55, head_length=0.62, ear_length=0.13, ear_width=0.05,
                   tail_length=0.75, mane_height=0.14, stripe_period=0.22, coat="brindle",
                   coat_rgb=(0.36, 0.34, 0.32), coat_alt_rgb=(0.20, 0.19, 0.18), neck_pitch_deg=45.0,
                   horn="curved", horn_length=0.45)
IMPALA = Morph(name="impala", species="impala", withers_height=0.90, body_length=1.05, leg_fraction=0.62,
               girth_radius=0.19, neck_length=0.48, head_length=0.36, ear_length=0.15, ear_width=0.05,
               tail_length=0.30, mane_height=0.02, white_belly=True, coat="solid", coat_rgb=(0.64, 0.40, 0.22),
               coat_alt_rgb=(0.12, 0.09, 0.07), horn="lyre", horn_length=0.50)
GIRAFFE = Morph(name="giraffe", species="giraffe", withers_height=2.9, body_length=1.9, leg_fraction=0.62,
                girth_radius=0.42, neck_length=1.9, head_length=0.62, ear_length=0.18, ear_width=0.06,
                tail_length=1.0, mane_height=0.05, stripe_period=0.30, coat="network", coat_rgb=(0.86, 0.80, 0.64),
                coat_alt_rgb=(0.52, 0.29, 0.13), horn="ossicone", horn_length=0.15, horn_rgb=(0.30, 0.22, 0.14))
BUFFALO = Morph(name="buffalo", species="buffalo", withers_height=1.5, body_length=1.95, leg_fraction=0.46,
                girth_radius=0.48, neck_length=0.42, head_length=0.60, ear_length=0.20, ear_width=0.10,
                tail_length=0.75, mane_height=0.02, coat="solid", coat_rgb=(0.10, 0.09, 0.085),
                coat_alt_rgb=(0.05, 0.045, 0.04), neck_pitch_deg=30.0, head_pitch_deg=60.0, leg_girth=1.4,
                horn="boss", horn_length=0.75, horn_rgb=(0.13, 0.12, 0.11))
CATTLE = Morph(name="cattle", species="cattle", withers_height=1.4, body_length=1.75, leg_fraction=0.50,
               girth_radius=0.42, neck_length=0.50, head_length=0.55, ear_length=0.18, ear_width=0.08,
               tail_length=0.85, mane_height=0.02, stripe_period=0.45, coat="patches", coat_rgb=(0.88, 0.86, 0.82),
               coat_alt_rgb=(0.08, 0.07, 0.07), neck_pitch_deg=40.0, leg_girth=1.2, horn="curved", horn_length=0.30,
               horn_rgb=(0.70, 0.66, 0.58))
DONKEY = Morph(name="donkey", species="donkey", withers_height=1.15, body_length=1.25, leg_fraction=0.55,
               girth_radius=0.26, neck_length=0.55, head_length=0.56, ear_length=0.28, ear_width=0.07,
               tail_length=0.50, mane_height=0.07, white_belly=True, coat="solid", coat_rgb=(0.46, 0.43, 0.41),
               coat_alt_rgb=(0.16, 0.14, 0.13))
# African elephant (Loxodonta africana) and white rhino (Ceratotherium simum): the two big grey animals a survey
# drone sees most next to zebras. Sizes of a cow elephant and an adult rhino; their grey skins often read as red or
# brown from the dust they wallow in, which the per-individual colour variation covers only in part.
ELEPHANT = Morph(name="elephant", species="elephant", withers_height=2.8, body_length=3.1, leg_fraction=0.50,
                 girth_radius=0.80, neck_length=0.45, head_length=0.95, ear_length=1.05, ear_width=0.42,
                 tail_length=1.1, mane_height=0.0, coat="solid", coat_rgb=(0.40, 0.38, 0.36),
                 coat_alt_rgb=(0.26, 0.25, 0.24), neck_pitch_deg=20.0, head_pitch_deg=75.0, leg_girth=2.4,
                 ear_droop=1.0, horn="tusk", horn_length=0.8, horn_rgb=(0.82, 0.77, 0.64), snout="trunk",
                 snout_length=1.6)
RHINO = Morph(name="rhino", species="rhino", withers_height=1.65, body_length=2.4, leg_fraction=0.40,
              girth_radius=0.60, neck_length=0.50, head_length=0.80, ear_length=0.20, ear_width=0.07,
              tail_length=0.60, mane_height=0.0, coat="solid", coat_rgb=(0.46, 0.43, 0.39),
              coat_alt_rgb=(0.30, 0.28, 0.26), neck_pitch_deg=22.0, head_pitch_deg=45.0, leg_girth=2.1,
              horn="nasal", horn_length=0.25, horn_rgb=(0.36, 0.33, 0.29), snout="horn", snout_length=0.55)
OTHER_SPECIES: tuple[str, ...] = ("wildebeest", "impala", "giraffe", "buffalo", "cattle", "donkey", "elephant", "rhino")
MORPHS: dict[str, Morph] = {m.name: m for m in (PLAINS, GREVY, FOAL, WILDEBEEST, IMPALA, GIRAFFE, BUFFALO, CATTLE,
                                                DONKEY, ELEPHANT, RHINO)}
"""Every body the asset bakes: the zebra morphs, then one per other species (in :data:`OTHER_SPECIES` order)."""


def get_morph(name: str) -> Morph:
    """Look a built-in morph up by name."""
    try:
        return MORPHS[name]
    except KeyError:
        raise ParameterError("morph", name, f"one of {sorted(MORPHS)}") from None


def bind_positions(m: Morph) -> FloatArray:
    """Joint positions (J, 3) of the standing bind pose in the asset frame, metres."""
    m.validate()
    h = m.withers_height
    half = m.body_length / 2
    back = h - 0.17 * h / 1.3  # spine line, a little below the withers' top
    elbow = m.leg_fraction * h
    knee = 0.32 * h
    fet = 0.10 * h
    hoof = 0.025 * h / 1.3 + 0.012
    leg_y = 0.55 * m.girth_radius
    s = h / 1.3  # generic scale for small offsets
    if m.neck_pitch_deg is None:
        neck_dir = np.array([0.55, 0.0, 0.835])  # a zebra's neck rises ~57 degrees from horizontal
    else:
        neck_dir = np.array([np.cos(np.radians(m.neck_pitch_deg)), 0.0, np.sin(np.radians(m.neck_pitch_deg))])
    p: dict[str, tuple[float, float, float]] = {
        "root": (0.0, 0.0, 0.0),
        "pelvis": (-half * 0.70, 0.0, back + 0.02 * s),
        "spine_1": (-half * 0.25, 0.0, back - 0.01 * s),
        "spine_2": (half * 0.20, 0.0, back - 0.01 * s),
        "chest": (half * 0.66, 0.0, back),
    }
    n1 = np.array([half * 0.95, 0.0, back + 0.14 * s])
    n2 = n1 + neck_dir * m.neck_length * 0.5
    hd = n1 + neck_dir * m.neck_length
    p["neck_1"] = tuple(n1)
    p["neck_2"] = tuple(n2)
    p["head"] = tuple(hd)
    p["jaw"] = tuple(hd + np.array([0.10, 0.0, -0.12]) * (m.head_length / 0.56))
    ey = 0.055 * m.head_length / 0.56
    p["ear_l"] = tuple(hd + np.array([-0.02 * s, ey, 0.05 * s]))
    p["ear_r"] = tuple(hd + np.array([-0.02 * s, -ey, 0.05 * s]))
    tb = np.array([-half * 1.07, 0.0, back + 0.08 * s])
    seg = m.tail_length / 3.2
    p["tail_1"] = tuple(tb)
    p["tail_2"] = tuple(tb + np.array([-0.25 * seg, 0.0, -0.97 * seg]))
    p["tail_3"] = tuple(tb + np.array([-0.35 * seg, 0.0, -1.97 * seg]))
    fx = half * 0.74
    hx = -half * 0.62
    for side, sy in (("l", 1.0), ("r", -1.0)):
        y = sy * leg_y
        p[f"shoulder_f{side}"] = (fx + 0.06 * s, y, elbow + 0.26 * s)
        p[f"elbow_f{side}"] = (fx - 0.08 * s, y * 1.05, elbow)
        p[f"knee_f{side}"] = (fx - 0.05 * s, y, knee)
        p[f"fetlock_f{side}"] = (fx - 0.04 * s, y, fet)
        p[f"hoof_f{side}"] = (fx + 0.01 * s, y, hoof)
        p[f"hip_h{side}"] = (hx + 0.02 * s, y * 1.05, back - 0.04 * s)
        p[f"stifle_h{side}"] = (hx + 0.14 * s, y * 1.15, elbow - 0.02 * s)
        p[f"hock_h{side}"] = (hx - 0.10 * s, y, knee + 0.09 * s)
        p[f"fetlock_h{side}"] = (hx - 0.07 * s, y, fet)
        p[f"hoof_h{side}"] = (hx - 0.03 * s, y, hoof)
    return np.array([p[n] for n in JOINT_NAMES], dtype=np.float64)


def forward_kinematics(bind: FloatArray, local_rot: FloatArray, root: FloatArray) -> FloatArray:
    """Global joint transforms from local rotations.

    Args:
        bind: (J, 3) bind-pose joint positions.
        local_rot: (..., J, 3, 3) rotation of each joint relative to its parent, in bind-aligned axes.
        root: (..., 4, 4) extra transform of the root joint (in-place clips move it only up and down,
            and tip it, e.g. when lying down).

    Returns:
        (..., J, 4, 4) joint-to-asset transforms. With identity rotations and root they are pure
        translations to ``bind``.
    """
    local_rot = np.asarray(local_rot, dtype=np.float64)
    batch = local_rot.shape[:-3]
    n = len(JOINT_NAMES)
    out = np.zeros(batch + (n, 4, 4))
    offsets = bind - np.where(PARENTS[:, None] >= 0, bind[np.maximum(PARENTS, 0)], 0.0)
    for j in range(n):
        local = rigid(local_rot[..., j, :, :], np.broadcast_to(offsets[j], batch + (3,)))
        parent = root if PARENTS[j] < 0 else out[..., PARENTS[j], :, :]
        out[..., j, :, :] = parent @ local
    return out
