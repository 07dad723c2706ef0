"""Cold builds of the native FMUs (issue 31): a run builds this machine's binary alone, in
a cache folder of its own that nothing hands on; the C files are compiled once per
platform to objects kept in the cache and reused; an edit recompiles what it touched."""

from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

from glider_cosim.cli.main import main
from glider_cosim.fmus import folders, native, objects
from glider_cosim.fmus.files import package_version
from glider_cosim.runner import simulate
from glider_fmi import toolchain

pytestmark = pytest.mark.integration

NAMES = ("GliderPlant", "GliderObserver", "GliderController")
HOST = toolchain.host_platform()


def binaries(fmu: Path) -> list[str]:
    with zipfile.ZipFile(fmu) as z:
        return sorted(n for n in z.namelist() if n.startswith("binaries/"))


def test_a_run_builds_this_machines_binary_alone_and_an_export_every_platforms(
    tmp_path, monkeypatch, capsys, native_dir
):
    """Into an empty cache: ``run --flavor native`` builds a host-only set in
    ``native-only-<platform>-<key>`` (9 objects compiled, 3 libraries linked); an export
    afterwards gets every platform's binary (the host's objects reused), and so does a
    build; a second build compiles nothing; the next run takes the full set, bit for bit
    the session's."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(cache))
    assert main(["run", "--flavor", "native", "--no-plots", "--stop-time", "2",
                 "--out", str(tmp_path / "run")]) == 0  # fmt: skip
    assert (objects.LAST.compiled, objects.LAST.reused, objects.LAST.linked) == (9, 0, 3)
    host = folders.cache_dir("native", host_only=True)
    assert host.name.startswith(f"native-only-{HOST}-")
    entries = {p.name for p in (cache / package_version()).iterdir()}
    assert {n for n in entries if not n.startswith("fastloop-")} == {
        "native-obj",
        host.name,
        "native-src",
        "native-vars",  # the variable tables, made once (issue 48)
        "unpacked",  # the FMUs the run loaded, unpacked once (issue 48)
        "locks",  # the build lock's files (filelock), never in an FMU folder (issue 53)
    }  # no full set: nothing can take this one for it
    for name in NAMES:
        assert binaries(host / f"{name}.fmu") == [f"binaries/linux64/{name}.so"]
    assert main(["cache"]) == 0
    listing = capsys.readouterr().out
    assert f"native FMUs, FMI 2.0, {HOST} only (to run here), current sources" in listing
    assert "native objects (each C file compiled per platform)" in listing

    out = tmp_path / "loop.ssp"
    assert main(["export-ssp", str(out), "--flavor", "native"]) == 0
    assert (objects.LAST.compiled, objects.LAST.reused) == (36, 9)  # 4 more platforms
    with zipfile.ZipFile(out) as z:
        fmu = tmp_path / "plant.fmu"
        fmu.write_bytes(z.read("resources/GliderPlant.fmu"))
    assert binaries(fmu) == binaries(native_dir / "GliderPlant.fmu")
    assert len(binaries(fmu)) == 4  # linux64, aarch64-linux, win64, darwin64 (2 slices)

    assert main(["build", "--flavor", "native", "--out", str(tmp_path / "built")]) == 0
    assert (objects.LAST.compiled, objects.LAST.reused, objects.LAST.linked) == (0, 45, 15)
    for name in NAMES:
        assert binaries(tmp_path / "built" / f"{name}.fmu") == binaries(native_dir / f"{name}.fmu")

    assert folders.prepare_fmus(None, "native", host_only=True) == folders.cache_dir("native")
    a = simulate("default", None, fmu_dir=native_dir, build=False, stop_time=10.0)
    b = simulate("default", None, fmu_dir=host, build=False, stop_time=10.0)
    assert a.status == b.status == "ok"
    assert np.array_equal(a.data, b.data)


def test_a_first_run_builds_the_python_runtime_for_this_machine_alone(
    tmp_path, monkeypatch, fmu_dir
):
    """Issue 48: a first ``glider-cosim run`` (the Python flavor) into an empty cache
    compiles the FMI runtime for this machine's platform alone (zig builds the C library
    pieces of one platform, not two: about 5 s of a newcomer's first run), into a set of
    its own that nothing hands on; its results are the full set's, bit for bit."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(cache))
    assert main(["run", "--no-plots", "--stop-time", "2", "--out", str(tmp_path / "run")]) == 0
    host = folders.cache_dir("python", host_only=True)
    assert host.name.startswith(f"python-only-{HOST}-")
    assert not folders.cache_dir("python").exists()  # no full set to take it for
    for name in NAMES:
        assert binaries(host / f"{name}.fmu") == [f"binaries/linux64/{name}.so"]
        assert len(binaries(fmu_dir / f"{name}.fmu")) == 2  # the full set: aarch64 too
    a = simulate("default", None, fmu_dir=fmu_dir, build=False, stop_time=10.0)
    b = simulate("default", None, fmu_dir=host, build=False, stop_time=10.0)
    assert a.status == b.status == "ok"
    assert np.array_equal(a.data, b.data)


