"""Making a Python FMU's bundled imports relative (glider_fmi.bundle), without an FMU."""

from __future__ import annotations

import sys
import types

import pytest

from glider_fmi.bundle import BundleImportError, bundle_names, relativize, relativize_bundle

NAMES = {"glider_plant", "glider_fmi", "pythonfmu", "Shim"}


@pytest.mark.parametrize(
    ("source", "level", "expected"),
    [
        ("from glider_plant.model import f, g as h\n", 2,
         "from ..glider_plant.model import f, g as h\n"),
        ("from pythonfmu import Fmi2Slave\n", 1, "from .pythonfmu import Fmi2Slave\n"),
        ("import glider_plant\n", 2, "from .. import glider_plant\n"),
        ("import glider_plant as gp\n", 1, "from . import glider_plant as gp\n"),
        ("import glider_plant.model as m\n", 2, "from ..glider_plant import model as m\n"),
        ("import os, glider_fmi, sys as s\n", 2,
         "import os; from .. import glider_fmi; import sys as s\n"),
        ("def f():\n    from glider_fmi.state_codec import dumps\n", 2,
         "def f():\n    from ..glider_fmi.state_codec import dumps\n"),
        ("from glider_plant import (\n    a,\n    b,\n)\nx = 1\n", 2,
         "from ..glider_plant import a, b\nx = 1\n"),
        # not bundled, already relative, a name that only starts like a bundled one
        ("import numpy\nfrom . import x\nfrom glider_plantx import y\n", 2,
         "import numpy\nfrom . import x\nfrom glider_plantx import y\n"),
        ("s = 'é'; from glider_fmi import a\n", 2, "s = 'é'; from ..glider_fmi import a\n"),
        ("a = 1\r\nfrom glider_fmi import b\r\n", 2, "a = 1\r\nfrom ..glider_fmi import b\r\n"),
    ],
)  # fmt: skip
def test_imports_of_bundled_names_become_relative(source, level, expected):
    assert relativize(source, NAMES, level) == expected


def test_import_of_a_submodule_without_alias_is_refused_with_the_fix():
    with pytest.raises(BundleImportError) as err:
        relativize("x = 1\nimport glider_plant.model\n", NAMES, 2, "resources/a/b.py")
    assert str(err.value) == (
        "resources/a/b.py: line 2: 'import glider_plant.model' cannot be made relative: write "
        "'from glider_plant import model' or 'import glider_plant.model as NAME'"
    )


def test_a_syntax_error_names_the_file_and_line():
    with pytest.raises(BundleImportError, match=r"^resources/x\.py: line 1: "):
        relativize("def (:\n", NAMES, 1, "resources/x.py")


def test_bundle_names_are_top_level_modules_and_packages():
    paths = ["Shim.py", "glider_plant/__init__.py", "glider_plant/model.py",
             "data/table.csv", "loose/mod.py", "slavemodule.txt"]  # fmt: skip
    assert bundle_names(paths) == {"Shim", "glider_plant"}


def test_a_relativized_bundle_imports_under_any_package_name(tmp_path):
    """The rewritten bundle runs as a package of any name, and never uses sys.modules'
    top-level entries of the same names."""
    files = {
        "Shim.py": b"from pkg.mod import VALUE\n",
        "pkg/__init__.py": b"",
        "pkg/mod.py": b"import pkg.helper as helper\nVALUE = helper.SEVEN * 6\n",
        "pkg/helper.py": b"SEVEN = 7\n",
        "notes.txt": b"import pkg\n",
    }
    out = relativize_bundle(files)
    assert out["notes.txt"] == files["notes.txt"] and out["pkg/helper.py"] == files["pkg/helper.py"]
    for rel, data in out.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(data)
    decoy = types.ModuleType("pkg")  # a host module of the same name must not be used
    sys.modules["pkg"] = decoy
    root = types.ModuleType("_bundle_under_test")
    root.__path__ = [str(tmp_path)]
    sys.modules["_bundle_under_test"] = root
    try:
        import importlib

        shim = importlib.import_module("_bundle_under_test.Shim")
        assert shim.VALUE == 42
        assert sys.modules["pkg"] is decoy
    finally:
        for name in [m for m in sys.modules if m == "pkg" or m.startswith("_bundle_under_test")]:
            del sys.modules[name]


def test_sources_of_our_packages_relativize_without_refusal():
    """Every module the FMUs bundle can be rewritten (no 'import a.b' without alias)."""
    from pathlib import Path

    import glider_controller
    import glider_fmi
    import glider_observer
    import glider_plant

    names = {"glider_controller", "glider_fmi", "glider_observer", "glider_plant", "pythonfmu"}
    for pkg in (glider_controller, glider_fmi, glider_observer, glider_plant):
        for f in Path(pkg.__file__).parent.glob("*.py"):
            text = f.read_text()
            assert relativize(text, names, 2, f.name) != text or "import glider_" not in text
