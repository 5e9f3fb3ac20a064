"""Coats: seeded, individual, striped."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.zebra.coat import (
    _cells,
    _mean_sin,
    _part_samples,
    _smoothstep,
    _smoothstep_into,
    _window,
    bake_coat,
    random_coat,
)
from zebra_sim_ros.zebra.mesh import build_mesh
from zebra_sim_ros.zebra.skeleton import BUFFALO, CATTLE, ELEPHANT, FOAL, GIRAFFE, GREVY, PLAINS, RHINO


def test_same_seed_same_coat_different_seed_different_coat() -> None:
    mesh = build_mesh(PLAINS, 0)
    a = bake_coat(PLAINS, random_coat(7, PLAINS), 128, mesh)
    b = bake_coat(PLAINS, random_coat(7, PLAINS), 128, mesh)
    c = bake_coat(PLAINS, random_coat(8, PLAINS), 128, mesh)
    assert a.dtype == np.uint8 and a.shape == (128, 128, 3)
    assert np.array_equal(a, b)
    differing = np.mean(np.any(a != c, axis=2))
    assert differing > 0.2, f"only {differing:.1%} of texels differ between two individuals"


@pytest.mark.parametrize("morph", [PLAINS, GREVY, FOAL], ids=["plains", "grevy", "foal"])
def test_barrel_is_striped(morph: object) -> None:
    tex = bake_coat(morph, random_coat(3, morph), 256)  # type: ignore[arg-type]
    barrel = tex[: int(256 * 0.45), :].astype(float).mean(axis=2)  # atlas rows of the barrel
    dark = np.mean(barrel < 90)
    assert 0.25 < dark < 0.7, f"dark share of the barrel {dark:.2f}"
    # Stripes: along the body (atlas u) brightness alternates many times.
    row = tex[int(256 * 0.34)].astype(float).mean(axis=1) > 128  # the flank (a quarter way round)
    changes = np.count_nonzero(row[1:] != row[:-1])
    assert changes >= 20


def test_grevy_stripes_are_narrower_than_plains() -> None:
    def crossings(morph: object) -> int:
        tex = bake_coat(morph, random_coat(1, morph), 512)  # type: ignore[arg-type]
        row = tex[int(512 * 0.34), 256:].astype(float).mean(axis=1) > 128  # the flank, front half
        return int(np.count_nonzero(row[1:] != row[:-1]))

    assert crossings(GREVY) > 1.3 * crossings(PLAINS)


def test_bad_coat_arguments_name_the_parameter() -> None:
    with pytest.raises(ParameterError, match="coat seed"):
        random_coat(-1, PLAINS)
    with pytest.raises(ParameterError, match="coat size"):
        bake_coat(PLAINS, random_coat(0, PLAINS), 8)


def test_cell_search_near_the_points_equals_a_search_of_all_cells() -> None:
    """The giraffe's and cattle's cells: searching only the seeds near a part first (and all of them again for
    points whose second-nearest lies beyond the reach) gives the same pattern as searching every seed."""
    rng = np.random.default_rng(5)
    seeds = rng.uniform(-1.0, 1.0, (400, 3))
    picks = rng.uniform(0.0, 1.0, 400)
    points = rng.uniform(-0.3, 0.3, (3000, 3)) * np.array([1.0, 0.2, 0.2])  # a thin part, like a leg
    full = _cells(points, seeds, 0.02, picks)
    for reach in (0.05, 0.2, 0.5):  # 0.05: most points need the second search; 0.5: none do
        near = _cells(points, seeds, 0.02, picks, reach=reach)
        assert np.allclose(near[0], full[0], rtol=0, atol=1e-9) and np.array_equal(near[1], full[1])  # picks: ids
    # and both against brute force: the nearest seed's pick, the gap between the two nearest distances
    d = np.linalg.norm(points[:, None] - seeds[None], axis=-1)
    order = np.argsort(d, axis=1)[:, :2]
    assert np.array_equal(full[1], picks[order[:, 0]])
    gap = np.take_along_axis(d, order, axis=1) @ np.array([-1.0, 1.0])
    assert np.allclose(full[0], np.clip((gap - 0.01) / 0.02, 0, 1) ** 2 * (3 - 2 * np.clip((gap - 0.01) / 0.02, 0, 1)))


@pytest.mark.parametrize("morph", [PLAINS, GIRAFFE, CATTLE], ids=["plains", "giraffe", "cattle"])
def test_a_coat_is_the_same_with_the_kept_geometry_or_a_given_mesh(morph: object) -> None:
    """bake_coat keeps each morph's mesh and texel geometry between coats; a mesh given by the caller, built
    afresh, gives the same texels, and a later coat does not see an earlier one's arrays."""
    first = bake_coat(morph, random_coat(11, morph), 128)  # type: ignore[arg-type]
    bake_coat(morph, random_coat(12, morph), 128)  # type: ignore[arg-type]
    again = bake_coat(morph, random_coat(11, morph), 128)  # type: ignore[arg-type]
    given = bake_coat(morph, random_coat(11, morph), 128, build_mesh(morph, 0))  # type: ignore[arg-type]
    assert np.array_equal(first, again) and np.array_equal(first, given)


