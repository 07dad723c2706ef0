"""One-FMU export of the closed loop (``glider-cosim export-fmu``).

Plant, observer and controller become a single FMI 2.0 co-simulation FMU, for tools
that take one FMU, built with fmu-manipulation-toolbox's FMU container
(``fmu_manipulation_toolbox.container.FMUContainer``, the library behind its
``fmucontainer`` command). The container embeds the three FMUs unchanged and steps
them at the scenario's step (0.02 s) whatever communication step its host uses.

Its scheduling is the container's default (parallel, one thread): at every internal
step all embedded FMUs step, then the container copies every linked output to its
inputs. Each link therefore carries the value of the previous internal step, exactly
as our master's ``coupling="jacobi"`` and libcosim's fixed-step algorithm do: the
container's glide angle equals our Jacobi run bit for bit, and differs from our
default Gauss-Seidel run by one sample of extra delay through the controller (0.47 deg
at most over the default scenario). The container's ``sequential`` mode (each FMU
stepped in turn with the outputs just computed, plant first) is neither scheme: the
observer integrates over ``[t_k, t_k + h]`` with the pitch measured at ``t_k + h``
(0.43 deg from our Gauss-Seidel run, 0.89 deg from our Jacobi run), so it is not used.

The container FMU exposes

- parameters: the closed loop's main ones (:data:`EXPOSED`: ``controller.K_c``,
  ``controller.law``, ``plant.theta_g_0``, ``plant.noise_std``, ``plant.noise_seed``),
  with the scenario's values as start values; the container passes a value set on them
  straight to the embedded FMU (fmu-manipulation-toolbox forwards a container input
  that feeds one FMU at the ``fmi2Set*`` call), so a host sets them as it would on our
  FMUs, before initialisation (or, for the tunable controller ones, between steps);
- outputs: every output of every instance, named ``plant.theta_g``,
  ``observer.V_hat``, ``controller.delta_cmd`` and so on;
- inputs: the disturbances ``plant.F_x``, ``plant.F_z``, ``plant.M_y`` (N, N, N m);
- the scenario's other parameter values as start values of the embedded FMUs, and its
  stop time as the default experiment.

Two things fmu-manipulation-toolbox 2.0 does not do are done here, after it has built the
container:

- **units**: its model description has no ``UnitDefinitions`` and no ``unit`` on any
  variable (``EmbeddedFMUPort.xml`` writes name, causality, variability, initial,
  description and start only). The embedded FMUs' unit definitions are copied in and
  every Real variable gets the ``unit`` and ``displayUnit`` of the embedded variable it
  maps to (``modelDescription.xml`` rewritten in the archive).
- **a quiet start**: its 2.0 binary sends three lines to the host's logger at every
  ``fmi2Instantiate``, whatever ``loggingOn`` says: ``[WARNING] FMUContainer 'V2.0'``,
  ``[ERROR] Solver configure....`` (logged at error level while the container reads
  its configuration: the string sits beside ``Container is configured.`` in
  ``container.so``, and is in none of the project's published sources) and
  ``[WARNING] Container use PARALLEL mode with MONO thread.`` (its ``logger()``
  forwards every warning and error to the host). The container's binary is kept as
  ``binaries/linux64/GliderLoop.container.so`` and ``GliderLoop.so`` is a small
  forwarder (``onefmu_quiet.c``, compiled by the build's C toolchain, zig by default)
  that drops exactly these three lines, and only during ``fmi2Instantiate``; every other
  message reaches the host unchanged.

pythonfmu FMUs need a Python interpreter in the host process: a C/C++ host of the
container needs the environment of ``glider-cosim host-env``.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.etree import ElementTree as ET

if TYPE_CHECKING:
    from ..scenarios.scenario import Scenario

#: model identifier (and file stem inside the build folder) of the container
CONTAINER_NAME = "GliderLoop"

#: parameters of the embedded FMUs that the container exposes as its own, by the same name
EXPOSED = (
    "controller.K_c",
    "controller.law",
    "plant.theta_g_0",
    "plant.noise_std",
    "plant.noise_seed",
)

#: the forwarder that silences the container's start-up lines (see the module's text)
QUIET_SOURCE = Path(__file__).with_name("onefmu_quiet.c")


class OneFMUError(ValueError):
    """The scenario cannot be exported as one FMU, or the container build failed.

    The message is one line naming the scenario key or the container's complaint.
    """


class _Collect(logging.Handler):
    """Keeps the container builder's warnings and errors (instead of printing them)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(" ".join(record.getMessage().split()))


