"""The explorer page: how long a change of a slider takes to re-simulate and redraw.

Writes ``explore.html`` for the default scenario (``glider-cosim explore``: the native FMI
3.0 FMUs' WebAssembly modules, the per-user cache's set, built if missing), loads it in
headless Chromium (Debian's, over the DevTools pipe of tests/integration/docs_browser.py,
in real time), reads the first run's time (the one drawn at load), then moves the K_c
slider ``--changes`` times and reads the time the page measured for each: the 60 s run's
3000 macro steps simulated, then the four plots drawn. ``--json``: one JSON object last.

    python bench/explore_page.py [--changes 10] [--json]
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _common import emit, parse_args

from glider_cosim.fmus.folders import prepare_fmus
from glider_cosim.runner.explore import write_page
from glider_cosim.scenarios.scenario import load_scenario

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "integration"))
from docs_browser import Browser  # noqa: E402

CHANGES = """window.glider.ready.then(() => new Promise(done => setTimeout(() => {{
  const seen = [Object.assign({{}}, window.glider.last)], el = document.getElementById('f-K_c');
  for (let i = 0; i < {n}; i++) {{
    el.value = String(6 + (i % 10)); el.dispatchEvent(new Event('input'));
    seen.push(Object.assign({{}}, window.glider.last));
  }}
  done(JSON.stringify(seen));
}}, 500)))"""


def measure(page: Path, n: int) -> list[dict]:
    """The page's own timings: the run at load, then ``n`` changes."""
    with Browser(timeout=120) as b:
        target = b._send("Target.createTarget", {"url": "about:blank"})["targetId"]
        s = b._send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        b._send("Page.enable", session=s)
        b._events.clear()
        b._send("Page.navigate", {"url": page.as_uri()}, session=s)
        deadline = time.monotonic() + 120
        while not any(e.get("method") == "Page.loadEventFired" for e in b._events):
            if time.monotonic() > deadline:
                raise TimeoutError("the page did not load")
            b._events.append(b._read())
        r = b._send("Runtime.evaluate", {"expression": CHANGES.format(n=n), "awaitPromise": True,
                                         "returnByValue": True}, session=s)  # fmt: skip
        return json.loads(r["result"]["value"])


def main() -> None:
    args = parse_args(__doc__, ("--changes", {"type": int, "default": 10}))
    fmus = prepare_fmus(None, "native", 3, host_only=True)
    with tempfile.TemporaryDirectory(prefix="explore_bench_") as tmp:
        page = write_page(Path(tmp), load_scenario(None), fmus)
        size = page.stat().st_size
        first, *changes = measure(page, args.changes)
    med = {k: round(statistics.median(c[k] for c in changes), 1)
           for k in ("simulate_ms", "draw_ms", "total_ms")}  # fmt: skip
    emit({
        "page_bytes": size,
        "steps": first["steps"],
        "changes": len(changes),
        "first_total_ms": round(first["total_ms"], 1),
        "simulate_ms_median": med["simulate_ms"],
        "draw_ms_median": med["draw_ms"],
        "total_ms_median": med["total_ms"],
        "total_ms_max": round(max(c["total_ms"] for c in changes), 1),
        "total_ms_min": round(min(c["total_ms"] for c in changes), 1),
    }, args.json)  # fmt: skip


if __name__ == "__main__":
    main()
