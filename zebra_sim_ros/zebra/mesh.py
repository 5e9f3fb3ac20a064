"""The zebra's skin: closed tubes swept along the bones, with UVs and skinning weights.

Each body part (barrel, neck, head, mane, tail, ears, legs, and the horns and snout of other species) is a
tube of elliptical rings around a smooth centre curve, closed at both ends by a fan, so every part is a
watertight, consistently wound (outward) surface; parts overlap where they join, as in most game-ready animal
models. Rings are skinned as a whole (weights from the ring centre's distance to the part's bones), which keeps the
cross-sections from collapsing when joints bend.

UVs are face-varying (one per triangle corner), so the mesh's vertices stay welded across the
texture seam. Each part owns a rectangle of the coat atlas; ``v`` runs upwards (OpenGL and USD).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.zebra.skeleton import JOINT_INDEX, LEG_CHAINS, Morph, bind_positions

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

PART_NAMES: tuple[str, ...] = (
    "barrel", "neck", "head", "mane", "tail", "ear_l", "ear_r", "leg_fl", "leg_fr", "leg_hl", "leg_hr",
    "horn_l", "horn_r", "snout",
)
"""Every morph has every part. A zebra's horns and snout are slivers a few millimetres across tucked inside its
head: never seen, but the topology (and so the texture atlas and the baked cache's face arrays) is one for all."""
# (rings, around) per part for each level of detail. LOD 0 is ~5k triangles, LOD 1 ~1.3k.
_RESOLUTION: dict[int, dict[str, tuple[int, int]]] = {
    0: {"barrel": (33, 24), "neck": (15, 16), "head": (17, 16), "mane": (13, 6), "tail": (13, 8),
        "ear": (7, 8), "leg": (23, 12), "horn": (11, 8), "snout": (15, 10)},
    1: {"barrel": (17, 12), "neck": (8, 8), "head": (9, 8), "mane": (7, 4), "tail": (7, 4),
        "ear": (4, 4), "leg": (12, 6), "horn": (6, 4), "snout": (8, 5)},
}
LODS: tuple[int, ...] = tuple(_RESOLUTION)
# Atlas rectangles (u0, v0, u1, v1) and whether the part's length runs along u (else along v).
_ATLAS: dict[str, tuple[tuple[float, float, float, float], bool]] = {
    "barrel": ((0.0, 0.55, 1.0, 1.0), True),
    "head": ((0.0, 0.30, 0.35, 0.55), True),
    "neck": ((0.35, 0.30, 0.65, 0.55), True),
    "mane": ((0.65, 0.30, 0.80, 0.55), True),
    "tail": ((0.80, 0.30, 1.0, 0.55), True),
    "leg_fl": ((0.0, 0.0, 0.125, 0.30), False),
    "leg_fr": ((0.125, 0.0, 0.25, 0.30), False),
    "leg_hl": ((0.25, 0.0, 0.375, 0.30), False),
    "leg_hr": ((0.375, 0.0, 0.5, 0.30), False),
    "ear_l": ((0.5, 0.0, 0.625, 0.30), False),
    "ear_r": ((0.625, 0.0, 0.75, 0.30), False),
    "horn_l": ((0.75, 0.0, 0.8125, 0.30), False),
    "horn_r": ((0.8125, 0.0, 0.875, 0.30), False),
    "snout": ((0.875, 0.0, 1.0, 0.30), False),
}
_ATLAS_PAD = 0.004  # keep texels of neighbouring parts from bleeding in under filtering


@dataclass(frozen=True)
class PartSpec:
    """A tube: control points with half-sizes, a reference 'up' for the rings, and its bones.

    ``ra`` is the half-size along the ring axis ``a`` (``up_ref`` made perpendicular to the curve);
    ``rb`` along ``b = tangent x a``. ``bones`` are (joint, start, end) segments whose distance to a
    ring centre sets that ring's weights.
    """

    name: str
    points: FloatArray
    ra: FloatArray
    rb: FloatArray
    up_ref: FloatArray
    bones: tuple[tuple[str, FloatArray, FloatArray], ...]
    falloff: float
    jaw: bool = False


@dataclass(frozen=True)
class PartGrid:
    """Where a part's vertices sit: ``grid[r, k]`` is the vertex of ring r, around-index k."""

    name: str
    grid: IntArray  # (R, n)
    cap_start: int
    cap_end: int
    rect: tuple[float, float, float, float]
    along_u: bool


@dataclass(frozen=True)
class ZebraMesh:
    """The bind-pose skin of one morph at one level of detail.

    Attributes:
        vertices: (V, 3) bind positions, metres, asset frame.
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        uv: (F, 3, 2) face-varying texture coordinates in [0, 1], v upwards.
        face_part: (F,) index into ``PART_NAMES``.
        joint_indices: (V, 4) skinning joints; joint_weights: (V, 4), rows sum to 1.
        parts: per-part vertex grids, for texture baking and keypoints.
    """

    vertices: FloatArray
    faces: IntArray
    uv: NDArray[np.float32]
    face_part: NDArray[np.int8]
    joint_indices: IntArray
    joint_weights: FloatArray
    parts: tuple[PartGrid, ...]

    def part(self, name: str) -> PartGrid:
        """The grid of the part called ``name``."""
        for p in self.parts:
            if p.name == name:
                return p
        raise ParameterError("part", name, f"one of {PART_NAMES}")


def _catmull_rom(points: FloatArray, samples_per_segment: int = 24) -> tuple[FloatArray, FloatArray]:
    """Dense samples of a uniform Catmull-Rom spline through ``points`` (C, D), and their parameter."""
    p = np.concatenate([points[:1], points, points[-1:]], axis=0)
    out = []
    params = []
    n_seg = len(points) - 1
    for i in range(n_seg):
        p0, p1, p2, p3 = p[i], p[i + 1], p[i + 2], p[i + 3]
        t = np.linspace(0.0, 1.0, samples_per_segment, endpoint=(i == n_seg - 1))[:, None]
        out.append(
            0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                   + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3)
        )
        params.append(i + t[:, 0])
    return np.concatenate(out), np.concatenate(params)


