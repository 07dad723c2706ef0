"""A run's plots, drawn in the run's own process once its results are written (issue 53,
item 6: the forked drawing process went): the five PNGs (matplotlib, through
``figures/mpl.py``) and ``plots.html`` (bokeh, ``figures/pages.py``) from the same specs,
each PNG saying what it shows, the page the same for the same run, a progress line
while they are drawn, and a drawing failure one line with the run's results kept."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from glider_cosim.figures.plots import PLOTS, PlotError, read_png_record, settings_text
from glider_cosim.runner import simulate
from glider_cosim.runner.run import draw_plots

pytestmark = pytest.mark.integration

#: the five PNGs a run draws, and its page
NAMES = [name for name, _, _ in PLOTS]
#: the ids bokeh gives a page's models (a process's counter) and elements (random UUIDs)
BOKEH_ID = re.compile(rb'"p\d+"|[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}')


def _same_ids(page: bytes) -> bytes:
    """``plots.html`` with bokeh's ids numbered in the order they first appear: two
    writes of one page are then the same bytes."""
    seen: dict[bytes, bytes] = {}
    return BOKEH_ID.sub(lambda m: seen.setdefault(m.group(), b"<id%d>" % len(seen)), page)


def _drawn(folder):
    """The PNGs and the page in ``folder``, the page's bokeh ids renumbered."""
    return {p.name: _same_ids(p.read_bytes()) if p.suffix == ".html" else p.read_bytes()
            for p in sorted(folder.iterdir()) if p.suffix in (".png", ".html")}  # fmt: skip


@pytest.fixture(scope="module")
def run(fmu_dir, tmp_path_factory):
    """A 5 s run of the default scenario (251 rows) with its plots, in this process."""
    out = tmp_path_factory.mktemp("run")
    return simulate("default", out=out, fmu_dir=fmu_dir, stop_time=5.0), out


def test_a_run_writes_five_pngs_and_its_page_in_its_own_process(run):
    result, out = run
    assert result.status == "ok"
    assert list(result.files) == ["results", "metrics", *NAMES, "page"]
    assert [p.name for p in result.files.values()] == [
        "results.csv", "metrics.json", *(f"{n}.png" for n in NAMES), "plots.html"]  # fmt: skip
    assert all(p.parent == out and p.stat().st_size > 0 for p in result.files.values())
    assert not list(out.glob("*.part"))
    assert b"Bokeh" in (out / "plots.html").read_bytes()


def test_every_png_says_what_it_shows(run):
    """Each PNG carries the run's events and settings in its text chunks, read back by
    ``read_png_record``, at 110 dpi, 770 px wide."""
    from PIL import Image

    result, out = run
    for name in NAMES:
        png = out / f"{name}.png"
        record = read_png_record(png)
        assert record["settings"] == settings_text(result.metrics), name
        assert record["events"] == result.metrics["events"], name
        with Image.open(png) as im:
            assert im.width == 770 and round(im.info["dpi"][0]) == 110, name


def test_the_same_run_draws_the_same_pngs_and_page(run, tmp_path):
    """Drawn again from the same results, elsewhere: the same PNG bytes, and the same
    page once bokeh's own ids are renumbered."""
    result, out = run
    files = draw_plots(result, tmp_path)
    assert list(files) == [*NAMES, "page"]
    mine, again = _drawn(out), _drawn(tmp_path)
    assert sorted(mine) == sorted(again) == sorted([f"{n}.png" for n in NAMES] + ["plots.html"])
    for name in mine:
        assert mine[name] == again[name], name


def test_a_drawing_failure_is_one_line_and_keeps_the_results(fmu_dir, tmp_path):
    (tmp_path / "pitch.png.part").mkdir()  # pitch.png cannot be written
    with pytest.raises(PlotError) as err:
        simulate("default", out=tmp_path, fmu_dir=fmu_dir, stop_time=2.0)
    text = str(err.value)
    assert text.startswith("PNG plots not written (") and "pitch.png.part" in text
    assert text.endswith("the run's results and metrics.json are kept") and "\n" not in text
    assert not (tmp_path / "pitch.png").exists()
    assert json.loads((tmp_path / "metrics.json").read_text())["status"] == "ok"
    assert len((tmp_path / "results.csv").read_text().splitlines()) == 102  # header, 101 rows


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "glider_cosim.cli", "run", *args],
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def test_the_command_says_it_draws_and_a_failure_is_one_error_line(fmu_dir, tmp_path):
    """In a pipe, one progress line while the plots are drawn; ``-q``, none. A PNG that
    cannot be written: exit 2, one error line naming it, results.csv and metrics.json
    kept."""
    out = tmp_path / "run"
    p = _cli("--fmu-dir", str(fmu_dir), "--stop-time", "2", "--out", str(out))
    assert p.returncode == 0, p.stderr
    assert p.stderr.splitlines() == [f"run: drawing the plots into {out}"]
    assert "plots.html" in p.stdout and (out / "depth.png").is_file()
    p = _cli("--fmu-dir", str(fmu_dir), "--stop-time", "2", "--out", str(out), "-q")
    assert (p.returncode, p.stderr) == (0, "")
    (out / "speed.png").unlink()
    (out / "speed.png.part").mkdir()
    p = _cli("--fmu-dir", str(fmu_dir), "--stop-time", "2", "--out", str(out), "-q")
    assert p.returncode == 2 and "Traceback" not in p.stderr
    (line,) = p.stderr.splitlines()
    assert line.startswith("glider-cosim run: error: ") and "PNG plots not written" in line
    assert "speed.png.part" in line and line.endswith("the run's results and metrics.json are kept")
    assert (out / "results.csv").is_file() and (out / "metrics.json").is_file()
    assert not (out / "speed.png").exists()
