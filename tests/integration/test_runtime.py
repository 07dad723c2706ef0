"""Our FMI layer (src/fmi/fmi2_layer.c) under raw FMI calls, on both back ends: statuses,
messages, the state machine, FMU state serialization, threads, references, and how the
Python back end is compiled."""

from __future__ import annotations

import ctypes
import gc
import math
import subprocess
import sys
import threading
from ctypes import c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

import numpy as np
import pytest
from raw_fmi import Loop, RawFMU
from system_tools import require_tool, tool_missing

from glider_fmi import compile as runtime

pytestmark = pytest.mark.integration
NAMES = {"plant": "GliderPlant", "observer": "GliderObserver", "controller": "GliderController"}
TERMINATED, LAST_SUCCESSFUL_TIME = 3, 2  # fmi2StatusKind


@pytest.fixture(scope="module")
def raw(flavor_dir, test_fmus) -> dict[str, RawFMU]:
    out = {inst: RawFMU(flavor_dir / f"{name}.fmu") for inst, name in NAMES.items()}
    out["probe"] = RawFMU(test_fmus["RuntimeTestProbe"])
    return out


def fresh(r: RawFMU, logging: bool = False):
    r.messages.clear()
    c = r.instantiate(logging=logging)
    assert c, r.messages
    return c


# ---------------------------------------------------------------- statuses and messages
def _init_with(r, c, **params):
    return r.initialize(c, **params)


def _set_int_then_init(r, c, **params):
    r.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
    r.set_integer(c, **params)
    r.EnterInitializationMode(c)
    return r.ExitInitializationMode(c)


def _step_with_input(r, c, **inputs):
    assert r.initialize(c) == 0
    r.set_real(c, **inputs)
    return r.DoStep(c, 0.0, 0.02, 1)


def _after_init(action):
    def run(r, c, **kw):
        assert r.initialize(c) == 0
        return action(r, c, **kw)

    return run


# (FMU, what is done, expected part of the one error message)
REFUSALS = {
    "parameter out of range": (
        "plant",
        lambda r, c: _init_with(r, c, m=-1.0),
        "fmi2ExitInitializationMode: m = -1.0 is invalid: expected a finite value in (0, inf)",
    ),
    "NaN parameter": (
        "plant",
        lambda r, c: _init_with(r, c, K_D=math.nan),
        "K_D = nan is invalid: expected a finite value",
    ),
    "Integer parameter out of range": (
        "plant",
        lambda r, c: _set_int_then_init(r, c, noise_seed=-1),
        "noise_seed = -1 is invalid: expected an integer in [0, 2147483647]",
    ),
    "inconsistent parameters": (
        "plant",
        lambda r, c: _init_with(r, c, delta_max=0.1, delta_0=0.2),
        "delta_0 = 0.2 is invalid: expected |delta_0| <= delta_max",
    ),
    "non-finite input": (
        "plant",
        lambda r, c: _step_with_input(r, c, F_x=math.inf),
        "fmi2DoStep: input F_x = inf at t = 0 s is invalid: expected a finite value",
    ),
    "fixed parameter after initialisation": (
        "controller",
        _after_init(lambda r, c: r.set_real(c, delta_max=0.3)),
        "fmi2SetReal: delta_max is a fixed parameter: it cannot be set after initialisation",
    ),
    "setting an output": (
        "controller",
        _after_init(lambda r, c: r.set_real(c, delta_cmd=0.3)),
        "fmi2SetReal: delta_cmd is an output: it cannot be set",
    ),
    "tunable parameter out of range": (
        "controller",
        _after_init(lambda r, c: r.set_real(c, K_c=-3.0)),
        "fmi2SetReal: K_c = -3.0 is invalid: expected a finite value in (0, inf)",
    ),
    "doStep before initialisation": (
        "plant",
        lambda r, c: r.DoStep(c, 0.0, 0.02, 1),
        "fmi2DoStep: not allowed in state 'instantiated'",
    ),
    "zero step": (
        "plant",
        _after_init(lambda r, c: r.DoStep(c, 0.0, 0.0, 1)),
        "fmi2DoStep: step of 0 s at t = 0 s is invalid: expected a finite step > 0",
    ),
    "step at the wrong time": (
        "plant",
        _after_init(lambda r, c: r.DoStep(c, 0.5, 0.02, 1)),
        "doStep at t = 0.5 s is invalid: expected the current time 0.0 s",
    ),
    "unknown value reference": (
        "plant",
        lambda r, c: r.GetReal(c, (c_uint * 1)(9999), 1, (c_double * 1)()),
        "fmi2GetReal: value reference 9999 does not exist: expected 0..",
    ),
    "wrong type": (
        "plant",
        lambda r, c: r.SetInteger(c, r.refs("m"), 1, (c_int * 1)(3)),
        "fmi2SetInteger: value reference 14 (m) is Real, not Integer",
    ),
    "NULL array": (
        "plant",
        lambda r, c: r.GetReal(c, None, 2, (c_double * 2)()),
        "fmi2GetReal: NULL vr array with nvr = 2",
    ),
    "Python exception in the slave": (
        "probe",
        _after_init(lambda r, c: r.set_integer(c, mode=1) or r.DoStep(c, 0.0, 0.1, 1)),
        "fmi2DoStep: ZeroDivisionError: division by zero",
    ),
    "slave refusing a value": (
        "probe",
        lambda r, c: _init_with(r, c, gain=-2.0),
        "fmi2ExitInitializationMode: ValueError: gain = -2.0 is invalid: expected > 0",
    ),
}


