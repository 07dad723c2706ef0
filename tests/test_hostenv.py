"""``glider-cosim host-env`` without building anything: what it prints for this Python."""

from __future__ import annotations

import importlib.util
import sysconfig

import pytest

from glider_cosim.interop import hostenv


def test_host_env_needs_no_numpy_or_scipy(monkeypatch):
    """The FMUs bundle what they import (pure-Python Riccati solver, no numpy): a Python
    without numpy or scipy serves a C host as well."""
    try:
        hostenv.libpython()
    except hostenv.HostEnvError:
        pytest.skip("this Python has no shared libpython")
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec",
        lambda name, *a: None if name.split(".")[0] in ("numpy", "scipy") else real(name, *a),
    )  # fmt: skip
    env = hostenv.host_env()
    assert env["LD_PRELOAD"].split()[0] == str(hostenv.libpython())
    assert sysconfig.get_paths()["purelib"] in env["PYTHONPATH"].split(":")
