"""``glider-cosim explore``: the page that runs the glider in headless Chromium.

- one self-contained ``explore.html`` (at most 5 MB, no ``src``/``href`` to anything, no
  resource fetched when it runs);
- ``window.glider.simulate`` for the default scenario and for K_c = 6 (and K_c = 5, a limit
  cycle, and the open loop, not settled) equals ``glider-cosim run --flavor native``
  within 1e-12 at every point of every recorded column, with the same metrics; so does a
  scenario whose observer stalls the run (open loop with a held tail, sensor noise:
  sec52-tail15), to the same stop;
- a scenario with events is refused with one line;
- a change of a slider re-simulates and redraws the 60 s run (3000 macro steps), the
  page prints each one's time against its 50 ms target, with no console error;
- a file that is not such a page is never written over.
"""

from __future__ import annotations

import csv
import json
import math
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from docs_browser import Browser, _error

pytestmark = [
    pytest.mark.integration,
    pytest.mark.requires_tool("chromium", "chromium-browser", "google-chrome"),
]


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "glider_cosim.cli", *args],
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def evaluate(page: Path, expressions: list[str], timeout: float = 120.0) -> tuple[list, list]:
    """Load ``page`` in headless Chromium, evaluate each expression (promises awaited,
    values returned as JSON); (values, console errors)."""
    with Browser(timeout=timeout) as b:
        target = b._send("Target.createTarget", {"url": "about:blank"})["targetId"]
        s = b._send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page.enable", "Runtime.enable", "Log.enable"):
            b._send(domain, session=s)
        b._events.clear()
        b._send("Page.navigate", {"url": page.as_uri()}, session=s)
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == "Page.loadEventFired" for e in b._events):
            assert time.monotonic() < deadline, "the page did not load"
            b._events.append(b._read())
        values = []
        for expr in expressions:
            r = b._send("Runtime.evaluate", {"expression": expr, "awaitPromise": True,
                                             "returnByValue": True}, session=s)  # fmt: skip
            assert "exceptionDetails" not in r, r["exceptionDetails"]
            values.append(json.loads(r["result"]["value"]))
        return values, [_error(e) for e in b._events if _error(e)]


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("explore")
    p = cli("explore", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == (
        f"wrote {out / 'explore.html'} (open this file in a browser; no server needed)"
    )
    return out / "explore.html"


def native_run(tmp: Path, *sets: str, scenario: str = "default") -> tuple[dict, dict]:
    out = tmp / ("native" + "".join(s.replace("=", "_") for s in sets))
    args = ["run", scenario, "--flavor", "native", "--out", str(out), "--no-plots"]
    p = cli(*args, *[a for s in sets for a in ("--set", s)])
    assert p.returncode == (1 if scenario == "sec52-tail15" else 0), p.stderr  # 1: it stalls
    with open(out / "results.csv", newline="") as f:
        rows = list(csv.reader(f))
    cols = {h: [float(r[i]) for r in rows[1:]] for i, h in enumerate(rows[0])}
    return cols, json.loads((out / "metrics.json").read_text())


def test_one_self_contained_page(page):
    html = page.read_text()
    assert len(html.encode()) <= 5 * 2**20
    assert not re.search(r"""\s(src|href)\s*=""", html)  # nothing to load
    (fetched,), errors = evaluate(page, ["JSON.stringify(performance.getEntriesByType("
                                         "'resource').map(e => e.name))"])  # fmt: skip
    assert fetched == [] and errors == []


SIMULATE = (
    "window.glider.ready.then(() => JSON.stringify((() => {{ const r = "
    "window.glider.simulate({settings}); delete r.messages; return r; }})()))"
)


@pytest.mark.parametrize(
    ("settings", "sets"),
    [
        ({}, []),  # settles
        ({"K_c": 6.0}, ["controller.K_c=6.0"]),
        ({"K_c": 5.0}, ["controller.K_c=5.0"]),  # a limit cycle
        ({"law": "open loop"}, ["controller.law=0"]),  # not settled
    ],
)
def test_simulate_equals_the_native_run(page, tmp_path, settings, sets):
    (got,), errors = evaluate(page, [SIMULATE.format(settings=json.dumps(settings))])
    want, metrics = native_run(tmp_path, *sets)
    assert errors == [] and got["status"] == "ok"
    assert len(got["time"]) == len(want["time"]) == 3001
    for col, values in want.items():
        page_values = got[col]
        worst = max(abs(a - b) for a, b in zip(values, page_values))
        assert worst <= 1e-12, (col, worst)
    m = got["metrics"]
    assert m["outcome"] == metrics["outcome"]
    for key in ("settling_time_s", "overshoot_rad", "rise_time_s", "control_effort",
                "outcome_period_s", "outcome_amplitude_rad", "outcome_rate_per_s"):  # fmt: skip
        assert m[key] == pytest.approx(metrics[key], abs=1e-9), key


def test_a_stalling_scenario_stops_where_the_native_run_stops(tmp_path):
    p = cli("explore", "sec52-tail15", "--out", str(tmp_path / "page"))
    assert p.returncode == 0, p.stderr
    (got,), errors = evaluate(tmp_path / "page" / "explore.html", [SIMULATE.format(settings="{}")])
    want, metrics = native_run(tmp_path, scenario="sec52-tail15")
    assert errors == [] and metrics["status"] == "stopped" and got["status"] == "stopped"
    assert "observer estimate glider stalled" in got["message"]
    assert len(got["time"]) == len(want["time"]) < 1500  # stopped at the same step
    for col, values in want.items():
        assert max(abs(a - b) for a, b in zip(values, got[col])) <= 1e-12, col
    assert got["metrics"]["outcome"] == metrics["outcome"] == "stopped"
    assert got["metrics"]["theta_ge_rad"] == metrics["theta_ge_rad"]  # the held tail's glide


def test_a_scenario_with_events_is_refused(tmp_path):
    p = cli("explore", "sec53-protocol", "--out", str(tmp_path))
    assert p.returncode == 2
    assert p.stderr.strip().splitlines()[-1] == (
        "glider-cosim explore: error: scenario sec53-protocol has events: the explorer runs "
        "scenarios without events, disturbances, input tables or external components "
        "(expected one such as default)"
    )
    assert not (tmp_path / "explore.html").exists()


CHANGES = """window.glider.ready.then(() => new Promise(done => setTimeout(() => {
  const seen = [], el = document.getElementById('f-K_c');
  for (const k of [6, 7, 8, 9, 10]) {
    el.value = String(k); el.dispatchEvent(new Event('input'));
    seen.push(Object.assign({}, window.glider.last,
                            {timing: document.getElementById('timing').textContent}));
  }
  done(JSON.stringify(seen));
}, 300)))"""


def test_a_change_is_simulated_and_drawn_and_its_time_shown(page):
    """Each change re-simulates the whole run; the page shows the time it took (the
    50 ms target is measured by bench/, not asserted here: a busy machine is slower)."""
    (seen,), errors = evaluate(page, [CHANGES])
    assert errors == []
    assert [s["steps"] for s in seen] == [3000] * 5
    assert all(s["total_ms"] > 0 for s in seen), seen
    assert re.fullmatch(r"3000 macro steps simulated in [\d.]+ ms and drawn in [\d.]+ ms: "
                        r"[\d.]+ ms \(target 50 ms\)", seen[-1]["timing"])  # fmt: skip


FORM = """window.glider.ready.then(() => new Promise(done => setTimeout(() => {
  const law = document.getElementById('f-law'), state = {};
  const label = (k) => document.getElementById('f-' + k).parentElement.textContent;
  for (const name of ['passivity', 'P', 'PI', 'open loop']) {
    law.value = name; law.dispatchEvent(new Event('input'));
    state[name] = ['K_c', 'K_P', 'K_I'].filter(k => !document.getElementById('f-' + k).disabled);
  }
  done(JSON.stringify({state, K_c: label('K_c'), ticks: window.glider.ticks,
                       text: document.body.innerText}));
}, 300)))"""


def test_the_form_says_how_k_c_acts_greys_unused_gains_and_has_round_ticks(page):
    """Issue 54: the law divides by K_c (a larger K_c is gentler), and the page says so;
    a law's unused gains are disabled; every axis is labelled at round values; the page
    says it needs no server."""
    (found,), errors = evaluate(page, [FORM])
    assert errors == []
    assert found["state"] == {"passivity": ["K_c"], "P": ["K_P"], "PI": ["K_P", "K_I"],
                              "open loop": []}  # fmt: skip
    assert "divides by K_c: larger is gentler" in found["K_c"]
    assert "Open this file in a browser; no server needed" in found["text"]
    assert set(found["ticks"]) == {"glide", "pitch", "tail", "speed"}
    for plot, axes in found["ticks"].items():
        for axis, labels in axes.items():
            values = [float(v.removesuffix(" s")) for v in labels]
            assert len(values) >= 3, (plot, axis, labels)
            steps = {round(b - a, 9) for a, b in zip(values, values[1:])}
            assert len(steps) == 1, (plot, axis, labels)  # evenly spaced
            (step,) = steps
            mant = step / 10 ** math.floor(math.log10(step))
            assert round(mant, 6) in (1.0, 2.0, 5.0), (plot, axis, labels)  # 1, 2 or 5 x 10^k
            assert all(abs(v / step - round(v / step)) < 1e-6 for v in values), (plot, labels)


def test_never_writes_over_a_file_not_its_own(tmp_path):
    (tmp_path / "explore.html").write_text("<html>mine</html>")
    p = cli("explore", "--out", str(tmp_path))
    assert p.returncode != 0
    assert p.stderr.strip().splitlines()[-1] == (
        f"glider-cosim explore: error: {tmp_path / 'explore.html'} exists and is not an "
        "explorer page of glider-cosim: expected a new file or one explore wrote"
    )
    assert (tmp_path / "explore.html").read_text() == "<html>mine</html>"
