"""The native build's objects (keys, includes, link flags) and which FMU set a command
gets from the cache (host-only for runs, every platform's for exports), without a
compiler."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

from glider_cosim.cli.commands import runs_here
from glider_cosim.fmus import cache, folders, objects
from glider_fmi import toolchain

ZIG = toolchain.Compiler("zig", ("zig", "cc"), frozenset(toolchain.PLATFORMS), "ziglang 0.0")
GCC = toolchain.Compiler("gcc", ("/usr/bin/gcc",), frozenset({"x86_64-linux"}), "gcc 13")
LINUX = objects.Target("x86_64-linux", toolchain.PLATFORMS["x86_64-linux"], ZIG)
FLAGS = ("-O2", "-Wall")


@pytest.fixture
def src(tmp_path) -> Path:
    (tmp_path / "a.h").write_text('#include "b.h"\n#include <math.h>\n')
    (tmp_path / "b.h").write_text("int b;\n")
    (tmp_path / "other.h").write_text("int o;\n")
    c = tmp_path / "a.c"
    c.write_text('#include "a.h"\n  #  include "missing.h"\nint f(void) { return b; }\n')
    return c


def test_local_includes_are_followed_into_headers(src):
    assert [p.name for p in objects.local_includes(src)] == ["a.h", "b.h"]


def test_an_object_key_follows_the_file_its_headers_the_flags_and_the_compiler(src):
    key = objects.object_key(LINUX, FLAGS, src, "fmi")
    (src.parent / "other.h").write_text("int changed;\n")  # included by nothing
    assert objects.object_key(LINUX, FLAGS, src, "fmi") == key
    changed = []
    (src.parent / "b.h").write_text("int b2;\n")  # included by a.h
    changed.append(objects.object_key(LINUX, FLAGS, src, "fmi"))
    src.write_text(src.read_text() + "\n")
    changed.append(objects.object_key(LINUX, FLAGS, src, "fmi"))
    changed.append(objects.object_key(LINUX, ("-O3", "-Wall"), src, "fmi"))
    changed.append(objects.object_key(LINUX, FLAGS, src, "other fmi headers"))
    arm = objects.Target("aarch64-linux", toolchain.PLATFORMS["aarch64-linux"], ZIG)
    changed.append(objects.object_key(arm, FLAGS, src, "fmi"))
    gcc = objects.Target("x86_64-linux", toolchain.PLATFORMS["x86_64-linux"], GCC)
    changed.append(objects.object_key(gcc, FLAGS, src, "fmi"))
    assert len({key, *changed}) == 1 + len(changed)


def test_zig_links_without_compiler_rt_but_on_windows():
    flags = {k: objects.link_flags(objects.Target(k, p, ZIG), ("-std=c99", "-O2"))
             for k, p in toolchain.PLATFORMS.items()}  # fmt: skip
    assert flags["x86_64-linux"] == ["-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-flto",
                                     "-rtlib=none"]  # fmt: skip
    assert flags["aarch64-darwin"][-1] == "-rtlib=none"
    assert flags["x86_64-windows"] == ["-O2", "-shared"]
    gcc = objects.Target("x86_64-linux", toolchain.PLATFORMS["x86_64-linux"], GCC)
    assert "-rtlib=none" not in objects.link_flags(gcc, FLAGS)
    assert objects.compile_flags(LINUX, FLAGS) == ["-O2", "-Wall", "-fPIC", "-fvisibility=hidden",
                                                   "-flto"]  # fmt: skip


def test_link_time_optimisation_is_zigs_on_linux_only_on_compile_and_link():
    for key, platform in toolchain.PLATFORMS.items():
        t = objects.Target(key, platform, ZIG)
        lto = platform.os == "linux"
        assert ("-flto" in objects.compile_flags(t, FLAGS)) is lto, key
        assert ("-flto" in objects.link_flags(t, FLAGS)) is lto, key
    gcc = objects.Target("x86_64-linux", toolchain.PLATFORMS["x86_64-linux"], GCC)
    assert "-flto" not in objects.compile_flags(gcc, FLAGS) + objects.link_flags(gcc, FLAGS)
    # the FMUs' staleness hashes follow the policy: a compiler with it differs from one without
    zig = toolchain.Toolchain((ZIG,), "zig").fingerprint()
    assert "lto ['aarch64-linux', 'x86_64-linux']" in zig
    assert "lto []" in toolchain.Toolchain((GCC,), "gcc").fingerprint()


def test_the_cache_lists_a_host_only_set_and_the_objects(tmp_path, monkeypatch):
    for name in ("native-only-x86_64-linux-0123456789abcdef", "native-fmi3-only-aarch64-linux-0123",
                 "native-obj"):  # fmt: skip
        (tmp_path / "0.0.1" / name).mkdir(parents=True)
    what = {e.name: e.what for e in cache.cache_entries(tmp_path)}
    assert what == {
        "native-fmi3-only-aarch64-linux-0123": "native FMUs, FMI 3.0, aarch64-linux only (to run "
        "here), other version",
        "native-obj": "native objects (each C file compiled per platform)",
        "native-only-x86_64-linux-0123456789abcdef": "native FMUs, FMI 2.0, x86_64-linux only "
        "(to run here), other version",
    }


@pytest.mark.parametrize("flavor", ["native", "python"])
@pytest.mark.parametrize(
    ("host_only", "full_current", "expected"),
    [(True, False, "host"), (True, True, "full"), (False, False, "full"), (False, True, "full")],
)
def test_a_run_takes_the_full_set_if_current_else_a_host_only_one(
    tmp_path, monkeypatch, flavor, host_only, full_current, expected
):
    """A run (``host_only``) takes the cache's full set if it is current, else a set for
    this machine alone in a folder of its own: native FMUs and, since issue 48, the Python
    flavor's FMI 2.0 ones (whose runtime is then built for one platform, not two)."""
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    monkeypatch.setattr(folders, "sources_key", lambda flavor="python": "k")
    monkeypatch.setattr(folders, "_current", lambda folder, flavor, fmi: full_current)
    calls = []
    monkeypatch.setattr(folders, "build_all", lambda out, **kw: calls.append((Path(out), kw)))
    got = folders.prepare_fmus(None, flavor, host_only=host_only)
    want = folders.cache_dir(flavor, host_only=expected == "host")
    assert got == want
    assert got.name == (
        f"{flavor}-k" if expected == "full" else f"{flavor}-only-{toolchain.host_platform()}-k"
    )
    assert calls == [(want, {"only_stale": True, "flavor": flavor, "fmi": 2,
                             "host_only": host_only})]  # fmt: skip
    # the Python flavor's FMI 3.0 set is always the full one
    assert folders.prepare_fmus(None, "python", 3, host_only=host_only) == folders.cache_dir(
        "python", 3
    )