def export_one_fmu(
    out_path: str | Path,
    scenario: Scenario | str | Path | None = None,
    fmu_dir: str | Path | None = None,
) -> Path:
    """Build the scenario's closed loop as one co-simulation FMU.

    Parameters
    ----------
    out_path : path
        The ``.fmu`` file to write (its folder is created).
    scenario : Scenario, path, shipped name or None
        The scenario (``None``: the default): its instances and connections
        (``feedback``, ``with_observer``), parameter values, constant inputs, step and
        stop time. Events, disturbances and swapped FMUs are refused.
    fmu_dir : path, optional
        Where our FMUs are (built there first if missing or stale; default: the per-user
        cache).

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    OneFMUError
        The scenario has events, disturbances or swapped FMUs, a parameter the FMUs lack,
        or the container builder failed.
    """
    from fmpy import read_model_description

    from ..extras import require

    require("interop", "fmu_manipulation_toolbox")
    from fmu_manipulation_toolbox.container import FMUContainer, FMUContainerError

    from ..components import component
    from ..fmus.folders import build_all, fmu_folder
    from ..scenarios.sampling import has_our_observer, with_sampling
    from ..scenarios.scenario import Scenario, load_scenario
    from ..scenarios.system import DISTURBANCE_INPUTS, scenario_connections
    from .container_order import initial_inputs, ordered

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    for key, present in (("event", sc.events), ("disturbance", sc.disturbances), ("fmus", sc.fmus)):
        if present:
            raise OneFMUError(
                f"{sc.source}: key '{key}': events, disturbances and swapped FMUs cannot be "
                "exported into one FMU"
            )
    from ..fmus.folders import folder_fmi
    from ..inputs.text import quote

    if fmu_dir is not None and folder_fmi(fmu_dir) == 3:
        raise OneFMUError(
            f"{quote(str(fmu_dir))} holds FMI 3.0 FMUs: the one-FMU export takes FMI 2.0 ones "
            "(the container is an FMI 2.0 FMU); use --fmu-dir with an FMI 2 folder"
        )
    built = build_all(fmu_folder(fmu_dir), only_stale=True, host_only=False)  # handed on
    files = {i: f"{component(i).model}.fmu" for i in sc.instances()}
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    log = logging.getLogger("fmu_manipulation_toolbox")
    handler = _Collect()
    old_level, old_propagate = log.level, log.propagate
    log.addHandler(handler)
    log.setLevel(logging.WARNING)
    log.propagate = False
    try:
        with tempfile.TemporaryDirectory(prefix="glider_container_") as tmp:
            work = Path(tmp)
            for inst, fname in files.items():
                shutil.copy2(built[component(inst).model], work / fname)
            container = ordered(FMUContainer)(CONTAINER_NAME, work, fmi_version=2)
            container.initial_inputs = {f: initial_inputs(work / f) for f in files.values()}
            container.stop_time = float(sc.stop_time)
            for fname in files.values():
                container.get_fmu(fname)
            for src, dst in scenario_connections(sc):
                (si, sv), (di, dv) = src.split(".", 1), dst.split(".", 1)
                container.add_link(files[si], sv, files[di], dv)
            for ref in DISTURBANCE_INPUTS:
                inst, name = ref.split(".", 1)
                container.add_input(ref, files[inst], name)
            exposed = [r for r in EXPOSED if r.split(".", 1)[0] in files]
            for ref in exposed:
                inst, name = ref.split(".", 1)
                container.add_input(ref, files[inst], name)
            types = {}  # instance.variable -> FMI type (the LS-REF parameter sets)
            for inst, fname in files.items():
                md = read_model_description(str(work / fname))
                for v in md.modelVariables:
                    types[f"{inst}.{v.name}"] = v.type
                    if v.causality == "output":
                        container.add_output(fname, v.name, f"{inst}.{v.name}")
            values = with_sampling(sc.parameters, sc.step, sc.source, has_our_observer(sc))
            for ref, value in sc.inputs.items():
                inst, _, name = ref.partition(".")
                values.setdefault(inst, {})[name] = value
            for inst, params in values.items():
                if inst not in files:
                    raise OneFMUError(f"{sc.source}: key '{inst}': the loop has no instance {inst}")
                for name, value in params.items():
                    try:
                        container.add_start_value(files[inst], name, _text(value))
                    except FMUContainerError as err:
                        raise OneFMUError(
                            f"{sc.source}: key '{inst}.{name}': {_reason(err)}"
                        ) from None
            container.add_implicit_rule(
                auto_input=False, auto_output=False, auto_link=False, auto_parameter=False
            )
            container.make_fmu(f"{CONTAINER_NAME}.fmu", step_size=float(sc.step))
            starts = {
                f"{i}.{n}": _text(v)
                for i, params in values.items()
                for n, v in params.items()
                if f"{i}.{n}" in exposed
            }
            from .onefmu_lsref import loop_entries

            folder = Path(built["GliderPlant"]).parent
            extra = loop_entries(sc, folder, CONTAINER_NAME, tuple(exposed), types)
            _finish(work / f"{CONTAINER_NAME}.fmu", work, files, out, starts, extra)
    except FMUContainerError as err:
        raise OneFMUError(f"{out}: the FMU container could not be built: {_reason(err)}") from None
    finally:
        log.removeHandler(handler)
        log.setLevel(old_level)
        log.propagate = old_propagate
    if not out.is_file():
        last = (handler.messages or ["no message"])[-1]
        raise OneFMUError(f"{out}: the FMU container was not written ({last})")
    return out


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _reason(err: Exception) -> str:
    return " ".join(str(getattr(err, "reason", err)).split())


