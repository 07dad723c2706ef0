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
def native_dir(tmp_path_factory) -> Path:
    """Our three FMUs in the native flavor (C99), built from the current sources."""
    from glider_cosim.build import build_all

    out = tmp_path_factory.mktemp("native_fmus")
    build_all(out, flavor="native")
    return out


@pytest.fixture(scope="session")
def fmi3_dirs(tmp_path_factory) -> dict[str, Path]:
    """Our three FMUs as FMI 3.0, in both flavors (flavor -> folder), built once."""
    from glider_cosim.fmi3 import build_fmi3

    dirs = {}
    for flavor in ("python", "native"):
        dirs[flavor] = tmp_path_factory.mktemp(f"fmi3_{flavor}")
        build_fmi3(dirs[flavor], flavor)
    return dirs


@pytest.fixture(scope="session", params=["python", "native"])
def flavor_dir(request) -> Path:
    """The three FMUs of each flavor in turn: tests that take it run on both."""
    return request.getfixturevalue("fmu_dir" if request.param == "python" else "native_dir")


@pytest.fixture(scope="session")
def test_fmus(tmp_path_factory) -> dict[str, Path]:
    """Small FMUs written for the tests (integrator, gain, delay, runtime probe), on our
    FMI runtime like ours."""
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


def pytest_sessionfinish(session, exitstatus):
    """Fail the session if it left temporary files (see :func:`pytest_configure`)."""
    leaked = _leaked_temp_files(session.config)
    if leaked:
        sys.stderr.write(f"\nthe test session left temporary files: {', '.join(leaked[:20])}\n")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
