"""The native flavor (C99 models behind the same FMI layer) where users put it.

- the FMUs: fmpy validate, only libc and libm (linux64), only KERNEL32/msvcrt (win64),
  ``sources/`` with ``buildDescription.xml`` and ``<SourceFiles>``;
- the same interface as the Python flavor, variable by variable;
- the same numbers: the default and the noise scenario, shared columns, bit for bit;
- a C host (tests/integration/c_host/host.c) under ``env -i`` in a mount namespace where
  every Python installation is hidden (checked), equal to our master;
- the win64 DLLs under wine, stepped by the same host cross-compiled with mingw-w64;
- rebuilt from ``sources/`` by fmpy's ``build_platform_binary`` and run, equal;
- valgrind memcheck on a C-host run (no error, nothing definitely lost);
- the same refusal messages as the Python flavor;
- ``run --fmu-dir`` with native FMUs runs them as they are.
The fuzz, the serialization round trip, the two-thread test and libcosim run on both
flavors in their own files (the ``flavor_dir`` fixture).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from c_host_helpers import (
    RECORD,
    STOP,
    hidden_rows,
    hidden_run,
    master_jacobi_run,
    unzip,
    valgrind_run,
    wine_rows,
)
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from raw_fmi import RawFMU
from system_tools import require_tool

from glider_cosim.fmus.folders import folder_flavor
from glider_cosim.fmus.native import NATIVE_COMPONENTS
from glider_cosim.runner import simulate
from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration
NAMES = [c.name for c in NATIVE_COMPONENTS]


@pytest.mark.parametrize("name", NAMES)
def test_native_fmu_is_valid_and_self_contained(native_dir, tmp_path, name):
    fmu = native_dir / f"{name}.fmu"
    assert validate_fmu(str(fmu)) == []
    d = unzip(fmu, tmp_path / name)
    assert folder_flavor(native_dir) == "native"
    so = d / "binaries" / "linux64" / f"{name}.so"
    require_tool("readelf", install="apt-get install binutils")
    require_tool("objdump", install="apt-get install binutils")
    needed = subprocess.run(["readelf", "-d", str(so)], capture_output=True, text=True,
                            check=True).stdout  # fmt: skip
    libs = {line.split("[")[1].rstrip("]") for line in needed.splitlines() if "NEEDED" in line}
    assert libs == {"libc.so.6", "libm.so.6"}
    dll = d / "binaries" / "win64" / f"{name}.dll"
    dump = subprocess.run(["objdump", "-p", str(dll)], capture_output=True, text=True,
                          check=True).stdout  # fmt: skip
    imports = {line.split(":")[1].strip() for line in dump.splitlines() if "DLL Name" in line}
    # zig links mingw-w64's runtime over the Universal C Runtime (in every Windows 10 and
    # 11, Windows 7 and 8.1 by update; in wine), not the old msvcrt.dll
    assert "KERNEL32.dll" in imports
    assert imports - {"KERNEL32.dll"} and all(
        i.startswith("api-ms-win-crt-") for i in imports - {"KERNEL32.dll"}
    ), imports
    md = read_model_description(str(fmu))
    listed = [f.strip() for f in (d / "modelDescription.xml").read_text().split('File name="')[1:]]
    sources = sorted(p.name for p in (d / "sources").glob("*.c"))
    assert sorted(x.split('"')[0] for x in listed) == sources
    assert {"fmi2_layer.c", "backend_native.c", "plant_model.c"} <= set(sources)
    assert (d / "sources" / "buildDescription.xml").is_file()
    assert md.coSimulation.canSerializeFMUstate and md.coSimulation.canGetAndSetFMUstate
    assert not md.coSimulation.needsExecutionTool
    assert not (d / "resources" / "slavemodule.txt").exists()  # no Python anywhere


def variable_table(fmu: Path) -> list[tuple]:
    md = read_model_description(str(fmu))
    return [
        (v.name, v.valueReference, v.type, v.causality, v.variability, v.initial, v.unit,
         v.displayUnit, v.start, v.min, v.max, v.description)
        for v in md.modelVariables
    ]  # fmt: skip


@pytest.mark.parametrize("name", NAMES)
def test_native_interface_equals_the_python_flavor(fmu_dir, native_dir, name):
    py, nat = fmu_dir / f"{name}.fmu", native_dir / f"{name}.fmu"
    assert variable_table(py) == variable_table(nat)
    a, b = read_model_description(str(py)), read_model_description(str(nat))
    assert a.coSimulation.modelIdentifier == b.coSimulation.modelIdentifier == name
    assert [(u.variable.name, [d.name for d in u.dependencies or []]) for u in a.outputs] == [
        (u.variable.name, [d.name for d in u.dependencies or []]) for u in b.outputs
    ]
    assert [u.variable.name for u in a.initialUnknowns] == [
        u.variable.name for u in b.initialUnknowns
    ]
    assert [u.name for u in a.unitDefinitions] == [u.name for u in b.unitDefinitions]


@pytest.mark.parametrize("scenario", ["default", "fig5-6-observer-noise"])
def test_native_equals_the_python_flavor_bit_for_bit(fmu_dir, native_dir, scenario):
    a = simulate(scenario, None, fmu_dir=fmu_dir, build=False)
    b = simulate(scenario, None, fmu_dir=native_dir, build=False)
    assert a.status == b.status == "ok"
    assert a.columns == b.columns and a.data.shape == b.data.shape == (3001, len(a.columns))
    diff = np.abs(a.data - b.data)
    print(f"{scenario}: max |native - python| = {diff.max():.3g} over {len(a.columns)} columns")
    assert diff.max() <= 1e-9  # the bound
    assert np.array_equal(a.data, b.data)  # what we reached on linux64: bit for bit


# ---------------------------------------------------------------- hosts
@pytest.fixture(scope="module")
def native_system(native_dir):
    return system_for(load_scenario("default"), native_dir)


@pytest.fixture(scope="module")
def master_rows(native_system) -> np.ndarray:
    return master_jacobi_run(native_system).array()


@pytest.mark.parametrize("threads", [False, True], ids=["main-thread", "thread-per-step"])
def test_c_host_with_no_python_reachable_equals_our_master(
    native_system, master_rows, tmp_path, threads
):
    got = hidden_rows(native_system, tmp_path, "host", [], threads=threads)
    assert got.shape == master_rows.shape == (round(STOP / 0.02) + 1, 1 + len(RECORD))
    assert np.array_equal(got, master_rows)  # bit for bit


def test_python_is_really_hidden_in_the_namespace(tmp_path):
    """The check inside hidden_run can fail: with the same mounts, python3 does not start."""
    fake_host = tmp_path / "host.sh"
    fake_host.write_text("#!/bin/sh\nexec python3 -c 'print(1)'\n")
    fake_host.chmod(0o755)
    p = hidden_run(fake_host, tmp_path / "none", tmp_path)
    assert p.returncode != 0 and "1" not in p.stdout


def test_win64_dlls_under_wine_equal_linux64(native_system, master_rows, tmp_path):
    got = wine_rows(native_system, tmp_path, "host.exe", [])
    assert got.shape == master_rows.shape
    diff = np.abs(got - master_rows).max()
    print(f"win64 under wine vs linux64: max diff {diff:.3g}")
    assert diff <= 1e-9  # Windows' libm may differ in the last bit


def test_rebuilt_from_sources_with_fmpy_runs_equal(native_dir, tmp_path):
    from fmpy.build import build_platform_binary

    require_tool("cmake")
    rebuilt = tmp_path / "rebuilt"
    rebuilt.mkdir()
    for name in NAMES:
        d = unzip(native_dir / f"{name}.fmu", tmp_path / name)
        shutil.rmtree(d / "binaries")
        build_platform_binary(str(d.resolve()))
        assert (d / "binaries" / "linux64" / f"{name}.so").is_file()
        with zipfile.ZipFile(rebuilt / f"{name}.fmu", "w") as z:
            for f in sorted(d.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(d).as_posix())
    a = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=20.0)
    b = simulate("default", None, fmu_dir=rebuilt, build=False, stop_time=20.0)
    assert a.status == b.status == "ok"
    diff = np.abs(a.data - b.data).max()
    print(f"rebuilt by fmpy (cmake, -O3) vs ours: max diff {diff:.3g}")
    assert diff <= 1e-9


def test_c_host_run_is_clean_under_valgrind(native_system, tmp_path):
    p = valgrind_run(native_system, tmp_path, "host", [])
    assert p.returncode == 0, p.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in p.stderr
    assert "definitely lost: 0 bytes" in p.stderr or "no leaks are possible" in p.stderr


# ---------------------------------------------------------------- messages
CASES = [
    ("GliderController", "K_c", float("nan")),
    ("GliderController", "law", 7),
    ("GliderPlant", "noise_seed", -5),
    ("GliderPlant", "V_0", -1.0),
    ("GliderPlant", "delta_0", 2.0),  # |delta_0| > delta_max (1.57)
    ("GliderObserver", "f_cutoff", 30.0),  # above Nyquist at 50 Hz
    ("GliderObserver", "R", 0.0),
    ("GliderPlant", "K_M0", -1.0),  # no descending glide
]


def refusal(fmu: Path, name: str, value) -> list[str]:
    r = RawFMU(fmu)
    c = r.instantiate("x")
    setter = r.set_integer if r.types[name] == "Integer" else r.set_real
    assert setter(c, **{name: value}) == 0
    assert r.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == 0
    assert r.EnterInitializationMode(c) == 0
    assert r.ExitInitializationMode(c) == 3
    out = r.errors()
    r.FreeInstance(c)
    return out


@pytest.mark.parametrize(("name", "var", "value"), CASES)
def test_refusals_say_the_same_in_both_flavors(fmu_dir, native_dir, name, var, value):
    py = refusal(fmu_dir / f"{name}.fmu", var, value)
    nat = refusal(native_dir / f"{name}.fmu", var, value)
    assert py and py == nat
    assert py[-1].startswith("x: fmi2ExitInitializationMode: ")


def test_stall_is_a_discard_with_the_same_message(fmu_dir, native_dir):
    msgs = {}
    for flavor, d in (("python", fmu_dir), ("native", native_dir)):
        r = RawFMU(d / "GliderPlant.fmu")
        c = r.instantiate("plant")
        # a tail held hard over: the glider tumbles and stalls
        assert r.set_real(c, delta_cmd=1.2) == 0
        assert r.initialize(c, delta_0=1.2) == 0
        t, st = 0.0, 0
        for k in range(3000):
            st = r.DoStep(c, k * 0.02, 0.02, 1)
            if st:
                t = k * 0.02
                break
        assert st == 2, f"{flavor}: no discard"  # fmi2Discard
        msgs[flavor] = (t, [m.text for m in r.messages if m.status == 2])
        r.FreeInstance(c)
    assert msgs["python"] == msgs["native"]
    assert "glider stalled" in msgs["native"][1][0]


def test_run_with_native_fmu_dir_runs_them_as_they_are(native_dir, tmp_path):
    before = {n: (native_dir / f"{n}.fmu").stat().st_mtime_ns for n in NAMES}
    p = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "run", "--fmu-dir",
                        str(native_dir), "--no-plots", "--out", str(tmp_path / "o"),
                        "--stop-time", "2"], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr
    after = {n: (native_dir / f"{n}.fmu").stat().st_mtime_ns for n in NAMES}
    assert before == after  # not rebuilt (as the Python flavor or at all)
    assert folder_flavor(native_dir) == "native"


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_simulate_fmu_runs_each_native_fmu(native_dir, fmu_dir, name):
    """The fmpy recipe (docs/how-to/use-the-fmus.md): each FMU alone with its start values."""
    a = fmpy.simulate_fmu(str(native_dir / f"{name}.fmu"), stop_time=5.0, output_interval=0.02)
    b = fmpy.simulate_fmu(str(fmu_dir / f"{name}.fmu"), stop_time=5.0, output_interval=0.02)
    assert len(a) == len(b) == 251
    assert a.dtype.names == b.dtype.names
    for col in a.dtype.names:
        assert np.array_equal(a[col], b[col]), col  # the same under fmpy's own loop


def test_a_step_that_does_not_match_f_sample_is_a_warning_once(fmu_dir, native_dir):
    """Another host never learns of a mismatch from our master: the observer says it."""
    seen = {}
    for flavor, d in (("python", fmu_dir), ("native", native_dir)):
        r = RawFMU(d / "GliderObserver.fmu")
        c = r.instantiate("obs")  # logging off: warnings pass all the same
        assert r.initialize(c) == 0
        statuses = [r.DoStep(c, k * 0.07, 0.07, 1) for k in range(3)]
        assert statuses == [0, 0, 0]  # fmi2OK: the host does not stop
        seen[flavor] = [(m.status, m.category, m.text) for m in r.messages if m.status == 1]
        r.FreeInstance(c)
        # a matching step says nothing
        c = r.instantiate("obs2")
        r.messages.clear()
        assert r.initialize(c) == 0 and r.DoStep(c, 0.0, 0.02, 1) == 0
        assert [m for m in r.messages if m.status == 1] == []
        r.FreeInstance(c)
    assert seen["python"] == seen["native"]
    assert len(seen["native"]) == 1
    status, category, text = seen["native"][0]
    assert category == "logStatusWarning"
    assert text == (
        "obs: communication step 0.07 s does not match f_sample = 50 Hz (1/step = 14.2857 Hz): "
        "the pre-filter runs once per step, its coefficients assume f_sample"
    )


def test_every_command_takes_the_native_flavor(native_dir, tmp_path):
    """report, sweep, export-ssp and export-fmu run on the native FMUs (--fmu-dir)."""
    cli = [sys.executable, "-m", "glider_cosim.cli"]
    runs = {
        "export-ssp": [*cli, "export-ssp", str(tmp_path / "g.ssp"), "--fmu-dir", str(native_dir)],
        "export-fmu": [*cli, "export-fmu", str(tmp_path / "g.fmu"), "--fmu-dir", str(native_dir)],
        "sweep": [*cli, "sweep", "--param", "controller.K_c=8,10", "--workers", "1",
                  "--stop-time", "5", "--no-plots", "--out", str(tmp_path / "sw"),
                  "--fmu-dir", str(native_dir)],
        "report": [*cli, "report", "--roa-grid", "none", "--out", str(tmp_path / "rep"),
                   "--fmu-dir", str(native_dir), "--no-progress"],
    }  # fmt: skip
    for name, cmd in runs.items():
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert p.returncode == 0, (name, p.stderr[-2000:])
    assert folder_flavor(native_dir) == "native"  # used as they are, never rebuilt
    with zipfile.ZipFile(tmp_path / "g.ssp") as z:
        plant = next(n for n in z.namelist() if n.endswith("GliderPlant.fmu"))
        (tmp_path / "p.fmu").write_bytes(z.read(plant))
    md = fmpy.read_model_description(str(tmp_path / "p.fmu"))
    assert md.generationTool.endswith("(native C99)")  # the SSP carries the native FMUs
    assert (tmp_path / "rep" / "report.md").is_file()
    assert "K_c" in (tmp_path / "sw" / "sweep.csv").read_text().splitlines()[0]


def test_a_system_compiler_builds_its_platform_bit_equal_and_says_what_is_left_out(
    native_dir, tmp_path, monkeypatch, caplog
):
    """``--compiler gcc`` without zig: linux64 only, one warning line naming the others;
    gcc's build runs the default scenario bit for bit like zig's."""
    from glider_cosim.fmus import native
    from glider_fmi import toolchain

    require_tool("gcc")
    monkeypatch.setattr(toolchain, "zig_available", lambda: False)
    with caplog.at_level("WARNING", logger="glider_cosim.fmus.native"):
        native.build_native(tmp_path, compiler="gcc")
    lines = [r.getMessage() for r in caplog.records if r.name == "glider_cosim.fmus.native"]
    assert lines == [
        "--compiler gcc builds no aarch64-linux, x86_64-windows, x86_64-darwin, aarch64-darwin: "
        "the native FMUs leave those out (zig, the default, builds every platform)"
    ]
    with zipfile.ZipFile(tmp_path / "GliderPlant.fmu") as z:
        assert [n for n in z.namelist() if n.startswith("binaries/")] == [
            "binaries/linux64/GliderPlant.so"
        ]
    monkeypatch.undo()
    a = simulate("default", None, fmu_dir=native_dir, build=False)
    b = simulate("default", None, fmu_dir=tmp_path, build=False)
    assert a.status == b.status == "ok"
    assert np.array_equal(a.data, b.data)


def test_a_missing_compiler_is_one_line(tmp_path):
    p = subprocess.run([sys.executable, "-m", "glider_cosim.cli", "build", "--flavor", "native",
                        "--compiler", "no-such-cc", "--out", str(tmp_path / "fmus")],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert p.returncode == 2
    assert p.stderr == (
        "glider-cosim build: error: --compiler no-such-cc: not found on PATH (the default, zig, "
        "comes with 'pip install': python -m ziglang cc)\n"
    )
    assert not list(Path(tmp_path).glob("fmus/*.fmu"))


def test_mingw_chosen_builds_win64_and_zig_the_rest(tmp_path):
    """``--compiler x86_64-w64-mingw32-gcc``: the DLL is mingw's (msvcrt.dll, not the
    UCRT), every other platform zig's."""
    from glider_cosim.fmus import native

    require_tool("x86_64-w64-mingw32-gcc", install="apt-get install gcc-mingw-w64-x86-64")
    native.build_native(tmp_path, compiler="x86_64-w64-mingw32-gcc")
    d = unzip(tmp_path / "GliderPlant.fmu", tmp_path / "p")
    bins = sorted(str(p.relative_to(d)) for p in (d / "binaries").rglob("*.*"))
    assert [b.split("/")[1] for b in bins] == ["aarch64-linux", "darwin64", "linux64", "win64"]
    require_tool("objdump", install="apt-get install binutils")
    dump = subprocess.run(["objdump", "-p", str(d / "binaries/win64/GliderPlant.dll")],
                          capture_output=True, text=True, check=True).stdout  # fmt: skip
    imports = {line.split(":")[1].strip() for line in dump.splitlines() if "DLL Name" in line}
    assert imports == {"KERNEL32.dll", "msvcrt.dll"}