def _sweep(spec: PartSpec, n_rings: int, n_around: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Ring vertices (R, n, 3), ring centres (R, 3) and the two cap centres (2, 3) of a tube."""
    data = np.concatenate([spec.points, spec.ra[:, None], spec.rb[:, None]], axis=1)
    dense, _ = _catmull_rom(data)
    seg = np.linalg.norm(np.diff(dense[:, :3], axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.linspace(0.0, arc[-1], n_rings)
    rings = np.stack([np.interp(target, arc, dense[:, d]) for d in range(dense.shape[1])], axis=1)
    centres, ra, rb = rings[:, :3], np.maximum(rings[:, 3], 1e-3), np.maximum(rings[:, 4], 1e-3)
    tangent = np.gradient(centres, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    a = spec.up_ref[None, :] - (tangent @ spec.up_ref)[:, None] * tangent
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(tangent, a)
    theta = 2 * np.pi * np.arange(n_around) / n_around
    verts = (centres[:, None, :] + ra[:, None, None] * np.cos(theta)[None, :, None] * a[:, None, :]
             + rb[:, None, None] * np.sin(theta)[None, :, None] * b[:, None, :])
    # Caps sit a little beyond the end rings so the ends are domed, not flat (hooves excepted: flat).
    dome_start = 0.35 * min(ra[0], rb[0])
    dome_end = 0.0 if spec.name.startswith("leg") else 0.35 * min(ra[-1], rb[-1])
    caps = np.stack([centres[0] - tangent[0] * dome_start, centres[-1] + tangent[-1] * dome_end])
    return verts, centres, caps


def _segment_distance(p: FloatArray, s0: FloatArray, s1: FloatArray) -> FloatArray:
    d = s1 - s0
    t = np.clip(((p - s0) @ d) / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.asarray(np.linalg.norm(p - (s0 + t[:, None] * d), axis=1))


def _ring_weights(spec: PartSpec, centres: FloatArray) -> tuple[IntArray, FloatArray]:
    """Per-ring (R, 4) joints and weights: inverse-distance to the part's bones, top four."""
    dist = np.stack([_segment_distance(centres, s0, s1) for _, s0, s1 in spec.bones], axis=1)
    w = 1.0 / (dist + spec.falloff) ** 4
    joints = np.array([JOINT_INDEX[j] for j, _, _ in spec.bones])
    order = np.argsort(-w, axis=1)[:, :4]
    top_w = np.take_along_axis(w, order, axis=1)
    top_j = joints[order]
    if top_w.shape[1] < 4:
        pad = 4 - top_w.shape[1]
        top_w = np.pad(top_w, ((0, 0), (0, pad)))
        top_j = np.pad(top_j, ((0, 0), (0, pad)), constant_values=top_j[:, :1].max())
    top_w /= top_w.sum(axis=1, keepdims=True)
    return top_j, top_w


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v))