@pytest.mark.parametrize("morph", [ELEPHANT, BUFFALO, RHINO], ids=["elephant", "buffalo", "rhino"])
def test_horns_and_tusks_take_their_own_colour(morph: object) -> None:
    """A tusk is ivory on a grey elephant, a buffalo's horn near-black; a rhino's front horn (its snout part) is horn,
    an elephant's trunk (its snout part) is skin."""
    size = 256
    tex = bake_coat(morph, random_coat(5, morph), size).astype(float) / 255  # type: ignore[arg-type]
    mesh = build_mesh(morph, 0)  # type: ignore[arg-type]

    def mean_rgb(part: str) -> np.ndarray:
        u0, v0, u1, v1 = mesh.part(part).rect
        block = tex[int((1 - v1) * size) + 2:int((1 - v0) * size) - 2, int(u0 * size) + 2:int(u1 * size) - 2]
        return block.reshape(-1, 3).mean(axis=0)

    horn = np.asarray(morph.horn_rgb)  # type: ignore[attr-defined]
    for part in ("horn_l", "horn_r"):
        got = mean_rgb(part)
        assert np.all(np.abs(got - horn) < 0.15 * horn + 0.02), (part, got, horn)
    snout, skin = mean_rgb("snout"), mean_rgb("barrel")
    if morph.snout == "horn":  # type: ignore[attr-defined]
        assert np.all(np.abs(snout - horn) < 0.15 * horn + 0.02)
    elif morph.snout == "trunk":  # type: ignore[attr-defined]
        assert np.abs(snout - skin).max() < 0.1 and np.abs(snout - horn).max() > 0.2


def _bare(params: object) -> object:
    """The same coat without its hide: no noise, creases, mud or dust."""
    return dataclasses.replace(params, hide_amp=0.0, wrinkle=0.0, mud_amount=0.0, dust=0.0)  # type: ignore


def test_a_zebra_coat_has_no_hide() -> None:
    """Zebras draw no hide, and hide settings forced onto a striped coat change nothing: zebra frames render as
    before the other species got one."""
    params = random_coat(4, PLAINS)
    assert (params.hide_amp, params.wrinkle, params.mud_amount, params.dust) == (0.0, 0.0, 0.0, 0.0)
    forced = dataclasses.replace(params, hide_amp=0.2, wrinkle=0.4, mud_amount=1.0, dust=0.5, mud_height=0.5,
                                 mud_rgb=(0.5, 0.3, 0.1))
    assert np.array_equal(bake_coat(PLAINS, params, 128), bake_coat(PLAINS, forced, 128))


