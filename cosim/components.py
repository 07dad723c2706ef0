"""The component registry: which components the loop is made of, and all that the rest of
glider-cosim asks of each one.

One place names the components: ``components.toml`` beside this module holds one line per
component, its name (the instance name in scenarios) and its folder; the folder's
``component.toml`` holds the rest (its FMU's model name, the packages and C sources its
FMUs are built from, its reference case, its default connections, what an FMU swapped in
for it must have). Every other module asks :func:`component` or :data:`COMPONENTS`;
``setup.py`` packages each folder as the import package ``glider_<name>``
(:func:`package_dirs`). Adding a component is one folder and one line:
``docs/how-to/add-a-component.md``.

This module imports nothing of glider-cosim's and no component package (it finds their
folders with :func:`importlib.util.find_spec`), so every layer may ask it.
"""

from __future__ import annotations

import importlib.util
import re
import tomllib
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

__all__ = ["COMPONENTS", "Component", "ComponentError", "UnknownComponentError", "by_model",
           "bundled", "component", "default_connections", "every_run", "fmi_folder",
           "names_in_words", "package_dirs", "registry"]  # fmt: skip

#: the registry: ``[components]`` name = folder (relative to the project root)
REGISTRY = Path(__file__).with_name("components.toml")
#: the shared FMI layer every component's FMU is built on (not a component of the loop)
FMI_PACKAGE = ("glider_fmi", "src/fmi")
_NAME = re.compile(r"[a-z][a-z0-9_]*")
_CONNECTION = re.compile(r"[A-Za-z_]\w*\.[A-Za-z_]\w*")
_NEEDS = ("required", "optional", "read")
_KEYS = {"model", "summary", "in_every_run", "estimator", "bundles", "c_sources", "inputs",
         "state_feedback", "driven", "interface", "reference", "kit"}  # fmt: skip


class ComponentError(ValueError):
    """The registry or a component's ``component.toml`` is wrong (names the file, the key
    and what was expected)."""


class UnknownComponentError(ValueError):
    """A component name the registry does not hold (names the known ones)."""


@dataclass(frozen=True)
class Component:
    """One component of the loop, as its ``component.toml`` describes it.

    Attributes
    ----------
    name : str
        The instance name (``plant``), the key of its table in a scenario.
    model : str
        Its FMU's model name, the slave class of its ``slave.py`` (``GliderPlant``).
    package : str
        Its import package (``glider_plant``).
    folder : pathlib.Path
        Its folder (the package's, installed or in a checkout).
    summary : str
        One line: what it is.
    in_every_run : bool
        In the default loop; otherwise a scenario adds it (``components = [...]``).
    estimator : bool
        Its outputs are estimates: an input left unconnected is wired by name to an
        estimator's output before another component's.
    bundles : tuple of str
        The components whose packages its Python FMU bundles besides its own.
    c_sources : tuple of pathlib.Path
        The native flavor's C files besides the FMI layer; empty: Python flavor only.
    inputs : dict
        Its default connections: input -> ``"instance.output"``.
    state_feedback : dict
        Its inputs under ``feedback = "state"``, where they differ.
    driven : dict
        Inputs the loop drives itself -> their value (disturbances).
    interface : dict
        What an FMU swapped in for it must have: variable -> (causality, unit, need).
    reference : dict
        Its reference case's parameters (``reference_input.csv`` -> ``reference_output.csv``).
    default_case, core
        The verification kit's cross-check case, and the variables every case needs.
    """

    name: str
    model: str
    package: str
    folder: Path
    summary: str = ""
    in_every_run: bool = False
    estimator: bool = False
    bundles: tuple[str, ...] = ()
    c_sources: tuple[Path, ...] = ()
    inputs: dict[str, str] = field(default_factory=dict)
    state_feedback: dict[str, str] = field(default_factory=dict)
    driven: dict[str, float] = field(default_factory=dict)
    interface: dict[str, tuple[str, str, str]] = field(default_factory=dict)
    reference: dict[str, Any] = field(default_factory=dict)
    default_case: str | None = None
    core: dict[str, str] = field(default_factory=dict)

    @property
    def slave(self) -> str:
        """``module:class`` of its pythonfmu slave (``glider_plant.slave:GliderPlant``)."""
        return f"{self.package}.slave:{self.model}"

    @property
    def native(self) -> bool:
        """True if it has a native flavor (C sources)."""
        return bool(self.c_sources)

    def slave_class(self) -> type:
        """The slave class (imports the component's package)."""
        module, _, cls = self.slave.partition(":")
        return getattr(importlib.import_module(module), cls)

    def connections(self, feedback: str = "observer") -> list[tuple[str, str]]:
        """Its default connections as ``(source, target)`` pairs, its inputs in order."""
        wiring = dict(self.inputs)
        if feedback == "state":
            wiring.update(self.state_feedback)
        return [(src, f"{self.name}.{inp}") for inp, src in wiring.items()]


