"""In-place animation clips, as joint rotations per frame.

A clip is a function of the phase ``t`` in [0, 1) that returns local joint rotations (yaw, pitch,
roll in degrees, in the joint's bind-aligned axes) and a root pitch. Looping clips are periodic in
``t``, so their last frame flows into the first. The root's height is not animated by hand: after
posing, :mod:`zebra_sim_ros.zebra.asset` lowers or raises each frame so the lowest point of the mesh
touches the ground, which keeps standing hooves at z = 0 and puts a lying zebra on its belly.

Gaits follow the footfall orders of real equids (phase of each leg's swing, as a fraction of the
stride): walk is the four-beat lateral sequence hind-left, fore-left, hind-right, fore-right a
quarter apart; trot moves diagonal pairs together half a stride apart; the transverse gallop lands
hind-left, hind-right, fore-left, fore-right.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.zebra.skeleton import JOINT_INDEX, JOINT_NAMES, LEG_CHAINS

FloatArray = NDArray[np.float64]
FPS = 30.0


@dataclass(frozen=True)
class Pose:
    """Local rotations (J, 3) as (yaw, pitch, roll) degrees, and the root pitch in degrees."""

    angles: FloatArray
    root_pitch: float = 0.0
    lift: float = 0.0  # metres above ground contact (a gallop's moment of suspension)


def _new() -> FloatArray:
    return np.zeros((len(JOINT_NAMES), 3))


def _set(a: FloatArray, joint: str, yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> None:
    a[JOINT_INDEX[joint]] += (yaw, pitch, roll)


def _wave(t: float, cycles: float, phase: float = 0.0) -> float:
    return float(np.sin(2 * np.pi * (cycles * t + phase)))


def _smooth(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x * x * (3 - 2 * x)


def _breathe(a: FloatArray, t: float, cycles: int, amount: float = 1.0) -> None:
    b = _wave(t, cycles)
    _set(a, "spine_1", pitch=0.6 * amount * b)
    _set(a, "spine_2", pitch=-0.6 * amount * b)


def _tail_idle(a: FloatArray, t: float, cycles: int, amp: float = 6.0) -> None:
    for k, j in enumerate(("tail_1", "tail_2", "tail_3")):
        _set(a, j, yaw=amp * (1 + 0.5 * k) * _wave(t, cycles, -0.12 * k))


def _ears(a: FloatArray, t: float, cycles: int, amp: float = 10.0) -> None:
    _set(a, "ear_l", yaw=amp * _wave(t, cycles), pitch=4 * _wave(t, cycles, 0.3))
    _set(a, "ear_r", yaw=-amp * _wave(t, cycles, 0.5), pitch=4 * _wave(t, cycles, 0.8))


def _head_down(a: FloatArray, amount: float, reach: float) -> None:
    """Lower the neck and head; ``reach`` 1 brings the muzzle to the grass."""
    _set(a, "chest", pitch=5 * amount)
    _set(a, "neck_1", pitch=(86 + 18 * reach) * amount)
    _set(a, "neck_2", pitch=(12 + 6 * reach) * amount)
    _set(a, "head", pitch=-(62 + 6 * reach) * amount)


def idle(t: float) -> Pose:
    """Standing at rest: breathing, small head and ear movements, a lazy tail."""
    a = _new()
    _breathe(a, t, 4)
    _set(a, "neck_1", pitch=3 * _wave(t, 1), yaw=4 * _wave(t, 1, 0.25))
    _set(a, "head", pitch=4 * _wave(t, 2, 0.1))
    _ears(a, t, 2)
    _tail_idle(a, t, 1)
    return Pose(a)


def graze(t: float) -> Pose:
    """Head down at the grass, cropping: the neck sways and the jaw chews."""
    a = _new()
    _breathe(a, t, 5)
    _head_down(a, 1.0, 1.0)
    _set(a, "neck_1", yaw=10 * _wave(t, 1))
    _set(a, "neck_2", pitch=3 * _wave(t, 3))
    _set(a, "jaw", pitch=-7 * max(0.0, _wave(t, 10)))
    _ears(a, t, 3, 8)
    _tail_idle(a, t, 2)
    # One fore leg a little forward, as grazing horses stand.
    _set(a, "shoulder_fl", pitch=-6)
    _set(a, "knee_fl", pitch=4)
    return Pose(a)


def drink(t: float) -> Pose:
    """Fore legs splayed, muzzle down to the water, swallowing."""
    a = _new()
    _breathe(a, t, 4)
    _head_down(a, 1.0, 1.15)
    _set(a, "head", pitch=2 * _wave(t, 6))
    _set(a, "jaw", pitch=-3 * max(0.0, _wave(t, 6)))
    for side, s in (("l", 1.0), ("r", -1.0)):
        _set(a, f"shoulder_f{side}", roll=-6 * s, pitch=-5)
        _set(a, f"knee_f{side}", pitch=3)
    _ears(a, t, 2, 6)
    _tail_idle(a, t, 2)
    return Pose(a)


def look_around(t: float) -> Pose:
    """Head up and alert, turning left then right."""
    a = _new()
    _breathe(a, t, 4)
    turn = _wave(t, 1)
    _set(a, "neck_1", yaw=30 * turn, pitch=-6)
    _set(a, "neck_2", yaw=14 * turn, pitch=-4)
    _set(a, "head", yaw=16 * _wave(t, 1, -0.05), roll=-6 * turn)
    _set(a, "ear_l", yaw=-25 * turn)
    _set(a, "ear_r", yaw=-25 * turn)
    _tail_idle(a, t, 1)
    return Pose(a)


def tail_swish(t: float) -> Pose:
    """Swatting flies: wide fast tail swings, a skin twitch of the barrel and ears."""
    a = _new()
    _breathe(a, t, 2)
    for k, j in enumerate(("tail_1", "tail_2", "tail_3")):
        _set(a, j, yaw=(22 + 12 * k) * _wave(t, 3, -0.08 * k), pitch=-10 * k * abs(_wave(t, 3)))
    _ears(a, t, 2, 12)
    _set(a, "head", yaw=5 * _wave(t, 1))
    return Pose(a)


def head_shake(t: float) -> Pose:
    """Three quick shakes of the head and neck, ears flapping."""
    a = _new()
    env = np.sin(np.pi * t) ** 2  # shakes fade in and out, so the clip loops at rest
    _set(a, "neck_2", roll=18 * env * _wave(t, 3), yaw=8 * env * _wave(t, 3, 0.25))
    _set(a, "head", roll=26 * env * _wave(t, 3, -0.08))
    _set(a, "ear_l", roll=-30 * env * _wave(t, 3, -0.2))
    _set(a, "ear_r", roll=-30 * env * _wave(t, 3, -0.2))
    _tail_idle(a, t, 1)
    return Pose(a)


@dataclass(frozen=True)
class Gait:
    """A symmetric gait: per-leg swing phase offsets and the stride shape."""

    offsets: dict[str, float]
    duty: float  # fraction of the stride a hoof is on the ground
    swing_fore: float  # degrees of fore-leg swing, peak to centre
    swing_hind: float
    flex: float  # degrees of carpus / hock flexion at mid-swing
    neck: float  # degrees of head nod
    pitch: float = 0.0  # degrees of body rocking (gallop)


WALK = Gait({"hl": 0.0, "fl": 0.25, "hr": 0.5, "fr": 0.75}, 0.62, 14, 16, 55, 5)
TROT = Gait({"fl": 0.0, "hr": 0.0, "fr": 0.5, "hl": 0.5}, 0.45, 20, 22, 75, 3)
GALLOP = Gait({"hl": 0.0, "hr": 0.1, "fl": 0.35, "fr": 0.45}, 0.32, 30, 30, 95, 8, pitch=4)


def _gait_pose(gait: Gait, t: float) -> Pose:
    a = _new()
    for leg, chain in LEG_CHAINS.items():
        fore = leg.startswith("f")
        amp = gait.swing_fore if fore else gait.swing_hind
        p = (t - gait.offsets[leg]) % 1.0
        swing = 1.0 - gait.duty
        if p < swing:  # lifted: swing forward from back (+amp) to front (-amp) with a smooth S
            s = p / swing
            angle = amp * (1 - 2 * _smooth(s))
            lift = np.sin(np.pi * s)
        else:  # planted: the body moves over the hoof, leg goes from front to back at constant speed
            s = (p - swing) / gait.duty
            angle = amp * (-1 + 2 * s)
            lift = 0.0
        _set(a, chain[0], pitch=angle)
        if fore:
            _set(a, chain[1], pitch=-0.25 * gait.flex * lift)
            _set(a, chain[2], pitch=gait.flex * lift)  # carpus folds the cannon backwards
            _set(a, chain[3], pitch=0.6 * gait.flex * lift)
        else:
            _set(a, chain[1], pitch=0.40 * gait.flex * lift)  # stifle folds the gaskin back and up
            _set(a, chain[2], pitch=-0.45 * gait.flex * lift)  # hock brings the cannon forward
            _set(a, chain[3], pitch=0.5 * gait.flex * lift)
            _set(a, chain[4], pitch=0.2 * gait.flex * lift)
    _set(a, "neck_1", pitch=gait.neck * _wave(t, 2, 0.1))
    _set(a, "head", pitch=-0.5 * gait.neck * _wave(t, 2, 0.1))
    _set(a, "tail_1", pitch=-15 - 10 * (gait.pitch > 0), yaw=4 * _wave(t, 1))
    _set(a, "tail_2", pitch=-8 * (gait.pitch > 0), yaw=6 * _wave(t, 1, -0.1))
    _ears(a, t, 1, 4)
    lift_body = 0.0
    if gait.pitch:
        lift_body = 0.06 * max(0.0, _wave(t, 1, 0.55))
    return Pose(a, root_pitch=gait.pitch * _wave(t, 1, 0.15), lift=lift_body)


def walk(t: float) -> Pose:
    """Four-beat walk in place."""
    return _gait_pose(WALK, t)


def trot(t: float) -> Pose:
    """Two-beat trot in place (diagonal pairs)."""
    return _gait_pose(TROT, t)


def gallop(t: float) -> Pose:
    """Transverse gallop in place, with a moment of suspension."""
    return _gait_pose(GALLOP, t)


def _fold_legs(a: FloatArray, fore: float, hind: float) -> None:
    """Fold the fore and hind legs under the body (sternal recumbency), each amount in [0, 1]."""
    for side in ("l", "r"):
        _set(a, f"shoulder_f{side}", pitch=-35 * fore)
        _set(a, f"elbow_f{side}", pitch=-20 * fore)
        _set(a, f"knee_f{side}", pitch=150 * fore)
        _set(a, f"fetlock_f{side}", pitch=-20 * fore)
        _set(a, f"hip_h{side}", pitch=-60 * hind, roll=(10 if side == "l" else -10) * hind)
        _set(a, f"stifle_h{side}", pitch=-30 * hind)
        _set(a, f"hock_h{side}", pitch=-125 * hind)
        _set(a, f"fetlock_h{side}", pitch=-10 * hind)
    _set(a, "tail_1", pitch=-20 * hind)


def lie_down(t: float) -> Pose:
    """From standing to lying: fore knees fold first, then the hind quarters (does not loop)."""
    a = _new()
    fore = _smooth(t / 0.6)
    hind = _smooth((t - 0.3) / 0.6)
    _fold_legs(a, fore, hind)
    _set(a, "neck_1", pitch=12 * _smooth(t) + 10 * np.sin(np.pi * t))
    return Pose(a, root_pitch=8 * (fore - hind))


def rest(t: float) -> Pose:
    """Lying on the chest, legs folded, breathing and dozing."""
    a = _new()
    _fold_legs(a, 1.0, 1.0)
    _set(a, "neck_1", pitch=12)
    _breathe(a, t, 4, 1.5)
    _set(a, "neck_1", pitch=6 * _wave(t, 1), yaw=10 * _wave(t, 1, 0.3))
    _set(a, "head", pitch=5 * _wave(t, 2))
    _ears(a, t, 2, 8)
    _tail_idle(a, t, 1, 3)
    return Pose(a)


@dataclass(frozen=True)
class Clip:
    """An in-place clip: ``frames`` frames at ``FPS``, looping or not."""

    name: str
    frames: int
    loop: bool
    fn: Callable[[float], Pose]
    doc: str

    def phase(self, frame: int) -> float:
        """Phase in [0, 1] of ``frame``: looping clips never reach 1, others end on it."""
        if not 0 <= frame < self.frames:
            raise ParameterError(f"{self.name}.frame", frame, f"0..{self.frames - 1}")
        return frame / self.frames if self.loop else frame / (self.frames - 1)

    def pose(self, frame: int) -> Pose:
        """The pose of frame ``frame``."""
        return self.fn(self.phase(frame))


def _clip(name: str, frames: int, loop: bool, fn: Callable[[float], Pose]) -> Clip:
    return Clip(name, frames, loop, fn, (fn.__doc__ or "").strip().splitlines()[0])


# 888 frames in all, as many as the paper's purchased model had.
CLIPS: tuple[Clip, ...] = (
    _clip("idle", 120, True, idle),
    _clip("graze", 150, True, graze),
    _clip("walk", 36, True, walk),
    _clip("trot", 24, True, trot),
    _clip("gallop", 18, True, gallop),
    _clip("look_around", 120, True, look_around),
    _clip("tail_swish", 60, True, tail_swish),
    _clip("head_shake", 45, True, head_shake),
    _clip("lie_down", 75, False, lie_down),
    _clip("rest", 120, True, rest),
    _clip("drink", 120, True, drink),
)
CLIP_INDEX: dict[str, int] = {c.name: i for i, c in enumerate(CLIPS)}
# Clips in which the animal stands on all four hooves the whole time.
STANDING_CLIPS: tuple[str, ...] = ("idle", "graze", "look_around", "tail_swish", "head_shake", "drink")
GAIT_CLIPS: dict[str, Gait] = {"walk": WALK, "trot": TROT, "gallop": GALLOP}


def get_clip(name: str) -> Clip:
    """Look a clip up by name."""
    try:
        return CLIPS[CLIP_INDEX[name]]
    except KeyError:
        raise ParameterError("clip", name, f"one of {[c.name for c in CLIPS]}") from None