def _offset(base: FloatArray, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> FloatArray:
    return np.asarray(base + np.array([dx, dy, dz]))


# rings' 'up' references: along the body, to the left, straight up
_X, _Y, _Z = np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])


def _barrel(m: Morph, P: dict[str, FloatArray], s: float) -> PartSpec:  # noqa: N803 - P for 'position'
    """Barrel: rump to the point of the chest; centre line below the spine."""
    g = m.girth_radius
    pel, s1, s2, ch = P["pelvis"], P["spine_1"], P["spine_2"], P["chest"]
    rump_end = _offset(pel, -0.37 * s - 0.25 * (m.body_length - 1.45 * s), 0, -0.10 * s)
    chest_front = _offset(ch, 0.26 * s, 0, -0.10 * s)
    pts = np.array([rump_end, _offset(pel, -0.28 * s, 0, -0.11 * s), _offset(pel, -0.10 * s, 0, -0.13 * s),
                    _offset(pel, 0.08 * s, 0, -0.16 * s), _offset(s1, 0, 0, -0.20 * s), _offset(s2, 0, 0, -0.21 * s),
                    _offset(ch, 0, 0, -0.13 * s), _offset(ch, 0.16 * s, 0, -0.10 * s), chest_front])
    ra = g * np.array([0.25, 0.80, 0.95, 0.98, 1.0, 1.04, 1.04, 0.90, 0.35])
    rb = g * np.array([0.22, 0.70, 0.86, 0.88, 0.94, 0.98, 0.86, 0.70, 0.30])
    return PartSpec("barrel", pts, ra, rb, _Z, (
        ("pelvis", rump_end, s1), ("spine_1", s1, s2), ("spine_2", s2, ch), ("chest", ch, chest_front),
    ), 0.10 * s)


def _neck(m: Morph, P: dict[str, FloatArray], s: float) -> PartSpec:  # noqa: N803
    """Neck: from inside the chest up to just behind the poll."""
    g = m.girth_radius
    n1, n2, hd = P["neck_1"], P["neck_2"], P["head"]
    nd = _unit(hd - n1)
    neck_start = _offset(P["chest"], 0.08 * s, 0, -0.06 * s)
    neck_end = hd + nd * 0.06 * s
    pts = np.array([neck_start, n1, (n1 + n2) / 2, n2, (n2 + hd) / 2, hd, neck_end])
    ra = g * np.array([0.80, 0.78, 0.66, 0.56, 0.48, 0.42, 0.18])
    rb = g * np.array([0.62, 0.52, 0.44, 0.38, 0.33, 0.30, 0.14])
    return PartSpec("neck", pts, ra, rb, _X, (
        ("chest", neck_start, n1), ("neck_1", n1, n2), ("neck_2", n2, hd), ("head", hd, neck_end),
    ), 0.08 * s)


