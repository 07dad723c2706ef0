"""The C99 twins of the models (``src/*/*_model.c``) are bit-identical to the Python models.

The three C files are compiled with the system compiler as one shared library (the native
FMUs' flags) and called through ctypes; every comparison is ``==`` on floats (or on the
message bytes), never approximate. Bit-identity holds on linux64, where CPython's ``math``
calls the same glibc libm as the C code.
"""

from __future__ import annotations

import csv
import ctypes
import math
import random
import struct
import subprocess
from pathlib import Path

import pytest
from system_tools import require_tool

from glider_controller.laws import PIController, passivity_law, passivity_output
from glider_observer.filter import ButterworthFilter, butterworth_coefficients
from glider_observer.model import linearization, observer_gain, observer_step, riccati_solution
from glider_plant.jacobian import plant_derivatives, plant_jacobian, rhs_jacobian
from glider_plant.model import (
    PitchSensor,
    StallError,
    check_state,
    constants,
    equilibrium,
    plant_step,
    rhs,
    saturate,
)
from glider_plant.params import GliderParams, ParameterError

SRC = Path(__file__).resolve().parents[1] / "src"
C_FILES = [
    SRC / "plant" / "plant_model.c",
    SRC / "observer" / "observer_model.c",
    SRC / "controller" / "controller_model.c",
]
CFLAGS = [
    "-std=c99",
    "-O2",
    "-ffp-contract=off",
    "-Wall",
    "-Wextra",
    "-pedantic",
    "-Werror=implicit-function-declaration",
]
PARAM_NAMES = ("m", "J2", "K_L0", "K_L", "K_D0", "K_D", "K_q", "K_M0", "K_M", "K_Fdelta",
               "K_udelta", "m0", "g")  # fmt: skip
R_GRID = (1e-4, 1e-3, 0.01, 0.1, 1.0, 10.0)
Q_GRID = [(q,) * 4 for q in (1e-4, 0.01, 0.1, 1.0, 10.0)] + [
    (1e-4, 10.0, 0.1, 1.0),
    (10.0, 1e-4, 1.0, 0.01),
    (0.01, 0.1, 10.0, 1e-4),
    (1e-4, 1e-4, 10.0, 10.0),
]
PERTURBED = (
    GliderParams(),
    GliderParams(m=12.0, J2=0.1),
    GliderParams(K_M0=0.2, K_D=200.0),
    GliderParams(K_q=-0.3, m0=0.2, K_L=250.0),
)

D = ctypes.c_double
D4 = D * 4
D6 = D * 6
D3 = D * 3
D5 = D * 5
D44 = D4 * 4


class CParams(ctypes.Structure):
    _fields_ = [(n, D) for n in PARAM_NAMES]


class CEq(ctypes.Structure):
    _fields_ = [(n, D) for n in ("V", "theta_g", "alpha", "omega2", "K_De", "K_Le")]


class CRandom(ctypes.Structure):
    _fields_ = [
        ("mt", ctypes.c_uint32 * 624),
        ("index", ctypes.c_int),
        ("has_gauss_next", ctypes.c_int),
        ("gauss_next", D),
    ]


class CSensor(ctypes.Structure):
    _fields_ = [("noise_std", D), ("rng", CRandom)]


class CButterworth(ctypes.Structure):
    _fields_ = [("c", D5), ("hist", D4), ("primed", ctypes.c_int)]


