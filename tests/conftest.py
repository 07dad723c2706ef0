"""Shared fixtures: FMUs are built once per test session into a temporary folder."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest
from system_tools import require_tool

#: pytester runs small sessions of their own (tests/test_system_tools.py)
pytest_plugins = ["pytester"]
HERE = Path(__file__).parent
#: the session's FMU cache, in its temporary folder (see :func:`pytest_configure`)
CACHE_FOLDER = "glider-cosim-cache"
CACHE_ENV = "GLIDER_COSIM_CACHE"


def pytest_configure(config):
    """Every temporary file of the session goes to one private folder, checked at the end.

    ``$TMPDIR`` (inherited by subprocesses) and :mod:`tempfile` point into it, so that
    pytest's ``tmp_path`` folders, our extracted FMUs and SSPs, and whatever the CLI
    subprocesses and Dask workers create all land there.

    The FMU cache (``$GLIDER_COSIM_CACHE``, the default FMU folder of runs and of the CLI)
    is one folder of it too, so that the session never writes into the user's cache and
    builds each flavor once, for the fixtures and for runs without ``--fmu-dir`` alike.
    """
    config.addinivalue_line(
        "markers",
        "requires_tool(*names): needs one of these programs on PATH; skipped when absent, "
        "failed when GLIDER_COSIM_REQUIRE_TOOLS=1 (tests/system_tools.py)",
    )
    base = tempfile.mkdtemp(prefix="glider-tests-")
    config._glider_tmp = (
        base,
        os.environ.get("TMPDIR"),
        tempfile.tempdir,
        os.environ.get(CACHE_ENV),
    )
    os.environ["TMPDIR"] = base
    os.environ[CACHE_ENV] = os.path.join(base, CACHE_FOLDER)
    tempfile.tempdir = base


def _leaked_temp_files(config) -> list[str]:
    """Entries left in the session's temporary folder besides pytest's own ``tmp_path``
    tree, after this process removed its extraction folder; the folder is then removed."""
    from glider_cosim.inputs import tempdirs

    base, old_env, old_tempdir, old_cache = config._glider_tmp
    tempdirs.cleanup()
    leaked = sorted(
        e.name
        for e in os.scandir(base)
        if not e.name.startswith("pytest-of-") and e.name != CACHE_FOLDER
    )
    tempfile.tempdir = old_tempdir
    for name, old in (("TMPDIR", old_env), (CACHE_ENV, old_cache)):
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old
    shutil.rmtree(base, ignore_errors=True)
    return leaked


def pytest_runtest_setup(item):
    """``@pytest.mark.requires_tool("a", "b")``: skip (or, under CI, fail) the test when
    none of the programs is on ``PATH`` (see :mod:`system_tools`)."""
    for mark in item.iter_markers("requires_tool"):
        require_tool(*mark.args, **mark.kwargs)


@pytest.fixture(scope="session")
def fmu_dir() -> Path:
    """Our three FMUs, built from the current sources into the session's cache (the
    folder runs without ``fmu_dir`` use too)."""
    from glider_cosim.fmus.folders import prepare_fmus

    return prepare_fmus(None, "python")


@pytest.fixture(scope="session")
def native_dir() -> Path:
    """Our three FMUs in the native flavor (C99), built from the current sources into
    the session's cache."""
    from glider_cosim.fmus.folders import prepare_fmus

    return prepare_fmus(None, "native")


@pytest.fixture(scope="session")
def fmi3_dirs(tmp_path_factory) -> dict[str, Path]:
    """Our three FMUs as FMI 3.0, in both flavors (flavor -> folder), built once."""
    from glider_cosim.fmus.fmi3 import build_fmi3

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
    from glider_cosim.fmus.python import package_slave
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
