"""Build the native flavor of the three FMUs (``glider-cosim build --flavor native``).

The same models in C99 (``src/*/<component>_model.c``) behind the same FMI layer
(``src/fmi/fmi2_layer.c``) as the Python flavor, with the native back end
(``src/fmi/backend_native.c``) instead of the embedded Python. The variables come from the
Python slaves' tables: :func:`vars_header` writes them as C (struct, value references,
start values, valid ranges and their wording), and the model description is the Python
slave's own, so both flavors have the same names, value references, causalities,
variabilities, units, start values and ranges.

Each FMU carries ``binaries/linux64/<id>.so`` (system C compiler), ``binaries/win64/<id>.dll``
(mingw-w64, when ``x86_64-w64-mingw32-gcc`` is installed) and ``sources/`` with every C file,
``buildDescription.xml`` and ``<SourceFiles>`` in the model description, so tools can
rebuild it (fmpy's ``build_platform_binary`` builds the sources as they are).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import logging
import math
import shutil
import subprocess
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import glider_controller
import glider_fmi
import glider_observer
import glider_plant
from glider_cosim.build import osp
from glider_fmi import compile as runtime

log = logging.getLogger(__name__)

#: resource naming the flavor of an FMU ("python" or "native")
FLAVOR_FILE = "resources/glider_cosim_flavor.txt"
#: resource holding the hash of the sources a native FMU was built from
NATIVE_HASH_FILE = "resources/glider_cosim_native.sha256"
#: flags of every native compile (the same on both platforms)
CFLAGS = (
    "-std=c99",
    "-O2",
    "-pedantic",
    "-Wall",
    "-Wextra",
    "-Werror=implicit-function-declaration",
    "-ffp-contract=off",
)
LINUX_FLAGS = ("-fPIC", "-shared", "-fvisibility=hidden")
WIN64_FLAGS = ("-shared", "-static-libgcc")
MINGW = "x86_64-w64-mingw32-gcc"

FMI_DIR = Path(glider_fmi.__file__).resolve().parent
#: the layer and the native back end, in every native FMU
LAYER_FILES = ("fmi_layer.h", "fmi_layer.c", "fmi2_layer.c", "native_model.h", "backend_native.c")


def _pkg(module: Any) -> Path:
    return Path(module.__file__).resolve().parent


@dataclass(frozen=True)
class NativeComponent:
    """A native FMU: its slave class (variables) and its C files (model + glue)."""

    name: str
    slave: str  # module:class of the Python slave that defines the variables
    files: tuple[Path, ...]  # C sources and headers, besides the layer

    def slave_class(self) -> type:
        module, _, cls = self.slave.partition(":")
        return getattr(__import__(module, fromlist=[cls]), cls)


PLANT_C = (_pkg(glider_plant) / "plant_model.h", _pkg(glider_plant) / "plant_model.c")
NATIVE_COMPONENTS: tuple[NativeComponent, ...] = (
    NativeComponent(
        "GliderPlant",
        "glider_plant.slave:GliderPlant",
        (*PLANT_C, _pkg(glider_plant) / "plant_fmu.c"),
    ),
    NativeComponent(
        "GliderObserver",
        "glider_observer.slave:GliderObserver",
        (
            *PLANT_C,
            _pkg(glider_observer) / "observer_model.h",
            _pkg(glider_observer) / "observer_model.c",
            _pkg(glider_observer) / "observer_fmu.c",
        ),
    ),
    NativeComponent(
        "GliderController",
        "glider_controller.slave:GliderController",
        (
            *PLANT_C,
            _pkg(glider_controller) / "controller_model.h",
            _pkg(glider_controller) / "controller_model.c",
            _pkg(glider_controller) / "controller_fmu.c",
        ),
    ),
)


class NativeBuildError(OSError):
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


def vars_header(c: NativeComponent) -> str:
    """``<Model>_vars.h``: the component's variables as a C struct and a NativeVar table."""
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
            f"    {ctype[v.type]} {v.name}; /* vr {vr}, {v.causality}, [{v.unit}] */"
            for vr, v in pairs
        ),
        f"}} {c.name}Vars;",
        "",
        "enum {",
        *(f"    VR_{v.name} = {vr}," for vr, v in pairs),
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
        causality = {"input": "NV_INPUT", "output": "NV_OUTPUT", "parameter": "NV_PARAMETER"}
        r = v.valid
        if r is None or v.causality == "output":
            rng = "0, -HUGE_VAL, HUGE_VAL, 0, 0, NULL"
        else:
            low = -math.inf if r.low is None else r.low
            high = math.inf if r.high is None else r.high
            rng = (
                f"1, {_c_double(low)}, {_c_double(high)}, {int(r.low_open)}, "
                f"{int(r.high_open)}, {_c_string(r.describe(v.type == 'Integer'))}"
            )
        lines.append(
            f"    {{{_c_string(v.name)}, '{v.type[0]}', {causality[v.causality]}, "
            f"{int(v.tunable)}, {int(v.name in computed)}, offsetof({c.name}Vars, {v.name}), "
            f"{_c_double(float(v.start))}, {rng}}},"
        )
    lines += ["};", "", "#endif", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------- sources and hash
def source_files(c: NativeComponent, fmi: int = 2) -> list[Path]:
    """Every C file of the component's FMU (the layer with the front end of FMI ``fmi``,
    the back end, models, glue)."""
    layer = [FMI_DIR / (f"fmi{fmi}_layer.c" if f == "fmi2_layer.c" else f) for f in LAYER_FILES]
    return layer + list(dict.fromkeys(c.files))


def native_hash(c: NativeComponent, fmi: int = 2) -> str:
    """SHA-256 over the C sources, the generated variables, the flags and the version."""
    h = hashlib.sha256(vars_header(c).encode())
    h.update(f"fmi{fmi}".encode())
    h.update(" ".join((*CFLAGS, *LINUX_FLAGS, *WIN64_FLAGS)).encode())
    h.update(_version().encode())
    h.update(osp.fingerprint().encode())
    for f in source_files(c, fmi):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def _version() -> str:
    try:
        return importlib.metadata.version("glider-cosim")
    except importlib.metadata.PackageNotFoundError:
        return "0"


def fmu_flavor(fmu: Path) -> str | None:
    """The flavor an FMU of ours records ("python", "native"), None if it records none."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(FLAVOR_FILE).decode().strip() or None
    except (OSError, KeyError, zipfile.BadZipFile):
        return None


def is_current(fmu: Path, c: NativeComponent, fmi: int = 2) -> bool:
    """True if ``fmu`` is a native FMU of FMI ``fmi`` built from the current sources."""
    try:
        with zipfile.ZipFile(fmu) as z:
            return z.read(NATIVE_HASH_FILE).decode().strip() == native_hash(c, fmi)
    except (OSError, KeyError, zipfile.BadZipFile):
        return False


# ---------------------------------------------------------------- compiling
def compile_binary(compiler: str, sources: list[Path], output: Path, flags: tuple[str, ...],
                   libs: tuple[str, ...] = ()) -> str:  # fmt: skip
    """Compile ``sources`` into the shared library ``output``; returns what the compiler
    printed (empty when warning-free).

    Raises
    ------
    NativeBuildError
        The compiler failed (its first lines quoted).
    """
    cmd = [
        compiler,
        *CFLAGS,
        *flags,
        f"-I{runtime.fmi_headers()}",
        f"-I{sources[0].parent}",
        *(str(s) for s in sources if s.suffix == ".c"),
        "-o",
        str(output),
        *libs,
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    except (OSError, subprocess.TimeoutExpired) as err:
        raise NativeBuildError(f"compiling {output.name} with {compiler} failed: {err}") from None
    if proc.returncode != 0 or not output.is_file():
        first = " ".join((proc.stderr or proc.stdout).strip().splitlines()[:3])
        raise NativeBuildError(
            f"compiling {output.name} with {compiler} failed (exit {proc.returncode}): {first}"
        )
    return (proc.stderr + proc.stdout).strip()


def mingw() -> str | None:
    """The mingw-w64 cross-compiler for win64, if installed."""
    return shutil.which(MINGW)


# ---------------------------------------------------------------- model description
def model_description(c: NativeComponent, sources: list[str]) -> bytes:
    """The Python slave's model description, for a native FMU: same variables, units and
    structure; a new GUID, our generation tool, no execution tool, and ``<SourceFiles>``."""
    cls = c.slave_class()
    with tempfile.TemporaryDirectory(prefix="glider_native_") as tmp:
        slave = cls(instance_name="codegen", resources=tmp)
        root = slave.to_xml(
            {
                "needsExecutionTool": "false",
                "canHandleVariableCommunicationStepSize": "true",
                "canBeInstantiatedOnlyOncePerProcess": "false",
                "canGetAndSetFMUstate": "true",
                "canSerializeFMUstate": "true",
            }
        )
    root.set(
        "guid",
        "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"glider-cosim/{c.name}/" + native_hash(c))) + "}",
    )
    root.set("generationTool", f"glider-cosim {_version()} (native C99)")
    root.set("version", _version())
    cs = root.find("CoSimulation")
    cs.set("needsExecutionTool", "false")
    cs.set("canGetAndSetFMUstate", "true")
    cs.set("canSerializeFMUstate", "true")
    for child in list(cs):
        cs.remove(child)
    files = ET.SubElement(cs, "SourceFiles")
    for name in sources:
        ET.SubElement(files, "File", name=name)
    ET.indent(root, "\t")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def build_description(c: NativeComponent, sources: list[str]) -> bytes:
    """``sources/buildDescription.xml`` (FMI 3.0 layout, allowed in FMI 2.0.4)."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    config = ET.SubElement(root, "BuildConfiguration", modelIdentifier=c.name)
    files = ET.SubElement(config, "SourceFileSet", language="C99")
    for name in sources:
        ET.SubElement(files, "SourceFile", name=name)
    ET.SubElement(config, "Library", name="m", description="libm (POSIX platforms)")
    ET.indent(root, "\t")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


# ---------------------------------------------------------------- building
#: where the binaries go, per FMI version
BINARY_DIRS = {2: ("binaries/linux64", "binaries/win64"),
               3: ("binaries/x86_64-linux", "binaries/x86_64-windows")}  # fmt: skip


def build_native_component(c: NativeComponent, out: Path, win64: str | None, fmi: int = 2) -> Path:
    """Build one native FMU of FMI ``fmi`` (2 or 3) into ``out`` (linux64 always, win64
    with the ``win64`` compiler)."""
    with tempfile.TemporaryDirectory(prefix=f"{c.name}_native_") as tmp:
        stage = Path(tmp)
        src = stage / "sources"
        src.mkdir()
        for f in source_files(c, fmi):
            shutil.copyfile(f, src / f.name)
        (src / f"{c.name}_vars.h").write_text(vars_header(c))
        files = sorted(p for p in src.iterdir() if p.suffix in (".c", ".h"))
        c_names = [p.name for p in files if p.suffix == ".c"]
        compiler = runtime.find_compiler()
        so = stage / f"{c.name}.so"
        printed = compile_binary(compiler, files, so, LINUX_FLAGS, ("-lm",))
        if printed:
            raise NativeBuildError(f"{c.name}: the C sources are not warning-free: {printed[:300]}")
        dll = None
        if win64:
            dll = stage / f"{c.name}.dll"
            printed = compile_binary(win64, files, dll, WIN64_FLAGS)
            if printed:
                raise NativeBuildError(f"{c.name} (win64): not warning-free: {printed[:300]}")
        out.mkdir(parents=True, exist_ok=True)
        fmu = out / f"{c.name}.fmu"
        from glider_cosim.build.files import replacing

        linux, windows = BINARY_DIRS[fmi]
        md = model_description(c, c_names)
        if fmi == 3:
            from glider_cosim.build.fmi3_description import fmi3_model_description

            md = fmi3_model_description(md)
        with replacing(fmu) as part, zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", md)
            z.writestr(osp.extra_path(md), osp.generate(md))
            z.write(so, f"{linux}/{c.name}.so")
            if dll is not None:
                z.write(dll, f"{windows}/{c.name}.dll")
            for p in files:
                z.write(p, f"sources/{p.name}")
            z.writestr("sources/buildDescription.xml", build_description(c, c_names))
            z.writestr(FLAVOR_FILE, "native\n")
            z.writestr(NATIVE_HASH_FILE, native_hash(c, fmi) + "\n")
    osp.write_beside(fmu)  # where OSP's tools look for it
    return fmu


def build_native(out: Path | str, only_stale: bool = False, fmi: int = 2) -> dict[str, Path]:
    """Build the three native FMUs of FMI ``fmi`` into ``out``; model identifier -> path.

    Without mingw-w64 the FMUs carry linux64 only, and a one-line warning says so.
    """
    out = Path(out)
    result = {c.name: out / f"{c.name}.fmu" for c in NATIVE_COMPONENTS}
    todo = [c for c in NATIVE_COMPONENTS if not (only_stale and is_current(result[c.name], c, fmi))]
    if not todo:
        return result
    win64 = mingw()
    if win64 is None:
        log.warning(
            "no %s found: the native FMUs carry linux64 only (win64 left out; install "
            "gcc-mingw-w64-x86-64)",
            MINGW,
        )
    for c in todo:
        result[c.name] = build_native_component(c, out, win64, fmi)
    return result
