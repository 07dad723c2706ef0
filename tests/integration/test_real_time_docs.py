"""docs/how-to/real-time.md: its Python client, run as written, closes the loop with the
master; the format table says what the reference codec does."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from glider_cosim.realtime import protocol as p
from glider_cosim.realtime.external import Endpoint
from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration
PAGE = Path(__file__).parents[2] / "docs" / "how-to" / "real-time.md"


def client_code() -> str:
    text = PAGE.read_text()
    section = text[text.index("## A client in Python") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_documented_client_runs_the_loop(native_dir, tmp_path):
    code = client_code()
    assert 25 <= len(code.strip().splitlines()) <= 35
    script = tmp_path / "client.py"
    script.write_text(code)
    proc = subprocess.Popen([sys.executable, str(script), "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        port = int(proc.stdout.readline().split()[-1])
        ext = {"controller": Endpoint(f"udp://127.0.0.1:{port}", 10.0)}
        r = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=2.0, external=ext)
        _, err = proc.communicate(timeout=30)  # the client ends at STOP
    finally:
        proc.kill()
        proc.wait(10)
    assert r.status == "ok" and proc.returncode == 0, err
    c = r.metrics["external"]["controller"]
    # START, the exchange that gives the command in Initialization Mode, each point
    assert c["round_trips"] == len(r.data) + 2 and c["malformed"] == 0
    delta = r.column("controller.delta_cmd")
    theta_g_hat = r.column("observer.theta_g_hat")
    # the client's law, as the page writes it
    assert abs(delta[10] - max(-0.3, min(0.3, -0.5 * (theta_g_hat[10] + 0.4)))) < 1e-15


def test_the_table_matches_the_codec():
    text = PAGE.read_text()
    for kind, name in p.TYPES.items():
        assert f"{kind} {name}" in text
    assert p.HEADER.size == 24 and "24-byte header" in text
    assert f"\n{p.MAX_VALUES} values a message" in text