def _mane(m: Morph, P: dict[str, FloatArray], s: float, neck: PartSpec) -> PartSpec:  # noqa: N803
    """Mane: a stiff crest on the neck's top line, from the withers to between the ears (skinned as the neck)."""
    g = m.girth_radius
    n1, hd = P["neck_1"], P["head"]
    nd = _unit(hd - n1)
    dorsal = _unit(np.cross(nd, np.array([0, 1.0, 0])) * -1.0)
    if dorsal[2] < 0:
        dorsal = -dorsal
    u = np.linspace(0.0, 1.0, 6)
    axis = n1[None, :] * (1 - u[:, None]) + (hd + nd * 0.03 * s)[None, :] * u[:, None]
    axis[0] = _offset(P["chest"], 0.02 * s, 0, 0.02 * s)
    depth = g * np.interp(u, [0, 0.5, 1], [0.78, 0.56, 0.42])
    pts = axis + dorsal[None, :] * (depth + 0.3 * m.mane_height)[:, None]
    ra = np.interp(u, [0, 0.15, 0.85, 1], [0.2, 1.0, 1.0, 0.4]) * (0.5 * m.mane_height + 0.015 * s)
    rb = np.full(6, 0.018 * s)
    return PartSpec("mane", pts, ra, rb, dorsal, neck.bones, 0.08 * s)


def _head(m: Morph, P: dict[str, FloatArray], s: float) -> PartSpec:  # noqa: N803
    """Head: behind the poll to the nose, hanging ``head_pitch_deg`` (a zebra's ~50) below horizontal."""
    hdir = head_direction(m)
    L = m.head_length  # noqa: N806
    u = np.array([0.0, 0.12, 0.32, 0.55, 0.78, 0.93, 1.0])
    pts = (P["head"] - hdir * 0.08 * L)[None, :] + (u * L)[:, None] * hdir[None, :]
    pts[1:3] += np.array([0, 0, -0.03 * L])  # jowls hang a little below the face line
    ra = L * np.array([0.12, 0.20, 0.18, 0.13, 0.115, 0.10, 0.05])
    rb = L * np.array([0.10, 0.15, 0.14, 0.10, 0.095, 0.085, 0.045])
    return PartSpec("head", pts, ra, rb, _Z, (("head", pts[0], pts[-1]),), 0.05 * s, jaw=True)


def _ears(m: Morph, P: dict[str, FloatArray], s: float) -> list[PartSpec]:  # noqa: N803
    """Ears: leaf-shaped, up and a little outwards and back; left first. With ``ear_droop`` they turn down and
    back into flaps that lie flat against the side of the head (an elephant's at 1)."""
    specs = []
    d = m.ear_droop
    for side, sy in (("l", 1.0), ("r", -1.0)):
        base = P[f"ear_{side}"] + d * m.head_length * np.array([-0.10, 0.22 * sy, 0.0])
        edir = _unit(np.array([-0.15 - 0.25 * d, (0.38 + 0.12 * d) * sy, 1.0 - 2.0 * d]))
        u = np.array([0.0, 0.25, 0.55, 0.85, 1.0])
        pts = base[None, :] + (u * m.ear_length)[:, None] * edir[None, :]
        rb = m.ear_width * np.array([0.55, 1.0, 0.92, 0.50, 0.12])
        ra = 0.022 * s * np.array([1.0, 0.9, 0.7, 0.45, 0.2])
        up = _X if d < 0.5 else _Y  # the flat of a drooping flap faces sideways
        specs.append(PartSpec(f"ear_{side}", pts, ra, rb, up, ((f"ear_{side}", pts[0], pts[-1]),), 0.05 * s))
    return specs


def head_direction(m: Morph) -> FloatArray:
    """Unit vector along the face line, from the poll to the nose (asset frame)."""
    a = np.radians(-m.head_pitch_deg)
    return np.array([np.cos(a), 0.0, np.sin(a)])