class CPI(ctypes.Structure):
    _fields_ = [("K_P", D), ("K_I", D), ("delta_max", D), ("integral", D)]


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """(library, compiler stderr)."""
    cc = require_tool("cc", "gcc", "clang", install="apt-get install gcc")
    out = tmp_path_factory.mktemp("cmodels") / "libglider_models.so"
    inc = [f"-I{SRC / d}" for d in ("plant", "observer", "controller", "fmi")]
    cmd = [cc, *CFLAGS, "-fPIC", "-shared", *inc, *map(str, C_FILES), "-o", str(out), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lib = ctypes.CDLL(str(out))
    sigs = {
        "glider_params_check": (ctypes.c_int, [ctypes.POINTER(CParams), ctypes.c_char_p,
                                               ctypes.c_size_t]),
        "glider_equilibrium": (None, [ctypes.POINTER(CParams), ctypes.POINTER(CEq)]),
        "glider_rhs": (None, [D, D, D, D, D, ctypes.POINTER(CParams), D, D, D, D4]),
        "glider_saturate": (D, [D, D]),
        "glider_rhs_jacobian": (None, [D, D, D, D, D, ctypes.POINTER(CParams), D, D, D, D * 32]),
        "glider_plant_jacobian": (None, [D6, D, D, D3, ctypes.POINTER(CParams), D, D, D * 88]),
        "glider_plant_derivatives": (None, [D6, D, D, D3, ctypes.POINTER(CParams), D, D,
                                            D * 7]),
        "glider_check_state": (ctypes.c_int, [ctypes.POINTER(D), ctypes.c_int, ctypes.c_char_p,
                                              ctypes.c_size_t]),
        "glider_plant_step": (ctypes.c_int, [D6, ctypes.POINTER(D), D, D,
                                             ctypes.POINTER(CParams), D, D3, D, ctypes.c_char_p,
                                             ctypes.c_size_t]),
        "py_hypot": (D, [D, D]),
        "py_float_repr": (None, [D, ctypes.c_char_p, ctypes.c_size_t]),
        "py_float_g": (None, [D, ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t]),
        "pyrandom_seed": (None, [ctypes.POINTER(CRandom), ctypes.c_uint32]),
        "pyrandom_random": (D, [ctypes.POINTER(CRandom)]),
        "pyrandom_gauss": (D, [ctypes.POINTER(CRandom), D, D]),
        "pitch_sensor_init": (ctypes.c_int, [ctypes.POINTER(CSensor), D, ctypes.c_uint32,
                                             ctypes.c_char_p, ctypes.c_size_t]),
        "pitch_sensor_measure": (D, [ctypes.POINTER(CSensor), D]),
        "butterworth_coefficients": (ctypes.c_int, [D, D, D5, ctypes.c_char_p,
                                                    ctypes.c_size_t]),
        "butterworth_init": (ctypes.c_int, [ctypes.POINTER(CButterworth), D, D, ctypes.c_char_p,
                                            ctypes.c_size_t]),
        "butterworth_filter": (D, [ctypes.POINTER(CButterworth), D]),
        "observer_linearization": (None, [ctypes.POINTER(CParams), ctypes.POINTER(CEq), D44]),
        "observer_riccati_solution": (ctypes.c_int, [ctypes.POINTER(CParams), D, D4, D44,
                                                     ctypes.c_char_p, ctypes.c_size_t]),
        "riccati_solve_filter_care": (ctypes.c_int, [D * 16, D * 16, D * 16, D * 16,
                                                     ctypes.c_char_p, ctypes.c_size_t]),
        "observer_gain": (ctypes.c_int, [ctypes.POINTER(CParams), D, D4, D4, ctypes.c_char_p,
                                         ctypes.c_size_t]),
        "observer_step": (ctypes.c_int, [D4, D, D, D, ctypes.POINTER(CParams), D4, D,
                                         ctypes.c_char_p, ctypes.c_size_t]),
        "passivity_output": (D, [D, D, ctypes.POINTER(CParams), ctypes.POINTER(CEq)]),
        "passivity_law": (D, [D, D, D, ctypes.POINTER(CParams), ctypes.POINTER(CEq), D]),
        "pi_init": (None, [ctypes.POINTER(CPI), D, D, D]),
        "pi_output": (D, [ctypes.POINTER(CPI), D]),
        "pi_update": (None, [ctypes.POINTER(CPI), D, D]),
    }  # fmt: skip
    for name, (res, args) in sigs.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args
    return lib, proc.stderr


@pytest.fixture(scope="module")
def lib(build):
    return build[0]


def cparams(p: GliderParams) -> CParams:
    return CParams(*(getattr(p, n) for n in PARAM_NAMES))


def ceq(lib, p: GliderParams) -> CEq:
    e = CEq()
    lib.glider_equilibrium(ctypes.byref(cparams(p)), ctypes.byref(e))
    return e


def buf():
    return ctypes.create_string_buffer(1024)


def bits(x: float) -> int:
    return struct.unpack("<q", struct.pack("<d", x))[0]


def same(a, b) -> bool:
    """Bit-identical float sequences (NaNs equal to NaNs)."""
    a, b = list(a), list(b)
    return len(a) == len(b) and all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in
                                    zip(a, b))  # fmt: skip