def _finish(
    built: Path,
    work: Path,
    files: dict[str, str],
    out: Path,
    starts: dict[str, str],
    extra: dict[str, bytes],
) -> None:
    """Copy the container to ``out`` with units in its model description and the quiet
    forwarder as its binary (the container's own kept beside it), and the files of
    ``extra`` (zip path -> bytes: its FMI-LS-REF folder)."""
    from glider_fmi.compile import fmi_headers
    from glider_fmi.toolchain import ToolchainError, host_command

    binary = f"binaries/linux64/{CONTAINER_NAME}.so"
    forwarder = work / "quiet.so"
    try:
        start = host_command()
    except ToolchainError as err:
        raise OneFMUError(f"{out}: the container's forwarder cannot be compiled: {err}") from None
    cmd = [*start, "-O2", f"-I{fmi_headers()}", str(QUIET_SOURCE), "-o", str(forwarder),
           "-ldl", "-lpthread"]  # fmt: skip
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or [f"exit code {p.returncode}"])[-1]
        raise OneFMUError(f"{out}: the container's forwarder did not compile: {last}")
    with zipfile.ZipFile(built) as z:
        names = z.namelist()
        if binary not in names:
            raise OneFMUError(f"{out}: the FMU container has no {binary}")
        md = with_units(z.read("modelDescription.xml"), work, files, starts)
        tmp = out.with_name(out.name + ".part")
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as dst:
            for info in z.infolist():
                data = z.read(info)
                if info.filename == "modelDescription.xml":
                    data = md
                elif info.filename == binary:
                    data = forwarder.read_bytes()
                    dst.writestr(
                        _entry(info, binary[: -len(".so")] + ".container.so"), z.read(info)
                    )
                dst.writestr(_entry(info, info.filename), data)
            for name, data in extra.items():
                dst.writestr(name, data)
    tmp.replace(out)


def _drop_time(root: ET.Element) -> None:
    """Remove the toolbox's ``time`` variable (``causality="independent"``): optional in
    FMI 2.0, and the FMI Library under libcosim reports "Start attribute is required for
    this causality, variability and initial combination" for it. The ``<Unknown
    index>`` entries are renumbered."""
    variables = root.find("ModelVariables")
    if variables is None:
        return
    listed = list(variables)
    time = [v for v in listed if v.get("causality") == "independent"]
    if not time:
        return
    old = {id(v): i for i, v in enumerate(listed, start=1)}
    for v in time:
        variables.remove(v)
    new = {old[id(v)]: i for i, v in enumerate(variables, start=1)}
    for unknown in root.iter("Unknown"):
        unknown.set("index", str(new[int(unknown.get("index"))]))
        deps = unknown.get("dependencies")
        if deps:
            unknown.set("dependencies", " ".join(str(new[int(d)]) for d in deps.split()))


def _entry(like: zipfile.ZipInfo, name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, like.date_time)
    info.external_attr = like.external_attr
    info.compress_type = zipfile.ZIP_DEFLATED
    return info


def with_units(
    xml: bytes, work: Path, files: dict[str, str], starts: dict[str, str] | None = None
) -> bytes:
    """The container's model description with the embedded FMUs' ``UnitDefinitions``
    and, on every Real variable, the ``unit`` and ``displayUnit`` of the embedded
    variable it maps to (outputs and inputs named ``instance.variable``; links named
    ``<model name, lower case>.variable`` by the toolbox); ``starts``: start values of
    the exposed parameters (the toolbox writes the embedded FMU's start value there,
    not the one given to ``add_start_value``)."""
    units: dict[str, ET.Element] = {}
    var_units: dict[str, tuple[str | None, str | None]] = {}
    for inst, fname in files.items():
        with zipfile.ZipFile(work / fname) as z:
            root = ET.fromstring(z.read("modelDescription.xml"))
        for unit in root.findall("UnitDefinitions/Unit"):
            units.setdefault(unit.get("name"), unit)
        model = root.get("modelName", "").lower()
        for v in root.findall("ModelVariables/ScalarVariable"):
            real = v.find("Real")
            if real is None or real.get("unit") is None:
                continue
            pair = (real.get("unit"), real.get("displayUnit"))
            var_units[f"{inst}.{v.get('name')}"] = pair
            var_units.setdefault(f"{model}.{v.get('name')}", pair)
    root = ET.fromstring(xml)
    _drop_time(root)
    used: set[str] = set()
    for v in root.findall("ModelVariables/ScalarVariable"):
        if v.get("name") in (starts or {}) and len(v):
            v[0].set("start", starts[v.get("name")])
        real = v.find("Real")
        pair = var_units.get(v.get("name", ""))
        if real is None or pair is None:
            continue
        real.set("unit", pair[0])
        if pair[1]:
            real.set("displayUnit", pair[1])
        used.add(pair[0])
    if used:
        defs = ET.Element("UnitDefinitions")
        defs.extend(units[u] for u in sorted(used) if u in units)
        children = list(root)
        at = next(
            (i for i, c in enumerate(children) if c.tag not in ("CoSimulation", "ModelExchange")),
            len(children),
        )
        root.insert(at, defs)
    return (
        b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode").encode()
    )