# Horn curves: control points as multiples of ``horn_length`` from the horn's base, in (forward, out, up) axes of
# the asset frame ("out" is +y for the left horn, -y for the right), or of the face ("face": along the face line,
# out, and the face's outward normal); and radii at those points, as multiples of ``horn_length``.
_HORN_CURVES: dict[str, tuple[str, tuple[tuple[float, float, float], ...], tuple[float, ...]]] = {
    "boss": ("body", ((0.0, -0.05, 0.0), (0.03, 0.28, 0.03), (0.07, 0.52, -0.10), (0.10, 0.72, -0.06),
                      (0.10, 0.84, 0.12), (0.03, 0.80, 0.30)), (0.13, 0.12, 0.08, 0.06, 0.04, 0.015)),
    "curved": ("body", ((0.0, 0.0, 0.0), (0.02, 0.35, 0.06), (0.06, 0.58, 0.24), (0.04, 0.64, 0.50),
                        (-0.04, 0.55, 0.75)), (0.10, 0.08, 0.065, 0.045, 0.015)),
    "lyre": ("body", ((0.0, 0.0, 0.0), (-0.10, 0.08, 0.30), (-0.22, 0.18, 0.55), (-0.20, 0.16, 0.80),
                      (-0.28, 0.20, 1.0)), (0.07, 0.055, 0.045, 0.035, 0.012)),
    "ossicone": ("body", ((0.0, 0.0, 0.0), (-0.10, 0.12, 0.55), (-0.15, 0.18, 1.0)), (0.25, 0.20, 0.28)),
    "tusk": ("body", ((0.0, 0.0, 0.0), (0.30, 0.10, -0.40), (0.62, 0.16, -0.50), (0.92, 0.14, -0.32),
                      (1.05, 0.10, -0.12)), (0.085, 0.080, 0.070, 0.055, 0.02)),
    "nasal": ("face", ((0.0, 0.0, 0.0), (0.05, 0.0, 0.50), (-0.05, 0.0, 1.0)), (0.40, 0.30, 0.06)),
}


def _hidden(name: str, P: dict[str, FloatArray], hdir: FloatArray, m: Morph, at: float) -> PartSpec:  # noqa: N803
    """A sliver a few millimetres across, deep inside the head at ``at`` of the head's length: an absent part."""
    c = P["head"] + hdir * at * m.head_length
    pts = np.array([c, c + hdir * 0.02 * m.head_length])
    r = np.full(2, 0.004)
    return PartSpec(name, pts, r, r, _Z, (("head", pts[0], pts[-1]),), 0.05)


def _face_normal(hdir: FloatArray) -> FloatArray:
    """The face's outward normal: the face line turned 90 degrees up."""
    return np.array([-hdir[2], 0.0, hdir[0]])


def _horns(m: Morph, P: dict[str, FloatArray], s: float) -> list[PartSpec]:  # noqa: N803
    """A pair of horns (or tusks) of style ``m.horn``, left first; hidden slivers when it is 'none'."""
    hdir = head_direction(m)
    if m.horn == "none":
        return [_hidden("horn_l", P, hdir, m, 0.15), _hidden("horn_r", P, hdir, m, 0.20)]
    frame, ctrl, radii = _HORN_CURVES[m.horn]
    L, H = m.horn_length, m.head_length  # noqa: N806
    normal = _face_normal(hdir)
    specs = []
    for side, sy in (("l", 1.0), ("r", -1.0)):
        if m.horn == "tusk":  # from the upper jaw, either side of the trunk's root
            base = P["head"] + hdir * 0.62 * H + np.array([0.0, 0.12 * H * sy, 0.0]) - normal * 0.10 * H
        elif m.horn == "nasal":  # the rear horn, on the midline of the face (both sides coincide)
            base = P["head"] + hdir * 0.45 * H + normal * 0.10 * H
        else:  # on the poll, either side of it
            base = P["head"] + np.array([0.02 * s, 0.07 * H * sy, 0.06 * s])
        c = np.asarray(ctrl)
        if frame == "face":
            off = c[:, 0:1] * hdir + c[:, 1:2] * np.array([0.0, sy, 0.0]) + c[:, 2:3] * normal
        else:
            off = c * np.array([1.0, sy, 1.0])
        pts = base[None, :] + L * off
        r = L * np.asarray(radii)
        specs.append(PartSpec(f"horn_{side}", pts, r, r, _X if frame == "body" else _Y,
                              (("head", pts[0], pts[-1]),), 0.05 * s))
    return specs