def test_compiles_without_warnings(build):
    assert build[1] == ""


# ---- formatting helpers -------------------------------------------------------------------


def _format_samples() -> list[float]:
    rng = random.Random(2024)
    xs = [0.0, -0.0, 1.0, -1.0, 0.1, 100.0, 1e-05, 1e-4, 1e16, 1e15, 9999999999999998.0,
          123456789012345678.0, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
          0.30000000000000004, 1 / 3, math.pi, 0.001, 1e22, 1e23, -2.5e-7]  # fmt: skip
    xs += [2.0**k for k in range(-1074, 1024, 7)]
    for _ in range(2500):
        x = struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0]
        if math.isfinite(x):
            xs.append(x)
    xs += [rng.uniform(-1e3, 1e3) for _ in range(1000)]
    xs += [rng.uniform(0, 1) * 10.0 ** rng.randint(-8, 20) for _ in range(1000)]
    xs += [float(rng.randint(-(10**6), 10**6)) for _ in range(200)]
    return xs


def test_py_float_repr_matches_repr(lib):
    b = buf()
    bad = []
    for x in _format_samples() + [math.inf, -math.inf, math.nan, -math.nan]:
        lib.py_float_repr(x, b, len(b))
        if b.value.decode() != repr(x):
            bad.append((repr(x), b.value.decode()))
    assert bad == []


def test_py_float_g_matches_format(lib):
    b = buf()
    bad = []
    for x in _format_samples()[::3] + [math.inf, -math.inf, math.nan, -math.nan]:
        for prec, spec in ((6, "g"), (6, ".6g"), (3, ".3g")):
            lib.py_float_g(x, prec, b, len(b))
            if b.value.decode() != format(x, spec):
                bad.append((x, spec, b.value.decode()))
    assert bad == []


def test_hypot_matches_math_hypot(lib):
    rng = random.Random(5)
    pairs = [(rng.uniform(0, 10), rng.uniform(0, 400)) for _ in range(2000)]

    def wide() -> float:
        return rng.uniform(-1, 1) * 10.0 ** rng.randint(-300, 300)

    pairs += [(wide(), wide()) for _ in range(2000)]
    pairs += [(0.0, 0.0), (3.0, 4.0), (math.inf, 1.0), (math.nan, 1.0), (5e-324, 5e-324)]
    assert same([lib.py_hypot(x, y) for x, y in pairs], [math.hypot(x, y) for x, y in pairs])


# ---- plant --------------------------------------------------------------------------------


def test_params_check_and_equilibrium(lib):
    b = buf()
    for p in PERTURBED:
        assert lib.glider_params_check(ctypes.byref(cparams(p)), b, len(b)) == 0
        e, pe = ceq(lib, p), equilibrium(p)
        assert same([e.V, e.theta_g, e.alpha, e.omega2, e.K_De, e.K_Le],
                    [pe.V, pe.theta_g, pe.alpha, pe.omega2, pe.K_De, pe.K_Le])  # fmt: skip
    for K_L0 in (-10.0, -303.6 * 0.39 / 14.7):
        with pytest.raises(ParameterError) as err:
            GliderParams(K_L0=K_L0)
        bad = CParams(*(K_L0 if n == "K_L0" else getattr(GliderParams(), n) for n in PARAM_NAMES))
        assert lib.glider_params_check(ctypes.byref(bad), b, len(b)) == 1
        assert b.value.decode() == str(err.value)