def registry(path: Path = REGISTRY) -> dict[str, str]:
    """The registry's lines: component name -> folder (relative to the project root)."""
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ComponentError(f"{path}: cannot be read: {err}") from None
    table = data.get("components")
    if not isinstance(table, dict) or not table:
        raise ComponentError(f'{path}: expected a [components] table of name = "src/<name>"')
    for name, folder in table.items():
        if not _NAME.fullmatch(name) or not isinstance(folder, str) or not folder:
            raise ComponentError(
                f"{path}: component {name!r} = {folder!r} is invalid: expected a lower-case "
                'name = the folder\'s path (e.g. noise = "src/noise")'
            )
    return dict(table)


def package_dirs(path: Path = REGISTRY) -> dict[str, str]:
    """Import package -> folder, for ``setup.py``: the FMI layer, each registered
    component as ``glider_<name>``, and ``glider_cosim``."""
    comps = {f"glider_{n}": folder for n, folder in registry(path).items()}
    return {FMI_PACKAGE[0]: FMI_PACKAGE[1], **comps, "glider_cosim": "cosim"}


def _folder(name: str, package: str, source: str) -> Path:
    """The package's folder: where it is imported from, else the checkout's folder."""
    spec = importlib.util.find_spec(package)
    if spec is not None and spec.origin:
        return Path(spec.origin).resolve().parent
    folder = REGISTRY.parent.parent / source
    if (folder / "__init__.py").is_file():
        return folder
    raise ComponentError(
        f"component {name!r}: package {package} is not installed and {folder} has no "
        "__init__.py: expected the folder of cosim/components.toml's line (reinstall after "
        "adding one: pip install -e .)"
    )


def _load(name: str, source: str, lines: dict[str, str]) -> Component:
    known = list(lines)
    package = f"glider_{name}"
    folder = _folder(name, package, source)
    path = folder / "component.toml"
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ComponentError(f"{path}: cannot be read: {err}") from None

    def bad(key: str, expected: str) -> ComponentError:
        return ComponentError(f"{path}: key {key!r} is invalid: expected {expected}")

    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise bad(unknown[0], f"one of {', '.join(sorted(_KEYS))}")
    model = data.get("model")
    if not isinstance(model, str) or not model.isidentifier():
        raise bad("model", "the FMU's model name, the slave class of slave.py")

    def table(key: str, check: Any, expected: str) -> dict[str, Any]:
        value = data.get(key, {})
        if not isinstance(value, dict) or not all(check(v) for v in value.values()):
            raise bad(key, expected)
        return dict(value)

    def names(key: str) -> list[str]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise bad(key, "a list of strings")
        return value

    for other in names("bundles"):
        if other not in known and other != "fmi":
            raise bad("bundles", f"fmi or components of the registry ({', '.join(known)})")
    c_sources = []
    for item in names("c_sources"):
        owner, sep, file = item.rpartition(":")
        if sep and owner not in known:
            raise bad("c_sources", f"'<component>:<file>' of a registered component, not {item!r}")
        base = _folder(owner, f"glider_{owner}", lines[owner]) if sep else folder
        c_sources.append(base / file)
    conn = table("inputs", lambda v: isinstance(v, str) and _CONNECTION.fullmatch(v),
                 "input = \"instance.output\"")  # fmt: skip
    state = table("state_feedback", lambda v: isinstance(v, str) and _CONNECTION.fullmatch(v),
                  "input = \"instance.output\"")  # fmt: skip
    driven = table("driven", lambda v: isinstance(v, int | float) and not isinstance(v, bool),
                   "input = a number")  # fmt: skip
    interface = table(
        "interface",
        lambda v: isinstance(v, list) and len(v) == 3 and v[2] in _NEEDS,
        f"variable = [causality, unit, need], need one of {', '.join(_NEEDS)}",
    )
    reference = data.get("reference", {})
    kit = data.get("kit", {})
    if not isinstance(reference, dict) or not isinstance(reference.get("parameters", {}), dict):
        raise bad("reference", "a table with parameters = { name = value, ... }")
    if not isinstance(kit, dict):
        raise bad("kit", "a table with default_case and core")
    return Component(
        name=name,
        model=model,
        package=package,
        folder=folder,
        summary=str(data.get("summary", "")),
        in_every_run=bool(data.get("in_every_run", False)),
        estimator=bool(data.get("estimator", False)),
        bundles=tuple(names("bundles")),
        c_sources=tuple(c_sources),
        inputs=conn,
        state_feedback=state,
        driven={k: float(v) for k, v in driven.items()},
        interface={k: tuple(v) for k, v in interface.items()},
        reference=dict(reference.get("parameters", {})),
        default_case=kit.get("default_case"),
        core=dict(kit.get("core", {})),
    )