def test_many_instances_in_one_process_each_keep_their_own_values(native_dir):
    """More live instances than the layer's lock-free table holds (64): every one is found
    (table or list), keeps its own values, and a freed one is refused, in any order."""
    import random

    r = RawFMU(native_dir / "GliderController.fmu")

    def run(c, k: int) -> float:
        assert r.set_real(c, V_hat=0.22, theta_g_hat=-0.45 + 0.002 * k) == 0
        assert r.DoStep(c, 0.0, 0.02, 1) == 0
        st, (u,) = r.get_real(c, "delta_cmd")
        assert st == 0
        return u

    alone = []
    for k in range(100):
        c = r.instantiate(f"alone{k}")
        assert c and r.initialize(c) == 0
        alone.append(run(c, k))
        r.FreeInstance(c)
    assert len(set(alone)) > 90  # the inputs matter: a mix-up between instances shows
    live = {}
    for k in range(100):
        live[k] = c = r.instantiate(f"c{k}")
        assert c and r.initialize(c) == 0
    assert [run(live[k], k) for k in range(100)] == alone
    order = list(live)
    random.Random(3).shuffle(order)
    for k in order[:70]:
        gone = live.pop(k)
        r.FreeInstance(gone)
        if gone not in live.values():  # the address may be reused by a later instance
            assert r.get_real(gone, "delta_cmd")[0] == 3  # fmi2Error, not a crash
    for k in range(100, 130):  # new ones take the freed slots
        live[k] = c = r.instantiate(f"c{k}")
        assert c and r.initialize(c) == 0
        assert run(c, k - 100) == alone[k - 100]
    for k, c in live.items():  # the 30 left of the first 100 still hold their values
        st, (u,) = r.get_real(c, "delta_cmd")
        assert st == 0 and u == alone[k % 100]
    for c in live.values():
        r.FreeInstance(c)


