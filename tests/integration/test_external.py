"""A component outside the process (``--external``, ``serve``): lockstep equals the run in
process bit for bit, the parameters reach the endpoint, a refusal and a silent endpoint
stop the run with one named line, and ``[external]`` in a scenario."""

from __future__ import annotations

import json
import socket
import subprocess
import sys

import numpy as np
import pytest
from realtime_helpers import Served

from glider_cosim.realtime import protocol as p
from glider_cosim.realtime.external import Endpoint
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration
CLI = "import sys; from glider_cosim.cli.main import console_main; console_main()"


def _run(native_dir, **kw):
    return simulate("default", None, fmu_dir=native_dir, build=False, **kw)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_lockstep_with_a_served_controller_equals_the_fmu_bit_for_bit(native_dir, coupling):
    with Served(native_dir / "GliderController.fmu") as srv:
        ext = _run(native_dir, stop_time=4.0, coupling=coupling, external={"controller": srv.url})
    ref = _run(native_dir, stop_time=4.0, coupling=coupling)
    assert ext.status == "ok" and np.array_equal(ext.data, ref.data)
    c = ext.metrics["external"]["controller"]
    assert c["round_trips"] >= 200 and c["late_replies"] == c["malformed"] == 0


def test_a_served_plant_and_the_parameters_sent_at_the_start(native_dir):
    sc = "default"
    with Served(native_dir / "GliderPlant.fmu") as srv:
        ext = simulate(sc, None, fmu_dir=native_dir, build=False, stop_time=2.0,
                       external={"plant": srv.url})  # fmt: skip
    ref = _run(native_dir, stop_time=2.0)
    assert np.array_equal(ext.data, ref.data)
    from glider_cosim.scenarios.overrides import apply_overrides, parse_sets
    from glider_cosim.scenarios.scenario import load_scenario

    other = apply_overrides(load_scenario("default"), parse_sets(["controller.K_c=9"]))
    with Served(native_dir / "GliderController.fmu") as srv:
        ext = simulate(other, None, fmu_dir=native_dir, build=False, stop_time=2.0,
                       external={"controller": srv.url})  # fmt: skip
    ref = simulate(other, None, fmu_dir=native_dir, build=False, stop_time=2.0)
    assert np.array_equal(ext.data, ref.data) and not np.array_equal(ext.data, ref.data * 0)
    assert not np.array_equal(ext.data, _run(native_dir, stop_time=2.0).data)  # K_c counted


def test_the_endpoint_refuses_a_bad_parameter_by_name(native_dir):
    with Served(native_dir / "GliderController.fmu") as srv:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(10)
        s.bind(("127.0.0.1", 0))
        from glider_cosim.master.instance import Instance

        vr = Instance("c", native_dir / "GliderController.fmu").vars["K_c"].valueReference
        s.sendto(p.encode(p.START, 1, 0.0, [0.02, float(vr), -1.0]), srv.addr)
        m = p.decode(s.recv(p.MAX_SIZE))
        s.sendto(p.encode(p.START, 2, 0.0, [0.02, 99999.0, 1.0]), srv.addr)
        m2 = p.decode(s.recv(p.MAX_SIZE))
        s.close()
    assert m.type == p.ERROR and m.seq == 1
    assert m.text.startswith("refused: fmi2") and ": K_c = -1.0 is invalid: expected " in m.text
    assert m2.type == p.ERROR and "value reference 99999: no parameter" in m2.text


def test_a_silent_endpoint_stops_the_run_with_one_line(native_dir, tmp_path):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))  # bound, never answers
    url = f"udp://127.0.0.1:{s.getsockname()[1]}"
    r = _run(native_dir, stop_time=1.0, external={"controller": Endpoint(url, timeout=0.5)})
    s.close()
    assert r.status == "error"
    assert (
        r.message == f"controller ({url}): no reply for 0.5 s (--external-timeout): the run stops"
    )


def test_cli_external_option_and_scenario_table(native_dir, tmp_path):
    with Served(native_dir / "GliderController.fmu") as srv:
        sc = tmp_path / "ext.toml"
        sc.write_text(f'stop_time = 1.0\n[external]\ncontroller = "{srv.url}"\n')
        base = [sys.executable, "-c", CLI, "run", "--fmu-dir", str(native_dir), "--no-plots"]
        a = subprocess.run(base + [str(sc), "--out", str(tmp_path / "a")], capture_output=True,
                           text=True, timeout=120)  # fmt: skip
        b = subprocess.run(base + ["--stop-time", "1", "--out", str(tmp_path / "b"),
                                   "--external", f"controller={srv.url}"],
                           capture_output=True, text=True, timeout=120)  # fmt: skip
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    ma = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert ma["external"]["controller"]["endpoint"] == srv.url
    assert (tmp_path / "a/results.csv").read_text() == (tmp_path / "b/results.csv").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text('[external]\npilot = "udp://127.0.0.1:1"\n')
    c = subprocess.run(base + [str(bad), "--out", str(tmp_path / "c")], capture_output=True,
                       text=True, timeout=60)  # fmt: skip
    assert c.returncode == 2 and "key 'external.pilot': expected an instance of" in c.stderr


def test_a_refused_start_stops_the_run_with_the_endpoints_reason(native_dir):
    from glider_cosim.scenarios.scenario import load_scenario

    sc = load_scenario("default")
    sc.parameters.setdefault("controller", {})["K_c"] = -1.0  # past the CLI's own check
    with Served(native_dir / "GliderController.fmu") as srv:
        r = simulate(sc, None, fmu_dir=native_dir, build=False, stop_time=1.0,
                     external={"controller": srv.url})  # fmt: skip
    assert r.status == "error" and len(r.data) == 0
    assert r.message == (
        f"controller ({srv.url}): refused: fmi2ExitInitializationMode: K_c = -1.0 is invalid: "
        "expected a finite value in (0, inf)"
    )