@cache
def _components() -> tuple[Component, ...]:
    lines = registry()
    return tuple(_load(name, folder, lines) for name, folder in lines.items())


def component(name: str) -> Component:
    """The component called ``name`` (an instance name: ``plant``).

    Raises
    ------
    UnknownComponentError
        ``name`` is not in the registry (the message names the known ones).
    """
    for c in _components():
        if c.name == name:
            return c
    known = ", ".join(c.name for c in _components())
    raise UnknownComponentError(f"component {name!r} is unknown: expected one of {known}")


def fmi_folder() -> Path:
    """The shared FMI layer's folder (``glider_fmi``: ``src/fmi``)."""
    return _folder("fmi", *FMI_PACKAGE)


def bundled(c: Component) -> tuple[tuple[str, Path], ...]:
    """The packages ``c``'s Python FMU bundles, its own first: (import name, folder)."""
    out = [(c.package, c.folder)]
    for b in c.bundles:
        out.append((FMI_PACKAGE[0], fmi_folder()) if b == "fmi" else
                   (component(b).package, component(b).folder))  # fmt: skip
    return tuple(out)


def names_in_words(names: list[str] | tuple[str, ...] | None = None) -> str:
    """``"plant, observer or controller"``: the components' names (default: every
    registered one) as a message lists the choices."""
    names = [c.name for c in _components()] if names is None else list(names)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def by_model(model: str) -> Component | None:
    """The component whose FMU's model name is ``model`` (``GliderPlant``), or None."""
    return next((c for c in _components() if c.model == model), None)


def every_run() -> tuple[Component, ...]:
    """The components of the default loop (``in_every_run``), in registry order."""
    return tuple(c for c in _components() if c.in_every_run)


def default_connections(
    instances: list[str] | tuple[str, ...] | None = None, feedback: str = "observer"
) -> list[tuple[str, str]]:
    """The loop's connections among ``instances`` (default: :func:`every_run`), as the
    components' ``[inputs]`` (and ``[state_feedback]``) say: each component's inputs in
    registry order, those whose source is not among ``instances`` left out."""
    names = [c.name for c in every_run()] if instances is None else list(instances)
    conns = []
    for c in _components():
        if c.name in names:
            conns += [(s, t) for s, t in c.connections(feedback) if s.partition(".")[0] in names]
    return conns


class _Lazy:
    """:data:`COMPONENTS`: the registry's components, read when first used."""

    def __iter__(self):
        return iter(_components())

    def __len__(self) -> int:
        return len(_components())

    def __getitem__(self, i: int) -> Component:
        return _components()[i]

    def __repr__(self) -> str:
        return repr(_components())


#: every registered component, in registry order (read on first use)
COMPONENTS = _Lazy()
