"""Every variable read as the Reference-FMUs' ``fmusim`` reads it, on every FMU we build.

fmusim (0.0.39) reads, after ``ExitInitializationMode`` and after each step, every
variable of each type in one get call per type (all value references of that type, in
model-description order, ``nValues`` = their number), the independent variable ``time``
included where the model description declares it (FMI 3). Here the same reads run on raw
ctypes calls (every status returned, nothing raised), for the three FMUs of both flavors
and both FMI versions, in the closed loop of the ``sec53-literal`` scenario (Jacobi
coupling at 50 Hz; tail held at 60 deg: the observer stops with a Discard at 9.8 s, the
plant at 11.1 s, the loop goes on with the FMUs still running):

- after ExitInitializationMode, after each step and after each FMU's Discard, every read
  returns OK and logs no error;
- the value of ``time`` is the FMU's current time: the start time, then the end of each
  step, and after a Discard the last successful time (which fmi3DoStep reports);
- FMI 3 model descriptions declare exactly one independent variable, ``time``; FMI 2
  ones declare none (nothing to read there);
- the observer and the plant did stop with a Discard (so the reads after one ran); the
  controller has no stall of its own.
"""

from __future__ import annotations

import ctypes
from ctypes import c_bool, c_char_p, c_double, c_int

import pytest
from fmi3_fuzz import TYPES, Raw3
from raw_fmi import RawFMU

from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for

pytestmark = pytest.mark.integration

STEP = 0.02
STOP = 15.0
FMI2_TYPES = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}


class Host:
    """One FMU on raw calls, driven as fmusim drives it."""

    def __init__(self, fmu, fmi: int):
        self.fmi = fmi
        self.raw = Raw3(fmu) if fmi == 3 else RawFMU(fmu)
        md = self.raw.md
        self.vars = {v.name: v for v in md.modelVariables}
        self.independent = [v.name for v in md.modelVariables if v.causality == "independent"]
        # one get per type, value references in model-description order (FMIRecorder.c)
        self.by_type: dict[str, list[int]] = {}
        for v in md.modelVariables:
            self.by_type.setdefault(v.type, []).append(v.valueReference)
        self.c = self.raw.instantiate("x")
        assert self.c, f"{md.modelName}: instantiate failed: {self.raw.messages}"
        self.name_of = {v.valueReference: v.name for v in md.modelVariables}
        self.values: dict[str, object] = {}
        self.reads = 0

    def errors(self) -> list:
        if self.fmi == 3:
            return [m for st, m in self.raw.messages if st >= 3]
        return [m.text for m in self.raw.messages if m.status >= 3]

    def _set(self, name: str, value) -> int:
        v = self.vars[name]
        ctype = TYPES[v.type] if self.fmi == 3 else FMI2_TYPES[v.type]
        vr = (ctypes.c_uint * 1)(v.valueReference)
        arr = (ctype * 1)(value)
        if self.fmi == 3:
            return getattr(self.raw.dll, f"fmi3Set{v.type}")(self.c, vr, 1, arr, 1)
        return getattr(self.raw.dll, f"fmi2Set{v.type}")(self.c, vr, 1, arr)

    def initialize(self, params: dict[str, float]) -> None:
        raw, c = self.raw.dll, self.c
        if self.fmi == 3:
            st = [raw.fmi3EnterInitializationMode(c, False, 0.0, 0.0, False, 0.0)]
        else:
            st = [raw.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)]
        for name, value in params.items():
            kind = self.vars[name].type
            st.append(self._set(name, bool(value) if kind == "Boolean" and self.fmi == 3 else
                                int(value) if kind in ("Integer", "Int32", "Boolean") else
                                float(value)))  # fmt: skip
        if self.fmi == 2:
            st.append(raw.fmi2EnterInitializationMode(c))
        st.append(getattr(raw, f"fmi{self.fmi}ExitInitializationMode")(c))
        assert st == [0] * len(st), (st, self.errors())

    def read_all(self, time: float, when: str) -> None:
        """Every variable, one get per type; every status OK, ``time`` = ``time``."""
        for typ, vrs in self.by_type.items():
            ctype = TYPES[typ] if self.fmi == 3 else FMI2_TYPES[typ]
            refs = (ctypes.c_uint * len(vrs))(*vrs)
            out = (ctype * len(vrs))()
            if self.fmi == 3:
                st = getattr(self.raw.dll, f"fmi3Get{typ}")(self.c, refs, len(vrs), out, len(vrs))
            else:
                st = getattr(self.raw.dll, f"fmi2Get{typ}")(self.c, refs, len(vrs), out)
            assert st == 0, f"{self.raw.md.modelName} {when}: get {typ}: {st} {self.errors()}"
            for vr, value in zip(vrs, out):
                self.values[self.name_of[vr]] = value
            self.reads += 1
        assert not self.errors()
        for name in self.independent:
            assert self.values[name] == time, (when, name, self.values[name], time)

    def do_step(self, t: float, h: float) -> tuple[int, float]:
        """(status, last successful time)."""
        if self.fmi == 3:
            flags = [c_bool() for _ in range(3)]
            last = c_double()
            st = self.raw.dll.fmi3DoStep(self.c, t, h, True, *map(ctypes.byref, flags),
                                         ctypes.byref(last))  # fmt: skip
            return st, last.value
        st = self.raw.dll.fmi2DoStep(self.c, t, h, 1)
        last = c_double()
        if st == 2:
            assert self.raw.dll.fmi2GetRealStatus(self.c, 2, ctypes.byref(last)) == 0
        return st, last.value if st == 2 else t + h

    def free(self) -> None:
        getattr(self.raw.dll, f"fmi{self.fmi}FreeInstance")(self.c)