def test_instances_made_and_freed_on_many_threads_stay_apart(native_dir):
    """Threads instantiating, stepping and freeing at once (ctypes drops the GIL in each
    call, so the calls overlap): the lock-free lookup never mixes instances up."""
    import threading

    r = RawFMU(native_dir / "GliderController.fmu")

    def run(k: int) -> float:
        c = r.instantiate(f"t{k}")
        assert c and r.initialize(c) == 0
        assert r.set_real(c, V_hat=0.22, theta_g_hat=-0.45 + 0.002 * (k % 50)) == 0
        assert r.DoStep(c, 0.0, 0.02, 1) == 0
        st, (u,) = r.get_real(c, "delta_cmd")
        r.FreeInstance(c)
        assert st == 0
        return u

    expected = [run(k) for k in range(50)]
    got: dict[int, list[float]] = {}

    def worker(w: int) -> None:
        got[w] = [run(k) for k in range(w, w + 400)]

    threads = [threading.Thread(target=worker, args=(w,)) for w in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for w in range(4):
        assert got[w] == [expected[k % 50] for k in range(w, w + 400)]


def test_the_exchanges_quick_path_gives_what_the_full_path_gives(native_dir):
    """The native back end's gets and sets of Reals skip the layer's call framing unless a
    call is logged: the same loop with every call logged (logFmiCalls: the full path)
    gives the same rows bit for bit, and an output set in between is still refused."""
    from ctypes import c_char_p

    from raw_fmi import Loop

    def run(logged: bool) -> tuple[list[list[float]], int]:
        raws = {n: RawFMU(native_dir / f"Glider{n.title()}.fmu")
                for n in ("plant", "observer", "controller")}  # fmt: skip
        loop = Loop(raws, "quick" if not logged else "full")
        loop.instantiate()
        if logged:
            for inst, raw in raws.items():
                cats = (c_char_p * 1)(b"logFmiCalls")
                assert raw.SetDebugLogging(loop.c[inst], 1, 1, cats) == 0
        loop.initialize({"controller": {"K_c": 10.0}})
        rows = loop.step(150)
        raw = raws["plant"]
        assert raw.set_real(loop.c["plant"], theta_meas=0.0) == 3  # an output: fmi2Error
        assert raw.errors()[-1].endswith("theta_meas is an output: it cannot be set")
        calls = sum(m.text == "fmi2GetReal" for r in raws.values() for m in r.messages)
        loop.free()
        return rows, calls

    quick, quick_calls = run(logged=False)
    full, full_calls = run(logged=True)
    assert quick_calls == 0 and full_calls > 150 * 5  # the full path logged every get
    assert np.array_equal(np.array(quick), np.array(full))
    assert np.isfinite(np.array(quick)).all() and len(quick) == 150