def test_rhs_bit_identical(lib):
    rng = random.Random(11)
    out = D4()
    for k in range(2000):
        p = PERTURBED[k % len(PERTURBED)]
        cp = cparams(p)
        args = (rng.uniform(0.01, 1.0), rng.uniform(-1.5, 1.5), rng.uniform(-0.5, 0.5),
                rng.uniform(-2, 2), rng.uniform(-0.5, 0.5))  # fmt: skip
        dist = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-0.1, 0.1)) if k % 2 else (
            0.0, 0.0, 0.0)  # fmt: skip
        lib.glider_rhs(*args, ctypes.byref(cp), *dist, out)
        assert same(out, rhs(*args, constants(p), *dist)), (k, args, dist)


def test_jacobian_and_derivatives_bit_identical(lib):
    """glider_rhs_jacobian, glider_plant_jacobian and glider_plant_derivatives equal the
    Python model's rhs_jacobian, plant_jacobian and plant_derivatives bit for bit (the
    command on both sides of the tail limit)."""
    rng = random.Random(12)
    body, jac, der = (D * 32)(), (D * 88)(), (D * 7)()
    for k in range(2000):
        p = PERTURBED[k % len(PERTURBED)]
        cp = cparams(p)
        x = (rng.uniform(0.01, 1.0), rng.uniform(-1.5, 1.5), rng.uniform(-0.5, 0.5),
             rng.uniform(-2, 2), rng.uniform(-9, 9), rng.uniform(-9, 9))  # fmt: skip
        delta, cmd, tau, dmax = rng.uniform(-1, 1), rng.uniform(-2, 2), 0.01, rng.uniform(0, 2)
        dist = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-0.1, 0.1)) if k % 2 else (
            0.0, 0.0, 0.0)  # fmt: skip
        u = p.K_udelta * delta
        lib.glider_rhs_jacobian(*x[:4], u, ctypes.byref(cp), *dist, body)
        want = rhs_jacobian(*x[:4], u, constants(p), *dist)
        assert same(body, [v for r in want for v in r]), k
        lib.glider_plant_jacobian(D6(*x), delta, cmd, D3(*dist), ctypes.byref(cp), tau, dmax, jac)
        want = plant_jacobian(x, delta, cmd, dist, p, tau, dmax)
        assert same(jac, [v for r in want for v in r]), k
        lib.glider_plant_derivatives(D6(*x), delta, cmd, D3(*dist), ctypes.byref(cp), tau, dmax,
                                     der)  # fmt: skip
        assert same(der, plant_derivatives(x, delta, cmd, dist, p, tau, dmax)), k


def _c_plant_step(lib, cp, x, delta, cmd, h, tau, dist, h_max):
    cx, cd, b = D6(*x), D(delta), buf()
    rc = lib.glider_plant_step(cx, ctypes.byref(cd), cmd, h, ctypes.byref(cp), tau, D3(*dist),
                               h_max, b, len(b))  # fmt: skip
    return rc, tuple(cx), cd.value, b.value.decode()


