"""Shared fixtures: one baked zebra library per test session, in a private cache folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from zebra_sim_ros.zebra.asset import ZebraLibrary, build_library


@pytest.fixture(scope="session")
def zebra_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("zebra_cache")


@pytest.fixture(scope="session")
def library(zebra_cache: Path) -> ZebraLibrary:
    return build_library(zebra_cache)
