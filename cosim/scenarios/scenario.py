"""TOML scenarios: the system around the glider's FMUs, its parameters and events.

A scenario is data: it is parsed with :mod:`tomllib` and checked key by key; nothing
in it is executed. Angles may be given in radians (numbers) or as ``"-35 deg"``.

Keys (all optional; defaults give the paper's Sec. 3.3 case)::

    name, summary, description, notes  strings (summary: one line, what
                              ``glider-cosim scenarios`` prints)
    stop_time = 60.0          s, > 0
    step = 0.02               communication step, s, > 0
    coupling = "gauss-seidel" or "jacobi"
    feedback = "observer"     controller fed by the observer, or "state" (true state)
    with_observer = true      false: no observer instance (only with feedback = "state")
    record = [...]            instance.variable list (default: every output)
    components = [...]        components of the registry to add to the loop (e.g.
                              ["noise"]: docs/how-to/add-a-component.md)
    [connections]             "instance.input" = "instance.output": connections over
                              the components' defaults
    [plant] [observer] [controller]   parameters of each instance (any component's name)
                              (controller.law may be "open-loop", "passivity", "p", "pi")
    [fmus]                    instance = "path/to/other.fmu" (swap a component)
    [external]                instance = "udp://127.0.0.1:9870" (an endpoint outside)
    [inputs]                  "plant.F_x" = 0.0: constant values of driven inputs
    [[disturbance]]           target, kind ("step"|"pulse"), time, value, duration
    [[event]]                 when = "plant.z >= 1.0" | "time >= 5", delay, set = {...}"""

from __future__ import annotations

import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from ..components import COMPONENTS, UnknownComponentError, component
from ..inputs.archives import InputFileError, regular_file
from ..inputs.text import did_you_mean, quote, shown_path
from ..inputs.values import Quantity
from ..master.spec import Disturbance, Event
from .fields import ScenarioError, parse_choice, parse_float, parse_law, parse_number, parse_table

#: every registered component's instance name (glider_cosim.components)
INSTANCES = tuple(c.name for c in COMPONENTS)
#: those in the default loop (``in_every_run``)
_EVERY_RUN = frozenset(c.name for c in COMPONENTS if c.in_every_run)


COUPLINGS = ("gauss-seidel", "jacobi")


FEEDBACKS = ("observer", "state")


_TOP = {
    "name", "summary", "description", "notes", "stop_time", "step", "coupling", "feedback",
    "with_observer", "record", "components", "connections",
    "fmus", "external", "inputs", "disturbance", "event", *INSTANCES,
}  # fmt: skip


_COND = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(>=|<=)\s*(.+?)\s*$")


_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,99}$")


#: largest scenario file read (bytes)
MAX_SCENARIO_BYTES = 4 * 2**20


@dataclass
class Scenario:
    """A parsed scenario (see the module docstring for the keys)."""

    name: str = "default"
    #: one line: what ``glider-cosim scenarios`` prints
    summary: str = ""
    description: str = ""
    notes: str = ""
    source: str = "<defaults>"
    stop_time: float = 60.0
    step: float = 0.02
    coupling: str = "gauss-seidel"
    feedback: str = "observer"
    observer: bool = True
    record: list[str] | None = None
    #: components added to the default loop (``components = [...]``), registry names
    components: list[str] = field(default_factory=list)
    #: ``"instance.input"`` -> ``"instance.output"``, over the components' defaults
    connections: dict[str, str] = field(default_factory=dict)
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    fmus: dict[str, str] = field(default_factory=dict)
    #: instance -> ``udp://HOST:PORT`` of the endpoint that serves it (``[external]``)
    external: dict[str, str] = field(default_factory=dict)
    inputs: dict[str, float] = field(default_factory=dict)
    disturbances: list[Disturbance] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    #: ``instance.variable`` -> where an overridden value came from (e.g. ``--set ...``)
    origins: dict[str, str] = field(default_factory=dict)
    #: SHA-256 of the scenario file's text ("" for a scenario built in code)
    sha256: str = ""
    #: ``instance.variable`` (or ``event.instance.variable``) -> value set over the file's
    overrides: dict[str, Any] = field(default_factory=dict)

    def instances(self) -> list[str]:
        """The instances of the loop, in registry order: the components in every run (the
        observer unless ``with_observer = false``) and those the scenario adds."""
        return [
            name
            for name in INSTANCES
            if (name in _EVERY_RUN and (self.observer or name != "observer"))
            or name in self.components
        ]


