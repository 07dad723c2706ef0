"""FMI-LS-WASM: the native FMI 3.0 FMUs' WebAssembly components, and our master on them.

- each FMU carries ``binaries/wasm32-wasip2/<id>.wasm`` and the layered standard's
  manifest; ``wasm-tools validate`` passes; ``wasm-tools component wit`` lists the draft's
  world: imports ``fmi:fmi3/types`` and ``fmi:fmi3/callbacks`` alone (no WASI: no file,
  clock or network), exports ``common`` and ``co-simulation`` with every function of the
  draft's ``co-simulation-instance``;
- the model description and the native binary are those of a build without components;
- ``run --flavor wasm`` equals ``run --flavor native --fmi 3`` within 1e-15 (the
  components' libm is WASI libc's, the native binaries' glibc's: sin, cos, exp, ... differ
  in the last bit here and there), with the same outcome and metrics to 1e-12;
- the call sequences of tests/integration/wasm_fuzz.py return the same statuses and the
  same messages from a component and from its FMU's native library (test_wasm_fuzz).
"""

from __future__ import annotations

import csv
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest
from system_tools import require_tool

from glider_cosim.fmus import wasm
from glider_cosim.fmus.folders import prepare_fmus

pytestmark = pytest.mark.integration
NAMES = ("GliderPlant", "GliderObserver", "GliderController")
#: the draft's co-simulation-instance (modelica/fmi-ls-wasm @ c1aac17,
#: wit/fmi3-co-simulation.wit): what a foreign runtime binds to
DRAFT_METHODS = """
instantiate-co-simulation set-debug-logging enter-initialization-mode exit-initialization-mode
enter-event-mode update-discrete-states terminate reset enter-configuration-mode
exit-configuration-mode get-float32 get-float64 get-int8 get-int16 get-int32 get-int64
get-uint8 get-uint16 get-uint32 get-uint64 get-boolean get-string get-binary get-clock
set-float32 set-float64 set-int8 set-int16 set-int32 set-int64 set-uint8 set-uint16
set-uint32 set-uint64 set-boolean set-string set-binary set-clock
get-number-of-variable-dependencies get-variable-dependencies get-fmu-state set-fmu-state
get-directional-derivative get-adjoint-derivative get-interval-decimal get-interval-fraction
get-shift-decimal get-shift-fraction set-interval-decimal set-interval-fraction
set-shift-decimal set-shift-fraction evaluate-discrete-states set-input-derivatives
get-output-derivatives do-step enter-step-mode
""".split()


@pytest.fixture(scope="module")
def wasm_dir() -> Path:
    """The native FMI 3 set this machine runs (the cache's; the one ``run --flavor wasm``
    uses)."""
    return prepare_fmus(None, "native", 3, host_only=True)


def test_components_in_the_fmus(wasm_dir, tmp_path):
    for name in NAMES:
        with zipfile.ZipFile(wasm_dir / f"{name}.fmu") as z:
            component = z.read(f"binaries/wasm32-wasip2/{name}.wasm")
            manifest = ET.fromstring(z.read("extra/org.modelica.fmi-ls-wasm/manifest.xml"))
        ns = "{http://fmi-standard.org/fmi-ls-manifest}"
        assert manifest.get(f"{ns}fmi-ls-name") == "org.modelica.fmi-ls-wasm"
        assert re.fullmatch(r"\d+\.\d+\.\d+", manifest.get(f"{ns}fmi-ls-version"))
        assert manifest.get(f"{ns}fmi-ls-description") == "FMI Layered Standard for WebAssembly"
        assert component[:8] == b"\0asm\x0d\0\x01\0"  # a component, not a core module
        path = tmp_path / f"{name}.wasm"
        path.write_bytes(component)
        wasm.validate(path)  # raises with wasm-tools' message
        text = wasm.component_wit(path)
        world = text[text.index("world root {") : text.index("}", text.index("world root {"))]
        imports = re.findall(r"import ([\w:/@.-]+);", world)
        exports = re.findall(r"export ([\w:/@.-]+);", world)
        assert sorted(imports) == ["fmi:fmi3/callbacks@3.0.0", "fmi:fmi3/types@3.0.0"], world
        assert sorted(exports) == ["fmi:fmi3/co-simulation@3.0.0", "fmi:fmi3/common@3.0.0"]
        assert "wasi" not in text
        callbacks = text[text.index("interface callbacks {") :]
        callbacks = callbacks[: callbacks.index("\n  }")]
        assert re.findall(r"([\w-]+): func", callbacks) == ["log-message"]
        cosim = text[text.index("resource co-simulation-instance {") :]
        cosim = cosim[: cosim.index("\n    }")]
        assert sorted(re.findall(r"([\w-]+): (?:static )?func", cosim)) == sorted(DRAFT_METHODS)
        assert "get-version: func() -> string;" in text


