"""`glider-cosim report`: every figure's scenario, the analysis, the agreement section."""

from __future__ import annotations

import re

import pytest

from glider_cosim.analysis import analyze
from glider_cosim.report import FIGURES, build_report

pytestmark = pytest.mark.integration


def test_report_is_written_with_figures_tables_and_findings(fmu_dir, tmp_path):
    path = build_report(tmp_path, fmu_dir, analysis=analyze, progress=False)
    text = path.read_text()
    for fig in FIGURES:
        assert (tmp_path / f"{fig.key}.png").stat().st_size > 10_000
        assert f"![{fig.key}]({fig.key}.png)" in text
        for run in fig.runs:
            assert f"| {run.label} |" in text
    assert (tmp_path / "communication_step.png").exists()
    m = re.search(r"against the monolithic sampled loop .*= ([0-9.e+-]+) \(target 1e-6 rad\)",
                  text)  # fmt: skip
    assert m and float(m.group(1)) <= 1e-6
    assert "## Where we agree with the paper, and where we do not" in text
    assert "**Disagreement**: the literal Sec. 5.3 protocol" in text
    assert "| passivity K_c = 10 (ours) | ok |" in text
    assert "**Disagreement**: the paper's K_c = 2" in text
    assert "the Schur complement of Sec. 3.2 is [[-1.26, 10.19]" in text
    assert re.search(r"stable K_c range, full-state, continuous time: \(5\.2\d, unbounded\)", text)