@pytest.fixture(scope="module")
def dirs(fmu_dir, native_dir, fmi3_dirs):
    """(FMI version, flavor) -> the folder of the three FMUs."""
    return {(2, "python"): fmu_dir, (2, "native"): native_dir,
            (3, "python"): fmi3_dirs["python"], (3, "native"): fmi3_dirs["native"]}  # fmt: skip


@pytest.mark.parametrize("flavor", ["python", "native"])
@pytest.mark.parametrize("fmi", [2, 3])
def test_every_variable_read_as_fmusim_reads_it(dirs, fmi, flavor):
    system = system_for(load_scenario("sec53-literal"), dirs[fmi, flavor])
    hosts = {inst: Host(fmu, fmi) for inst, fmu in system.fmus.items()}
    try:
        for h in hosts.values():
            assert h.independent == (["time"] if fmi == 3 else [])
        for inst, h in hosts.items():
            h.initialize(system.parameters.get(inst, {}))
            h.read_all(0.0, "after ExitInitializationMode")
        running, discards, t, steps = set(hosts), {}, 0.0, 0
        while running and t < STOP - 1e-9:
            for src, dst in system.connections:  # Jacobi: the outputs read after the last step
                (si, sn), (di, dn) = src.split("."), dst.split(".")
                if di in running:
                    assert hosts[di]._set(dn, hosts[si].values[sn]) == 0, hosts[di].errors()
            for inst in sorted(running):
                h = hosts[inst]
                st, last = h.do_step(t, STEP)
                if st == 2:  # Discard: the last successful time is the step's start
                    assert last == t
                    h.read_all(t, f"after the Discard at t = {t}")
                    discards[inst] = t
                    running.discard(inst)
                    continue
                assert st == 0, (inst, t, st, h.errors())
                h.read_all(t + STEP, f"after the step at t = {t}")
            t += STEP
            steps += 1
        reads = {inst: h.reads for inst, h in hosts.items()}
        print(f"FMI {fmi} {flavor}: {steps} steps, Discards {discards}, get calls {reads}")
        assert set(discards) == {"observer", "plant"}, discards
        assert discards["observer"] == pytest.approx(9.8, abs=0.03)
        assert discards["plant"] == pytest.approx(11.1, abs=0.03)
    finally:
        for h in hosts.values():
            h.free()