def _parse_components(data: dict[str, Any], sc: Scenario) -> None:
    """``components`` (registry names added to the loop) and ``[connections]``."""
    source = sc.source
    comps = data.get("components", [])
    if not (isinstance(comps, list) and all(isinstance(c, str) for c in comps)):
        raise ScenarioError(f"{source}: key 'components': expected a list of component names")
    for name in comps:
        try:
            c = component(name)
        except UnknownComponentError as err:
            raise ScenarioError(f"{source}: key 'components': {err}") from None
        if c.in_every_run or name in sc.components:
            raise ScenarioError(
                f"{source}: key 'components': {quote(name)} is already in the loop: expected "
                "a component the default loop does not have, once"
            )
        sc.components.append(name)
    insts = sc.instances()
    for target, src in parse_table(data.get("connections", {}),
                                   f"{source}: key 'connections'").items():  # fmt: skip
        where = f"{source}: key {quote(f'connections.{target}')}"
        for ref, what in ((target, "input"), (src, "output")):
            inst, dot, var = ref.partition(".") if isinstance(ref, str) else ("", "", "")
            if not dot or not var or inst not in insts:
                raise ScenarioError(
                    f"{where}: {quote(str(ref))} is invalid: expected 'instance.{what}' of an "
                    f"instance of the loop ({', '.join(insts)})"
                )
        sc.connections[target] = src


def _tables(
    data: dict[str, Any], name: str, source: str, keys: tuple[str, ...]
) -> list[tuple[str, dict[str, Any]]]:
    """The array of tables ``[[name]]`` of a scenario, each with where it stands
    (``"SOURCE: key name[i]"``), every key one of ``keys``."""
    items = data.get(name, [])
    if not isinstance(items, list):
        raise ScenarioError(f"{source}: key {quote(name)}: expected an array of tables")
    out = []
    for i, item in enumerate(items):
        where = f"{source}: key {name}[{i}]"
        table = parse_table(item, where)
        extra = set(table) - set(keys)
        if extra:
            key = sorted(extra)[0]
            raise ScenarioError(f"{where}: unknown key {quote(key)}" + did_you_mean(key, keys))
        out.append((where, table))
    return out


