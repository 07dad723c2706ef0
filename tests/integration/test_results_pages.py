"""plots.html and report.html: one self-contained file each, every figure drawn in
headless Chromium with no console error, the run's settings recorded."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest
from chromium_page import load

pytestmark = [
    pytest.mark.integration,
    pytest.mark.requires_tool("chromium", "chromium-browser"),
]


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "glider_cosim.cli", *args], capture_output=True,
                          text=True, timeout=600, check=False)  # fmt: skip


def _self_contained(text: str) -> None:
    assert not re.search(r"<script[^>]+src=", text), "a script is fetched"
    assert not re.search(r"<link[^>]+href=", text), "a stylesheet is fetched"


def test_run_writes_plots_html_that_renders_every_figure(fmu_dir, tmp_path):
    out = tmp_path / "run"
    proc = _run("run", "--out", str(out), "--fmu-dir", str(fmu_dir), "--set",
                "controller.K_c=6")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    page = out / "plots.html"
    text = page.read_text()
    _self_contained(text)
    pngs = sorted(out.glob("*.png"))
    assert len(pngs) == 5
    found = load(page)
    assert found["errors"] == [] and found["console"] == [] and found["fetched"] == []
    assert len(found["figures"]) == len(pngs) and all(n >= 1 for n in found["figures"])
    settings = json.loads(re.search(r"id='run-settings'>(.*?)</script>", text).group(1))
    metrics = json.loads((out / "metrics.json").read_text())["run"]
    assert settings["scenario"] == metrics["scenario"] == "default"
    assert settings["overrides"] == metrics["overrides"] == {"controller.K_c": 6}
    assert settings["flavor"] == {k: v["flavor"] for k, v in metrics["fmus"].items()}
    assert set(settings["fmi_version"].values()) == {"2.0"}
    assert settings["package"].endswith(metrics["package_version"])


def test_no_plots_skips_the_page(fmu_dir, tmp_path):
    out = tmp_path / "run"
    proc = _run("run", "--out", str(out), "--fmu-dir", str(fmu_dir), "--stop-time", "2",
                "--no-plots")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert not (out / "plots.html").exists() and not list(out.glob("*.png"))


def test_a_page_that_cannot_be_written_keeps_the_results(fmu_dir, tmp_path):
    out = tmp_path / "run"
    (out / "plots.html").mkdir(parents=True)  # a folder where the page goes
    proc = _run("run", "--out", str(out), "--fmu-dir", str(fmu_dir), "--stop-time", "2")
    assert proc.returncode == 0, proc.stderr
    assert "plots.html not written" in proc.stderr
    assert (out / "results.csv").stat().st_size > 0 and (out / "metrics.json").exists()
    assert len(list(out.glob("*.png"))) == 5