def test_runs_run_here_and_exports_hand_on():
    def ns(command: str, **kw: object) -> argparse.Namespace:
        return argparse.Namespace(command=command, **kw)

    assert runs_here(ns("run"))
    assert runs_here(ns("sweep", scheduler=None))
    assert not runs_here(ns("sweep", scheduler="tcp://elsewhere:8786"))  # workers elsewhere
    assert runs_here(ns("report", scheduler=None))
    assert not runs_here(ns("export-ssp"))
    assert not runs_here(ns("export-fmu"))


def test_a_host_helper_built_as_the_fmus_gets_their_link_time_optimisation():
    key = toolchain.host_platform()
    if key is None:
        pytest.skip("this machine is none of our platforms")
    chain = toolchain.Toolchain((ZIG,), "zig")
    lto = toolchain.PLATFORMS[key].os == "linux"
    assert ("-flto" in toolchain.host_command(chain, lto=True)) is lto
    assert "-flto" not in toolchain.host_command(chain)


WINDOWS = objects.Target("x86_64-windows", toolchain.PLATFORMS["x86_64-windows"], ZIG)


def test_zigs_windows_runtime_is_built_ahead_by_zig_build_lib_on_every_core(tmp_path):
    """zig's C runtime for Windows is built ahead with ``zig build-lib`` of an empty
    library, the link's target and optimisation mode (``-O2``: ReleaseFast) and four jobs
    more than the cores (zig's runtime build holds that many waiting); nothing for the
    other platforms, other compilers or an unknown level."""
    cmd = objects.RuntimeWarmer.command(WINDOWS, ("-std=c99", "-O2"), tmp_path)
    assert cmd is not None
    assert cmd[:8] == ["zig", "build-lib", "-target", "x86_64-windows-gnu", "-O", "ReleaseFast",
                       "-dynamic", "-lc"]  # fmt: skip
    assert cmd[8] == f"-j{(os.cpu_count() or 1) + 4}"
    assert cmd[9:] == [str(tmp_path / "glider_runtime.c"),
                       f"-femit-bin={tmp_path / 'glider_runtime.dll'}",
                       "--cache-dir", str(tmp_path / "zig-local")]  # fmt: skip
    assert objects.RuntimeWarmer.command(WINDOWS, ("-Os",), tmp_path)[5] == "ReleaseSmall"
    assert objects.RuntimeWarmer.command(WINDOWS, ("-O1",), tmp_path) is None  # unknown
    assert objects.RuntimeWarmer.command(LINUX, ("-O2",), tmp_path) is None
    mingw = toolchain.Compiler("x86_64-w64-mingw32-gcc", ("/usr/bin/x86_64-w64-mingw32-gcc",),
                               frozenset({"x86_64-windows"}), "gcc 13")  # fmt: skip
    own = objects.Target("x86_64-windows", toolchain.PLATFORMS["x86_64-windows"], mingw)
    assert objects.RuntimeWarmer.command(own, ("-O2",), tmp_path) is None


