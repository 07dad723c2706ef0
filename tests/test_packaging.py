"""Packaging and the FMU cache, without building anything: every package folder is in
the distribution ``setup.py`` describes (from the component registry), and the cache's
location and keys."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from setup_args import setup_kwargs

from glider_cosim.fmus import folders as build

ROOT = Path(__file__).resolve().parents[1]


_setuptools = setup_kwargs


def package_folders() -> set[str]:
    """Every folder with an ``__init__.py`` under the roots of ``package-dir``, as the
    dotted name it installs as."""
    found = set()
    for name, root in _setuptools()["package_dir"].items():
        for init in (ROOT / root).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / root)
            found.add(".".join((name, *rel.parts)))
    return found


def test_every_package_folder_is_in_the_distribution():
    """A new subpackage (a folder with ``__init__.py``) missing from ``packages`` would
    import from a checkout and fail from the wheel: list it in pyproject.toml."""
    given = _setuptools()
    listed = set(given["packages"])
    assert package_folders() - listed == set(), "setup.py leaves these out"
    assert listed - package_folders() == set()
    # every registered component is a package, with its component.toml in the wheel
    from glider_cosim.components import registry

    for name, folder in registry().items():
        assert given["package_dir"][f"glider_{name}"] == folder
        assert "*.toml" in given["package_data"][f"glider_{name}"]
    assert "components.toml" in given["package_data"]["glider_cosim"]


def test_the_cache_follows_xdg_then_the_platform(monkeypatch, tmp_path):
    import platformdirs

    monkeypatch.delenv(build.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert build.cache_root() == tmp_path / "glider-cosim"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert build.cache_root() == Path(platformdirs.user_cache_dir()) / "glider-cosim"
    if sys.platform == "linux":
        assert build.cache_root() == tmp_path / "home" / ".cache" / "glider-cosim"
    monkeypatch.setenv(build.CACHE_ENV, str(tmp_path / "own"))
    assert build.cache_root() == tmp_path / "own"


def test_the_cache_folder_is_keyed_by_version_flavor_and_sources(monkeypatch, tmp_path):
    from glider_cosim.fmus.files import package_version as _version

    monkeypatch.setenv(build.CACHE_ENV, str(tmp_path))
    python, native = build.cache_dir("python"), build.cache_dir("native")
    assert python.parent == native.parent == tmp_path / _version()
    assert python.name.startswith("python-") and native.name.startswith("native-")
    assert build.cache_dir("python") == python  # stable for the same sources
    monkeypatch.setattr(build, "source_hash", lambda c: "edited " + c.name)
    assert build.cache_dir("python") != python  # other sources, another folder: rebuilt
    assert build.fmu_folder(None) == build.cache_dir("python")
    assert build.fmu_folder("x") == Path("x")
    with pytest.raises(ValueError, match="flavor 'java' is invalid"):
        build.cache_dir("java")


def test_the_api_defaults_are_the_cache_not_the_current_folder():
    import inspect

    from glider_cosim.interop import onefmu
    from glider_cosim.interop import ssp_export as ssp
    from glider_cosim.runner import monolithic
    from glider_cosim.runner import run as runner
    from glider_cosim.studies import report
    from glider_cosim.verify import writing as verify

    assert runner.DEFAULT_FMU_DIR is None
    for f in (runner.simulate, report.build_report, ssp.export_ssp, onefmu.export_one_fmu,
              verify.write_references, verify.export, monolithic.simulate_monolithic,
              monolithic.simulate_continuous):  # fmt: skip
        assert inspect.signature(f).parameters["fmu_dir"].default is None, f.__qualname__
    assert build.DEFAULT_DIRS["python"] == Path("fmus")  # `glider-cosim build` exports here