@pytest.mark.parametrize("morph", [ELEPHANT, BUFFALO, RHINO], ids=["elephant", "buffalo", "rhino"])
def test_a_solid_hide_is_textured_and_muddy_up_to_its_mud_line(morph: object) -> None:
    """A solid coat is no flat colour: the hide's noise and creases spread the barrel's brightness; mud covers what
    lies below the mud line, in the mud's colour, and leaves what lies well above it alone."""
    size = 256
    params = dataclasses.replace(random_coat(9, morph), dust=0.0, mud_amount=1.0, mud_height=0.3,  # type: ignore
                                 mud_rgb=(0.45, 0.28, 0.17))
    mesh = build_mesh(morph, 0)  # type: ignore[arg-type]
    hide = bake_coat(morph, params, size, mesh).astype(float)  # type: ignore[arg-type]
    bare = bake_coat(morph, _bare(params), size, mesh).astype(float)  # type: ignore[arg-type]
    rows, cols, p, _, _ = _part_samples(mesh, "barrel", size)
    lum_hide, lum_bare = hide[rows, cols].mean(axis=-1), bare[rows, cols].mean(axis=-1)
    assert lum_hide.std() > 1.5 * lum_bare.std() + 2.0, (lum_hide.std(), lum_bare.std())
    height = mesh.vertices[:, 2].max()
    for leg in ("leg_fl", "leg_hl"):
        rows, cols, p, _, _ = _part_samples(mesh, leg, size)
        low = p[..., 2] < 0.3 * height - 0.2 * height  # well under the line, even where the noise lifts it
        assert low.sum() > 20
        got = hide[rows[low], cols[low]].reshape(-1, 3).mean(axis=0) / 255
        assert np.all(np.abs(got - np.array(params.mud_rgb)) < 0.5 * np.array(params.mud_rgb)), (leg, got)
    rows, cols, p, _, _ = _part_samples(mesh, "neck", size)
    high = p[..., 2] > 0.3 * height + 0.2 * height
    no_mud = dataclasses.replace(params, mud_amount=0.0)  # type: ignore[arg-type]
    clean = bake_coat(morph, no_mud, size, mesh).astype(float)  # type: ignore[arg-type]
    changed = np.abs(hide[rows[high], cols[high]] - clean[rows[high], cols[high]]).max(axis=-1) > 1.0
    assert high.sum() > 20 and changed.mean() < 0.01, changed.mean()  # (texels shared with a neighbouring part aside)


def test_the_in_place_helpers_give_what_their_plain_forms_give() -> None:
    """bake_coat's helpers that work in their argument's memory: the mean of the waves' sines, the smoothstep and
    the part's atlas window give what numpy's mean (of float32 sines), the plain smoothstep and the index arrays
    give; the float32 sines are within float32's reach of float64's."""
    rng = np.random.default_rng(5)
    for k in (3, 4, 6):
        waves, phase = rng.normal(size=(40, 30, k)) * 20, rng.uniform(0, 2 * np.pi, k)
        got = _mean_sin(waves.copy(), phase)
        want = np.mean(np.sin((waves + phase).astype(np.float32)).astype(np.float64), axis=-1)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        # arguments up to ~90 rad: float32's spacing there is 7.6e-6; a coat texel's level is 1/255
        np.testing.assert_allclose(got, np.mean(np.sin(waves + phase), axis=-1), rtol=0, atol=2e-5)
        assert not np.array_equal(got, np.mean(np.sin(waves + phase), axis=-1))  # float32 sines indeed
    x = rng.uniform(-0.5, 1.5, (50, 3))
    for e0, e1 in ((0.3, 0.0), (0.0, 1.0)):
        np.testing.assert_allclose(_smoothstep_into(e0, e1, x.copy()), _smoothstep(e0, e1, x), rtol=0, atol=1e-15)
    mesh = build_mesh(PLAINS, 0)
    img = np.zeros((128, 128))
    for pg in mesh.parts:
        rows, cols, _, _, _ = _part_samples(mesh, pg.name, 128)
        a, b = img.copy(), img.copy()
        a[rows, cols] = 1 + rows * 1000 + cols
        b[_window(rows, cols)] = 1 + rows * 1000 + cols
        assert np.array_equal(a, b), pg.name
