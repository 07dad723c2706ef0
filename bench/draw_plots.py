"""The run's PNG plots, drawn with Pillow: each plot's spec, drawing and PNG, and the
import a drawing process pays before it can draw.

A native run of the default scenario in memory (3001 rows), then, per plot, the best of
``--repeat`` times of: its spec (``plots.build_specs``), its drawing
(``raster.render``) and its PNG (``raster.png_bytes``, into memory; ``_pillow_png_ms``:
Pillow's encoder at zlib level 1, for comparison); the five
in all (``render_png`` into files, best of ``--repeat``); and, in new interpreters, the
import of what the drawing process imports (Pillow and the drawing modules, numpy
included) against matplotlib's pyplot (median of ``--repeat``).

Usage: python bench/draw_plots.py [--repeat 8] [--native-dir fmus/native] [--json]
"""

from __future__ import annotations

import io
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
    from glider_cosim.figures import plots, raster
    from glider_cosim.runner import simulate

    result = simulate("default", out=None, fmu_dir=args.native_dir)
    out: dict[str, object] = {"rows": int(len(result.data))}
    with tempfile.TemporaryDirectory(prefix="glider-bench-draw-") as name:
        folder = Path(name)
        raster.warm()
        for spec, path, _ in plots.build_specs(result, folder):
            stem = path.stem
            out[f"{stem}_spec_ms"] = _best_ms(
                lambda stem=stem: plots.build_specs(result, folder, [stem]), args.repeat
            )
            out[f"{stem}_draw_ms"] = _best_ms(lambda spec=spec: raster.render(spec), args.repeat)
            image = raster.render(spec)
            out[f"{stem}_png_ms"] = _best_ms(
                lambda image=image: raster.png_bytes(image, {}), args.repeat
            )
            out[f"{stem}_pillow_png_ms"] = _best_ms(
                lambda image=image: image.save(io.BytesIO(), format="PNG", compress_level=1),
                args.repeat,
            )
        out["five_pngs_ms"] = _best_ms(lambda: plots.write_plots(result, folder), args.repeat)
    out["import_drawing_s"] = _import_s(
        "from glider_cosim.figures import raster, plots, pages; raster.warm()", args.repeat
    )
    out["import_matplotlib_s"] = _import_s(
        "import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot", args.repeat
    )
    out["import_nothing_s"] = _import_s("pass", args.repeat)
    emit(out, args.json)


if __name__ == "__main__":
    main()
