"""The explorer's JavaScript copy of the run's metrics (``cosim/runner/explore.js``,
its "metrics" section) equals numpy's (``runner/metrics.py``, ``runner/outcome.py``) on
every shipped scenario's recorded run: the script's section runs under node on each
scenario's columns, and each metric the page shows is compared with the run's. A
scenario the explorer refuses (events, disturbances...) is shown refused."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import pytest

from glider_cosim.runner import simulate
from glider_cosim.runner.explore import ExploreError, page_data
from glider_cosim.scenarios.scenario import load_scenario, shipped_scenarios

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(shutil.which("node") is None, reason="needs node (apt-get install nodejs)"),
]

SCRIPT = Path(__file__).resolve().parents[2] / "cosim" / "runner" / "explore.js"
BEGIN, END = (
    "/* ------------------------------------------------------------ metrics",
    ("/* ------------------------------------------------------------ drawing"),
)
#: the metrics the JavaScript computes, compared with numpy's
KEYS = ("theta_ge_rad", "control_effort", "max_abs_delta_cmd_rad", "settling_band_rad",
        "rise_time_s", "overshoot_rad", "settling_time_s", "outcome_period_s",
        "outcome_amplitude_rad", "outcome_rate_per_s")  # fmt: skip
#: explore.js's law names, by the controller's law number
LAWS = {0: "open loop", 1: "passivity", 2: "P", 3: "PI"}

#: runs the section on each case read from stdin: [{r, s, completed, theta_ge}, ...]
RUNNER = """
const cases = JSON.parse(require("fs").readFileSync(0, "utf8"));
const out = [];
for (const c of cases) {
  const D = { theta_ge: { closed: c.theta_ge, open: c.theta_ge } };
  out.push((function (D) {
%s
    return metrics(c.r, c.s, c.completed);
  })(D));
}
process.stdout.write(JSON.stringify(out));
"""


def js_section() -> str:
    text = SCRIPT.read_text()
    assert text.count(BEGIN) == 1 and text.count(END) == 1, "explore.js's sections moved"
    return text[text.index(BEGIN) : text.index(END)]


def test_the_javascript_metrics_are_numpys_on_every_shipped_scenario(native_dir):
    cases, runs, refused = [], [], []
    for name in shipped_scenarios():
        scenario = load_scenario(name)
        try:
            page_data(scenario, native_dir)
        except ExploreError as err:
            if "the explorer runs scenarios without events" in str(err):
                refused.append(name)  # the explorer does not run it: nothing to compare
                continue
            # accepted: the page's modules are the FMI 3 FMUs' (not this folder's)
        result = simulate(name, fmu_dir=native_dir, build=False, plots=False)
        m = result.metrics
        assert m["t_on_s"] == 0.0, name  # the script's metrics start at t = 0
        law = int(result.scenario.parameters.get("controller", {}).get("law", 1))
        r = {"time": result.data[:, 0].tolist(),
             "plant.theta_g": result.column("plant.theta_g").tolist(),
             "controller.delta_cmd": result.column("controller.delta_cmd").tolist()}  # fmt: skip
        cases.append({"r": r, "s": {"law": LAWS[law]}, "completed": result.status == "ok",
                      "theta_ge": m["theta_ge_rad"]})  # fmt: skip
        runs.append((name, m))
    assert sorted(refused) == ["sec53-literal", "sec53-protocol"]  # their events
    assert len(runs) + len(refused) == len(shipped_scenarios())
    proc = subprocess.run(["node", "-e", RUNNER % js_section()], input=json.dumps(cases),
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout)
    outcomes = set()
    for (name, want), js in zip(runs, got, strict=True):
        assert js["outcome"] == want["outcome"], (name, js["outcome"], want["outcome"])
        outcomes.add(want["outcome"])
        for key in KEYS:
            w, g = want.get(key), js.get(key)
            if w is None:
                assert g is None, (name, key, g)
            else:
                assert g is not None and math.isclose(g, w, rel_tol=1e-9, abs_tol=1e-12), (
                    name, key, g, w
                )  # fmt: skip
    assert {"settled", "limit cycle", "stopped"} <= outcomes, outcomes
