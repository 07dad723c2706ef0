"""The native FMUs' variables as C (``<Model>_vars.h``), made from the Python slaves'
tables and kept in the FMU cache under a hash of what they are made from (issue 48)."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from glider_fmi import toolchain

from .. import components as registry
from .files import cache_root, package_version
from .native_description import c_name, jacobian_lines

#: whether :func:`vars_header` writes the tables it makes to the cache
_KEEP = {"on": True}


@contextlib.contextmanager
def tables_not_kept():
    """Within it, :func:`vars_header` writes nothing to the cache (it still reads what
    is there): ``glider-cosim cache`` lists the cache without adding to it."""
    before = _KEEP["on"]
    _KEEP["on"] = False
    try:
        yield
    finally:
        _KEEP["on"] = before


class NativeBuildError(toolchain.ToolchainError):
    """A native FMU cannot be built here (no compiler, a compiler error)."""


# ---------------------------------------------------------------- the variables as C
def _c_double(x: float) -> str:
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "-HUGE_VAL"
    return repr(float(x))


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _slave_variables(cls: type) -> list[tuple[int, Any]]:
    """(value reference, Var) of a slave class, in value-reference order."""
    with tempfile.TemporaryDirectory(prefix="glider_native_") as tmp:
        slave = cls(instance_name="codegen", resources=tmp)
        spec = {v.name: v for v in cls.VARIABLES}
        pairs = sorted((vr, spec[v.name]) for vr, v in slave.vars.items())
    if [vr for vr, _ in pairs] != list(range(len(pairs))):
        raise NativeBuildError(f"{cls.__name__}: value references are not 0..n-1")
    return pairs


def _pythonfmu_version_file() -> Path:
    """pythonfmu's ``_version.py`` (its version, read without importing pythonfmu or
    ``importlib.metadata``: 15 ms of a run)."""
    spec = importlib.util.find_spec("pythonfmu")
    if spec is None or not spec.submodule_search_locations:  # pragma: no cover - a dependency
        raise NativeBuildError("pythonfmu is not installed: expected pythonfmu==0.7.0")
    return Path(spec.submodule_search_locations[0]) / "_version.py"


def _header_key(c: Any) -> str:
    """A hash over everything :func:`vars_header` reads: the Python sources of the
    packages the slaves come from (the FMI layer's and every registered component's:
    their variables, ranges, wording), this generator, the
    names and Jacobian lines it takes from :mod:`.native_description` and the pythonfmu
    that numbers the variables (its version file)."""
    files = [Path(__file__), Path(__file__).with_name("native_description.py")]
    for folder in (registry.fmi_folder(), *(c.folder for c in registry.COMPONENTS)):
        files += sorted(folder.glob("*.py"))
    files.append(_pythonfmu_version_file())
    stamp = tuple((str(f), st.st_mtime_ns, st.st_size) for f in files for st in [f.stat()])
    digest = hashlib.sha256(f"{c.slave}\n{_sources_digest(stamp)}".encode())
    return f"{c.name}-{digest.hexdigest()[:32]}"


@functools.lru_cache(maxsize=4)
def _sources_digest(stamp: tuple[tuple[str, int, int], ...]) -> str:
    """The hash of the files of ``stamp`` (path, modification time and size: read again
    when one changes; each run's staleness check asks for it 9 times, for 3 slaves)."""
    h = hashlib.sha256()
    for path, _, _ in stamp:
        h.update(f"{Path(path).parent.name}/{Path(path).name}\n".encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def vars_header(c: Any) -> str:
    """``<Model>_vars.h``: the component's variables as a C struct and a NativeVar table.

    Kept in the FMU cache under a hash of what it is made from (:func:`_header_key`):
    made anew, it imports the slave and pythonfmu and instantiates the slave, 20-60 ms a
    component of every run's staleness check (issue 48)."""
    key = _header_key(c)
    memo = cache_root() / package_version() / "native-vars" / f"{key}.h"
    try:
        return memo.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        pass
    text = make_vars_header(c)
    if not _KEEP["on"]:
        return text
    try:
        memo.parent.mkdir(parents=True, exist_ok=True)
        part = memo.with_name(f"{memo.name}.{os.getpid()}.part")
        part.write_text(text, encoding="utf-8")
        os.replace(part, memo)  # whole or absent, whoever writes it at the same time
    except OSError:
        pass  # a cache that cannot be written: made anew each time
    return text


def make_vars_header(c: Any) -> str:
    """:func:`vars_header` made from the slave class (without the cache)."""
    cls = c.slave_class()
    pairs = _slave_variables(cls)
    computed = set(getattr(cls, "COMPUTED", ()))
    guard = f"{c.name.upper()}_VARS_H"
    ctype = {"Real": "double", "Integer": "int", "Boolean": "int"}
    lines = [
        f"/* {c.name}'s variables, generated by glider-cosim from {c.slave}: do not edit. */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "#include <math.h>",
        "#include <stddef.h>",
        '#include "native_model.h"',
        "",
        f"#define MODEL_IDENTIFIER {_c_string(c.name)}",
        "",
        "typedef struct {",
        *(
            f"    {ctype[v.type]} {c_name(v.name)}; /* vr {vr}, {v.causality}, [{v.unit}] */"
            for vr, v in pairs
        ),
        f"}} {c.name}Vars;",
        "",
        "enum {",
        *(f"    VR_{c_name(v.name)} = {vr}," for vr, v in pairs),
        f"    {c.name.upper()}_NVARS = {len(pairs)}",
        "};",
        "",
        f"static const char {c.name.upper()}_TYPES[] = "
        + _c_string("".join(v.type[0] for _, v in pairs))
        + ";",
        f"static const char *const {c.name.upper()}_NAMES[] = {{",
        *(f"    {_c_string(v.name)}," for _, v in pairs),
        "};",
        "",
        f"static const NativeVar {c.name.upper()}_VARS[] = {{",
    ]
    for _, v in pairs:
        r = v.valid
        if r is None or v.causality in ("output", "local"):
            rng = "0, -HUGE_VAL, HUGE_VAL, 0, 0, NULL"
        else:
            low = -math.inf if r.low is None else r.low
            high = math.inf if r.high is None else r.high
            rng = (
                f"1, {_c_double(low)}, {_c_double(high)}, {int(r.low_open)}, "
                f"{int(r.high_open)}, {_c_string(r.describe(v.type == 'Integer'))}"
            )
        lines.append(
            f"    {{{_c_string(v.name)}, '{v.type[0]}', NV_{v.causality.upper()}, "
            f"{int(v.tunable)}, {int(v.name in computed)}, "
            f"offsetof({c.name}Vars, {c_name(v.name)}), {_c_double(float(v.start))}, {rng}}},"
        )
    inputs = [str(vr) for vr, v in pairs if v.causality == "input" and v.type == "Real"]
    up = c.name.upper()
    lines += ["};", "", "/* the Real inputs' value references (checked finite at each step) */",
              f"static const unsigned {up}_REAL_INPUTS[] = {{{', '.join(inputs or ['0'])}}};",
              f"#define {up}_NREAL_INPUTS {len(inputs)}", "", *jacobian_lines(cls, up), "",
              "#endif", ""]  # fmt: skip
    return "\n".join(lines)