@pytest.mark.parametrize("logging", [False, True], ids=["logging off", "logging on"])
@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_refusals_are_fmi2error_with_their_message_logged(raw, case, logging):
    inst, action, expected = REFUSALS[case]
    r = raw[inst]
    c = fresh(r, logging)
    if case == "wrong type":
        expected = expected.replace("14", str(r.vr["m"]))
    status = action(r, c)
    errors = [m for m in r.messages if m.status >= 3]
    r.FreeInstance(c)
    assert status == 3  # fmi2Error: never fmi2Fatal
    assert len(errors) == 1, [m.text for m in errors]
    assert expected in errors[0].text
    assert errors[0].text.startswith("x: ")  # the instance named in the message itself
    assert errors[0].status == 3 and errors[0].category == "logStatusError"
    assert errors[0].instance == "x"
    debug = [m for m in r.messages if m.status == 0]
    # a traceback (debug message) with logging on, unless the slave refused a value itself
    plain = case in ("Python exception in the slave", "slave refusing a value")
    assert bool(debug) == (logging and plain)
    assert all("Traceback (most recent call last)" in m.text for m in debug)


def test_debug_messages_follow_logging_and_categories(raw):
    r = raw["probe"]

    def step_messages(c, **debug_logging):
        if debug_logging:
            cats = debug_logging["categories"]
            arr = (c_char_p * len(cats))(*(x.encode() for x in cats))
            assert r.SetDebugLogging(c, int(debug_logging["on"]), len(cats), arr) == 0
        r.messages.clear()
        assert r.DoStep(c, r_time[c], 0.1, 1) == 0
        r_time[c] += 0.1
        return [(m.status, m.category, m.text) for m in r.messages]

    r_time: dict[int, float] = {}
    quiet = fresh(r, logging=False)
    loud = fresh(r, logging=True)
    for c in (quiet, loud):
        assert r.initialize(c) == 0 and r.set_integer(c, mode=3) == 0
        r_time[c] = 0.0
    warning = (1, "logStatusWarning", "a warning")
    debug = (0, "logAll", "a debug message with 100% of its text")
    assert step_messages(quiet) == [warning]  # warnings pass, debug messages do not
    assert step_messages(loud) == [debug, warning]  # '%' arrives intact
    assert step_messages(loud, on=True, categories=["logStatusWarning"]) == [warning]
    calls = step_messages(loud, on=True, categories=["logFmiCalls"])
    assert calls == [(0, "logFmiCalls", "fmi2DoStep")]  # only the categories named
    assert step_messages(loud, on=False, categories=["logStatusWarning", "logFmiCalls"]) == []
    assert step_messages(loud, on=True, categories=["logAll"]) == [debug, warning]
    arr = (c_char_p * 1)(b"nope")
    assert r.SetDebugLogging(loud, 1, 1, arr) == 3
    assert "log category 'nope' is unknown: expected one of logStatusWarning," in r.errors()[-1]
    r.FreeInstance(quiet)
    r.FreeInstance(loud)


