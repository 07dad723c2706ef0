"""The run's PNG plots, drawn with matplotlib: each plot's spec and its PNG, and the
import a run with plots pays before it can draw.

A native run of the default scenario in memory (3001 rows), then, per plot, the best of
``--repeat`` times of: its spec (``plots.build_specs``) and its PNG (``mpl.draw_png``
into a file, as the run draws it); the five in all (``write_plots`` into
files, best of ``--repeat``); and, in new interpreters, the import of the drawing
modules (matplotlib and bokeh with them, numpy included), against nothing (``pass``)
(median of ``--repeat``).

Usage: python bench/draw_plots.py [--repeat 8] [--native-dir fmus/native] [--json]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import emit, parse_args


def _best_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return round(min(times) * 1e3, 2)


def _import_s(code: str, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        times.append(time.perf_counter() - t0)
    return round(statistics.median(times), 3)


def main() -> None:
    args = parse_args(__doc__, ("--repeat", {"type": int, "default": 8}),
                      ("--native-dir", {"default": "fmus/native"}))  # fmt: skip
    from glider_cosim.figures import mpl, plots
    from glider_cosim.runner import simulate

    result = simulate("default", out=None, fmu_dir=args.native_dir)
    out: dict[str, object] = {"rows": int(len(result.data))}
    with tempfile.TemporaryDirectory(prefix="glider-bench-draw-") as name:
        folder = Path(name)
        for spec, path, meta in plots.build_specs(result, folder):
            stem = path.stem
            out[f"{stem}_spec_ms"] = _best_ms(
                lambda stem=stem: plots.build_specs(result, folder, [stem]), args.repeat
            )
            out[f"{stem}_png_ms"] = _best_ms(
                lambda spec=spec, path=path, meta=meta: mpl.draw_png(spec, path, metadata=meta),
                args.repeat,
            )
        out["five_pngs_ms"] = _best_ms(lambda: plots.write_plots(result, folder), args.repeat)
    out["import_drawing_s"] = _import_s(
        "from glider_cosim.figures import mpl, plots, pages", args.repeat
    )
    out["import_nothing_s"] = _import_s("pass", args.repeat)
    emit(out, args.json)


if __name__ == "__main__":
    main()