def _snout(m: Morph, P: dict[str, FloatArray], s: float) -> PartSpec:  # noqa: N803
    """What grows from the muzzle: an elephant's trunk (down to near the ground, the tip curled forward) or a
    rhino's front horn; a hidden sliver when ``m.snout`` is 'none'."""
    hdir = head_direction(m)
    H, L = m.head_length, m.snout_length  # noqa: N806
    if m.snout == "none":
        return _hidden("snout", P, hdir, m, 0.25)
    normal = _face_normal(hdir)
    if m.snout == "trunk":  # skinned to the jaw so grazing lowers it with the head
        base = P["head"] + hdir * 0.78 * H
        u = np.array([0.0, 0.2, 0.45, 0.7, 0.88, 1.0])
        down = np.array([0.0, 0.0, -1.0])
        pts = base[None, :] + L * (u[:, None] * (0.85 * down + 0.15 * hdir)[None, :])
        pts[-2:] += L * np.array([[0.05, 0.0, 0.02], [0.12, 0.0, 0.06]])  # the tip curls forward
        r = H * np.array([0.20, 0.16, 0.12, 0.09, 0.075, 0.06])
        return PartSpec("snout", pts, r, r * 0.9, _X, (("head", base, pts[2]), ("jaw", pts[2], pts[-1])), 0.1 * s)
    base = P["head"] + hdir * 0.86 * H + normal * 0.06 * H  # a rhino's front horn, on the nose
    pts = base[None, :] + L * (np.array([0.0, 0.45, 0.8, 1.0])[:, None] * normal[None, :]
                               + np.array([0.0, 0.05, -0.02, -0.14])[:, None] * hdir[None, :])
    r = L * np.array([0.30, 0.20, 0.11, 0.03])
    return PartSpec("snout", pts, r, r, _Y, (("head", pts[0], pts[-1]),), 0.05 * s)


def _tail(m: Morph, P: dict[str, FloatArray], s: float) -> PartSpec:  # noqa: N803
    """Tail: from under the rump's top to a tuft."""
    t1, t2, t3 = P["tail_1"], P["tail_2"], P["tail_3"]
    tip = t3 + _unit(t3 - t2) * (m.tail_length / 3.2) * 1.25
    t0 = _offset(t1, 0.06 * s, 0, 0.0)
    pts = np.array([t0, t1, t2, t3, (t3 + tip) / 2, tip * 0.7 + t3 * 0.3, tip])
    r = s * np.array([0.040, 0.040, 0.028, 0.022, 0.030, 0.038, 0.012])
    return PartSpec("tail", pts, r, r * 0.9, _X, (
        ("tail_1", t0, t2), ("tail_2", t2, t3), ("tail_3", t3, tip),
    ), 0.05 * s)


