"""A run's plots drawn off the critical path (issue 31 point 2, ``figures/drawing.py``):
the forked drawing process writes the same files as drawing in the process, a failure
there is a one-line ``PlotError`` with the run's results kept, a killed child is named,
and no child, half-written file or zombie is left behind."""

from __future__ import annotations

import multiprocessing
import os
import signal
from pathlib import Path

import pytest

from glider_cosim.figures import drawing
from glider_cosim.runner import simulate

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(not hasattr(os, "fork"), reason="the drawing process is forked"),
]


@pytest.fixture(scope="module")
def result(native_dir):
    """A short native run in memory (5 s, 251 rows), its metrics and events included."""
    return simulate("default", out=None, fmu_dir=native_dir, stop_time=5.0)


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_the_child_writes_what_the_process_writes(result, tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    drawing.draw_plots(result, here)
    drawer = drawing.start_drawer()
    assert drawer is not None  # Linux forks
    files = drawer.draw(result, there)
    assert set(files) == {"glide_angle", "pitch", "tail_angle", "speed", "depth", "page"}
    mine, theirs = _files(here), _files(there)
    assert sorted(mine) == sorted(theirs)
    for name in mine:  # byte for byte: the same figures, metadata and page
        assert mine[name] == theirs[name], name
    assert multiprocessing.active_children() == []


def test_the_child_draws_after_its_warm_up_what_the_process_draws(result, tmp_path):
    """A child given time to import Pillow, load the fonts and fork its partner writes
    what the process writes."""
    import time

    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    drawing.draw_plots(result, here)
    drawer = drawing.start_drawer()
    _partner_of(drawer._process.pid)
    time.sleep(0.5)
    drawer.draw(result, there)
    assert _files(here) == _files(there)
    assert multiprocessing.active_children() == []


_MAPPED = """
import sys, time
from pathlib import Path
from glider_cosim.figures import drawing
drawer = drawing.start_drawer()
child = drawer._process.pid
deadline = time.monotonic() + 20
while not Path(f"/proc/{child}/task/{child}/children").read_text().split():
    assert time.monotonic() < deadline, "no partner forked"
    time.sleep(0.02)
print(Path(f"/proc/{child}/maps").read_text())
drawer.close()
"""


def test_the_drawing_process_never_loads_matplotlib():
    """The point of drawing with Pillow (issue 31): matplotlib's import alone (0.55 s)
    outlasted a native run without plots. A fresh interpreter starts a drawing process
    and the libraries mapped into it, once it is ready, are read from /proc."""
    import subprocess
    import sys

    maps = subprocess.run([sys.executable, "-c", _MAPPED], capture_output=True, text=True,
                          check=True, timeout=120).stdout  # fmt: skip
    libraries = {line.split()[-1] for line in maps.splitlines() if line.endswith(".so")
                 or ".so." in line or ".cpython-" in line}  # fmt: skip
    assert any("/PIL/_imaging" in lib for lib in libraries), sorted(libraries)
    assert not [lib for lib in libraries if "/matplotlib/" in lib]


def test_a_failure_in_the_child_is_one_plot_error(result, tmp_path):
    (tmp_path / "pitch.png.part").mkdir()  # the child cannot write pitch.png
    drawer = drawing.start_drawer()
    with pytest.raises(drawing.PlotError) as err:
        drawer.draw(result, tmp_path)
    text = str(err.value)
    assert text.startswith("PNG plots not written (") and "pitch.png.part" in text
    assert text.endswith("the run's results and metrics.json are kept") and "\n" not in text
    assert not (tmp_path / "pitch.png").exists()
    assert multiprocessing.active_children() == []


def test_a_killed_child_is_named(result, tmp_path):
    drawer = drawing.start_drawer()
    os.kill(drawer._process.pid, signal.SIGKILL)
    drawer._process.join(5)
    with pytest.raises(drawing.PlotError, match=r"the drawing process exited \(signal 9\)"):
        drawer.draw(result, tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == []
    assert multiprocessing.active_children() == []


def test_an_unused_child_ends_and_is_reaped():
    drawer = drawing.start_drawer()
    pid = drawer._process.pid
    drawer.close()
    assert not drawer._process.is_alive() and drawer._process.exitcode == 0
    with pytest.raises(ChildProcessError):  # reaped: no zombie left with that pid
        os.waitpid(pid, os.WNOHANG)


def test_a_run_with_plots_leaves_no_child_and_no_part_file(native_dir, tmp_path):
    r = simulate("default", out=tmp_path, fmu_dir=native_dir, stop_time=5.0)
    assert r.status == "ok" and (tmp_path / "plots.html").is_file()
    assert {"glide_angle", "pitch", "tail_angle", "speed", "depth", "page"} <= set(r.files)
    assert multiprocessing.active_children() == []
    assert not list(tmp_path.glob("*.part"))


def _partner_of(pid: int, timeout: float = 20.0) -> int:
    """The drawing process's partner (its one child), once forked."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        children = (Path(f"/proc/{pid}/task/{pid}/children").read_text()).split()
        if children:
            return int(children[0])
        time.sleep(0.02)
    raise AssertionError(f"the drawing process {pid} forked no partner in {timeout} s")


def _dead(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in "ZX"
    except FileNotFoundError:
        return True


def test_the_partner_draws_its_share_and_is_reaped(result, tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    drawing.draw_plots(result, here)  # in this process, alone
    drawer = drawing.start_drawer()
    partner = _partner_of(drawer._process.pid)
    child = drawer._process.pid
    drawer.draw(result, there)
    assert _files(here) == _files(there)
    assert _dead(partner) and _dead(child)
    from glider_cosim.figures.plots import PLOTS

    names = [name for name, _, _ in PLOTS]
    mine, theirs = drawing.shares()  # every plot once, the cost evenly split, the page theirs
    assert sorted(mine + theirs) == sorted(names) and not set(mine) & set(theirs)
    assert (mine, theirs) == (("pitch", "tail_angle", "depth"), ("glide_angle", "speed"))
    cost = [sum(drawing.COST.get(n, 1.0) for n in share) for share in (mine, theirs + ("page",))]
    assert cost == [5.0, 4.0]


def test_a_failure_in_the_partners_share_is_one_plot_error(result, tmp_path):
    assert "speed" in drawing.shares()[1]
    (tmp_path / "speed.png.part").mkdir()  # the partner cannot write speed.png
    drawer = drawing.start_drawer()
    _partner_of(drawer._process.pid)
    with pytest.raises(drawing.PlotError) as err:
        drawer.draw(result, tmp_path)
    text = str(err.value)
    assert text.startswith("PNG plots not written (") and "speed.png.part" in text
    assert "\n" not in text
    assert not (tmp_path / "speed.png").exists()
    assert multiprocessing.active_children() == []


def test_the_partner_dies_with_the_drawing_process():
    import time

    drawer = drawing.start_drawer()
    partner = _partner_of(drawer._process.pid)
    os.kill(drawer._process.pid, signal.SIGKILL)
    drawer._process.join(5)
    deadline = time.monotonic() + 10
    while not _dead(partner) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert _dead(partner)
    drawer.close()


@pytest.mark.requires_tool("pngcheck")
def test_pngcheck_finds_the_runs_pngs_valid(result, tmp_path):
    """glider-cosim writes its PNGs itself (``raster.png_bytes``): a PNG checker we did
    not write reads every chunk, its CRC and the image data."""
    import subprocess

    files = drawing.draw_plots(result, tmp_path)
    pngs = [str(p) for p in files.values() if p.suffix == ".png"]
    assert len(pngs) == 5
    done = subprocess.run(["pngcheck", "-v", *pngs], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count("No errors detected") == 5
    assert done.stdout.count("keyword: glider-cosim:settings") == 5
