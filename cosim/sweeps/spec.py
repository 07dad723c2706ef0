"""The sweep's parameter specs and its list of runs (``--param INSTANCE.NAME=SPEC``).

See :mod:`glider_cosim.sweeps.sweep` for the grammar. Nothing here needs Dask.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..components import component
from ..inputs.text import did_you_mean
from ..inputs.values import parse_quantity
from ..scenarios.scenario import INSTANCES, Scenario
from ..scenarios.system import system_for

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_PCT = rf"({_NUM})(%?)"


class SweepSpecError(ValueError):
    """A ``--param`` spec or sweep option is malformed (the message names it)."""


@dataclass(frozen=True)
class ParamSpec:
    """One swept parameter: a fixed list of values, or a random distribution."""

    target: str  # instance.name
    values: tuple[float, ...] = ()
    dist: str = ""  # "uniform" | "normal"
    args: tuple[tuple[float, bool], ...] = ()  # (value, is_percent)
    #: the values as written (numbers, :class:`~glider_cosim.inputs.values.Quantity`):
    #: a list's values, a range's ends, absolute bounds; checked like ``--set``
    given: tuple[float, ...] = ()
    #: the ``--param`` argument, for messages
    item: str = ""

    @property
    def random(self) -> bool:
        return bool(self.dist)

    def draw(self, nominal: float, rng: np.random.Generator) -> float:
        def val(a: tuple[float, bool]) -> float:
            x, pct = a
            return nominal * (1 + x / 100) if pct else x

        if self.dist == "uniform":
            return float(rng.uniform(val(self.args[0]), val(self.args[1])))
        sd = abs(nominal) * self.args[0][0] / 100 if self.args[0][1] else self.args[0][0]
        return float(rng.normal(nominal, sd))


def _value(text: str, where: str) -> float:
    """A number, or a number with a unit (:func:`~glider_cosim.inputs.values.parse_quantity`,
    as ``--set`` reads it: checked against the variable's unit before any run)."""
    text = text.strip()
    q = parse_quantity(text)
    if q is not None:
        return q
    if re.fullmatch(r"[-+]?\d{1,18}", text):
        return int(text)  # shown as written in messages
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise SweepSpecError(
            f"{where}: {text!r} is not a number: expected a finite number (or one with the "
            "variable's unit, e.g. 'X deg')"
        )
    return v


#: significant digits of a range's values (:func:`range_values`): every decimal of at
#: most 15 digits is a distinct double whose shortest ``repr`` is that decimal
RANGE_DIGITS = 15


def range_values(
    start_text: str, stop_text: str, start: float, stop: float, num: int
) -> tuple[float, ...]:
    """The ``num`` values of the range ``START:STOP:NUM`` as a user expects them printed.

    Each value is ``start + i (stop - start) / (num - 1)`` computed exactly (in rational
    arithmetic) from the ends as written, rounded to :data:`RANGE_DIGITS` significant
    digits (half to even), and passed to the FMU as the double nearest that decimal: its
    ``repr`` (what ``sweep.csv`` shows) is the decimal, e.g. ``0.1:0.5:5`` gives 0.1,
    0.2, 0.3, 0.4, 0.5 (numpy's ``linspace`` gives 0.30000000000000004), ``0:1:4`` gives
    0.333333333333333. Ends written with the same unit are interpolated in that unit
    (``-30 deg:-20 deg:3`` is -30, -25, -20 deg, each converted to rad as ``--set "X
    deg"`` converts it); other ends by their values in the variable's unit.
    """
    from decimal import Decimal, localcontext
    from fractions import Fraction

    from ..inputs.values import _QUANTITY, Degrees, Quantity

    def written(text: str, value: float) -> Fraction:
        if isinstance(value, Quantity):
            return Fraction(Decimal(_QUANTITY.match(value.text).group(1)))
        return Fraction(Decimal(text.strip()))

    same_unit = type(start) is type(stop) and (
        not isinstance(start, Quantity) or start.unit == stop.unit
    )
    if same_unit:
        a, b = written(start_text, start), written(stop_text, stop)
    else:
        a, b = Fraction(float(start)), Fraction(float(stop))
    out = []
    for i in range(num):
        exact = a if num == 1 else a + (b - a) * i / (num - 1)
        with localcontext() as ctx:
            ctx.prec = RANGE_DIGITS
            text = Decimal(exact.numerator) / Decimal(exact.denominator)
        value = float(text)
        out.append(math.radians(value) if same_unit and isinstance(start, Degrees) else value)
    return tuple(out)


def parse_param(item: str) -> ParamSpec:
    """Parse ``INSTANCE.NAME=SPEC`` (grammar in the module docstring)."""
    where = f"--param {item!r}"
    target, sep, spec = item.partition("=")
    inst, dot, name = target.strip().partition(".")
    if not sep or not dot or inst not in INSTANCES or not name:
        raise SweepSpecError(
            f"{where}: expected INSTANCE.NAME=SPEC with INSTANCE one of {', '.join(INSTANCES)}"
            + (did_you_mean(inst, INSTANCES) if dot and inst not in INSTANCES else "")
        )
    spec = spec.strip()
    target = f"{inst}.{name}"
    m = re.fullmatch(r"(uniform|normal)\(\s*(.*?)\s*\)", spec)
    if m:
        parts = [p.strip() for p in m.group(2).split(",")]
        want = 2 if m.group(1) == "uniform" else 1
        if len(parts) != want:
            raise SweepSpecError(
                f"{where}: {m.group(1)} takes {want} argument(s), e.g. "
                + ("uniform(-20%,+20%)" if want == 2 else "normal(20%)")
            )
        args = []
        for p in parts:
            pm = re.fullmatch(_PCT, p)
            if not pm:
                raise SweepSpecError(f"{where}: {p!r} is not a number or a percentage")
            args.append((float(pm.group(1)), pm.group(2) == "%"))
        if m.group(1) == "normal" and args[0][0] < 0:
            raise SweepSpecError(f"{where}: the standard deviation must be >= 0")
        bounds = tuple(v for v, pct in args if not pct) if m.group(1) == "uniform" else ()
        return ParamSpec(target, dist=m.group(1), args=tuple(args), given=bounds, item=item)
    if ":" in spec:
        parts = spec.split(":")
        if len(parts) != 3:
            raise SweepSpecError(f"{where}: a range is START:STOP:NUM, e.g. 2:20:10")
        start, stop = _value(parts[0], where), _value(parts[1], where)
        try:
            num = int(parts[2])
        except ValueError:
            raise SweepSpecError(f"{where}: NUM {parts[2]!r} must be a whole number") from None
        if num < 1:
            raise SweepSpecError(f"{where}: NUM must be >= 1")
        values = range_values(parts[0], parts[1], start, stop, num)
        return ParamSpec(target, values=values, given=(start, stop), item=item)
    given = tuple(_value(v, where) for v in spec.split(",") if v.strip())
    if not given:
        raise SweepSpecError(f"{where}: no values")
    return ParamSpec(target, values=tuple(float(v) for v in given), given=given, item=item)


def run_id(params: dict[str, float], seed: int | None, scenario: Scenario, stop: float) -> str:
    """Deterministic id of a run (resume key)."""
    key = json.dumps([scenario.name, scenario.source, stop, seed, sorted(params.items())])
    return hashlib.sha1(key.encode()).hexdigest()[:16]


def check_ranges_of(specs: Sequence[ParamSpec], scenario: Scenario) -> None:
    """Check every value written in ``specs`` against our FMUs' variable tables (unit and
    valid range), as ``run --set`` does, before anything is built or run.

    Raises
    ------
    SweepSpecError
        ``--param 'ITEM': VALUE is invalid: expected ...`` for the first value refused.
    """
    from ..inputs.check import check_ranges
    from ..inputs.values import ValueCheckError

    for spec in specs:
        inst, _, name = spec.target.partition(".")
        for value in spec.given:
            try:
                check_ranges({inst: {name: value}}, lambda ref, s=spec: f"--param {s.item!r}",
                             set(scenario.fmus))  # fmt: skip
            except ValueCheckError as err:
                raise SweepSpecError(str(err)) from None


def check_targets(
    scenario: Scenario,
    fmu_dir: Path,
    targets: Iterable[str],
    specs: Sequence[ParamSpec] = (),
) -> None:
    """Check that every swept ``instance.name`` is a parameter or input of its FMU, and
    every value written in ``specs`` fits it (type, unit, ``min``/``max``), as for
    ``run --set``.

    The model descriptions of the scenario's FMUs (``fmu_dir`` unless swapped) are the
    source; raises :class:`SweepSpecError` naming the first target or value that is
    refused, before any work is sent.
    """
    from fmpy import read_model_description

    from ..inputs.values import ValueCheckError, check_value

    fmus = system_for(scenario, fmu_dir).fmus
    variables: dict[str, dict[str, str]] = {}
    models: dict[str, str] = {}
    descriptions: dict[str, Any] = {}
    targets = [*targets, *(s.target for s in specs)]
    for t in targets:
        inst, _, name = t.partition(".")
        if inst not in fmus:
            raise SweepSpecError(
                f"--param {t}: the scenario {scenario.name} has no instance '{inst}' "
                f"(instances: {', '.join(fmus)})" + did_you_mean(inst, fmus)
            )
        if inst not in variables:
            try:
                md = read_model_description(str(fmus[inst]))
            except Exception as err:  # noqa: BLE001 - fmpy raises plain Exception
                raise SweepSpecError(f"instance {inst}: {fmus[inst]} is not a readable FMU "
                                     f"({err})") from None  # fmt: skip
            variables[inst] = {v.name: v.causality for v in md.modelVariables}
            models[inst] = md.modelName
            descriptions[inst] = md
        causality = variables[inst].get(name)
        if causality is None:
            raise SweepSpecError(
                f"--param {t}: instance {inst} ({models[inst]}) has no variable '{name}'"
                + did_you_mean(
                    name, [n for n, c in variables[inst].items() if c in ("parameter", "input")]
                )  # fmt: skip
            )
        if causality not in ("parameter", "input"):
            raise SweepSpecError(f"--param {t}: {t} has causality {causality}: expected one of "
                                 "parameter, input")  # fmt: skip
    for spec in specs:
        inst, _, name = spec.target.partition(".")
        md = descriptions[inst]
        var = next(v for v in md.modelVariables if v.name == name)
        for value in spec.given:
            try:
                check_value(value, md, var, f"--param {spec.item!r}")
            except ValueCheckError as err:
                raise SweepSpecError(str(err)) from None


def nominal_values(scenario: Scenario, fmu_dir: Path, targets: Iterable[str]) -> dict[str, float]:
    """Nominal value of each target: the scenario's, else the FMU's default."""
    from ..fmus.variables import parameter_defaults

    fmus = system_for(scenario, fmu_dir).fmus
    defaults = {}
    out = {}
    for t in targets:
        inst, _, name = t.partition(".")
        if name in scenario.parameters.get(inst, {}):
            out[t] = float(scenario.parameters[inst][name])
            continue
        if inst not in defaults:
            defaults[inst] = parameter_defaults(fmus[inst])
        if name not in defaults[inst]:
            raise SweepSpecError(f"--param {t}: {component(inst).model} has no parameter '{name}'")
        out[t] = float(defaults[inst][name])
    return out


def expand(
    specs: Sequence[ParamSpec],
    scenario: Scenario,
    fmu_dir: Path,
    samples: int = 10,
    seeds: Sequence[int] | None = None,
    rng_seed: int = 0,
    stop_time: float | None = None,
) -> list[dict[str, Any]]:
    """The list of runs: ``{"run_id", "params", "seed"}``."""
    grid = [s for s in specs if not s.random]
    rand = [s for s in specs if s.random]
    nominal = nominal_values(scenario, fmu_dir, [s.target for s in rand])
    rng = np.random.default_rng(rng_seed)
    stop = stop_time or scenario.stop_time
    runs = []
    for combo in itertools.product(*(s.values for s in grid)):
        base = {s.target: v for s, v in zip(grid, combo, strict=True)}
        for _ in range(samples if rand else 1):
            params = dict(base)
            params.update({s.target: s.draw(nominal[s.target], rng) for s in rand})
            for seed in seeds if seeds is not None else [None]:
                runs.append({"run_id": run_id(params, seed, scenario, stop), "params": params,
                             "seed": seed})  # fmt: skip
    return runs


__all__ = ["ParamSpec", "SweepSpecError", "check_ranges_of", "check_targets", "expand",
           "nominal_values", "parse_param", "run_id"]  # fmt: skip