def _legs(P: dict[str, FloatArray], s: float, girth: float = 1.0) -> list[PartSpec]:  # noqa: N803
    """Legs, down to flat hoof soles on z = 0, in :data:`LEG_CHAINS` order; ``girth`` thickens them (fully from the
    knee down, by its square root at the top)."""
    taper = np.sqrt(girth) + (girth - np.sqrt(girth)) * np.clip(np.arange(10) / 5.0, 0.0, 1.0)
    specs = []
    for leg, chain in LEG_CHAINS.items():
        fore = leg.startswith("f")
        top, mid, low, fet, hoof = (P[c] for c in chain)
        body_joint = "chest" if fore else "pelvis"
        sole = np.array([hoof[0] + 0.01 * s, hoof[1], 0.0])
        start = _offset(top, 0.0, -0.25 * top[1], 0.14 * s)
        if fore:
            pts = np.array([start, top, (top + mid) / 2, mid, mid * 0.55 + low * 0.45, low,
                            (low + fet) / 2, fet, _offset(hoof, 0, 0, 0.035 * s), sole])
            ra = s * np.array([0.12, 0.12, 0.10, 0.085, 0.062, 0.045, 0.033, 0.042, 0.036, 0.047])
            rb = s * np.array([0.09, 0.085, 0.075, 0.065, 0.050, 0.044, 0.029, 0.036, 0.034, 0.043])
        else:
            pts = np.array([start, top, top * 0.45 + mid * 0.55, mid, (mid + low) / 2, low,
                            (low + fet) / 2, fet, _offset(hoof, 0, 0, 0.035 * s), sole])
            ra = s * np.array([0.17, 0.17, 0.16, 0.115, 0.07, 0.052, 0.036, 0.042, 0.036, 0.047])
            rb = s * np.array([0.11, 0.105, 0.095, 0.075, 0.05, 0.042, 0.030, 0.036, 0.034, 0.043])
        if girth != 1.0:
            ra, rb = ra * taper, rb * taper
        bones = ((body_joint, start, top), (chain[0], top, mid), (chain[1], mid, low), (chain[2], low, fet),
                 (chain[3], fet, hoof), (chain[4], hoof, sole))
        specs.append(PartSpec(f"leg_{leg}", pts, ra, rb, _X, bones, 0.05 * s))
    return specs


def part_specs(m: Morph) -> list[PartSpec]:
    """The tubes of a zebra of morph ``m``, placed on its bind skeleton, in :data:`PART_NAMES`' drawing order
    (barrel, neck, mane, head, ears, tail, legs)."""
    j = bind_positions(m)
    P = {n: j[i] for n, i in JOINT_INDEX.items()}  # noqa: N806 - P for 'position' reads best here
    s = m.withers_height / 1.3
    neck = _neck(m, P, s)
    return [_barrel(m, P, s), neck, _mane(m, P, s, neck), _head(m, P, s), *_ears(m, P, s), _tail(m, P, s),
            *_legs(P, s, m.leg_girth), *_horns(m, P, s), _snout(m, P, s)]


def build_mesh(m: Morph, lod: int = 0) -> ZebraMesh:
    """Sweep every part of morph ``m`` at level of detail ``lod`` (0 = full, 1 = distant)."""
    if lod not in _RESOLUTION:
        raise ParameterError("lod", lod, f"one of {LODS}")
    res = _RESOLUTION[lod]
    verts: list[FloatArray] = []
    faces: list[IntArray] = []
    uvs: list[FloatArray] = []
    face_part: list[NDArray[np.int8]] = []
    jidx: list[IntArray] = []
    jw: list[FloatArray] = []
    grids: list[PartGrid] = []
    base = 0
    for spec in part_specs(m):
        key = spec.name.split("_")[0] if spec.name.startswith(("ear", "leg", "horn")) else spec.name
        n_rings, n_around = res[key]
        ring_verts, centres, caps = _sweep(spec, n_rings, n_around)
        rj, rw = _ring_weights(spec, centres)
        vj = np.repeat(rj, n_around, axis=0)
        vw = np.repeat(rw, n_around, axis=0)
        if spec.jaw:
            vj, vw = _blend_jaw(ring_verts, centres, vj, vw, n_rings, n_around)
        grid = base + np.arange(n_rings * n_around).reshape(n_rings, n_around)
        cap0, cap1 = base + n_rings * n_around, base + n_rings * n_around + 1
        cap_j = np.concatenate([rj[:1], rj[-1:]])
        cap_w = np.concatenate([rw[:1], rw[-1:]])
        verts += [ring_verts.reshape(-1, 3), caps]
        jidx += [vj, cap_j]
        jw += [vw, cap_w]
        f, uv = _tube_faces(grid, cap0, cap1, *_ATLAS[spec.name])
        faces.append(f)
        uvs.append(uv)
        face_part.append(np.full(len(f), PART_NAMES.index(spec.name), dtype=np.int8))
        grids.append(PartGrid(spec.name, grid, cap0, cap1, *_ATLAS[spec.name]))
        base = cap1 + 1
    return ZebraMesh(
        vertices=np.concatenate(verts),
        faces=np.concatenate(faces).astype(np.int64),
        uv=np.concatenate(uvs).astype(np.float32),
        face_part=np.concatenate(face_part),
        joint_indices=np.concatenate(jidx).astype(np.int64),
        joint_weights=np.concatenate(jw),
        parts=tuple(grids),
    )


