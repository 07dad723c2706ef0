"""What a run records about itself: its settings, its FMUs, the events its plots mark.

``metrics.json`` gets a ``run`` object (:func:`run_record`): the scenario's name, source
and SHA-256, every override (``--set`` and the command-line options), the package
version and, per instance, the FMU's file, SHA-256, GUID, model name, flavor and
version. A run into an existing folder first removes
what an earlier run wrote there (:func:`clear_owned`), and nothing else.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..fmus.files import file_sha256, package_version
from ..fmus.variables import overrides_words, plain, short, with_unit
from .metrics import speed_stop

#: files a run writes into its folder (removed before a run into the same folder)
OWNED = (
    "results.csv",
    "results.parquet",
    "metrics.json",
    "glide_angle.png",
    "pitch.png",
    "tail_angle.png",
    "speed.png",
    "depth.png",
    "plots.html",
)
#: a resource inside an FMU that names its flavor (the runtime behind the slave)
FLAVOR_RESOURCES = ("resources/glider_cosim_flavor.txt",)
#: what a third-party FMU is recorded as
DEFAULT_FLAVOR = "unknown"


def clear_owned(out: Path) -> list[Path]:
    """Remove the files an earlier run wrote into ``out`` (:data:`OWNED`); return them.

    Anything else in the folder (the user's files, other commands' outputs) stays.
    """
    removed = []
    for name in OWNED:
        path = Path(out) / name
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(path)
    return removed


def scenario_sha256(scenario: Any) -> str:
    """The SHA-256 of the scenario file's text, or of the scenario's settings (canonical
    JSON) for one built in code."""
    if getattr(scenario, "sha256", ""):
        return scenario.sha256
    data = {
        "name": scenario.name,
        "stop_time": scenario.stop_time,
        "step": scenario.step,
        "coupling": scenario.coupling,
        "feedback": scenario.feedback,
        "observer": scenario.observer,
        "parameters": {i: {k: plain(v) for k, v in p.items()}
                       for i, p in scenario.parameters.items()},
        "events": [
            {"when": f"{e.variable} {e.op} {e.threshold}", "delay": e.delay,
             "set": {k: plain(v) for k, v in e.actions.items()}}
            for e in scenario.events
        ],
        "fmus": dict(scenario.fmus),
    }  # fmt: skip
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def flavor_of(md: Any, read: Callable[[str], bytes | None]) -> tuple[str, str]:
    """(flavor, version) of an FMU, as it says: ``read(name)`` gives the bytes of one of
    its files (``None`` if it has none).

    The flavor is read from a resource (:data:`FLAVOR_RESOURCES`, one word) or from the
    model description's ``generationTool`` (``PythonFMU ...``: ``"python"``), else
    :data:`DEFAULT_FLAVOR`. The version is the model description's ``version``
    attribute, else the generation tool's.
    """
    flavor = None
    for rel in FLAVOR_RESOURCES:
        data = read(rel)
        word = data.decode(errors="replace").strip().split() if data is not None else []
        if word:
            flavor = word[0][:40]
            break
    tool = str(getattr(md, "generationTool", "") or "")
    if flavor is None and tool.lower().startswith("pythonfmu"):
        flavor = "python"
    version = str(getattr(md, "version", "") or "") or tool
    return flavor or DEFAULT_FLAVOR, version


def fmu_flavor(inst: Any) -> tuple[str, str]:
    """(flavor, version) of an instance's FMU (:func:`flavor_of`, from its unpacked folder)."""
    unzipdir = getattr(inst, "unzipdir", None)

    def read(rel: str) -> bytes | None:
        path = Path(unzipdir) / rel if unzipdir else None
        return path.read_bytes() if path is not None and path.is_file() else None

    return flavor_of(inst.md, read)


def zip_flavor(fmu: Path, md: Any) -> tuple[str, str]:
    """(flavor, version) of an FMU file (:func:`flavor_of`, read from the archive)."""
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
        return flavor_of(md, lambda rel: z.read(rel)[:1000] if rel in names else None)


def fmu_record(inst: Any) -> dict[str, Any]:
    flavor, version = fmu_flavor(inst)
    return {
        "file": str(inst.fmu),
        "sha256": file_sha256(inst.fmu),
        "guid": inst.md.guid,
        "model_name": inst.md.modelName,
        "generation_tool": inst.md.generationTool,
        "flavor": flavor,
        "version": version,
        "fmi_version": str(getattr(inst.md, "fmiVersion", "") or ""),
    }


