"""Build the three FMUs with pythonfmu (``glider-cosim build``)."""

from __future__ import annotations

import hashlib
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import glider_controller
import glider_observer
import glider_plant

#: resource file in each FMU holding the hash of the sources it was built from
HASH_FILE = "resources/glider_cosim_source.sha256"


@dataclass(frozen=True)
class Component:
    """An FMU: its model identifier and the packages it bundles (slave script first)."""

    name: str
    packages: tuple[Path, ...]

    @property
    def slave_module(self) -> str:
        """Module holding the slave class, e.g. ``glider_plant.slave``."""
        return f"{PACKAGE_NAMES[self.packages[0]]}.slave"

    @property
    def sources(self) -> list[Path]:
        return sorted(f for pkg in self.packages for f in pkg.glob("*.py"))


def _pkg(module) -> Path:
    return Path(module.__file__).resolve().parent


COMPONENTS: tuple[Component, ...] = (
    Component("GliderPlant", (_pkg(glider_plant),)),
    Component("GliderObserver", (_pkg(glider_observer), _pkg(glider_plant))),
    Component("GliderController", (_pkg(glider_controller), _pkg(glider_plant))),
)
PACKAGE_NAMES = {
    _pkg(glider_plant): "glider_plant",
    _pkg(glider_observer): "glider_observer",
    _pkg(glider_controller): "glider_controller",
}


def source_hash(c: Component) -> str:
    """SHA-256 over the component's source files and the script shim that build writes."""
    h = hashlib.sha256(shim_text(c).encode())
    for f in c.sources:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def shim_text(c: Component) -> str:
    """The FMU's script: it only imports the slave class (see build_component)."""
    return (
        f'"""pythonfmu entry point of {c.name}: the slave is {c.slave_module}."""\n\n'
        f'from {c.slave_module} import {c.name}\n\n__all__ = ["{c.name}"]\n\n'
        "# pythonfmu 0.7 releases one reference to this namespace per instantiation that\n"
        "# it never owned; the slave's constructor gives one back, this one bridges the\n"
        "# gap between the two (see glider_plant.fmi_base).\n"
        "_NAMESPACE = globals()\n"
    )


def is_current(fmu: Path, c: Component) -> bool:
    """True if ``fmu`` exists and was built from the current sources."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(HASH_FILE).decode().strip() == source_hash(c)
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


def build_component(c: Component, out: Path) -> Path:
    """Build one FMU into ``out`` and return its path."""
    from pythonfmu.builder import FmuBuilder

    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"{c.name}_") as tmp:
        stage = Path(tmp)
        # The FMU's script is a shim that imports the slave class: pythonfmu re-executes
        # the script at every instantiation (and leaks what it defines), so it defines
        # nothing itself. Its name is the model identifier, unique per FMU.
        script = stage / f"{c.name}.py"
        script.write_text(shim_text(c))
        project = []
        for pkg in c.packages:
            dst = stage / PACKAGE_NAMES[pkg]
            shutil.copytree(pkg, dst, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
            project.append(dst)
        (stage / "glider_cosim_source.sha256").write_text(source_hash(c) + "\n")
        project.append(stage / "glider_cosim_source.sha256")
        fmu = FmuBuilder.build_FMU(
            script,
            dest=out,
            project_files=project,
            canGetAndSetFMUstate=True,
        )
    return Path(fmu)


def build_all(out: Path | str = "fmus", only_stale: bool = False) -> dict[str, Path]:
    """Build GliderPlant, GliderObserver and GliderController into ``out``.

    Parameters
    ----------
    out : path
        Output folder (created if missing).
    only_stale : bool
        Rebuild only FMUs that are missing or were built from other sources.

    Returns
    -------
    dict
        Model identifier -> path of the ``.fmu``.
    """
    out = Path(out)
    result = {}
    for c in COMPONENTS:
        fmu = out / f"{c.name}.fmu"
        if not (only_stale and is_current(fmu, c)):
            fmu = build_component(c, out)
        result[c.name] = fmu
    return result
