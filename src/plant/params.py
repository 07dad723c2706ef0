"""Model constants of the glider (paper Sec. 3.3) and their validation.

One table, :data:`MODEL_CONSTANTS`, is the single source for the constants'
defaults, units, descriptions and valid ranges: the pure models read it, the FMU
slaves declare their parameters from it and the docs are generated from it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields


class ParameterError(ValueError):
    """A parameter is outside its valid range (the message names it, its value and the range)."""


@dataclass(frozen=True)
class Range:
    """A valid interval for a parameter; ``None`` means unbounded on that side.

    ``low_open``/``high_open`` make the bound strict (``>`` instead of ``>=``).
    """

    low: float | None = None
    high: float | None = None
    low_open: bool = True
    high_open: bool = True

    def contains(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        if self.high is not None and (value >= self.high if self.high_open else value > self.high):
            return False
        return True

    def describe(self, integer: bool = False) -> str:
        """The range in words; ``integer``: for an Integer variable (bounds as integers)."""
        fmt = (lambda x: f"{int(x)}") if integer else (lambda x: f"{x:g}")
        lo = "(-inf" if self.low is None else ("(" if self.low_open else "[") + fmt(self.low)
        hi = "inf)" if self.high is None else fmt(self.high) + (")" if self.high_open else "]")
        return f"{'an integer' if integer else 'a finite value'} in {lo}, {hi}"


@dataclass(frozen=True)
class ParamSpec:
    """Metadata of one parameter: default, SI unit, description, valid range."""

    name: str
    default: float
    unit: str
    description: str
    valid: Range = Range()


def check_value(name: str, value: float, valid: Range) -> float:
    """Return ``value`` as float if it lies in ``valid``, else raise :class:`ParameterError`.

    Parameters
    ----------
    name : str
        Variable name used in the message.
    value : float
        Value to check.
    valid : Range
        Valid interval.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{name} = {value!r} is invalid: expected {valid.describe()}"
        ) from None
    if not valid.contains(v):
        raise ParameterError(f"{name} = {v!r} is invalid: expected {valid.describe()}")
    return v


POSITIVE = Range(low=0.0)
NEGATIVE = Range(high=0.0)
FINITE = Range()
NON_NEGATIVE = Range(low=0.0, low_open=False)

# The paper's Sec. 3.3 list. K_Fdelta = 29.5 is the unlabelled "delta = 29.5" of the
# list (reading notes, decision 2); K_udelta is not given (decision 3).
MODEL_CONSTANTS: tuple[ParamSpec, ...] = (
    ParamSpec("m", 10.0, "kg", "mass incl. added mass, m1 = m3 = m", POSITIVE),
    ParamSpec("J2", 0.08, "kg.m2", "pitch inertia incl. added inertia", POSITIVE),
    ParamSpec("K_L0", 0.0, "kg/m", "lift coefficient, constant term", FINITE),
    ParamSpec("K_L", 303.6, "kg/m", "lift coefficient, slope in alpha", POSITIVE),
    ParamSpec("K_D0", 3.15, "kg/m", "drag coefficient, constant term", POSITIVE),
    ParamSpec("K_D", 282.8, "kg/m", "drag coefficient, quadratic in alpha", NON_NEGATIVE),
    ParamSpec("K_q", -0.8, "kg/s", "pitch damping coefficient (negative)", NEGATIVE),
    ParamSpec("K_M0", 0.39, "kg", "pitch moment coefficient, constant term", FINITE),
    ParamSpec("K_M", -14.7, "kg", "pitch moment coefficient, slope (negative)", NEGATIVE),
    ParamSpec("K_Fdelta", 29.5, "kg/m", "control-surface force coefficient", NON_NEGATIVE),
    ParamSpec("K_udelta", 1.0, "1", "u_delta = K_udelta * delta", POSITIVE),
    ParamSpec("m0", 0.05, "kg", "excess mass (negative buoyancy); > 0 glides down", POSITIVE),
    ParamSpec("g", 9.81, "m/s2", "gravitational acceleration", POSITIVE),
)


@dataclass(frozen=True)
class GliderParams:
    """Constants of Eqs. (1)-(9) in SI units (defaults: the paper's Sec. 3.3)."""

    m: float = 10.0
    J2: float = 0.08
    K_L0: float = 0.0
    K_L: float = 303.6
    K_D0: float = 3.15
    K_D: float = 282.8
    K_q: float = -0.8
    K_M0: float = 0.39
    K_M: float = -14.7
    K_Fdelta: float = 29.5
    K_udelta: float = 1.0
    m0: float = 0.05
    g: float = 9.81

    def __post_init__(self) -> None:
        for spec in MODEL_CONSTANTS:
            check_value(spec.name, getattr(self, spec.name), spec.valid)
        alpha_e = -self.K_M0 / self.K_M
        k_le = self.K_L0 + self.K_L * alpha_e
        if not k_le > 0.0:
            raise ParameterError(
                f"K_L0 + K_L*alpha_e = {k_le!r} is invalid: expected > 0 "
                "(no descending steady glide otherwise)"
            )

    @classmethod
    def from_mapping(cls, values: Mapping[str, float]) -> GliderParams:
        """Build from any mapping that has (at least) the constants' names."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: float(v) for k, v in values.items() if k in names})

    def as_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


assert tuple(s.name for s in MODEL_CONSTANTS) == tuple(f.name for f in fields(GliderParams))
assert all(s.default == f.default for s, f in zip(MODEL_CONSTANTS, fields(GliderParams)))