def test_an_edit_recompiles_only_the_files_it_touched(tmp_path, monkeypatch, native_dir):
    """The session's objects serve a host-only build (nothing compiled); a changed
    GliderPlant_vars.h recompiles plant_fmu.c alone, the one file that includes it."""
    native.build_native(tmp_path / "a", host_only=True)
    assert (objects.LAST.compiled, objects.LAST.reused) == (0, 9)
    real = native.vars_header

    def edited(c: native.NativeComponent) -> str:
        return real(c) + ("/* edited */\n" if c.name == "GliderPlant" else "")

    monkeypatch.setattr(native, "vars_header", edited)
    native.build_native(tmp_path / "b", host_only=True)
    assert (objects.LAST.compiled, objects.LAST.reused) == (1, 8)
    assert native.built_platforms(tmp_path / "b" / "GliderPlant.fmu") == {HOST}


def test_a_warning_fails_the_build_and_keeps_no_object(tmp_path, monkeypatch):
    """-Wall -Wextra on every compile: a file that warns fails with its message, and no
    object of it is kept for the next build to reuse."""
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    src = tmp_path / "src" / "warns.c"
    src.parent.mkdir()
    src.write_text("int f(int x) { int unused; return x; }\n")
    chain = toolchain.select()
    target = objects.Target(HOST, toolchain.PLATFORMS[HOST], chain.for_platform(HOST))
    with pytest.raises(toolchain.ToolchainError, match=rf"warns.c \({HOST}\): not warning-free: "):
        objects.build_binaries({"W": [src]}, [target], native.CFLAGS, tmp_path / "stage")
    assert not [p for p in (tmp_path / "cache").rglob("*") if p.is_file()]


def _runtime_files(log: str, own: str) -> set[str]:
    """The files of zig's cache in the lld-link line ``log`` shows (ZIG_VERBOSE_LINK) but
    the object of the source ``own`` compiled: the C runtime the link takes."""
    line = next(x for x in log.splitlines() if x.startswith("lld-link"))
    cache = str(objects.zig_cache())
    return {a for a in line.split() if a.startswith(cache) and Path(a).name != f"{own}.obj"}


def test_the_windows_runtime_built_ahead_is_the_one_the_links_use(
    tmp_path, monkeypatch, native_dir
):
    """zig's C runtime for Windows built ahead (``objects.RuntimeWarmer``: ``zig
    build-lib`` on every core) is cached under the keys of the links' ``zig cc``: in zig's
    cache, where the session's build linked the Windows DLLs, it finds every piece the
    links used (dllcrt2.obj, libmingw32.lib, zigc.lib, compiler_rt.lib, the import
    libraries) and builds none anew."""
    key = "x86_64-windows"
    zig = toolchain.select().for_platform(key)
    assert zig is not None and zig.is_zig
    target = objects.Target(key, toolchain.PLATFORMS[key], zig)
    held = sorted(objects.zig_cache().glob("o/*/libmingw32.lib"))
    assert held  # the session's native build linked for Windows
    monkeypatch.setenv("ZIG_VERBOSE_LINK", "1")
    src = tmp_path / "f.c"
    src.write_text("int f(void) { return 1; }\n")
    link = [*zig.argv(target.platform), *objects.link_flags(target, native.CFLAGS), str(src),
            "-o", str(tmp_path / "f.dll")]  # fmt: skip
    linked = subprocess.run(link, capture_output=True, text=True, timeout=600, check=True)
    warmer = objects.RuntimeWarmer(target, native.CFLAGS, tmp_path / "warm")
    assert warmer.started
    warmer.wait()
    assert warmer.process.returncode == 0
    ahead = _runtime_files((tmp_path / "warm" / "zig.log").read_text(), "glider_runtime")
    assert {Path(f).name for f in ahead} >= {"dllcrt2.obj", "libmingw32.lib", "kernel32.lib"}
    assert ahead == _runtime_files(linked.stderr, "f")
    assert sorted(objects.zig_cache().glob("o/*/libmingw32.lib")) == held
