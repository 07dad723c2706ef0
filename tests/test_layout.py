"""The package's layout: one direction of imports, no circle, a docstring per module,
and the diagram of it in docs/explanation/code-layout.md.

Every import is counted, at module level, inside functions and under ``TYPE_CHECKING``
alike: an import deferred into a function is still a dependency. The layers, from the
bottom, are :data:`LAYERS`; a module may import its own subpackage and the layers below
it, never a layer above or a sibling on its own layer. docs "Where things are" shows
the same picture.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from glider_cosim.components import COMPONENTS, package_dirs

ROOT = Path(__file__).resolve().parents[1]
#: import package -> its folder, as ``setup.py`` maps them (from the component registry)
ROOTS = {name: ROOT / folder for name, folder in package_dirs().items()}
#: the components' packages (the registry's): one layer group, over the FMI layer
COMPONENT_PACKAGES = tuple(c.package for c in COMPONENTS)
#: the layers, bottom first: the FMI layer, the components' packages, then the groups of
#: ``glider_cosim`` (its subpackages and top-level modules); docs "Where things are"
#: draws the same
LAYERS = (
    ("glider_fmi",),
    ("glider_<component>",),
    ("components",),
    ("inputs", "progress", "extras"),
    ("fmus",),
    ("master",),
    ("scenarios",),
    ("interop", "realtime", "figures"),
    ("runner",),
    ("sweeps", "verify"),
    ("studies",),
    ("testing", "cli"),
)
LEVEL = {group: i for i, names in enumerate(LAYERS) for group in names}
#: the components' pure models: no FMI, no master
MODEL_PACKAGES = COMPONENT_PACKAGES


def modules() -> dict[str, Path]:
    """Every module of the five import packages, by dotted name."""
    found = {}
    for pkg, folder in ROOTS.items():
        for path in folder.rglob("*.py"):
            parts = (pkg, *path.relative_to(folder).with_suffix("").parts)
            name = ".".join(parts).removesuffix(".__init__")
            found[name] = path
    return found


def imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of ours that ``name`` imports (anywhere in the file)."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            # ``from pkg import sub`` imports the submodule; ``from mod import name`` the module
            subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in known]
            targets = subs if len(subs) == len(node.names) else [base, *subs]
        else:
            continue
        for t in targets:
            while t and t not in known:  # ``import a.b.c`` of a name inside a module
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


GRAPH = {n: imports(n, p, modules()) for n, p in modules().items()}


def group(name: str) -> str | None:
    """The layer group of a module: its top-level package, or for ``glider_cosim`` its
    subpackage or top-level module (None: ``glider_cosim`` itself)."""
    parts = name.split(".")
    if parts[0] in COMPONENT_PACKAGES:
        return "glider_<component>"
    if parts[0] != "glider_cosim":
        return parts[0]
    return parts[1] if len(parts) > 1 else None


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph``, as the modules along it, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return [*stack[stack.index(m) :], m]
            if m not in state and (c := visit(m)):
                return c
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (c := visit(n)):
            return c
    return None


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Imports against :data:`LAYERS`, as ``"a -> b (why)"``."""
    bad = []
    for a, targets in sorted(graph.items()):
        ga = group(a)
        if a.endswith(".__main__"):  # an entry point: imported by nothing, may use the CLI
            continue
        for b in sorted(targets):
            gb = group(b)
            if b.endswith(".__main__"):
                bad.append(f"{a} -> {b} (an entry point is never imported)")
            elif ga is None or gb is None or ga == gb:
                continue
            elif LEVEL[gb] >= LEVEL[ga]:
                how = "sideways" if LEVEL[gb] == LEVEL[ga] else "upward"
                bad.append(f"{a} -> {b} ({how}: {ga} is on layer {LEVEL[ga]}, {gb} on {LEVEL[gb]})")
    return bad


def test_every_group_is_on_a_layer():
    groups = {group(n) for n in GRAPH if group(n)}
    assert groups - set(LEVEL) == set(), (
        "place the new subpackage in LAYERS (and docs/explanation/code-layout.md)"
    )
    assert set(LEVEL) - groups == set()


def test_no_import_circle():
    assert find_cycle(GRAPH) is None, " -> ".join(find_cycle(GRAPH) or ())


def test_imports_go_one_way():
    assert upward_imports(GRAPH) == []


def test_the_pure_models_import_no_fmi_layer():
    """``model``, ``params``, ``laws``, ``filter``, ``riccati``: plain equations; only a
    component's ``slave``, its variable table ``variables`` and ``fmi_vars`` know the FMI
    layer."""
    for name, targets in GRAPH.items():
        if name.startswith(MODEL_PACKAGES) and not name.endswith(
            (".slave", ".variables", ".fmi_vars")
        ):
            assert not {t for t in targets if t.startswith("glider_fmi")}, name


def test_the_checks_catch_a_circle_and_an_upward_import():
    """The checks above can fail: a made-up graph with both defects."""
    graph = {
        "glider_cosim.master.a": {"glider_cosim.runner.b"},
        "glider_cosim.runner.b": {"glider_cosim.master.a"},
        "glider_plant.model": {"glider_cosim.runner.b"},
    }
    assert find_cycle(graph) == ["glider_cosim.master.a", "glider_cosim.runner.b",
                                 "glider_cosim.master.a"]  # fmt: skip
    assert upward_imports(graph) == [
        "glider_cosim.master.a -> glider_cosim.runner.b (upward: master is on layer 5, "
        "runner on 8)",
        "glider_plant.model -> glider_cosim.runner.b (upward: glider_<component> is on layer "
        "1, runner on 8)",
    ]
    imported = imports("glider_cosim.x.y", ROOT / "tests" / "test_layout.py", modules())
    assert "glider_cosim" not in imported  # this file imports nothing of ours


@pytest.mark.parametrize("name", sorted(modules()))
def test_every_module_says_what_it_is_for(name):
    doc = ast.get_docstring(ast.parse(modules()[name].read_text()))
    assert doc and doc.strip(), f"{name}: add a one-line docstring of what it is for"


def readme_diagram() -> dict[str, tuple[int, set[str]]]:
    """docs "Where things are": package -> (layer, modules named)."""
    text = (ROOT / "docs" / "explanation" / "code-layout.md").read_text()
    section = text[text.index("# Where things are") :]
    start = section.index("```\nlayer") + 4
    block = section[start : section.index("\n```", start)]
    rows: dict[str, tuple[int, set[str]]] = {}
    last = None
    for line in block.splitlines()[1:]:
        words = line.split("(")[0].split()
        if line.startswith(" " * 10) and last:  # a continuation of the modules
            rows[last][1].update(words)
            continue
        level, package, *mods = words
        rows[package] = (int(level), {m for m in mods if m != "-"})
        last = package
    return rows


def test_the_readme_draws_the_layers_and_every_module():
    rows = readme_diagram()
    want = {}
    for i, groups in enumerate(LAYERS):
        for g in groups:
            packages = [g if g.startswith("glider_") else f"glider_cosim.{g}"]
            if g == "glider_<component>":  # each component package of the default loop,
                # and one added to the registry if the diagram names it: adding a
                # component changes no file but its folder and its registry line
                packages = [c.package for c in COMPONENTS if c.in_every_run or c.package in rows]
            for package in packages:
                mods = {
                    n.removeprefix(package + ".")
                    for n in GRAPH
                    if n.startswith(package + ".") and not n.endswith((".__main__", ".__init__"))
                }
                want[package] = (i, mods)
    assert rows == want
