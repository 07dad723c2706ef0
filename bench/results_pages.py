"""The results pages: bokeh against plotly on the default run's figures.

Both draw the same figure specs (the run's plots, :func:`glider_cosim.figures.plots.build_specs`,
the PNGs' own), every sample kept, the library's JavaScript inline once per page. Measured:
the page's size in bytes; its load time in headless Chromium (the wall time of
``chromium --headless --dump-dom`` on the page minus that on an empty page, median of
``--repeat``); and what writing ``plots.html`` adds to ``glider-cosim run`` (the spec and
the page, against the PNGs alone). ``--json``: one JSON object on stdout. plotly is not
a dependency of glider-cosim: without it (``pip install plotly`` for the comparison) the
plotly figures are ``null`` and a line on stderr says so. Chromium is Debian's.

    python bench/results_pages.py [--repeat 5] [--json]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from glider_cosim.figures.pages import run_settings, write_page, write_run_page
from glider_cosim.figures.plots import write_plots
from glider_cosim.runner.run import simulate
from glider_cosim.scenarios.scenario import load_scenario


def plotly_page(path: Path, specs: list[dict], title: str) -> Path:
    """The same figures with plotly: one figure per spec, its panels as subplots."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    dash = {"solid": "solid", "dashed": "dash", "dashdot": "dashdot", "dotted": "dot"}
    parts = []
    for k, spec in enumerate(specs):
        nrow = 1 + max(p["row"] for p in spec["panels"])
        ncol = 1 + max(p["col"] for p in spec["panels"])
        fig = make_subplots(nrow, ncol, shared_xaxes=True)
        for p in spec["panels"]:
            for ln in p["lines"]:
                mode = "+".join(m for m, on in (("lines", ln["lines"]),
                                                ("markers", bool(ln["marker"]))) if on)  # fmt: skip
                fig.add_trace(go.Scatter(x=ln["x"], y=ln["y"], name=ln["name"], mode=mode,
                                         showlegend=ln["legend"], opacity=ln["alpha"],
                                         line={"color": ln["color"], "width": ln["width"],
                                               "dash": dash[ln["dash"]],
                                               "shape": "hv" if ln["step"] else "linear"}),
                              row=p["row"] + 1, col=p["col"] + 1)  # fmt: skip
        fig.update_layout(title=spec["title"], height=320 * nrow)
        parts.append(fig.to_html(full_html=False, include_plotlyjs=k == 0))
    path.write_text(f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{title}"
                    f"</title></head><body>{''.join(parts)}</body></html>\n")  # fmt: skip
    return path


def chromium_load_s(page: Path, repeat: int, tmp: Path) -> float:
    exe = shutil.which("chromium")
    if exe is None:
        raise SystemExit("needs Debian's chromium (apt-get install chromium)")

    def once(p: Path) -> float:
        t0 = time.perf_counter()
        subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu",
                        f"--user-data-dir={tmp}/profile", "--dump-dom", p.as_uri()],
                       capture_output=True, check=True, timeout=120)  # fmt: skip
        return time.perf_counter() - t0

    blank = tmp / "blank.html"
    blank.write_text("<!DOCTYPE html><html><body></body></html>\n")
    once(blank)  # the profile made, the binary in the page cache
    return statistics.median(once(page) - once(blank) for _ in range(repeat))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="glider-bench-pages-") as name:
        tmp = Path(name)
        result = simulate(load_scenario(None), tmp / "run", plots=False)
        t0 = time.perf_counter()
        specs: list = []
        write_plots(result, tmp / "run", keep=specs)
        t_png = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_run_page(result, tmp / "run", specs)
        t_page = time.perf_counter() - t0
        bokeh = write_page(tmp / "bokeh.html", "default", specs, run_settings(result.metrics))
        plotly = None
        if importlib.util.find_spec("plotly") is None:
            print("results_pages: plotly is not installed (pip install plotly): bokeh alone",
                  file=sys.stderr)  # fmt: skip
        else:
            plotly = plotly_page(tmp / "plotly.html", specs, "default")
        out = {
            "rows": int(len(result.data)),
            "figures": len(specs),
            "bokeh_bytes": bokeh.stat().st_size,
            "plotly_bytes": plotly.stat().st_size if plotly else None,
            "bokeh_load_s": round(chromium_load_s(bokeh, args.repeat, tmp), 3),
            "plotly_load_s": round(chromium_load_s(plotly, args.repeat, tmp), 3)
            if plotly
            else None,
            "pngs_s": round(t_png, 3),
            "plots_html_s": round(t_page, 3),
        }
    if args.json:
        json.dump(out, sys.stdout)
        print()
    else:
        for k, v in out.items():
            print(f"{k:>14}: {v}")


if __name__ == "__main__":
    main()
