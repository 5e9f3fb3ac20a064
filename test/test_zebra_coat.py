"""Coats: seeded, individual, striped."""

from __future__ import annotations

import numpy as np
import pytest

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.zebra.coat import bake_coat, random_coat
from zebra_sim_ros.zebra.mesh import build_mesh
from zebra_sim_ros.zebra.skeleton import FOAL, GREVY, PLAINS


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
