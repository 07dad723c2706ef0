"""FMU state to bytes and back, for ``fmi2SerializeFMUstate`` / ``fmi2DeSerializeFMUstate``.

A slave's FMU state (:meth:`GliderSlave._get_fmu_state`) holds its variables and its
internal objects: parameter records, filter history, observer estimate, PI integrator,
noise generator. They are written as JSON with tagged containers, so that floats round
trip exactly (shortest repr), tuples stay tuples, and objects come back as the same
classes:

- ``{"t": [...]}`` a tuple, ``{"d": {...}}`` a dict with string keys;
- ``{"r": state}`` a :class:`random.Random` (its ``getstate()``);
- ``{"o": "module:Class", "a": {...}}`` an object of one of the slave's own packages,
  rebuilt without calling ``__init__`` from its attributes.

Decoding only ever imports modules whose name starts with one of the allowed prefixes
and never evaluates anything: a crafted byte string cannot run code, it can only be
refused with :class:`StateCodecError`.

Module names are written as the slave's packages name themselves outside an FMU
(``glider_plant.params``): inside an FMU, where the bundle is a package of its own
(``_glider_fmu_<hash>.glider_plant.params``, see :mod:`glider_fmi.bundle`), its name is
left out when writing and put back when reading, so a state moves between FMUs and
hosts with other bundles, and only the reading FMU's own modules are imported.
"""

from __future__ import annotations

import importlib
import json
import random
from collections.abc import Sequence
from typing import Any

FORMAT = "glider-fmi-state/1"

#: the bundle's package and a dot inside an FMU ("_glider_fmu_<hash>."), else ""
_BUNDLE = __name__.removesuffix("glider_fmi.state_codec")


class StateCodecError(ValueError):
    """A state that cannot be written or read (the message says which part and why)."""


def _encode(value: Any, prefixes: tuple[str, ...], path: str) -> Any:
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, list):
        return [_encode(v, prefixes, f"{path}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, tuple):
        return {"t": [_encode(v, prefixes, f"{path}[{i}]") for i, v in enumerate(value)]}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise StateCodecError(f"{path}: dict keys must be strings")
        return {"d": {k: _encode(v, prefixes, f"{path}.{k}") for k, v in value.items()}}
    if isinstance(value, random.Random):
        return {"r": _encode(value.getstate(), prefixes, f"{path}.state")}
    cls = type(value)
    module = cls.__module__.removeprefix(_BUNDLE) if _BUNDLE else cls.__module__
    if module.startswith(prefixes) and hasattr(value, "__dict__"):
        attrs = {k: _encode(v, prefixes, f"{path}.{k}") for k, v in vars(value).items()}
        return {"o": f"{module}:{cls.__qualname__}", "a": attrs}
    raise StateCodecError(
        f"{path}: {module}.{cls.__qualname__} cannot be serialized: expected plain "
        f"data, random.Random or an object of {', '.join(prefixes)}*"
    )


def _decode(value: Any, prefixes: tuple[str, ...], path: str) -> Any:
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, list):
        return [_decode(v, prefixes, f"{path}[{i}]") for i, v in enumerate(value)]
    if not isinstance(value, dict) or len(value) not in (1, 2):
        raise StateCodecError(f"{path}: unexpected {type(value).__name__}")
    if "t" in value and len(value) == 1:
        return tuple(_decode(v, prefixes, f"{path}[{i}]") for i, v in enumerate(value["t"]))
    if "d" in value and len(value) == 1:
        return {k: _decode(v, prefixes, f"{path}.{k}") for k, v in value["d"].items()}
    if "r" in value and len(value) == 1:
        rng = random.Random()
        try:
            rng.setstate(_decode(value["r"], prefixes, f"{path}.state"))
        except (TypeError, ValueError) as err:
            raise StateCodecError(f"{path}: invalid random generator state ({err})") from None
        return rng
    if set(value) == {"o", "a"} and isinstance(value["o"], str):
        module, _, qualname = value["o"].partition(":")
        if not module.startswith(prefixes) or not qualname:
            raise StateCodecError(
                f"{path}: class {value['o'][:200]!r} is not allowed: expected one of "
                f"{', '.join(prefixes)}*"
            )
        try:
            cls: Any = importlib.import_module(_BUNDLE + module)
            for part in qualname.split("."):
                cls = getattr(cls, part)
        except (ImportError, AttributeError):
            raise StateCodecError(f"{path}: class {value['o'][:200]!r} not found") from None
        if not isinstance(cls, type) or not isinstance(value["a"], dict):
            raise StateCodecError(f"{path}: {value['o'][:200]!r} is not a class with attributes")
        obj = cls.__new__(cls)
        obj.__dict__.update({k: _decode(v, prefixes, f"{path}.{k}") for k, v in value["a"].items()})
        return obj
    raise StateCodecError(f"{path}: unknown tag {sorted(value)[:3]}")


def dumps(state: dict[str, Any], prefixes: Sequence[str]) -> bytes:
    """Serialize a slave's FMU state.

    Parameters
    ----------
    state : dict
        What the slave's ``_get_fmu_state`` returned.
    prefixes : sequence of str
        Module-name prefixes whose objects may be written (the slave's own packages).

    Returns
    -------
    bytes
        UTF-8 JSON, with the format name first.
    """
    body = _encode(state, tuple(prefixes), "state")
    return json.dumps({"format": FORMAT, "state": body}, separators=(",", ":")).encode()


def loads(data: bytes, prefixes: Sequence[str]) -> dict[str, Any]:
    """Read bytes written by :func:`dumps`.

    Raises
    ------
    StateCodecError
        Not such bytes, another format, or a class outside ``prefixes``.
    """
    try:
        doc = json.loads(bytes(data).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as err:
        raise StateCodecError(f"the state is not UTF-8 JSON ({err})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise StateCodecError(f"the state is not in the format {FORMAT}")
    state = _decode(doc.get("state"), tuple(prefixes), "state")
    if not isinstance(state, dict):
        raise StateCodecError("the state is not a mapping of names to values")
    return state