def parse_scenario(data: dict[str, Any], source: str = "<string>") -> Scenario:
    """Check and convert the TOML document ``data`` (from ``source``) to a :class:`Scenario`."""
    for key in data:
        if key not in _TOP:
            raise ScenarioError(
                f"{source}: unknown key {quote(key)}: expected one of {', '.join(sorted(_TOP))}"
                + did_you_mean(key, _TOP)
            )
    sc = Scenario(source=source)
    for key in ("name", "summary", "description", "notes"):
        if key in data:
            if not isinstance(data[key], str):
                raise ScenarioError(f"{source}: key '{key}': expected a string")
            setattr(sc, key, data[key])
    if "\n" in sc.summary:
        raise ScenarioError(f"{source}: key 'summary': expected one line")
    if "name" in data:
        check_name(sc.name, f"{source}: key 'name'")
    if "stop_time" in data:
        sc.stop_time = parse_float(data["stop_time"], f"{source}: key 'stop_time'", positive=True)
    if "step" in data:
        sc.step = parse_float(data["step"], f"{source}: key 'step'", positive=True)
    if "coupling" in data:
        sc.coupling = parse_choice(data["coupling"], COUPLINGS, f"{source}: key 'coupling'")
    if "feedback" in data:
        sc.feedback = parse_choice(data["feedback"], FEEDBACKS, f"{source}: key 'feedback'")
    if "with_observer" in data:
        if not isinstance(data["with_observer"], bool):
            raise ScenarioError(f"{source}: key 'with_observer': expected true or false")
        sc.observer = data["with_observer"]
        if not sc.observer and sc.feedback != "state":
            raise ScenarioError(
                f"{source}: key 'with_observer': false needs feedback = 'state' (the "
                "controller would have no input)"
            )
        for key in ("observer", "fmus"):
            if not sc.observer and "observer" in (data if key == "observer" else
                                                  data.get("fmus", {})):  # fmt: skip
                raise ScenarioError(f"{source}: key '{key}': the scenario has no observer")
    if "record" in data:
        rec = data["record"]
        if not (isinstance(rec, list) and all(isinstance(r, str) for r in rec)):
            raise ScenarioError(f"{source}: key 'record': expected a list of 'instance.variable'")
        sc.record = list(rec)
    _parse_components(data, sc)
    for inst in INSTANCES:
        if inst in data:
            if inst not in sc.instances():
                raise ScenarioError(
                    f"{source}: key {quote(inst)}: the scenario has no {inst}: expected "
                    f"components = [{quote(inst)}] to add it"
                )
            params = {}
            for k, v in parse_table(data[inst], f"{source}: key '{inst}'").items():
                where = f"{source}: key {quote(f'{inst}.{k}')}"
                if inst == "controller" and k == "law":
                    v = parse_law(v, where)
                params[k] = parse_number(v, where, f"{inst}.{k}")
            sc.parameters[inst] = params
    for k, v in parse_table(data.get("fmus", {}), f"{source}: key 'fmus'").items():
        if k not in INSTANCES:
            raise ScenarioError(
                f"{source}: key {quote(f'fmus.{k}')}: unknown instance: expected one of "
                f"{', '.join(INSTANCES)}"
            )
        if not isinstance(v, str) or not v or "\0" in v:
            raise ScenarioError(f"{source}: key 'fmus.{k}': expected a path string")
        path = Path(v)
        if not path.is_absolute() and not source.startswith("<"):
            path = Path(source).parent / path
        try:
            regular_file(path, f"{source}: key 'fmus.{k}'", "FMU")
        except InputFileError as err:
            raise ScenarioError(str(err)) from None
        sc.fmus[k] = str(path)
    for k, v in parse_table(data.get("external", {}), f"{source}: key 'external'").items():
        if k not in INSTANCES or not isinstance(v, str) or not v.startswith("udp://"):
            raise ScenarioError(
                f"{source}: key {quote(f'external.{k}')}: expected an instance of "
                f"{', '.join(INSTANCES)} = 'udp://HOST:PORT'"
            )
        sc.external[k] = v
    for k, v in parse_table(data.get("inputs", {}), f"{source}: key 'inputs'").items():
        sc.inputs[k] = parse_float(v, f"{source}: key {quote(f'inputs.{k}')}", angle=True)
    for where, d in _tables(data, "disturbance", source, ("target", "kind", "time", "value",
                                                           "duration")):  # fmt: skip
        kind = d.get("kind", "step")
        if kind not in ("step", "pulse"):
            raise ScenarioError(
                f"{where}.kind: {quote(kind)} is invalid: expected 'step' or 'pulse'"
            )
        if not isinstance(d.get("target"), str):
            raise ScenarioError(f"{where}.target: expected 'instance.variable' (e.g. plant.F_z)")
        sc.disturbances.append(
            Disturbance(
                target=d["target"],
                kind=kind,
                time=parse_float(d.get("time", 0.0), f"{where}.time", non_negative=True),
                value=parse_float(d.get("value", 0.0), f"{where}.value"),
                duration=parse_float(
                    d.get("duration", 0.0), f"{where}.duration", positive=kind == "pulse"
                ),
            )
        )
    for where, e in _tables(data, "event", source, ("when", "delay", "set")):
        when = e.get("when", "")
        m = _COND.match(when) if isinstance(when, str) and len(when) < 1000 else None
        if not m:
            raise ScenarioError(
                f"{where}.when: {quote(when)} is invalid: expected 'time >= T' or "
                "'instance.variable >= X' (or <=)"
            )
        actions = {}
        for target, v in parse_table(e.get("set", {}), f"{where}.set").items():
            if target == "controller.law":
                v = parse_law(v, f"{where}.set.{target}")
            actions[target] = parse_number(v, f"{where}.set.{quote(target)}", target)
        if not actions:
            raise ScenarioError(f"{where}.set: expected at least one 'instance.variable' = value")
        try:
            threshold = float(m.group(3))
        except ValueError:
            threshold = parse_float(m.group(3), f"{where}.when", angle=True)
        if not math.isfinite(threshold):
            raise ScenarioError(
                f"{where}.when: threshold {quote(m.group(3))} is invalid: expected a finite number"
            )
        if isinstance(threshold, Quantity) and m.group(1) == "time":
            if threshold.unit != "s":
                raise ScenarioError(
                    f"{where}.when: {quote(m.group(3))} is invalid: time is in s, not "
                    f"{threshold.unit}"
                )
            threshold = float(threshold)
        sc.events.append(
            Event(
                variable=m.group(1),
                op=m.group(2),
                threshold=threshold,
                actions=actions,
                delay=parse_float(e.get("delay", 0.0), f"{where}.delay", non_negative=True),
            )
        )
    return sc


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Load a scenario file, or a shipped one by name (``None``: the default).

    Raises
    ------
    ScenarioError
        If the file does not exist, is not valid TOML or has invalid keys.
    """
    if path is None:
        path = "default"
    p = Path(path)
    if not p.exists() and p.suffix == "" and str(path) in shipped_scenarios():
        text = (resources.files("glider_cosim") / "scenarios" / f"{path}.toml").read_text()
        source = f"<shipped>/{path}.toml"
    else:
        shown = _shown(str(path))
        if not p.exists():
            raise ScenarioError(
                f"{shown}: scenario file does not exist (shipped scenarios: "
                f"{', '.join(shipped_scenarios())})" + did_you_mean(str(path), shipped_scenarios())
            )
        try:
            regular_file(p, shown, "scenario file")
            if p.stat().st_size > MAX_SCENARIO_BYTES:
                raise ScenarioError(
                    f"{shown}: scenario file is larger than {MAX_SCENARIO_BYTES} bytes"
                )
            text = p.read_text(encoding="utf-8")
        except InputFileError as err:
            raise ScenarioError(str(err)) from None
        except (OSError, UnicodeDecodeError) as err:
            reason = getattr(err, "strerror", None) or err
            raise ScenarioError(f"{shown}: cannot read scenario file ({reason})") from None
        source = str(p)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"{_shown(source)}: not valid TOML ({err})") from None
    except RecursionError:
        raise ScenarioError(f"{_shown(source)}: not valid TOML (nested too deeply)") from None
    try:
        sc = parse_scenario(data, source)
    except RecursionError:
        raise ScenarioError(f"{_shown(source)}: values nested too deeply") from None
    sc.sha256 = hashlib.sha256(text.encode()).hexdigest()
    return sc


_shown = shown_path


def check_name(name: str, where: str) -> str:
    """``name`` if it is a plain name (it becomes a results folder), else ScenarioError.

    Letters, digits, ``.``, ``_``, ``+``, ``-``; at most 100 characters; not starting
    with ``.`` or ``-`` (so no path, no ``..``).
    """
    if not isinstance(name, str) or not _NAME.match(name):
        raise ScenarioError(
            f"{where}: {quote(name)} is not a name: expected letters, digits, '.', '_', '+', "
            "'-' (at most 100, not a path)"
        )
    return name


def one_line_summary(sc: Scenario, width: int = 80) -> str:
    """What a scenario is, in one line: its ``summary``, else its description's first
    sentence, cut at a word to about ``width`` characters."""
    text = " ".join((sc.summary or sc.description).split())
    if not sc.summary:
        text = text.split(". ")[0].removesuffix(".")
    if len(text) > width:
        text = text[: width - 3].rsplit(" ", 1)[0] + "..."
    return text


def shipped_scenarios() -> list[str]:
    """Names of the scenarios shipped in the package."""
    d = resources.files("glider_cosim") / "scenarios"
    return sorted(f.name[:-5] for f in d.iterdir() if f.name.endswith(".toml"))


def describe_shipped() -> str:
    """The shipped scenarios, one line each: the name, then what it is
    (:func:`one_line_summary`); what ``glider-cosim scenarios`` prints (no final newline)."""
    names = shipped_scenarios()
    width = max(len(n) for n in names)
    return "\n".join(f"{name:<{width}}  {one_line_summary(load_scenario(name))}" for name in names)
