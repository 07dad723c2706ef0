"""A run's plots drawn off the critical path (issue 31 point 2, ``runner/drawing.py``):
the forked drawing process writes the same files as drawing in the process, a failure
there is a one-line ``PlotError`` with the run's results kept, a killed child is named,
and no child, half-written file or zombie is left behind."""

from __future__ import annotations

import multiprocessing
import os
import signal
from pathlib import Path

import pytest

from glider_cosim.runner import drawing, simulate

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


def test_figures_made_ahead_draw_the_same_files(result, tmp_path):
    """The blank figures the drawing process makes while the run runs are the ones the
    plots take, and the files are byte for byte those of figures made on demand."""
    from glider_cosim.runner import plots

    fresh, ahead = tmp_path / "fresh", tmp_path / "ahead"
    fresh.mkdir()
    ahead.mkdir()
    drawing.draw_plots(result, fresh)
    for kind in plots.FIGURE_KIND.values():
        plots.make_ahead(kind)
    made = [fig for kind in ("single", "pair") for fig, _ in plots._AHEAD[kind]]
    assert len(made) == len(plots.PLOTS)
    kept: list = []
    built = plots.write_plots(drawing.PlotData.of(result), ahead, keep=kept)
    try:
        assert plots._AHEAD == {"single": [], "pair": []}  # every one taken
        assert set(map(id, kept)) == set(map(id, made))
    finally:
        plots.discard_ahead()
        for fig in kept:
            plots.plt.close(fig)
    mine = _files(fresh)
    for name, path in built.items():
        assert path.read_bytes() == mine[path.name], name


def test_the_child_draws_on_figures_made_ahead(result, tmp_path):
    """A child given time to make its blank figures writes what the process writes."""
    import time

    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    drawing.draw_plots(result, here)
    drawer = drawing.start_drawer()
    time.sleep(3.0)  # matplotlib imported, the fonts and the blank figures made
    drawer.draw(result, there)
    assert _files(here) == _files(there)
    assert multiprocessing.active_children() == []


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
    from glider_cosim.runner.plots import FIGURE_KIND

    mine, theirs = drawing.shares()  # every plot once, the panels about evenly split
    assert sorted(mine + theirs) == sorted(FIGURE_KIND) and not set(mine) & set(theirs)
    panels = [sum(2 if FIGURE_KIND[n] == "pair" else 1 for n in share) for share in (mine, theirs)]
    assert panels == [4, 3]


def test_a_failure_in_the_partners_share_is_one_plot_error(result, tmp_path):
    assert "tail_angle" in drawing.shares()[1]
    (tmp_path / "tail_angle.png.part").mkdir()  # the partner cannot write tail_angle.png
    drawer = drawing.start_drawer()
    _partner_of(drawer._process.pid)
    with pytest.raises(drawing.PlotError) as err:
        drawer.draw(result, tmp_path)
    text = str(err.value)
    assert text.startswith("PNG plots not written (") and "tail_angle.png.part" in text
    assert "\n" not in text
    assert not (tmp_path / "tail_angle.png").exists()
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
