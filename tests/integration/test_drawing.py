"""A run's plots drawn off the critical path (issue 31 point 2, ``runner/drawing.py``):
the forked drawing process writes the same files as drawing in the process, a failure
there is a one-line ``PlotError`` with the run's results kept, a killed child is named,
and no child, half-written file or zombie is left behind."""

from __future__ import annotations

import multiprocessing
import os
import signal

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