def test_plant_reference_sequence_with_sensor(lib):
    """The slave's loop on src/plant/reference_input.csv (noise_std 0.01, seed 7)."""
    p = GliderParams()
    cp = cparams(p)
    with open(SRC / "plant" / "reference_input.csv") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    delta_max, tau, h_max = math.pi / 2, 0.01, 0.02
    x = (0.2, math.radians(-35.0), math.radians(1.0), 0.0, 0.0, 0.0)
    cx, delta, cdelta = x, 0.0, 0.0
    sensor = PitchSensor(0.01, 7)
    cs, b = CSensor(), buf()
    assert lib.pitch_sensor_init(ctypes.byref(cs), 0.01, 7, b, len(b)) == 0
    assert lib.pitch_sensor_measure(ctypes.byref(cs), x[1] + x[2]) == sensor.measure(x[1] + x[2])
    for r0, r1 in zip(rows, rows[1:]):
        h = 0.02
        cmd = saturate(r0["delta_cmd"], delta_max)
        assert lib.glider_saturate(r0["delta_cmd"], delta_max) == cmd
        dist = (r0["F_x"], r0["F_z"], r0["M_y"])
        x, delta = plant_step(x, delta, cmd, h, p, tau, dist, h_max)
        rc, cx, cdelta, _ = _c_plant_step(lib, cp, cx, cdelta, cmd, h, tau, dist, h_max)
        assert rc == 0 and cx == x and cdelta == delta, r1["time"]
        th = x[1] + x[2]
        assert lib.pitch_sensor_measure(ctypes.byref(cs), th) == sensor.measure(th)
    assert lib.pitch_sensor_init(ctypes.byref(cs), -1.0, 0, b, len(b)) == 1
    with pytest.raises(ParameterError) as err:
        PitchSensor(-1.0, 0)
    assert b.value.decode() == str(err.value)


def test_plant_random_commands_jumps_and_disturbances(lib):
    rng = random.Random(3)
    for p in PERTURBED[:3]:
        cp = cparams(p)
        x = cx = (0.25, -0.6, 0.02, 0.0, 0.0, 0.0)
        delta = cdelta = 0.0
        for k in range(120):
            # occasional large jumps force the servo sub-stepping branch
            cmd = rng.choice([0.0, rng.uniform(-0.05, 0.05), rng.uniform(-1.2, 1.2)])
            h = rng.choice([0.02, 0.05, 0.013, 0.1])
            tau = rng.choice([0.01, 0.03])
            dist = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.02, 0.02))
            h_max = rng.choice([0.02, 0.005])
            x, delta = plant_step(x, delta, cmd, h, p, tau, dist, h_max)
            rc, cx, cdelta, _ = _c_plant_step(lib, cp, cx, cdelta, cmd, h, tau, dist, h_max)
            assert rc == 0 and cx == x and cdelta == delta, k


