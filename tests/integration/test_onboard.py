"""``glider-cosim build-onboard controller``: the native controller's C model as a program
(no Python, no FMI) serving the endpoint; in lockstep a run with it equals the run with
the controller FMU bit for bit on x86_64 and on aarch64 (under qemu-user), to about
1e-16 on Windows (under wine: another libm), checked under valgrind, and it refuses a
bad parameter as the FMU does."""

from __future__ import annotations

import socket
import subprocess

import numpy as np
import pytest
from c_host_helpers import AARCH64_SYSROOT, QEMU, wine_env
from system_tools import require_tool

from glider_cosim.master.instance import Instance
from glider_cosim.realtime import protocol as p
from glider_cosim.realtime.external import Endpoint
from glider_cosim.realtime.onboard import OnboardBuildError, build_onboard
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration


def _served_run(cmd: list[str], native_dir, stop: float = 6.0, env=None):
    prog = subprocess.Popen([*cmd, "--listen", "udp://127.0.0.1:0", "--once"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        line = prog.stdout.readline()
        assert line.startswith("serving GliderController on udp://127.0.0.1:"), line
        url = line.split()[-1]
        r = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=stop,
                     external={"controller": Endpoint(url, timeout=20.0)})  # fmt: skip
        _, err = prog.communicate(timeout=60)  # --once: it exits after the STOP
    finally:
        prog.kill()
        prog.wait(10)
    return r, prog.returncode, err


@pytest.fixture(scope="module")
def reference(native_dir):
    return simulate("default", None, fmu_dir=native_dir, build=False, stop_time=6.0).data


def test_x86_64_program_equals_the_fmu_bit_for_bit_under_valgrind(native_dir, reference, tmp_path):
    prog = build_onboard(tmp_path / "x86", "x86_64-linux")
    r, code, _ = _served_run([str(prog)], native_dir)
    assert r.status == "ok" and code == 0 and np.array_equal(r.data, reference)
    require_tool("valgrind")
    vg = ["valgrind", "--error-exitcode=9", "--leak-check=full", "-q", str(prog)]
    r, code, err = _served_run(vg, native_dir, stop=1.0)
    assert r.status == "ok" and code == 0, err
    assert np.array_equal(r.data, reference[:51])


def test_aarch64_program_under_qemu_equals_the_fmu(native_dir, reference, tmp_path):
    prog = build_onboard(tmp_path / "arm", "aarch64-linux")
    r, code, _ = _served_run([QEMU, "-L", AARCH64_SYSROOT, str(prog)], native_dir)
    assert r.status == "ok" and code == 0 and np.array_equal(r.data, reference)


def test_windows_program_under_wine_equals_the_fmu(native_dir, reference, tmp_path):
    prog = build_onboard(tmp_path / "win", "x86_64-windows")
    assert prog.name.endswith(".exe") and prog.read_bytes()[:2] == b"MZ"
    r, code, _ = _served_run(["wine", str(prog)], native_dir, stop=2.0, env=wine_env(tmp_path))
    # Windows' libm is not glibc's: equal to the last bits or so, not bit for bit
    assert r.status == "ok" and r.data.shape == (101, reference.shape[1])
    diff = np.abs(r.data - reference[:101]).max()
    print(f"onboard x86_64-windows (wine) vs the linux FMU: max diff {diff:.3g}")
    assert diff < 1e-12


def test_the_program_refuses_a_bad_parameter_and_a_bad_target(native_dir, tmp_path):
    prog = build_onboard(tmp_path / "x86")
    srv = subprocess.Popen([str(prog), "--listen", "udp://127.0.0.1:0"], stdout=subprocess.PIPE,
                           text=True)  # fmt: skip
    try:
        port = int(srv.stdout.readline().rsplit(":", 1)[1])
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(10)
        vr = Instance("c", native_dir / "GliderController.fmu").vars["K_c"].valueReference
        s.sendto(b"junk", ("127.0.0.1", port))  # dropped, the program goes on
        s.sendto(p.encode(p.START, 4, 0.0, [0.02, float(vr), -1.0]), ("127.0.0.1", port))
        m = p.decode(s.recv(p.MAX_SIZE))
        s.close()
    finally:
        srv.kill()
        srv.wait(10)
    assert m.type == p.ERROR and m.seq == 4
    assert m.text.startswith("refused: K_c = -1.0 is invalid: expected ")
    with pytest.raises(OnboardBuildError, match="--target 'sparc' is unknown: expected one of"):
        build_onboard(tmp_path / "x", "sparc")