def test_description_and_native_binary_unchanged(wasm_dir, tmp_path, monkeypatch):
    """A build without components (as when wasm-tools is missing) has the same model
    description and native binaries: other hosts see the same FMU."""
    from glider_cosim.fmus.native import build_native

    monkeypatch.setattr(wasm, "available", lambda: "switched off by the test")
    plain = build_native(tmp_path, fmi=3, host_only=True)
    for name in NAMES:
        with zipfile.ZipFile(wasm_dir / f"{name}.fmu") as a, zipfile.ZipFile(plain[name]) as b:
            assert "binaries/wasm32-wasip2/" + name + ".wasm" not in b.namelist()
            assert _undated(a.read("modelDescription.xml")) == _undated(
                b.read("modelDescription.xml")
            )
            so = f"binaries/x86_64-linux/{name}.so"
            assert a.read(so) == b.read(so)


def _undated(md: bytes) -> bytes:
    """A model description without its build time (each build writes its own)."""
    return re.sub(rb'generationDateAndTime="[^"]*"', b"", md)


def _rows(path: Path) -> tuple[list[str], list[list[float]]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(x) for x in r] for r in rows[1:]]


def test_run_flavor_wasm_equals_native(wasm_dir, tmp_path):
    """``run --flavor wasm`` (the components under wasmtime) against ``--flavor native
    --fmi 3`` (the same C as shared libraries): the same rows, to 1e-15."""
    outs = {}
    for flavor in ("native", "wasm"):
        outs[flavor] = tmp_path / flavor
        cmd = [sys.executable, "-m", "glider_cosim.cli", "run", "--flavor", flavor,
               "--out", str(outs[flavor]), "--no-plots"]  # fmt: skip
        if flavor == "native":
            cmd += ["--fmi", "3"]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stderr
        assert "outcome: settled" in p.stdout
    head_n, native = _rows(outs["native"] / "results.csv")
    head_w, components = _rows(outs["wasm"] / "results.csv")
    assert head_n == head_w and len(native) == len(components) == 3001
    worst = max(abs(a - b) for rn, rw in zip(native, components) for a, b in zip(rn, rw))
    assert worst <= 1e-15, worst
    import json

    run = json.loads((outs["wasm"] / "metrics.json").read_text())["run"]
    assert run["options"]["--flavor"] == "wasm"  # the run record says what ran