def test_plant_stall_message(lib):
    p = GliderParams()
    cp = cparams(p)
    # slow horizontal glide braked by a force against the velocity: V falls through V_STALL
    x = (0.004, 0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(StallError) as err:
        plant_step(x, 0.0, 0.3, 0.5, p, 0.01, (-5.0, 0.0, 0.0), 0.02)
    rc, cx, _, msg = _c_plant_step(lib, cp, x, 0.0, 0.3, 0.5, 0.01, (-5.0, 0.0, 0.0), 0.02)
    assert rc == 1 and msg == str(err.value) and cx == x
    b = buf()
    for state in ((0.0, 0.0, 0.0, 0.0), (0.2, math.nan, 0.0, 0.0), (-math.inf, 0, 0, 0),
                  (math.nan, 0, 0, 0), (1e-3, 0, 0, 0)):  # fmt: skip
        with pytest.raises(StallError) as err:
            check_state(state)
        assert lib.glider_check_state((D * 4)(*state), 4, b, len(b)) == 1
        assert b.value.decode() == str(err.value)
    assert lib.glider_check_state((D * 4)(0.2, 0, 0, 0), 4, b, len(b)) == 0


@pytest.mark.parametrize("seed", [0, 1, 3, 12345, 2**31 - 1])
def test_pyrandom_gauss_matches_cpython(lib, seed):
    r = CRandom()
    lib.pyrandom_seed(ctypes.byref(r), seed)
    py = random.Random(seed)
    s = 0.01 if seed % 2 else 1.0
    assert [lib.pyrandom_gauss(ctypes.byref(r), 0.0, s) for _ in range(3000)] == [
        py.gauss(0, s) for _ in range(3000)
    ]
    assert [lib.pyrandom_random(ctypes.byref(r)) for _ in range(50)] == [
        py.random() for _ in range(50)
    ]


# ---- observer -----------------------------------------------------------------------------


def test_butterworth_coefficients_filter_and_messages(lib):
    c, b = D5(), buf()
    for fs, fc in ((50.0, 10.0), (100.0, 3.0), (1000.0, 499.0), (20.0, 0.1), (50.0, 24.99)):
        assert lib.butterworth_coefficients(fs, fc, c, b, len(b)) == 0
        assert same(c, butterworth_coefficients(fs, fc))
        f, cf = ButterworthFilter(fs, fc), CButterworth()
        assert lib.butterworth_init(ctypes.byref(cf), fs, fc, b, len(b)) == 0
        rng = random.Random(int(fs + fc))
        xs = [rng.uniform(-1, 1) for _ in range(300)]
        assert [lib.butterworth_filter(ctypes.byref(cf), x) for x in xs] == [f(x) for x in xs]
    for fs, fc in ((50.0, 25.0), (50.0, 0.0), (-1.0, 1.0), (math.inf, 1.0), (50.0, math.nan),
                   (0.3, 0.2), (1e17, 6e16), (50.0, -0.0)):  # fmt: skip
        with pytest.raises(ParameterError) as err:
            butterworth_coefficients(fs, fc)
        assert lib.butterworth_coefficients(fs, fc, c, b, len(b)) == 1
        assert b.value.decode() == str(err.value)


def test_linearization_bit_identical(lib):
    A = D44()
    for p in PERTURBED:
        lib.observer_linearization(ctypes.byref(cparams(p)), ctypes.byref(ceq(lib, p)), A)
        assert [list(r) for r in A] == linearization(p)


def test_observer_gain_grid_bit_identical(lib):
    """C Riccati solver = pure-Python solver, over the R x Q grid and perturbed constants."""
    H, P, b = D4(), D44(), buf()
    for p in PERTURBED:
        cp = cparams(p)
        for R in R_GRID:
            for Q in Q_GRID:
                assert lib.observer_gain(ctypes.byref(cp), R, D4(*Q), H, b, len(b)) == 0, b.value
                assert tuple(H) == observer_gain(p, R, Q), (p, R, Q)
        assert lib.observer_riccati_solution(ctypes.byref(cp), 0.1, D4(*Q_GRID[5]), P, b,
                                             len(b)) == 0  # fmt: skip
        assert [list(r) for r in P] == riccati_solution(p, 0.1, Q_GRID[5])


def test_observer_gain_messages(lib):
    p = GliderParams()
    cp, H, b = cparams(p), D4(), buf()
    cases = [(0.0, (0.1,) * 4), (-1.0, (0.1,) * 4), (math.nan, (0.1,) * 4),
             (0.1, (0.1, 0.0, 0.1, 0.1)), (0.1, (0.1, 0.1, math.inf, 0.1)),
             (0.1, (0.1, 0.1, 0.1, -1e-300)), (math.inf, (0.0,) * 4)]  # fmt: skip
    for R, Q in cases:
        with pytest.raises(ParameterError) as err:
            observer_gain(p, R, Q)
        assert lib.observer_gain(ctypes.byref(cp), R, D4(*Q), H, b, len(b)) == 1
        assert b.value.decode() == str(err.value)


def test_observer_step_sequences(lib):
    rng = random.Random(9)
    for p in PERTURBED[:2]:
        cp = cparams(p)
        e = equilibrium(p)
        H = observer_gain(p, 0.1, (0.1,) * 4)
        xh = (e.V, e.theta_g, e.alpha, 0.0)
        cxh = D4(*xh)
        b = buf()
        for k in range(300):
            theta = e.theta_g + e.alpha + 0.05 * math.sin(0.1 * k) + rng.gauss(0, 0.005)
            u = rng.choice([0.0, 0.03, -0.03])
            h = rng.choice([0.02, 0.05])
            xh = observer_step(xh, theta, u, h, p, H, 0.02)
            assert lib.observer_step(cxh, theta, u, h, ctypes.byref(cp), D4(*H), 0.02, b,
                                     len(b)) == 0  # fmt: skip
            assert tuple(cxh) == xh, k
    # a stall: the estimate is driven to V <= 0 by a huge gain
    p = GliderParams()
    Hbad = (1e4, 0.0, 0.0, 0.0)
    xh0 = (0.2, -0.4, 0.02, 0.0)
    with pytest.raises(StallError) as err:
        observer_step(xh0, -5.0, 0.0, 0.02, p, Hbad)
    cxh = D4(*xh0)
    assert lib.observer_step(cxh, -5.0, 0.0, 0.02, ctypes.byref(cparams(p)), D4(*Hbad), 0.02,
                             b, len(b)) == 1  # fmt: skip
    assert b.value.decode() == str(err.value) and tuple(cxh) == xh0


# ---- controller ---------------------------------------------------------------------------


def test_passivity_law_bit_identical(lib):
    rng = random.Random(21)
    for p in PERTURBED:
        cp, e, pe = cparams(p), ceq(lib, p), equilibrium(p)
        for _ in range(500):
            V, th = rng.uniform(0.05, 0.6), rng.uniform(-1.5, 0.5)
            K_c, dmax = rng.choice([0.5, 10.0, 100.0]), rng.choice([0.05, math.pi / 2])
            assert lib.passivity_output(V, th, ctypes.byref(cp), ctypes.byref(e)) == (
                passivity_output(V, th, p, pe)
            )
            assert lib.passivity_law(V, th, K_c, ctypes.byref(cp), ctypes.byref(e), dmax) == (
                passivity_law(V, th, K_c, p, pe, dmax)
            )


def test_pi_sequences_with_saturation_and_antiwindup(lib):
    rng = random.Random(33)
    saturated = held = 0
    for K_P, K_I, dmax in ((2.0, 1.0, math.pi / 2), (5.0, 3.0, 0.1), (2.0, 0.0, 0.2),
                           (0.0, 10.0, 0.05)):  # fmt: skip
        pi, c = PIController(K_P, K_I, dmax), CPI()
        lib.pi_init(ctypes.byref(c), K_P, K_I, dmax)
        for k in range(400):
            err = 0.3 * math.sin(0.02 * k) + rng.uniform(-0.05, 0.05)
            out = pi.output(err)
            assert lib.pi_output(ctypes.byref(c), err) == out
            saturated += abs(out) == dmax
            h = rng.choice([0.02, 0.05])
            before = pi.integral
            pi.update(err, h)
            held += K_I != 0.0 and pi.integral == before
            lib.pi_update(ctypes.byref(c), err, h)
            assert c.integral == pi.integral
    assert saturated > 50 and held > 20  # saturation and the anti-windup branch are exercised


def test_riccati_failure_messages(lib):
    """Systems without a stabilizing solution: same stage and text in C and Python."""
    from glider_observer.riccati import RiccatiError, solve_filter_care

    def flat(M):
        return (D * 16)(*(x for row in M for x in row))

    eye = [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)]
    cases = [
        # undamped oscillator the measurement does not see: imaginary-axis eigenvalues
        ([[0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, -1, 0], [0, 0, 0, -2]], 2),
        # unstable mode the measurement does not see (undetectable)
        ([[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -2, 0], [0, 0, 0, -3]], 1),
    ]
    b = buf()
    for A, k in cases:
        A = [[float(a) for a in row] for row in A]
        G = [[1.0 if i == j == k else 0.0 for j in range(4)] for i in range(4)]
        with pytest.raises(RiccatiError) as err:
            solve_filter_care(A, eye, G)
        rc = lib.riccati_solve_filter_care(flat(A), flat(eye), flat(G), (D * 16)(), b, len(b))
        assert rc == 1 and b.value.decode() == str(err.value)