def test_discard_is_the_clean_stop(raw):
    r = raw["probe"]
    c = fresh(r)
    assert r.initialize(c) == 0
    assert r.DoStep(c, 0.0, 0.1, 1) == 0
    r.messages.clear()
    assert r.set_integer(c, mode=2) == 0
    assert r.DoStep(c, 0.1, 0.1, 1) == 2  # fmi2Discard
    assert [(m.status, m.text) for m in r.messages][0] == (2, "stopped at t = 0.1")
    term, last = c_int(), c_double()
    assert r.GetBooleanStatus(c, TERMINATED, ctypes.byref(term)) == 0 and term.value == 1
    assert r.GetRealStatus(c, LAST_SUCCESSFUL_TIME, ctypes.byref(last)) == 0
    assert last.value == pytest.approx(0.1)
    assert r.get_real(c, "y")[0] == 0  # getters still work
    assert r.Terminate(c) == 0
    assert r.DoStep(c, 0.1, 0.1, 1) == 3
    assert "fmi2DoStep: not allowed in state 'terminated'" in r.errors()[-1]
    r.FreeInstance(c)


def test_after_an_error_only_getters_state_reset_and_free(raw):
    r = raw["plant"]
    c = fresh(r)
    assert r.initialize(c, m=-1.0) == 3
    st, (m,) = r.get_real(c, "m")
    assert st == 0 and m == -1.0
    for call in (lambda: r.DoStep(c, 0.0, 0.02, 1), lambda: r.set_real(c, m=10.0),
                 lambda: r.Terminate(c), lambda: r.EnterInitializationMode(c)):  # fmt: skip
        assert call() == 3
        assert r.errors()[-1].endswith(
            "not allowed after an error: only getters, FMU-state functions, fmi2Reset and "
            "fmi2FreeInstance are allowed then"
        )
    assert r.Reset(c) == 0
    assert r.get_real(c, "m") == (0, [10.0])  # start values back
    assert r.initialize(c) == 0 and r.DoStep(c, 0.0, 0.02, 1) == 0
    r.FreeInstance(c)


@pytest.mark.parametrize(
    "state", ["instantiated", "initialization", "stepping", "discarded", "terminated", "error"]
)
def test_free_works_in_every_state_and_a_freed_instance_is_refused(raw, state):
    r = raw["probe"]
    c = fresh(r)
    if state != "instantiated":
        r.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
        r.EnterInitializationMode(c)
    if state in ("stepping", "discarded", "terminated"):
        r.ExitInitializationMode(c)
        r.DoStep(c, 0.0, 0.1, 1)
    if state == "discarded":
        r.set_integer(c, mode=2)
        assert r.DoStep(c, 0.1, 0.1, 1) == 2
    if state == "terminated":
        assert r.Terminate(c) == 0
    if state == "error":
        assert r.DoStep(c, 0.0, 0.1, 1) == 3
    r.FreeInstance(c)
    # the pointer is no instance any more: statuses, never a crash
    assert r.DoStep(c, 0.0, 0.1, 1) == 3
    assert r.get_real(c, "y")[0] == 3
    r.FreeInstance(c)  # a double free is ignored


def test_invalid_arguments_are_statuses(raw):
    r = raw["plant"]
    c = fresh(r)
    assert r.GetReal(c, None, 0, None) == 0  # nvr = 0: nothing to do
    assert r.DoStep(None, 0.0, 0.02, 1) == 3
    assert r.GetReal(c_void_p(12345), r.refs("V"), 1, (c_double * 1)()) == 3
    assert r.initialize(c) == 0
    assert r.DoStep(c, 0.0, 0.02, 1) == 0
    assert r.Terminate(c) == 0
    assert r.Terminate(c) == 3  # twice
    assert r.Reset(c) == 0 and r.initialize(c) == 0
    assert r.GetFMUstate(c, None) == 3
    assert r.SetFMUstate(c, c_void_p(4242)) == 3
    r.Reset(c)
    bad = b"not a state" * 40
    state = c_void_p()
    assert r.DeSerializeFMUstate(c, bad, len(bad), ctypes.byref(state)) == 3
    assert "not a serialized state of this runtime" in r.errors()[-1]
    r.Reset(c)
    assert r.CancelStep(c) == 3 and "not supported by this FMU" in r.errors()[-1]
    r.Reset(c)
    assert r.Instantiate(b"y", 0, b"", b"file:///nonexistent", None, 0, 0) is None  # ME
    assert r.instantiate("y", resources="http://example.org/x") is None
    assert "fmuResourceLocation 'http://example.org/x' is invalid" in r.errors()[-1]
    if r.native:  # a native FMU needs no resources
        other = r.instantiate("y", resources="file:///nonexistent/resources")
        assert other is not None
        r.FreeInstance(other)
    else:
        assert r.instantiate("y", resources="file:///nonexistent/resources") is None
        assert "/nonexistent/resources/slavemodule.txt is missing" in r.errors()[-1]
    r.FreeInstance(c)


