"""Shared fixtures: FMUs are built once per test session into a temporary folder."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

HERE = Path(__file__).parent


def pytest_configure(config):
    """Every temporary file of the session goes to one private folder, checked at the end.

    ``$TMPDIR`` (inherited by subprocesses) and :mod:`tempfile` point into it, so that
    pytest's ``tmp_path`` folders, our extracted FMUs and SSPs, and whatever the CLI
    subprocesses and Dask workers create all land there.
    """
    base = tempfile.mkdtemp(prefix="glider-tests-")
    config._glider_tmp = (base, os.environ.get("TMPDIR"), tempfile.tempdir)
    os.environ["TMPDIR"] = base
    tempfile.tempdir = base


def _leaked_temp_files(config) -> list[str]:
    """Entries left in the session's temporary folder besides pytest's own ``tmp_path``
    tree, after this process removed its extraction folder; the folder is then removed."""
    from glider_cosim import tempdirs

    base, old_env, old_tempdir = config._glider_tmp
    tempdirs.cleanup()
    leaked = sorted(e.name for e in os.scandir(base) if not e.name.startswith("pytest-of-"))
    tempfile.tempdir = old_tempdir
    if old_env is None:
        os.environ.pop("TMPDIR", None)
    else:
        os.environ["TMPDIR"] = old_env
    shutil.rmtree(base, ignore_errors=True)
    return leaked


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
    """Fail the session if it left temporary files (see :func:`pytest_configure`)."""
    leaked = _leaked_temp_files(session.config)
    if leaked:
        sys.stderr.write(f"\nthe test session left temporary files: {', '.join(leaked[:20])}\n")
        session.exitstatus = exitstatus = pytest.ExitCode.TESTS_FAILED
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