class FakeWarmer:
    def __init__(self, events: list[str]):
        self.events = events

    def wait(self) -> None:
        self.events.append("wait")

    def stop(self) -> None:
        self.events.append("stop")


class FakeWindows(FakeWarmer):
    target = WINDOWS


def _fake_build(monkeypatch, tmp_path, events, compile_job):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))

    def start(targets, cflags, stage):
        events.append("start")
        return {"x86_64-windows": FakeWarmer(events)}

    monkeypatch.setattr(objects, "start_runtimes", start)
    monkeypatch.setattr(objects, "_compile", compile_job)
    monkeypatch.setattr(objects, "_link", lambda t, f, objs, out: events.append(f"link {t.key}"))
    src = tmp_path / "a.c"
    src.write_text("int a;\n")
    return lambda: objects.build_binaries({"A": [src], "B": [src]}, [WINDOWS, LINUX], FLAGS,
                                          tmp_path / "stage", workers=1)  # fmt: skip


def test_the_windows_runtime_starts_before_the_compiles_and_its_links_come_last(
    tmp_path, monkeypatch
):
    """The runtime is started before the first compile; the Windows links come after
    every other link, each once the runtime is built, whatever the order of the targets;
    the built libraries keep the targets' order."""
    events: list[str] = []
    build = _fake_build(monkeypatch, tmp_path, events,
                        lambda t, f, src, obj: events.append(f"compile {t.key}"))  # fmt: skip
    built = build()
    assert events == ["start", "compile x86_64-windows", "compile x86_64-linux",
                      "link x86_64-linux", "link x86_64-linux",
                      "wait", "link x86_64-windows", "wait", "link x86_64-windows",
                      "stop"]  # fmt: skip
    assert list(built["A"]) == ["x86_64-windows", "x86_64-linux"]


def test_a_failed_compile_ends_the_runtime_built_ahead(tmp_path, monkeypatch):
    """A compile that fails ends the runtime's build (no zig left running for a minute)
    and links nothing."""
    events: list[str] = []

    def fail(t, f, src, obj):
        events.append(f"compile {t.key}")
        raise toolchain.ToolchainError(f"a.c ({t.key}): not warning-free: x")

    build = _fake_build(monkeypatch, tmp_path, events, fail)
    with pytest.raises(toolchain.ToolchainError, match="not warning-free"):
        build()
    assert events[0] == "start" and events[-1] == "stop"
    assert not [e for e in events if e.startswith(("link", "wait"))]


class Lines:
    """A progress that keeps its notes and steps."""

    def __init__(self):
        self.lines: list[str] = []

    def note(self, text: str) -> None:
        self.lines.append(text)

    def step(self, label: str) -> None:
        self.lines.append(label)

    def set_total(self, total: int) -> None:
        pass


def test_the_runtime_built_ahead_is_named_before_the_first_compile(tmp_path, monkeypatch):
    """The progress names zig's runtime build as it starts, before the compiles, with its
    cache and the wait, and not again at the Windows links."""
    monkeypatch.setenv("ZIG_GLOBAL_CACHE_DIR", str(tmp_path / "zig"))
    events: list[str] = []
    _fake_build(monkeypatch, tmp_path, events, lambda t, f, src, obj: None)
    monkeypatch.setattr(
        objects, "start_runtimes", lambda *a: {"x86_64-windows": FakeWindows(events)}
    )
    progress = Lines()
    src = tmp_path / "a.c"
    objects.build_binaries({"A": [src]}, [WINDOWS, LINUX], FLAGS, tmp_path / "stage",
                           workers=1, progress=progress)  # fmt: skip
    assert progress.lines[0] == (
        f"zig builds its C runtime (mingw-w64) for x86_64-windows once into "
        f"{tmp_path / 'zig'}, beside the compiles (about 1 min)"
    )
    assert progress.lines[1] == "compiling a.c for x86_64-windows"
    assert sum("zig builds" in line for line in progress.lines) == 1 + 1  # + Linux' stubs
