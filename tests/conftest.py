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


def pytest_sessionfinish(session, exitstatus):
    session.config._glider_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave without the C-level exit handlers once pytest is done.

    A process that loaded pythonfmu binaries next to numpy's OpenBLAS can abort in
    OpenBLAS's thread shutdown at exit (seen once in about 20 runs of the FMU tests,
    'corrupted double-linked list' from blas_thread_shutdown_ under gdb); the CLI leaves
    the same way. The exit status is pytest's own.
    """
    import os
    import sys

    status = getattr(config, "_glider_exitstatus", None)
    if status is not None and os.environ.get("GLIDER_COSIM_NORMAL_EXIT") != "1":
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