def test_run_flavor_wasm_needs_fmi3(tmp_path):
    p = subprocess.run(
        [sys.executable, "-m", "glider_cosim.cli", "run", "--flavor", "wasm", "--fmi", "2",
         "--out", str(tmp_path / "o")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert p.returncode == 2
    assert p.stderr.strip().splitlines()[-1] == (
        "glider-cosim run: error: --flavor wasm runs FMI 3.0 components: expected --fmi 3 or none"
    )


def test_wasm_fuzz(wasm_dir):
    """The differential call-sequence fuzz: component and native library agree on every
    status and message."""
    here = Path(__file__).parent
    fmus = [str(wasm_dir / f"{n}.fmu") for n in NAMES]
    p = subprocess.run([sys.executable, str(here / "wasm_fuzz.py"), "7", "40", *fmus],
                       capture_output=True, text=True, timeout=900)  # fmt: skip
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert p.stdout.strip().endswith("done")
    for n in NAMES:
        m = re.search(rf"{n}: (\d+) calls, (\d+) steps OK, (\d+) fmi3Error", p.stdout)
        assert m and int(m[1]) > 500 and int(m[2]) > 20 and int(m[3]) > 20, p.stdout[-2000:]


def test_a_trap_is_fatal_with_a_message(wasm_dir):
    """A component that traps (a guest's ``unreachable``, fuel run out) stops the run with
    fmi3Fatal and one line naming it; no later call enters the component."""
    import wasmtime

    from glider_cosim.master import CoSimulation
    from glider_cosim.master.errors import FMUCallError
    from glider_cosim.master.wasm import components
    from glider_cosim.scenarios.scenario import load_scenario
    from glider_cosim.scenarios.system import system_for

    sc = load_scenario(None)
    with components():
        sim = CoSimulation(system_for(sc, wasm_dir), step=sc.step, coupling=sc.coupling)
        try:
            sim.initialize()
            sim.communication_point()
            plant = sim.instances["plant"].slave
            calls = []

            def trap(*args):
                calls.append(args)
                raise wasmtime.WasmtimeError("wasm trap: wasm `unreachable` instruction executed")

            plant._calls["do-step"] = trap
            with pytest.raises(FMUCallError) as caught:
                sim.do_step()
            assert caught.value.status == 4 and len(calls) == 1
            assert str(caught.value) == (
                "plant: fmi3DoStep at t = 0 s returned fmi3Fatal: [fmi3Fatal] the component "
                "trapped (wasm trap: wasm `unreachable` instruction executed)"
            )
            assert plant.call("get-float64", [0]) == "fatal" and len(calls) == 1
        finally:
            sim.close()


def _glue_sources(tmp: Path) -> list[str]:
    """The plant's native FMI 3 sources and the glue, staged in ``tmp``."""
    from glider_cosim.fmus.native import NATIVE_COMPONENTS, source_files, vars_header

    plant = next(c for c in NATIVE_COMPONENTS if c.name == "GliderPlant")
    for f in source_files(plant, 3):
        (tmp / f.name).write_bytes(f.read_bytes())
    (tmp / "GliderPlant_vars.h").write_text(vars_header(plant))
    names = [f.name for f in source_files(plant, 3) if f.suffix == ".c"]
    return [str(tmp / n) for n in names] + [str(wasm.glue_source())]


@pytest.mark.parametrize("check", ["asan", "valgrind"])
def test_the_glue_under_memory_checks(tmp_path, check):
    """The glue built natively (warning-free), every function of the world called by
    tests/integration/wasm_glue_harness.c, clean under ASan + UBSan and valgrind memcheck."""

    from glider_fmi.compile import fmi_headers

    tools = {"asan": "gcc", "valgrind": "valgrind"}
    require_tool("gcc")
    require_tool(tools[check])
    sanitize = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    flags = ["-g", "-O1", "-std=c99", "-Wall", "-Wextra", "-Werror", "-Wno-attributes",
             "-ffp-contract=off", *(sanitize if check == "asan" else [])]  # fmt: skip
    exe = tmp_path / "harness"
    harness = Path(__file__).with_name("wasm_glue_harness.c")
    build = subprocess.run(
        ["gcc", *flags, "-isystem", str(fmi_headers()), f"-I{tmp_path}", *_glue_sources(tmp_path),
         str(harness), "-o", str(exe), "-lm", "-lpthread"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert build.returncode == 0 and not build.stderr.strip(), build.stderr
    cmd = [str(exe)]
    if check == "valgrind":
        cmd = ["valgrind", "-q", "--error-exitcode=9", "--leak-check=full",
               "--errors-for-leak-kinds=definite,indirect", *cmd]  # fmt: skip
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip() == "steps 200, messages 676, fatal 0"
    assert p.stderr.strip() == ""
