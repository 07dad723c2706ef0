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
    """Small FMUs written for the tests (integrator, gain, delay, runtime probe), on our
    FMI runtime like ours."""
    import tempfile

    from glider_cosim.build import package_slave
    from glider_fmi.compile import compile_runtime

    out = tmp_path_factory.mktemp("test_fmus")
    src = HERE / "integration" / "fmus_src"
    with tempfile.TemporaryDirectory() as tmp:
        binary = Path(tmp) / "runtime.so"
        compile_runtime(binary)
        return {
            p.stem: package_slave(p, out, binary)
            for p in sorted(src.glob("*Test*.py"))
            if not p.stem.startswith("Swap")
        }