def test_slave_module_is_imported_once_and_references_balance(raw):
    r = raw["probe"]
    cycle_refs = []
    for k in range(30):
        c = fresh(r)
        assert r.initialize(c) == 0
        assert r.get_real(c, "y")[0] == 0
        executions = (c_int * 1)()
        assert r.GetInteger(c, r.refs("executions"), 1, executions) == 0
        assert executions[0] == 1  # the script ran once in this process
        assert r.DoStep(c, 0.0, 0.1, 1) == 0 and r.Reset(c) == 0
        r.FreeInstance(c)
        gc.collect()  # pythonfmu's slaves are reference cycles (variables' getters)
        # the FMU's own module, in its bundle's package (not the build's import of the script)
        suffix = ".RuntimeTestProbe"
        (module,) = [m for n, m in sys.modules.items()
                     if n.startswith("_glider_fmu_") and n.endswith(suffix)]  # fmt: skip
        if k >= 10:  # after warm-up: caches of pythonfmu and ctypes are filled
            cycle_refs.append((sys.getrefcount(module.RuntimeTestProbe),
                               sys.getrefcount(vars(module))))  # fmt: skip
    assert len(set(cycle_refs)) == 1, cycle_refs


# ---------------------------------------------------------------- state and threads
LOOP_PARAMS = {
    "noise": {"plant": {"noise_std": 0.02, "noise_seed": 7}, "controller": {"K_c": 10.0}},
    "pi": {"plant": {"noise_std": 0.01}, "controller": {"law": 3, "K_P": 0.5, "K_I": 0.2}},
}


@pytest.mark.parametrize("case", sorted(LOOP_PARAMS))
def test_serialized_state_continues_bit_for_bit_in_a_new_instance(raw, case):
    loop_raws = {k: raw[k] for k in NAMES}
    for r in loop_raws.values():
        assert r.md.coSimulation.canSerializeFMUstate
    whole = Loop(loop_raws, "whole")
    whole.instantiate()
    whole.initialize(LOOP_PARAMS[case])
    expected = whole.step(200)
    whole.free()

    first = Loop(loop_raws, "first")
    first.instantiate()
    first.initialize(LOOP_PARAMS[case])
    got = first.step(100)
    blobs = {}
    for inst, r in loop_raws.items():
        c, state, size = first.c[inst], c_void_p(), c_size_t()
        assert r.GetFMUstate(c, ctypes.byref(state)) == 0
        assert r.SerializedFMUstateSize(c, state, ctypes.byref(size)) == 0
        buf = ctypes.create_string_buffer(size.value)
        assert r.SerializeFMUstate(c, state, buf, size.value) == 0
        blobs[inst] = buf.raw
        assert r.FreeFMUstate(c, ctypes.byref(state)) == 0 and state.value is None
    first.free()

    second = Loop(loop_raws, "second")
    second.instantiate()  # a new instance: only instantiated, then the state
    for inst, r in loop_raws.items():
        c, state = second.c[inst], c_void_p()
        blob = blobs[inst]
        assert r.DeSerializeFMUstate(c, blob, len(blob), ctypes.byref(state)) == 0, r.errors()
        assert r.SetFMUstate(c, state) == 0, r.errors()
        assert r.FreeFMUstate(c, ctypes.byref(state)) == 0
    second.k = first.k
    got += second.step(100)
    second.free()
    assert np.array_equal(np.array(got), np.array(expected))  # bit for bit
    assert np.ptp(np.array(expected)[:, 0]) > 0  # it moved


def test_a_state_of_another_model_is_refused(raw):
    plant, obs = raw["plant"], raw["observer"]
    c, d = fresh(plant), fresh(obs)
    assert plant.initialize(c) == 0
    state, size = c_void_p(), c_size_t()
    assert plant.GetFMUstate(c, ctypes.byref(state)) == 0
    assert plant.SerializedFMUstateSize(c, state, ctypes.byref(size)) == 0
    buf = ctypes.create_string_buffer(size.value)
    assert plant.SerializeFMUstate(c, state, buf, size.value) == 0
    other = c_void_p()
    assert obs.DeSerializeFMUstate(d, buf.raw, size.value, ctypes.byref(other)) == 3
    assert "the state is one of model GliderPlant: expected GliderObserver" in obs.errors()[-1]
    plant.FreeInstance(c)
    obs.FreeInstance(d)


