"""A compile has no fixed time limit (issue 54): a slow machine is slow, not failed."""

from __future__ import annotations

import subprocess
import sys

import pytest

from glider_fmi import toolchain


def test_a_compile_runs_without_a_time_limit(monkeypatch):
    seen: dict = {}
    real = subprocess.run

    def recording(cmd, **kw):
        seen.update(kw)
        return real(cmd, **kw)

    monkeypatch.setattr(subprocess, "run", recording)
    # a "compiler" that prints nothing: warning-free
    assert toolchain.run([sys.executable, "-c", "pass"], "nothing.c") == ""
    assert seen.get("timeout") is None


def test_a_failed_compile_is_named_with_its_first_lines():
    cmd = [sys.executable, "-c", "import sys; sys.exit('x.c:1: error: no')"]
    with pytest.raises(toolchain.ToolchainError, match=r"^compiling x.c with .* \(exit 1\): x.c:1"):
        toolchain.run(cmd, "x.c")
    with pytest.raises(toolchain.ToolchainError, match=r"^compiling y.c with /no/such/cc failed"):
        toolchain.run(["/no/such/cc"], "y.c")
