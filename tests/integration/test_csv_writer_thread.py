"""The CSV recorder's C writer thread (cosim/master/csvwriter.c), driven from C by
csvwriter_harness.c (faster than the thread: the caller formats blocks for it, as a run
does when the queue is full and at close): the file holds every block handed over, in
order, each value as Python's repr; a file that cannot be written is reported by errno; no data race
(ThreadSanitizer), no memory error or leak (ASan and UBSan, valgrind memcheck); the
sources compile warning-free with -Wall -Wextra, the Windows stub with mingw-w64 too."""

from __future__ import annotations

import errno
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from system_tools import require_tool

from glider_cosim.master import fastloop
from glider_cosim.runner.recorders import repr_row

pytestmark = pytest.mark.integration
HARNESS = Path(__file__).with_name("csvwriter_harness.c")
SOURCES = [str(p) for p in fastloop.SOURCES]
WARNINGS = ["-Wall", "-Wextra", "-Werror"]


def build(tmp_path: Path, name: str, flags: list[str]) -> Path:
    out = tmp_path / name
    require_tool("gcc")
    subprocess.run(["gcc", "-std=gnu11", "-g", "-O1", *WARNINGS, *flags, str(HARNESS), *SOURCES,
                    "-pthread", "-lm", "-o", str(out)], check=True)  # fmt: skip
    return out


def expected_text(raw: Path, ncol: int) -> str:
    values = np.fromfile(raw, dtype=np.float64).reshape(-1, ncol)
    return "t,c1,c2\n" + "".join(repr_row(r) for r in values.tolist())


@pytest.fixture(scope="module")
def tsan(tmp_path_factory) -> Path:
    return build(tmp_path_factory.mktemp("tsan"), "harness_tsan", ["-fsanitize=thread"])


@pytest.fixture(scope="module")
def asan(tmp_path_factory) -> Path:
    return build(tmp_path_factory.mktemp("asan"), "harness_asan",
                 ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"])  # fmt: skip


@pytest.mark.parametrize("nslots", [1, 2, 4])
def test_every_block_is_written_in_order_as_repr_without_a_data_race(tsan, tmp_path, nslots):
    csv, raw = tmp_path / "rows.csv", tmp_path / "rows.bin"
    env = {**os.environ, "TSAN_OPTIONS": "halt_on_error=1 exitcode=66"}
    p = subprocess.run([str(tsan), "rows", str(csv), str(raw), "3", str(nslots), "200",
                        str(nslots)],
                       capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert "ThreadSanitizer" not in p.stderr
    assert csv.read_text() == expected_text(raw, 3)


def test_the_writer_is_clean_under_asan_and_ubsan(asan, tmp_path):
    csv, raw = tmp_path / "rows.csv", tmp_path / "rows.bin"
    p = subprocess.run([str(asan), "rows", str(csv), str(raw), "17", "4", "60", "7"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert csv.read_text() == expected_text(raw, 17)
    missing = tmp_path / "no such folder" / "x.csv"
    p = subprocess.run([str(asan), "fail", str(missing), "50"], capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert (p.returncode, p.stdout) == (0, f"put {errno.ENOENT} close {errno.ENOENT}\n"), p.stderr


@pytest.mark.parametrize("sanitizer", ["asan", "tsan"])
def test_a_writer_closed_before_its_start_leaves_the_file_it_made_empty(
    sanitizer, request, tmp_path
):
    # made when the recorder is made, before the run knows its columns: a put before the
    # start is refused (EINVAL), close ends the thread cleanly (the recorder removes it)
    exe = request.getfixturevalue(sanitizer)
    csv = tmp_path / "idle.csv"
    env = {**os.environ, "TSAN_OPTIONS": "halt_on_error=1 exitcode=66"}
    p = subprocess.run([str(exe), "idle", str(csv)], capture_output=True, text=True, env=env,
                       timeout=300)  # fmt: skip
    assert (p.returncode, p.stdout) == (0, f"put {errno.EINVAL} close 0\n"), p.stderr
    assert "Sanitizer" not in p.stderr
    assert csv.read_bytes() == b""


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_disk_is_reported_by_the_next_put_and_by_close(asan):
    # the header's write fails at once; the puts that follow return ENOSPC (the rows are
    # dropped, not waited for); close returns it too
    p = subprocess.run([str(asan), "fail", "/dev/full", "100000"], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert (p.returncode, p.stdout) == (0, f"put {errno.ENOSPC} close {errno.ENOSPC}\n"), p.stderr


def test_the_writer_is_clean_under_valgrind(tmp_path):
    require_tool("valgrind")
    exe = build(tmp_path, "harness", [])
    csv, raw = tmp_path / "rows.csv", tmp_path / "rows.bin"
    p = subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full",
                        "--errors-for-leak-kinds=definite,indirect", "--track-fds=yes", str(exe),
                        "rows", str(csv), str(raw), "5", "2", "40", "11"],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert p.returncode == 0, p.stderr[-3000:]
    assert "definitely lost" not in p.stderr or "definitely lost: 0 bytes" in p.stderr
    assert "FILE DESCRIPTORS: 3 open (3 std) at exit" in p.stderr, p.stderr[-3000:]  # closed
    assert csv.read_text() == expected_text(raw, 5)


def test_the_windows_stub_compiles_warning_free(tmp_path):
    cc = require_tool("x86_64-w64-mingw32-gcc", install="apt-get install gcc-mingw-w64-x86-64")
    source = fastloop.SOURCE.with_name("csvwriter.c")
    obj = tmp_path / "csvwriter.o"
    subprocess.run([cc, "-std=gnu11", "-O2", *WARNINGS, "-c", str(source), "-I",
                    str(source.parent), "-o", str(obj)], check=True)  # fmt: skip
    require_tool("x86_64-w64-mingw32-nm", install="apt-get install binutils-mingw-w64-x86-64")
    symbols = subprocess.run(["x86_64-w64-mingw32-nm", str(obj)],
                             capture_output=True, text=True, check=True).stdout  # fmt: skip
    assert all(f" T glider_csv_{f}" in symbols for f in ("open", "start", "put", "close")), symbols
