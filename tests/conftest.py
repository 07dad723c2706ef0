"""Shared fixtures: FMUs are built once per test session into a temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest

HERE = Path(__file__).parent


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    """Our three FMUs, built from the current sources."""
    from glider_cosim.build import build_all

    out = tmp_path_factory.mktemp("fmus")
    build_all(out)
    return out


@pytest.fixture(scope="session")
def test_fmus(tmp_path_factory) -> dict[str, Path]:
    """Small FMUs written for the master's tests (integrator, gain, delay)."""
    from pythonfmu.builder import FmuBuilder

    out = tmp_path_factory.mktemp("test_fmus")
    src = HERE / "integration" / "fmus_src"
    return {
        p.stem: Path(FmuBuilder.build_FMU(p, dest=out)) for p in sorted(src.glob("MasterTest*.py"))
    }