def run_record(scenario: Any, sim: Any, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``run`` object of ``metrics.json``.

    Parameters
    ----------
    scenario : Scenario
        As run (its ``overrides`` are the ``--set`` values and the report's variations).
    sim : CoSimulation
        Loaded (its instances' model descriptions and files are read).
    options : dict, optional
        The options given (``{"--step": 0.01, ...}``, or the API's keyword arguments).
    """
    return {
        "scenario": scenario.name,
        "scenario_source": scenario.source,
        "scenario_sha256": scenario_sha256(scenario),
        "overrides": {k: plain(v) for k, v in scenario.overrides.items()},
        "options": {k: plain(v) for k, v in (options or {}).items()},
        "package": "glider-cosim",
        "package_version": package_version(),
        "python": platform.python_version(),
        "fmus": {name: fmu_record(inst) for name, inst in sim.instances.items()},
    }


#: options that change what a run computes (the others change only what it writes)
_RESULT_OPTIONS_SKIPPED = ("--no-plots", "--format", "--max-steps", "--max-extract-mb",
                           "--fmu-dir", "--flavor", "--fmi")  # fmt: skip


def settings_of(run: dict[str, Any]) -> dict[str, Any]:
    """What made a run's results, from its ``run`` record: the scenario (name and
    SHA-256), the overrides, the options that change results, and each FMU's flavor and
    FMI version. Two runs with the same settings give the same results."""
    fmus = run.get("fmus") or {}
    return {
        "scenario": run.get("scenario"),
        "scenario_sha256": run.get("scenario_sha256"),
        "overrides": run.get("overrides") or {},
        "options": {
            k: v for k, v in (run.get("options") or {}).items() if k not in _RESULT_OPTIONS_SKIPPED
        },  # fmt: skip
        "flavors": sorted({str(f.get("flavor")) for f in fmus.values()}),
        "fmi": sorted({str(f.get("fmi_version")) for f in fmus.values()}),
    }


def describe_settings(run: dict[str, Any], sha: bool = False) -> str:
    """``"scenario default, controller.K_c=6, python FMUs, FMI 2.0"``: a run's settings
    (:func:`settings_of`) in one line (``sha``: with the scenario's SHA-256, shortened)."""
    st = settings_of(run)
    parts = [f"scenario {st['scenario']}"]
    parts += overrides_words(st["overrides"]) or ["no overrides"]
    parts += [k if v is True else f"{k} {short(v)}" for k, v in st["options"].items()]
    parts.append(f"{'/'.join(st['flavors']) or '?'} FMUs, FMI {'/'.join(st['fmi']) or '?'}")
    if sha and st["scenario_sha256"]:
        parts.append(f"scenario sha256 {str(st['scenario_sha256'])[:12]}")
    return ", ".join(parts)


def replaced_note(out: Path, run: dict[str, Any]) -> str | None:
    """The note for a run into ``out`` whose ``metrics.json`` was made with other settings
    (:func:`settings_of`) than ``run``: what the replaced results were made with, in one
    line; ``None`` if there is none, it is unreadable, or the settings are the same."""
    try:
        old = json.loads((Path(out) / "metrics.json").read_text(encoding="utf-8")).get("run")
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(old, dict) or settings_of(old) == settings_of(run):
        return None
    sha = old.get("scenario_sha256") != run.get("scenario_sha256")  # the file was edited
    return (
        f"replacing the results in {out} made with other settings: "
        f"{describe_settings(old, sha)} (this run: {describe_settings(run, sha)})"
    )


def overrides_text(metrics: dict[str, Any]) -> str:
    """``"controller.K_c=6, plant.theta_g_0=-30 deg"``: a run's overrides ("" if none)."""
    return ", ".join(overrides_words((metrics.get("run") or {}).get("overrides", {})))


def marked_events(sim: Any, status: str, error: Any = None) -> list[dict[str, Any]]:
    """What every time plot marks: the controller's enable time, the takeover by an
    event (e.g. at 1 m depth), and a stall or a Discard that stopped the run.

    Each is ``{"kind": "enable"|"takeover"|"stall"|"discard"|"error", "time_s": t,
    "label": text}``.
    """
    out: list[dict[str, Any]] = []
    ctrl = sim.system.parameters.get("controller", {})
    t_enable = ctrl.get("t_enable", 0.0)
    if isinstance(t_enable, int | float) and float(t_enable) > 0:
        out.append({"kind": "enable", "time_s": float(t_enable),
                    "label": f"controller enabled (t_enable = {float(t_enable):g} s)"})  # fmt: skip
    for ev in sim.system.events:
        if ev.fired_at is None or not any(t.startswith("controller.") for t in ev.actions):
            continue
        t = ev.fired_at + ev.delay
        sets = ", ".join(f"{k} = {with_unit(k, v)}" for k, v in ev.actions.items())
        at = with_unit(ev.variable, float(ev.threshold))
        label = f"takeover at {ev.variable} {ev.op} {at} ({sets})"
        out.append({"kind": "takeover", "time_s": float(t), "label": label})
    if error is not None and status in ("stopped", "error"):
        t = getattr(error, "time", None)
        text = str(error)
        kind = "error" if status == "error" else ("stall" if "stall" in text else "discard")
        speed = speed_stop(text)  # a speed that fell to zero, or one that diverged
        verb = "diverged" if speed and speed[2] == "diverges" else "stalled"
        what = {"stall": f"{verb} (fmi2Discard)", "discard": "fmi2Discard",
                "error": "fmi2Error"}[kind]  # fmt: skip
        if t is not None and math.isfinite(float(t)):
            out.append({"kind": kind, "time_s": float(t),
                        "label": f"{getattr(error, 'instance', '?')} {what}"})  # fmt: skip
    return out