def test_two_loops_stepped_in_two_threads_equal_sequential_runs(raw):
    loop_raws = {k: raw[k] for k in NAMES}
    params = [
        {"controller": {"K_c": 8.0}, "plant": {"noise_std": 0.01, "noise_seed": 1}},
        {"controller": {"K_c": 12.0}, "plant": {"noise_std": 0.02, "noise_seed": 2}},
    ]
    steps = 1500

    def run(i: int, out: dict) -> None:
        loop = Loop(loop_raws, f"t{i}")
        loop.instantiate()
        loop.initialize(params[i])
        out[i] = loop.step(steps)
        loop.free()

    sequential: dict[int, list] = {}
    for i in (0, 1):
        run(i, sequential)
    concurrent: dict[int, list] = {}
    threads = [threading.Thread(target=run, args=(i, concurrent)) for i in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in (0, 1):
        assert np.array_equal(np.array(concurrent[i]), np.array(sequential[i]))
    assert not np.array_equal(np.array(sequential[0]), np.array(sequential[1]))


# ---------------------------------------------------------------- compiling the runtime
def test_runtime_compiles_warning_free_and_links_no_python(tmp_path):
    out = tmp_path / "runtime.so"
    printed = runtime.compile_runtime(out)
    assert printed == ""  # -Wall -Wextra: no warning
    assert {"-Wall", "-Wextra"} <= set(runtime.CFLAGS)
    require_tool("nm", install="apt-get install binutils")
    nm = subprocess.run(["nm", "-D", "--undefined-only", str(out)], capture_output=True,
                        text=True, check=True).stdout  # fmt: skip
    assert "Py" not in nm  # every Python function is resolved at run time
    exported = subprocess.run(["nm", "-D", "--defined-only", str(out)], capture_output=True,
                              text=True, check=True).stdout  # fmt: skip
    names = {line.split()[-1] for line in exported.splitlines()}
    assert {"fmi2Instantiate", "fmi2DoStep", "fmi2SerializeFMUstate"} <= names
    assert all(n.startswith("fmi2") for n in names if not n.startswith("_"))


def test_our_python_declarations_are_pythons(tmp_path):
    """glider_python.h after Python.h (limited API 3.11): any prototype that differs from
    Python's is a "conflicting types" error. And the check can fail: one changed return
    type is refused."""
    import sysconfig

    include = Path(sysconfig.get_paths()["include"])
    require_tool("gcc")
    if not (include / "Python.h").is_file():
        tool_missing(f"this Python's headers are not installed ({include / 'Python.h'})")
    here = Path(runtime.__file__).parent
    src = tmp_path / "check.c"
    src.write_text('#define Py_LIMITED_API 0x030B0000\n#include <Python.h>\n'
                   '#include "glider_python.h"\n')  # fmt: skip

    def compile_with(folder: Path) -> subprocess.CompletedProcess:
        return subprocess.run(["gcc", "-std=gnu11", "-Wall", "-Wextra", "-Werror", f"-I{include}",
                               f"-I{folder}", "-c", str(src), "-o", str(tmp_path / "c.o")],
                              capture_output=True, text=True)  # fmt: skip

    assert compile_with(here).returncode == 0, compile_with(here).stderr
    bad = tmp_path / "bad"
    bad.mkdir()
    text = (here / "glider_python.h").read_text()
    assert "long PyLong_AsLong(PyObject *);" in text
    (bad / "glider_python.h").write_text(text.replace("long PyLong_AsLong", "int PyLong_AsLong"))
    p = compile_with(bad)
    assert p.returncode != 0 and "conflicting types" in p.stderr


def test_the_runtime_needs_no_python_headers():
    """No Python.h anywhere in the runtime's sources, and no Python include folder on its
    command line."""
    for f in (*runtime.runtime_sources(), *runtime.runtime_sources(True), *runtime.RUNTIME_HEADERS):
        assert "Python.h" not in "".join(
            line for line in f.read_text().splitlines() if line.startswith("#include")
        ), f.name
    import re
    import sysconfig

    here = Path(runtime.__file__).parent
    backend = (here / "backend_python.c").read_text()
    table = backend[backend.index("#define PY_FUNCTIONS") : backend.index("#define DECLARE")]
    used = set(re.findall(r"X\((\w+)\)", table))
    header = (here / "glider_python.h").read_text()
    declared = set(re.findall(r"\b(Py\w+)\(", header))
    assert len(used) == 48 and declared == used  # exactly what the back end resolves
    cmd = runtime.compile_command(Path("x.so"))
    assert sysconfig.get_paths()["include"] not in cmd
    assert "x86_64-linux-gnu.2.17" in cmd  # zig, for glibc 2.17


# ---------------------------------------------------------------- a plain fmpy user
FMPY_CASES = {  # start value(s) -> (call that fails, expected message)
    "parameter out of range": ({"m": -1.0}, "fmi2ExitInitializationMode",
                               "m = -1.0 is invalid: expected a finite value in (0, inf)"),
    "NaN parameter": ({"K_L": math.nan}, "fmi2ExitInitializationMode",
                      "K_L = nan is invalid: expected a finite value"),
    "Integer parameter out of range": ({"noise_seed": -5}, "fmi2ExitInitializationMode",
                                       "noise_seed = -5 is invalid"),
    "inconsistent parameters": ({"delta_max": 0.1, "delta_0": 0.2}, "fmi2ExitInitializationMode",
                                "delta_0 = 0.2 is invalid: expected |delta_0| <= delta_max"),
    "non-finite input": ({"F_z": math.inf}, "fmi2DoStep",
                         "input F_z = inf at t = 0 s is invalid: expected a finite value"),
}  # fmt: skip


@pytest.mark.parametrize("logging", [False, True], ids=["debug_logging off", "on"])
@pytest.mark.parametrize("case", sorted(FMPY_CASES))
def test_fmpy_simulate_fmu_reports_the_refusal(fmu_dir, case, logging, tmp_path, capsys):
    """What a user of ``fmpy.simulate_fmu`` sees (its default: debug_logging=False), with
    fmpy's own logger. (A ``logger=`` passed to simulate_fmu would stay installed in
    fmpy's process-global logging proxy after the call and crash the next FMU message.)"""
    from fmpy import extract, simulate_fmu
    from fmpy.fmi1 import FMICallException

    # simulate_fmu would leave its own extraction behind when the FMU fails
    unzipped = extract(str(fmu_dir / "GliderPlant.fmu"), str(tmp_path / "plant"))

    start, call, expected = FMPY_CASES[case]
    with pytest.raises(FMICallException, match=rf"{call} failed with status 3 \(error\)"):
        simulate_fmu(unzipped, start_values=start, stop_time=1.0,
                     output_interval=0.02, debug_logging=logging)  # fmt: skip
    printed = capsys.readouterr().out.splitlines()
    errors = [line.removeprefix("[ERROR] ") for line in printed if line.startswith("[ERROR] ")]
    assert len(errors) == 1 and f": {call}: {expected}" in errors[0], errors


CURRENT_AFTER_RUN = """
import sys
from pathlib import Path
import fmpy
from glider_cosim.fmus.python import COMPONENTS, is_current
fmus = Path(sys.argv[1])
# an FMU run first in this process (before anything of ours imports the slave tables)
r = fmpy.simulate_fmu(str(fmus / "GliderPlant.fmu"), stop_time=0.2, output_interval=0.02)
import pythonfmu
print("pythonfmu from", pythonfmu.__file__)
ok = "ok" if len(r) == 11 else "short"
print("current", all(is_current(fmus / f"{c.name}.fmu", c) for c in COMPONENTS), ok)
"""


def test_fmus_stay_current_in_a_process_that_ran_them(fmu_dir):
    """An FMU run first does not replace the host's own modules: ``import pythonfmu``
    afterwards is the host's installed one, not the FMU's bundled copy (until 0.4 the
    FMU's resources/ went on sys.path and it was the FMU's, which once made every later
    build check rebuild the FMUs), and the build hash stays current."""
    p = subprocess.run([sys.executable, "-c", CURRENT_AFTER_RUN, str(fmu_dir)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    import pythonfmu

    assert f"pythonfmu from {pythonfmu.__file__}\n" in p.stdout
    assert "/resources/" not in p.stdout
    assert "current True ok" in p.stdout
