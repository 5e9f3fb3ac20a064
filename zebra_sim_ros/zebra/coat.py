"""Per-individual coats: procedural stripe textures drawn from a seed (and the other species' coats).

The stripes are a solid texture: a stripe phase defined on the bind-pose body (vertical bands on the
barrel, arcs over the haunch, rings round the legs, bands across the neck and a fine pattern on the
face), warped by smooth random waves. Baking it into each part's atlas rectangle through the mesh
makes stripes continue across part seams. Each individual draws its own warp, stripe width, stripe
spacing and colours from a ``numpy.random.Generator``; the same seed gives the same coat, bit for bit.

Other species (:data:`~zebra_sim_ros.zebra.skeleton.OTHER_SPECIES`) use the same machinery with their morph's
``coat``: brindle (faint bands, a wildebeest), solid (an impala, buffalo or donkey: one colour with dark points
and a white belly where the morph has one; an elephant's or a rhino's grey skin), network (a giraffe: dark cells
parted by pale lines) or patches (cattle: cells of one colour or the other, or a solid coat). Horns and tusks take
the morph's ``horn_rgb``. Their hide is not flat: a few octaves of brightness noise (hair and skin), creases
(an elephant's and a rhino's wrinkles, fainter on a buffalo), mud up the legs to a height drawn per individual, and
a dusting of the same earth over the whole body. Zebras' coats have none of these and are unchanged.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.zebra.mesh import ZebraMesh, build_mesh, head_direction
from zebra_sim_ros.zebra.skeleton import JOINT_INDEX, Morph, bind_positions

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CoatParams:
    """What makes one coat differ from another. Colours are linear-ish sRGB in [0, 1]."""

    seed: int
    period_scale: float  # multiplies the morph's stripe period
    black_fraction: float  # share of each stripe period that is black
    warp_amplitude: float  # in stripe periods
    wave_k: tuple[tuple[float, float, float], ...]  # warp wave vectors, radians per metre
    wave_phase: tuple[float, ...]
    base_rgb: tuple[float, float, float]
    stripe_rgb: tuple[float, float, float]
    shadow_stripes: bool
    pattern: str = "stripes"  # the morph's coat (skeleton.COATS)
    cell_seed: int = 0  # cells of network and patches coats
    # the hide of other species (zebras: all zero, no effect)
    hide_amp: float = 0.0  # relative brightness noise (its standard deviation, roughly)
    wrinkle: float = 0.0  # how much the creases darken
    mud_rgb: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the earth on the legs and, thinly, all over
    mud_height: float = 0.0  # share of the animal's height that the mud reaches
    mud_amount: float = 0.0  # opacity of the mud on the legs (0: none)
    dust: float = 0.0  # opacity of the earth over the whole body
    hide_seed: int = 0  # the noise waves of the hide


def random_coat(seed: int, morph: Morph) -> CoatParams:
    """Draw a coat for one individual from ``seed``."""
    if seed < 0:
        raise ParameterError("coat seed", seed, "an integer >= 0")
    rng = np.random.default_rng([seed, 0xC0A7])
    if morph.coat != "stripes":
        return _species_coat(seed, morph, rng)
    n = 6
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    k = direction * rng.uniform(5.0, 14.0, size=(n, 1))
    cream = rng.uniform(0.0, 1.0)
    base = (0.93 - 0.05 * cream, 0.91 - 0.08 * cream, 0.86 - 0.16 * cream)
    if morph.name == "foal":  # foals' stripes are brown
        stripe = tuple(rng.uniform([0.22, 0.14, 0.08], [0.32, 0.22, 0.14]))
    else:
        d = rng.uniform(0.03, 0.09)
        stripe = (d + rng.uniform(0, 0.04), d + rng.uniform(0, 0.02), d)
    return CoatParams(
        seed=seed,
        period_scale=float(rng.uniform(0.85, 1.15)),
        black_fraction=float(rng.uniform(0.40, 0.55)),
        warp_amplitude=float(rng.uniform(0.12, 0.35)),
        wave_k=tuple((float(row[0]), float(row[1]), float(row[2])) for row in k),
        wave_phase=tuple(float(v) for v in rng.uniform(0, 2 * np.pi, size=n)),
        base_rgb=tuple(float(v) for v in base),  # type: ignore[arg-type]
        stripe_rgb=tuple(float(v) for v in stripe),  # type: ignore[arg-type]
        shadow_stripes=morph.name == "plains" and bool(rng.uniform() < 0.8),
    )


def _species_coat(seed: int, morph: Morph, rng: np.random.Generator) -> CoatParams:
    """A coat of another species: its morph's colours varied per individual (+-12% brightness, a little hue)."""
    base = np.asarray(morph.coat_rgb) * rng.uniform(0.88, 1.12) * rng.uniform(0.95, 1.05, 3)
    alt = np.asarray(morph.coat_alt_rgb) * rng.uniform(0.85, 1.15) * rng.uniform(0.95, 1.05, 3)
    pattern = morph.coat
    if pattern == "patches":  # cattle: black and white, brown and white, or a solid brown, black or red coat
        kind = rng.uniform()
        if kind < 0.3:
            alt = np.array([0.38, 0.22, 0.12]) * rng.uniform(0.8, 1.2)
        elif kind < 0.6:
            pattern = "solid"
            base = [np.array([0.36, 0.22, 0.12]), np.array([0.07, 0.06, 0.06]),
                    np.array([0.55, 0.30, 0.15])][int(rng.integers(3))] * rng.uniform(0.85, 1.15)
    direction = rng.normal(size=(6, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    k = direction * rng.uniform(3.0, 8.0, size=(6, 1))
    period_scale, warp_amplitude = float(rng.uniform(0.85, 1.15)), float(rng.uniform(0.1, 0.25))
    wave_phase = tuple(float(v) for v in rng.uniform(0, 2 * np.pi, size=6))
    cell_seed = int(rng.integers(0, 2**31 - 1))
    # the hide, drawn after everything above so that those draws are what they were before it existed
    thick = morph.name in ("elephant", "rhino")
    earth = _EARTH[int(rng.integers(len(_EARTH)))] * rng.uniform(0.85, 1.15) * rng.uniform(0.95, 1.05, 3)
    hide_amp = float(rng.uniform(0.05, 0.14))
    wrinkle = float(rng.uniform(0.25, 0.45) if thick else rng.uniform(0.05, 0.15) if morph.name == "buffalo"
                    else rng.uniform(0.0, 0.05))
    mud_height = float(rng.uniform(0.12, 0.45))
    mud_amount = float(rng.uniform(0.4, 0.9)) if rng.uniform() < 0.5 else 0.0
    dust = float(rng.uniform(0.0, 0.5 if thick or morph.name == "buffalo" else 0.2))
    return CoatParams(
        seed=seed, period_scale=period_scale, black_fraction=0.35, warp_amplitude=warp_amplitude,
        wave_k=tuple((float(row[0]), float(row[1]), float(row[2])) for row in k), wave_phase=wave_phase,
        base_rgb=tuple(float(v) for v in np.clip(base, 0, 1)),  # type: ignore[arg-type]
        stripe_rgb=tuple(float(v) for v in np.clip(alt, 0, 1)),  # type: ignore[arg-type]
        shadow_stripes=False, pattern=pattern, cell_seed=cell_seed,
        hide_amp=hide_amp, wrinkle=wrinkle, mud_rgb=tuple(float(v) for v in np.clip(earth, 0, 1)),  # type: ignore
        mud_height=mud_height, mud_amount=mud_amount, dust=dust, hide_seed=int(rng.integers(0, 2**31 - 1)))


# Earth that sticks to a hide: wet dark mud, red laterite, grey dust, ochre (linear-ish sRGB)
_EARTH = (np.array([0.20, 0.16, 0.12]), np.array([0.45, 0.28, 0.17]), np.array([0.55, 0.50, 0.44]),
          np.array([0.50, 0.40, 0.26]))


def _hide(p: FloatArray, params: CoatParams, height: float) -> tuple[FloatArray, FloatArray]:
    """The hide at bind-pose points ``p`` (..., 3), metres, z up from the ground: a brightness factor (...) and the
    opacity (...) of the earth on it (mud up the legs, dust all over)."""
    rng = np.random.default_rng([params.hide_seed, 0x41DE])
    fbm, amp, norm = np.zeros(p.shape[:-1]), 1.0, 0.0
    for octave in range(4):  # wavelengths of about 45, 20, 9 and 4 cm
        d = rng.normal(size=(4, 3))
        k = d / np.linalg.norm(d, axis=1, keepdims=True) * 14.0 * 2.2 ** octave
        fbm += amp * _mean_sin(p @ k.T, rng.uniform(0, 2 * np.pi, 4))
        norm, amp = norm + amp, amp * 0.55
    fbm /= norm  # standard deviation about 0.25
    d = rng.normal(size=(3, 3))
    k = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(70.0, 110.0, size=(3, 1))
    s = p @ k.T  # creases at the zero lines of three waves bent by the noise
    s += rng.uniform(0, 2 * np.pi, 3)
    s += 4.0 * fbm[..., None]
    s32 = _sin32(s)
    s = _smoothstep_into(0.3, 0.0, np.abs(s32, out=s32).astype(np.float64))
    crease = np.maximum(np.maximum(s[..., 0], s[..., 1]), s[..., 2])
    shade = np.clip(1.0 + params.hide_amp * 4.0 * fbm, 0.5, 1.5) * (1.0 - params.wrinkle * crease)
    h = params.mud_height * height
    mud = _smoothstep(h + 0.06, h - 0.06, p[..., 2] + 0.15 * height * fbm) * params.mud_amount
    earth = 1.0 - (1.0 - mud) * (1.0 - params.dust * np.clip(0.6 + 2.0 * fbm, 0, 1))
    return shade, earth


def _cells(p: FloatArray, seeds: FloatArray, line: float, rng_pick: FloatArray,
           reach: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Cellular pattern at bind positions ``p`` (N, 3): how far inside its cell each point is (0 on the border line
    of width ``line`` m, 1 beyond it) and that cell's random pick 0..1.

    The two nearest cell seeds are found on squared distances from one matrix product (|q|^2 - 2 q.s + |s|^2),
    then their distances are taken exactly, as the difference's norm. With ``reach`` > 0 only the seeds within
    ``reach`` of the points' bounding box are searched first; a point whose second-nearest seed among them lies
    farther than ``reach`` is searched again among all seeds, so the result is the same as a search of all. A
    giraffe's coat (about 1,000 cells) bakes in tens of milliseconds instead of seconds."""
    if reach > 0 and len(p):
        near_box = np.all((seeds >= p.min(axis=0) - reach) & (seeds <= p.max(axis=0) + reach), axis=1)
        if near_box.sum() >= 2:
            idx = np.flatnonzero(near_box)
            inside, pick, d1 = _nearest_two(p, seeds[idx], line, rng_pick[idx])
            again = d1 > reach
            if again.any():
                inside[again], pick[again], _ = _nearest_two(p[again], seeds, line, rng_pick)
            return inside, pick
    inside, pick, _ = _nearest_two(p, seeds, line, rng_pick)
    return inside, pick


def _nearest_two(p: FloatArray, seeds: FloatArray, line: float,
                 rng_pick: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`_cells` over all of ``seeds`` (at least two), and each point's distance to its second-nearest."""
    inside = np.empty(len(p))
    pick = np.empty(len(p))
    second = np.empty(len(p))
    s2 = np.einsum("ij,ij->i", seeds, seeds)
    for a in range(0, len(p), _CELL_CHUNK):
        q = p[a:a + _CELL_CHUNK]
        rows = np.arange(len(q))
        d2 = s2[None, :] - 2.0 * (q @ seeds.T)  # |q - s|^2 less |q|^2, the same for every seed of a row
        i0 = np.argmin(d2, axis=1)
        d2[rows, i0] = np.inf
        i1 = np.argmin(d2, axis=1)
        d0 = np.linalg.norm(q - seeds[i0], axis=-1)
        d1 = np.linalg.norm(q - seeds[i1], axis=-1)
        near = np.where(d0 <= d1, i0, i1)
        inside[a:a + _CELL_CHUNK] = _smoothstep(0.5 * line, 1.5 * line, np.abs(d1 - d0))
        pick[a:a + _CELL_CHUNK] = rng_pick[near]
        second[a:a + _CELL_CHUNK] = np.maximum(d0, d1)
    return inside, pick, second


_CELL_CHUNK = 4096  # points per matrix product in :func:`_cells` (4096 x 1,000 cells: 33 MB)


def _smoothstep(e0: float, e1: float, x: FloatArray) -> FloatArray:
    """0 below ``e0``, 1 beyond ``e1``, the cubic ``t * t * (3 - 2 * t)`` between; ``x`` is left as it is."""
    return _smoothstep_into(e0, e1, np.array(x, dtype=np.float64))


def _smoothstep_into(e0: float, e1: float, x: FloatArray) -> FloatArray:
    """:func:`_smoothstep` computed in ``x``'s own memory (``x``, float64, is overwritten). Texel arrays are large
    enough that fresh temporaries cost as much as the arithmetic."""
    x -= e0
    x /= e1 - e0
    t = np.clip(x, 0.0, 1.0, out=x)
    w = t * 2
    np.subtract(3, w, out=w)
    t *= t
    t *= w
    return t


def _sin32(x: FloatArray) -> NDArray[np.float32]:
    """``sin(x)`` taken in float32: numpy's float32 ``sin`` is vectorised where its float64 one is not (3 ns an element
    against 27 on a CPU without AVX-512), and a coat needs no more: the arguments stay under a few hundred radians,
    where float32 is good to about 3e-5, against the 4e-3 of one level of an 8-bit texel (one texel in 10^5 comes out
    one level off the float64 bake)."""
    s = x.astype(np.float32)
    return np.sin(s, out=s)


def _mean_sin(waves: FloatArray, phase: FloatArray) -> FloatArray:
    """``mean(sin(waves + phase), axis=-1)`` (float64), ``waves`` (..., K) overwritten; the sines are
    :func:`_sin32`'s. The K waves are summed one after the other, in order, then divided by K (numpy's ``mean`` at a
    tenth of its time)."""
    waves += phase
    s = _sin32(waves)
    total = s[..., 0].astype(np.float64)
    for j in range(1, s.shape[-1]):
        total += s[..., j]
    total /= s.shape[-1]
    return total


def _window(rows: NDArray[np.int64], cols: NDArray[np.int64]) -> tuple[slice, slice] | tuple[NDArray[np.int64], ...]:
    """Where a part's texels go in the atlas: the rectangle :func:`_part_samples` made (``rows``/``cols`` from a
    meshgrid of two ranges) as two slices, much faster to write through than the index arrays themselves."""
    if rows.size == 0 or rows[0, 0] < 0 or cols[0, 0] < 0:
        return rows, cols
    return slice(int(rows[0, 0]), int(rows[-1, 0]) + 1), slice(int(cols[0, 0]), int(cols[0, -1]) + 1)


def _part_samples(mesh: ZebraMesh, name: str, size: int) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                                   FloatArray, FloatArray, FloatArray]:
    """Texel rows/cols inside a part's rectangle and the bind position, along, around under each."""
    pg = mesh.part(name)
    u0, v0, u1, v1 = pg.rect
    c0, c1 = int(np.floor(u0 * size)), int(np.ceil(u1 * size))
    r0, r1 = int(np.floor((1 - v1) * size)), int(np.ceil((1 - v0) * size))
    rows, cols = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    u = (cols + 0.5) / size
    v = 1.0 - (rows + 0.5) / size
    fu = np.clip((u - u0) / (u1 - u0), 0, 1)
    fv = np.clip((v - v0) / (v1 - v0), 0, 1)
    along, around = (fu, fv) if pg.along_u else (fv, fu)
    n_rings, n = pg.grid.shape
    rr = along * (n_rings - 1)
    kk = around * n
    r_lo = np.clip(np.floor(rr).astype(int), 0, n_rings - 2)
    k_lo = np.floor(kk).astype(int) % n
    fr = (rr - r_lo)[..., None]
    fk = (kk - np.floor(kk))[..., None]
    vtx = mesh.vertices
    g = pg.grid
    p = ((1 - fr) * ((1 - fk) * vtx[g[r_lo, k_lo]] + fk * vtx[g[r_lo, (k_lo + 1) % n]])
         + fr * ((1 - fk) * vtx[g[r_lo + 1, k_lo]] + fk * vtx[g[r_lo + 1, (k_lo + 1) % n]]))
    return rows, cols, p, along, around


class _Pattern(NamedTuple):
    """What a part's stripe phase, forced black and forced white are made of but the individual's stripe period: the
    same for every coat of a morph, so worked out once with the part's texels (:func:`_geometry`). The phase is
    ``dist / (per * period) ** power``, but on the barrel: there ``(1 - rump) * (dist / period) + rump * (arc / (1.2 *
    period))``, bands on the body turning into arcs round the haunch (:func:`_phase`: the same operations in the
    same order as when the phase was computed whole, so the coats are the same bytes)."""

    dist: FloatArray  # the phase times the period's multiple: a distance across the part's bands, metres
    per: float
    power: float | None  # what ``per * period`` is raised to (the legs: 0.95); None: not raised
    rump: FloatArray | None  # barrel: the haunch's share (0..1), 1 - it, and the distance from the haunch's centre
    body: FloatArray | None
    arc: FloatArray | None
    dark_extra: FloatArray  # forced black (0..1)
    keep: FloatArray  # 1 - forced white


def _part_pattern(name: str, p: FloatArray, along: FloatArray, around: FloatArray, morph: Morph) -> _Pattern:
    """The stripe pattern's geometry under each texel of part ``name`` (``p`` bind positions, ``along``/``around``
    0..1 on the part's tube); :func:`_phase` gives the stripe phase (in periods) for an individual's period."""
    j = _bind(morph)
    pel, n1, hd = j[JOINT_INDEX["pelvis"]], j[JOINT_INDEX["neck_1"]], j[JOINT_INDEX["head"]]
    x, z = p[..., 0], p[..., 2]
    dark_extra = np.zeros_like(x)
    white_extra = np.zeros_like(x)
    rump = body = arc = None
    per, power = 0.5, None
    if name == "barrel":
        haunch = pel + np.array([0.45, 0.0, -0.55]) * morph.withers_height / 1.3
        rump = _smoothstep(pel[0] + 0.25, pel[0] - 0.15, x)
        dist, body, arc = x, 1 - rump, np.linalg.norm((p - haunch)[..., [0, 2]], axis=-1)
        ang = np.abs(around - 0.5)  # 0.5 = straight down; 0 or 1 = along the spine
        dark_extra = (ang > 0.47).astype(float) * (morph.coat in ("stripes", "brindle"))  # dorsal stripe
        if morph.white_belly:
            white_extra = _smoothstep(0.14, 0.08, ang)
    elif name in ("neck", "mane"):
        nd = (hd - n1) / np.linalg.norm(hd - n1)
        dist, per = p @ nd, 0.9
    elif name == "head":
        dist, per = p @ head_direction(morph), 0.35
        dark_extra = _smoothstep(0.80, 0.88, along)  # the dark muzzle
    elif name.startswith("leg"):
        dist, per, power = z, 0.45, 0.95
        dark_extra = _smoothstep(0.955, 0.97, along)  # hooves
        if morph.white_belly:
            white_extra = _smoothstep(0.30, 0.20, z)  # Grévy's fade to white low on the legs
    elif name.startswith("ear"):
        dist = z
        dark_extra = _smoothstep(0.72, 0.8, along)
        white_extra = 0.6 * _smoothstep(0.5, 0.3, around % 1.0)
    elif name == "snout":  # a trunk: the skin of the body, ringed (horns and a nasal horn are coloured in bake_coat)
        dist = z
    else:  # tail: striped at the root, black tuft
        dist = z
        dark_extra = _smoothstep(0.62, 0.7, along)
    return _Pattern(dist, per, power, rump, body, arc, dark_extra, 1 - white_extra)


def _phase(pat: _Pattern, period: float) -> FloatArray:
    """A part's stripe phase, in periods, for an individual's stripe ``period`` (metres)."""
    if pat.rump is not None and pat.body is not None and pat.arc is not None:
        return pat.body * (pat.dist / period) + pat.rump * (pat.arc / (1.2 * period))
    if pat.power is None:
        return pat.dist / (pat.per * period)
    return pat.dist / (pat.per * period) ** pat.power


_BIND: dict[str, FloatArray] = {}


def _bind(morph: Morph) -> FloatArray:
    """``bind_positions(morph)``, worked out once per process (read-only; a morph is keyed by all its fields)."""
    key = repr(morph)
    got = _BIND.get(key)
    if got is None:
        got = _BIND[key] = bind_positions(morph)
        got.flags.writeable = False
    return got


_Samples = tuple[NDArray[np.int64], NDArray[np.int64], FloatArray, FloatArray, FloatArray, _Pattern]
_GEOMETRY: OrderedDict[tuple[str, int], list[tuple[str, _Samples]]] = OrderedDict()
_MESHES: dict[str, ZebraMesh] = {}
_GEOMETRY_KEEP = 16  # (morph, size) entries kept: eleven morphs at 256 texels take about 61 MB


def _geometry_mesh(morph: Morph) -> ZebraMesh:
    """The full-detail mesh of ``morph``, built once per process (a morph is keyed by all its fields)."""
    key = repr(morph)
    if key not in _MESHES:
        _MESHES[key] = build_mesh(morph, 0)
    return _MESHES[key]


def _samples(mesh: ZebraMesh, morph: Morph, size: int) -> list[tuple[str, _Samples]]:
    """Each part's texels, what lies under them (:func:`_part_samples`) and its stripe pattern's geometry."""
    got = []
    for pg in mesh.parts:
        rows, cols, p, along, around = _part_samples(mesh, pg.name, size)
        got.append((pg.name, (rows, cols, p, along, around, _part_pattern(pg.name, p, along, around, morph))))
    return got


def _geometry(morph: Morph, size: int) -> list[tuple[str, _Samples]]:
    """:func:`_samples` of ``morph``'s own mesh at ``size`` texels: the same for every individual of a morph, so
    computed once and kept (the :data:`_GEOMETRY_KEEP` latest)."""
    key = (repr(morph), size)
    got = _GEOMETRY.get(key)
    if got is None:
        got = _samples(_geometry_mesh(morph), morph, size)
        for _, (*arrays, pattern) in got:
            for a in [*arrays, *(v for v in pattern if isinstance(v, np.ndarray))]:
                a.flags.writeable = False  # shared by every later coat: a stray write would change them all
        _GEOMETRY[key] = got
        while len(_GEOMETRY) > _GEOMETRY_KEEP:
            _GEOMETRY.popitem(last=False)
    else:
        _GEOMETRY.move_to_end(key)
    return got


def bake_coat(morph: Morph, params: CoatParams, size: int = 512, mesh: ZebraMesh | None = None) -> NDArray[np.uint8]:
    """The coat atlas (size, size, 3) uint8 RGB for one individual; row 0 is the top (v = 1)."""
    if not 32 <= size <= 4096:
        raise ParameterError("coat size", size, "32..4096 texels")
    if mesh is None:
        mesh, samples = _geometry_mesh(morph), _geometry(morph, size)
    else:
        samples = _samples(mesh, morph, size)
    pel_x = _bind(morph)[JOINT_INDEX["pelvis"], 0]
    period = morph.stripe_period * params.period_scale
    img = np.zeros((size, size, 3))
    base = np.array(params.base_rgb)
    black = np.array(params.stripe_rgb)
    k = np.array(params.wave_k)
    ph = np.array(params.wave_phase)
    edge = 0.06  # soft edge, in stripe periods, so the texture is anti-aliased already

    height = float(mesh.vertices[:, 2].max())
    mud_rgb = np.array(params.mud_rgb)
    seeds = picks = np.zeros((0, 3))
    if params.pattern in ("network", "patches"):
        crng = np.random.default_rng([params.cell_seed, 0xCE11])
        lo, hi = mesh.vertices.min(axis=0) - 0.1, mesh.vertices.max(axis=0) + 0.1
        n_cells = int(np.clip(np.prod(hi - lo) / period ** 3, 8, 4000))
        seeds, picks = crng.uniform(lo, hi, (n_cells, 3)), crng.uniform(0, 1, n_cells)
    for name, (rows, cols, p, along, _, pattern) in samples:
        if name.startswith("horn") or (name == "snout" and morph.snout == "horn"):
            # Horn or tusk: its own colour, a little darker at the base and lighter towards the tip; no coat pattern.
            img[_window(rows, cols)] = np.clip(np.asarray(morph.horn_rgb) * (0.8 + 0.35 * along[..., None]), 0, 1)
            continue
        warp = params.warp_amplitude * _mean_sin(p @ k.T, ph) * 2.0
        f = (_phase(pattern, period) + warp) % 1.0
        # Black where f < black_fraction, with soft edges at both ends of the band.
        b = _smoothstep(-edge, edge, f) * _smoothstep(params.black_fraction + edge, params.black_fraction - edge, f)
        b = b + _smoothstep(1 - edge, 1 + edge, f)
        if params.pattern in ("network", "patches"):
            flat = p.reshape(-1, 3) + 0.05 * warp.reshape(-1, 1)
            inside, pick = _cells(flat, seeds, 0.12 * period, picks, reach=2.0 * period)
            b = (inside if params.pattern == "network" else (pick < 0.45) * (0.3 + 0.7 * inside)).reshape(f.shape)
        elif params.pattern == "solid":
            b = np.zeros_like(f)
        elif params.pattern == "brindle":
            b = 0.6 * b  # faint bands
        b = np.clip(np.maximum(b, pattern.dark_extra) * pattern.keep, 0, 1)
        col = base * (1 - b[..., None]) + black * b[..., None]
        if params.pattern != "stripes":  # other species: hide noise, creases, mud and dust
            shade, earth = _hide(p, params, height)
            col = col * shade[..., None] * (1 - earth[..., None]) + mud_rgb * earth[..., None] * shade[..., None]
        if params.shadow_stripes and name == "barrel":
            mid = params.black_fraction + (1 - params.black_fraction) / 2
            sh = _smoothstep(0.12, 0.0, np.abs(f - mid)) * _smoothstep(pel_x + 0.4, pel_x, p[..., 0]) * 0.45
            col = col * (1 - sh[..., None]) + np.array([0.55, 0.45, 0.36]) * sh[..., None]
        img[_window(rows, cols)] = col
    img *= 255
    return np.clip(np.round(img, out=img), 0, 255, out=img).astype(np.uint8)