def _blend_jaw(ring_verts: FloatArray, centres: FloatArray, vj: IntArray, vw: FloatArray,
               n_rings: int, n_around: int) -> tuple[IntArray, FloatArray]:
    """Hand the lower front of the head to the jaw joint, fading in towards the mouth."""
    u = np.repeat(np.linspace(0, 1, n_rings), n_around)
    below = (ring_verts[:, :, 2] < centres[:, None, 2]).reshape(-1)
    depth = (centres[:, None, 2] - ring_verts[:, :, 2]).reshape(-1)
    scale = max(float(depth.max()), 1e-9)
    w_jaw = np.clip((u - 0.35) / 0.25, 0, 1) * np.clip(depth / (0.5 * scale), 0, 1) * below
    vj = vj.copy()
    vw = vw.copy()
    vj[:, 1] = JOINT_INDEX["jaw"]
    vw[:, 1] = w_jaw
    vw[:, 0] = 1.0 - w_jaw
    vw[:, 2:] = 0.0
    return vj, vw


def _tube_faces(grid: IntArray, cap0: int, cap1: int, rect: tuple[float, float, float, float],
                along_u: bool) -> tuple[IntArray, FloatArray]:
    """Triangles (outward winding) and face-varying UVs of a capped tube."""
    n_rings, n = grid.shape
    u0, v0, u1, v1 = rect
    u0, v0, u1, v1 = u0 + _ATLAS_PAD, v0 + _ATLAS_PAD, u1 - _ATLAS_PAD, v1 - _ATLAS_PAD

    def uv_of(r: NDArray[np.float64], k: NDArray[np.float64]) -> FloatArray:
        along = r / (n_rings - 1)
        around = k / n
        if along_u:
            return np.stack([u0 + along * (u1 - u0), v0 + around * (v1 - v0)], -1)
        return np.stack([u0 + around * (u1 - u0), v0 + along * (v1 - v0)], -1)

    rr, kk2 = np.meshgrid(np.arange(n_rings - 1), np.arange(n), indexing="ij")
    r, k = rr.reshape(-1), kk2.reshape(-1)
    k1 = (k + 1) % n
    a, b, c, d = grid[r, k], grid[r, k1], grid[r + 1, k1], grid[r + 1, k]
    rf, kf = r.astype(float), k.astype(float)
    ua, ub, uc, ud = uv_of(rf, kf), uv_of(rf, kf + 1), uv_of(rf + 1, kf + 1), uv_of(rf + 1, kf)
    tris = [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]
    tuv = [np.stack([ua, ub, uc], 1), np.stack([ua, uc, ud], 1)]
    kk = np.arange(n)
    kc = kk.astype(float)
    first, last = np.zeros(n), np.full(n, float(n_rings - 1))
    tris.append(np.stack([np.full(n, cap0), grid[0, (kk + 1) % n], grid[0, kk]], 1))
    tuv.append(np.stack([uv_of(first, kc + 0.5), uv_of(first, kc + 1), uv_of(first, kc)], 1))
    tris.append(np.stack([np.full(n, cap1), grid[-1, kk], grid[-1, (kk + 1) % n]], 1))
    tuv.append(np.stack([uv_of(last, kc + 0.5), uv_of(last, kc), uv_of(last, kc + 1)], 1))
    return np.concatenate(tris), np.concatenate(tuv)
