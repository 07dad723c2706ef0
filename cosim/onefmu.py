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

- outputs: every output of every instance, named ``plant.theta_g``,
  ``observer.V_hat``, ``controller.delta_cmd`` and so on;
- inputs: the disturbances ``plant.F_x``, ``plant.F_z``, ``plant.M_y`` (N, N, N m);
- the scenario's parameter values as start values of the embedded FMUs, and its stop
  time as the default experiment.

pythonfmu FMUs need a Python interpreter in the host process: a C/C++ host of the
container needs the environment of ``glider-cosim host-env``.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .scenario import Scenario

#: model identifier (and file stem inside the build folder) of the container
CONTAINER_NAME = "GliderLoop"


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
    fmu_dir: str | Path = "fmus",
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
    fmu_dir : path
        Where our FMUs are (built there first if missing or stale).

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
    from fmu_manipulation_toolbox.container import FMUContainer, FMUContainerError

    from .build import build_all
    from .runner import DISTURBANCE_INPUTS, FMU_NAMES, default_connections
    from .scenario import Scenario, has_our_observer, load_scenario, with_sampling

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    for key, present in (("event", sc.events), ("disturbance", sc.disturbances), ("fmus", sc.fmus)):
        if present:
            raise OneFMUError(
                f"{sc.source}: key '{key}': events, disturbances and swapped FMUs cannot be "
                "exported into one FMU"
            )
    from .build import folder_fmi
    from .inputs.text import quote

    if folder_fmi(fmu_dir) == 3:
        raise OneFMUError(
            f"{quote(str(fmu_dir))} holds FMI 3.0 FMUs: the one-FMU export takes FMI 2.0 ones "
            "(the container is an FMI 2.0 FMU); use --fmu-dir with an FMI 2 folder"
        )
    built = build_all(fmu_dir, only_stale=True)
    files = {i: f"{n}.fmu" for i, n in FMU_NAMES.items() if sc.observer or i != "observer"}
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
                shutil.copy2(built[FMU_NAMES[inst]], work / fname)
            container = FMUContainer(CONTAINER_NAME, work, fmi_version=2)
            container.stop_time = float(sc.stop_time)
            for fname in files.values():
                container.get_fmu(fname)
            for src, dst in default_connections(sc.feedback, sc.observer):
                (si, sv), (di, dv) = src.split(".", 1), dst.split(".", 1)
                container.add_link(files[si], sv, files[di], dv)
            for ref in DISTURBANCE_INPUTS:
                container.add_input(ref, files["plant"], ref.split(".", 1)[1])
            for inst, fname in files.items():
                md = read_model_description(str(work / fname))
                for v in md.modelVariables:
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
            shutil.copyfile(work / f"{CONTAINER_NAME}.fmu", out)
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
