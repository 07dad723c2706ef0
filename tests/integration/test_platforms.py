"""Every platform the FMUs carry, checked here without the machines themselves.

- every Linux binary (both flavors, FMI 2 and 3, x86_64 and aarch64) needs glibc 2.17 at
  most: the highest ``GLIBC_`` version its dynamic symbol table asks for;
- the aarch64 native FMUs (FMI 2's ``aarch64-linux``, FMI 3's ``aarch64-linux``) run
  under qemu-user, stepped by the C host built for aarch64, and equal x86_64 bit for bit;
- the macOS binaries, as Mach-O: FMI 2's one universal ``darwin64`` file (x86_64 and
  arm64), FMI 3's ``x86_64-darwin`` and ``aarch64-darwin``; each a dylib exporting
  exactly the FMI functions and importing only libSystem;
- every flavor and FMI version builds, and the Quick start's ``glider-cosim run`` runs,
  with cc, gcc, clang and mingw-w64 hidden (PATH, and a mount namespace over the files).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from c_host_helpers import (
    RECORD,
    STOP,
    master_jacobi_run,
    qemu_rows,
)
from elftools.elf.elffile import ELFFile
from system_tools import require_tool, tool_missing

from glider_cosim.scenarios.scenario import load_scenario
from glider_cosim.scenarios.system import system_for
from glider_fmi import macho, toolchain

pytestmark = pytest.mark.integration
NAMES = ("GliderPlant", "GliderObserver", "GliderController")
FMI3_HOST = ["-DGLIDER_HOST_FMI3"]


# ---------------------------------------------------------------- glibc 2.17
def glibc_versions(data: bytes) -> set[tuple[int, ...]]:
    """The ``GLIBC_x.y`` versions an ELF file's dynamic symbols need (``.gnu.version_r``)."""
    import io

    elf = ELFFile(io.BytesIO(data))
    needed = elf.get_section_by_name(".gnu.version_r")
    versions = set()
    if needed is not None:
        for _lib, aux in needed.iter_versions():
            for a in aux:
                if a.name.startswith("GLIBC_") and a.name[6:7].isdigit():
                    versions.add(tuple(int(x) for x in a.name[6:].split(".")))
    return versions


def linux_binaries(folder: Path) -> dict[str, bytes]:
    found = {}
    for name in NAMES:
        with zipfile.ZipFile(folder / f"{name}.fmu") as z:
            for entry in z.namelist():
                if entry.startswith("binaries/") and entry.endswith(".so"):
                    found[f"{name}:{entry}"] = z.read(entry)
    return found


def test_glibc_check_can_fail(tmp_path):
    """The reader sees a binary that needs a newer glibc: this machine's own build."""
    src = tmp_path / "x.c"
    src.write_text("#include <math.h>\ndouble f(double x) { return exp(x) + log(x); }\n")
    require_tool("gcc")
    subprocess.run(["gcc", "-O2", "-fPIC", "-shared", str(src), "-o", str(tmp_path / "x.so"),
                    "-lm"], check=True)  # fmt: skip
    assert max(glibc_versions((tmp_path / "x.so").read_bytes())) > toolchain.GLIBC_MAX


def test_every_linux_binary_needs_glibc_2_17_at_most(fmu_dir, native_dir, fmi3_dirs):
    folders = {"python": fmu_dir, "native": native_dir,
               "python fmi3": fmi3_dirs["python"], "native fmi3": fmi3_dirs["native"]}  # fmt: skip
    seen = {}
    for kind, folder in folders.items():
        for where, data in linux_binaries(folder).items():
            versions = glibc_versions(data)
            assert versions, where
            seen[f"{kind} {where}"] = max(versions)
    for where, top in seen.items():
        assert top <= toolchain.GLIBC_MAX, (where, top)
    dirs = {w.split(":")[1].rsplit("/", 1)[0] for w in seen}
    assert dirs == {"binaries/linux64", "binaries/aarch64-linux", "binaries/x86_64-linux"}
    assert len(seen) == 4 * 3 * 2  # two Linux platforms per FMU, 12 FMUs
    print("highest GLIBC_ needed:", ".".join(map(str, max(seen.values()))))


# ---------------------------------------------------------------- aarch64 under qemu
@pytest.fixture(scope="module")
def x86_rows(native_dir) -> np.ndarray:
    return master_jacobi_run(system_for(load_scenario("default"), native_dir)).array()


def test_aarch64_native_fmus_under_qemu_equal_x86_64(native_dir, x86_rows, tmp_path):
    got = qemu_rows(system_for(load_scenario("default"), native_dir), tmp_path, "host", [])
    assert got.shape == x86_rows.shape == (round(STOP / 0.02) + 1, 1 + len(RECORD))
    diff = np.abs(got - x86_rows).max()
    print(f"aarch64 (qemu) vs x86_64, FMI 2: max diff {diff:.3g}")
    assert np.array_equal(got, x86_rows)  # bit for bit


def test_aarch64_native_fmi3_fmus_under_qemu_equal_x86_64(fmi3_dirs, x86_rows, tmp_path):
    system = system_for(load_scenario("default"), fmi3_dirs["native"])
    got = qemu_rows(system, tmp_path, "host3", FMI3_HOST)
    assert got.shape == x86_rows.shape
    print(f"aarch64 (qemu) vs x86_64, FMI 3: max diff {np.abs(got - x86_rows).max():.3g}")
    assert np.array_equal(got, x86_rows)  # bit for bit


# ---------------------------------------------------------------- macOS as Mach-O
def fmi_functions(folder: Path, name: str, entry: str) -> set[str]:
    """The functions the x86_64 Linux binary exports (the FMI functions)."""
    with zipfile.ZipFile(folder / f"{name}.fmu") as z:
        import io

        elf = ELFFile(io.BytesIO(z.read(entry)))
    dynsym = elf.get_section_by_name(".dynsym")
    return {s.name for s in dynsym.iter_symbols()
            if s["st_shndx"] != "SHN_UNDEF" and s["st_info"]["bind"] == "STB_GLOBAL"}  # fmt: skip


#: what zig's Mach-O linker exports besides the code: the image's header symbols
MACHO_LINKER_SYMBOLS = {"_mh_dylib_header", "__dso_handle"}


@pytest.mark.parametrize("fmi", [2, 3])
def test_macos_binaries_are_dylibs_exporting_fmi_importing_libsystem(native_dir, fmi3_dirs, fmi):
    folder = native_dir if fmi == 2 else fmi3_dirs["native"]
    linux = "binaries/linux64" if fmi == 2 else "binaries/x86_64-linux"
    for name in NAMES:
        fmi_names = fmi_functions(folder, name, f"{linux}/{name}.so")
        assert {f"fmi{fmi}GetVersion", f"fmi{fmi}DoStep", f"fmi{fmi}FreeInstance"} <= fmi_names
        assert all(n.startswith(f"fmi{fmi}") for n in fmi_names)
        with zipfile.ZipFile(folder / f"{name}.fmu") as z:
            if fmi == 2:
                files = {"universal": z.read(f"binaries/darwin64/{name}.dylib")}
                assert macho.read(files["universal"])[0].arch == "x86_64"
                assert z.read(f"binaries/darwin64/{name}.dylib")[:4] == b"\xca\xfe\xba\xbe"
            else:
                files = {a: z.read(f"binaries/{a}-darwin/{name}.dylib")
                         for a in ("x86_64", "aarch64")}  # fmt: skip
        slices = [s for data in files.values() for s in macho.read(data)]
        assert sorted(s.arch for s in slices) == ["arm64", "x86_64"]
        for s in slices:
            assert s.filetype == macho.MH_DYLIB
            assert s.dylibs == ("/usr/lib/libSystem.B.dylib",)
            assert s.exports - MACHO_LINKER_SYMBOLS == fmi_names, name
            assert not any(u.startswith(("Py", "_Py")) for u in s.undefined)


def test_universal_file_agrees_with_llvm_lipo(native_dir, tmp_path):
    """An independent reader of our fat header: LLVM's lipo (installed with clang)."""
    lipo = shutil.which("llvm-lipo") or next(
        (str(p) for p in sorted(Path("/usr/bin").glob("llvm-lipo-*"))), None
    )
    if lipo is None:
        tool_missing("llvm-lipo is not installed (apt-get install llvm; .ci/run installs it)")
    with zipfile.ZipFile(native_dir / "GliderPlant.fmu") as z:
        (tmp_path / "p.dylib").write_bytes(z.read("binaries/darwin64/GliderPlant.dylib"))
    p = subprocess.run([lipo, "-info", str(tmp_path / "p.dylib")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split("are:")[-1].split() == ["x86_64", "arm64"]


# ---------------------------------------------------------------- no system compiler
COMPILERS = ("cc", "gcc", "clang", "c99", "tcc", "x86_64-w64-mingw32-gcc")
PREFIXES = ("gcc-", "clang-", "x86_64-linux-gnu-gcc", "x86_64-w64-mingw32-gcc",
            "aarch64-linux-gnu-gcc")  # fmt: skip


def compiler_files() -> list[str]:
    """Every system C compiler's file (resolved), to mount /dev/null over."""
    found = set()
    for folder in ("/usr/bin", "/usr/local/bin", "/bin"):
        for p in Path(folder).glob("*"):
            n = p.name
            if n in COMPILERS or n.startswith(PREFIXES):
                try:
                    found.add(str(p.resolve()))
                except OSError:
                    continue
    return sorted(f for f in found if Path(f).is_file())


def python_includes() -> list[str]:
    """The folders holding a ``Python.h``: this interpreter's and the system's."""
    import sysconfig

    found = {sysconfig.get_paths()["include"], *map(str, Path("/usr/include").glob("python3*"))}
    return sorted(f for f in found if Path(f, "Python.h").is_file())


def hidden_compilers(tmp_path: Path, commands: list[list[str]]) -> subprocess.CompletedProcess:
    """``commands`` in a shell with PATH only a folder of symlinks to python3 and sh, and
    (where ``unshare -m`` is permitted) /dev/null mounted over every compiler's file and a
    tmpfs over every folder holding ``Python.h``;
    first checking that none of cc, gcc, clang, mingw can be started."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    for tool in ("sh",):
        os.symlink(shutil.which(tool), bin_ / tool)
    os.symlink(sys.executable, bin_ / "python3")
    script = "set -e\n"
    namespace = subprocess.run(["unshare", "-m", "true"], capture_output=True).returncode == 0
    if namespace:
        script += "".join(f"mount --bind /dev/null '{f}'\n" for f in compiler_files())
        for inc in python_includes():  # and no Python headers
            script += f"mount -t tmpfs none '{inc}'\n"
        script += "".join(f"test ! -e '{i}/Python.h' || exit 92\n" for i in python_includes())
    script += f"export PATH='{bin_}'\n"
    for cc in [*COMPILERS, "/usr/bin/gcc", "/usr/bin/cc", "/usr/bin/clang"]:
        if namespace or not cc.startswith("/"):
            script += f"if {cc} --version >/dev/null 2>&1; then echo '{cc} runs' >&2; exit 90; fi\n"
    for cmd in commands:
        script += " ".join(shlex.quote(c) for c in cmd) + "\n"
    argv = ["unshare", "-m", "/bin/sh", "-c", script] if namespace else ["/bin/sh", "-c", script]
    env = {k: v for k, v in os.environ.items() if k not in ("CC", toolchain.COMPILER_ENV)}
    return subprocess.run(argv, capture_output=True, text=True, timeout=1800, env=env,
                          cwd=tmp_path)  # fmt: skip


def test_the_hidden_compiler_check_can_fail(tmp_path):
    """The same shell, told to use gcc, fails: the compilers really are out of reach."""
    probe = "import subprocess; subprocess.run(['gcc', '--version'], check=True)"
    p = hidden_compilers(tmp_path, [[sys.executable, "-c", probe]])
    assert p.returncode != 0
    assert "FileNotFoundError" in p.stderr or "No such file" in p.stderr


def test_every_build_and_the_quick_start_need_no_system_compiler(tmp_path):
    cli = [sys.executable, "-m", "glider_cosim.cli"]
    cache = tmp_path / "cache"
    # a cache of its own: sources staged anew, so zig compiles them (its C libraries of
    # each target may come from its own cache)
    env = [shutil.which("env"), f"GLIDER_COSIM_CACHE={cache}"]
    cmds = [
        [*env, *cli, "build", "--flavor", flavor, "--fmi", str(fmi), "--out",
         str(tmp_path / f"{flavor}{fmi}")]
        for flavor in ("python", "native") for fmi in (2, 3)
    ]  # fmt: skip
    cmds.append([*env, *cli, "run", "--no-plots", "--out", str(tmp_path / "run")])
    p = hidden_compilers(tmp_path, cmds)
    assert p.returncode == 0, p.stderr[-3000:]
    for flavor in ("python", "native"):
        for fmi in (2, 3):
            fmus = sorted(f.name for f in (tmp_path / f"{flavor}{fmi}").glob("*.fmu"))
            assert fmus == sorted(f"{n}.fmu" for n in NAMES), (flavor, fmi)
    with zipfile.ZipFile(tmp_path / "native2" / "GliderPlant.fmu") as z:
        bins = sorted(n for n in z.namelist() if n.startswith("binaries/"))
    assert bins == [
        "binaries/aarch64-linux/GliderPlant.so",
        "binaries/darwin64/GliderPlant.dylib",
        "binaries/linux64/GliderPlant.so",
        "binaries/win64/GliderPlant.dll",
    ]
    assert (tmp_path / "run" / "results.csv").is_file()
    assert "outcome: settled" in p.stdout
    assert list(cache.glob("*/fastloop-*/fastloop.so"))  # the master's C loop, in the cache


# ---------------------------------------------------------------- the master's C loop
def test_the_fast_loop_is_built_once_per_cache(tmp_path):
    """Two processes on one cache: the first builds the helper, the second loads the same
    file untouched; a deleted helper is built again."""
    env = {**os.environ, "GLIDER_COSIM_CACHE": str(tmp_path / "cache")}
    probe = ("import os; from glider_cosim.master import fastloop; p = fastloop.built_library(); "
             "print(p, os.stat(p).st_mtime_ns, fastloop.library() is not None)")  # fmt: skip

    def ask() -> list[str]:
        p = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                           env=env, timeout=300)  # fmt: skip
        assert p.returncode == 0, p.stderr
        return p.stdout.split()

    first, second = ask(), ask()
    assert first == second and first[2] == "True"
    lib = Path(first[0])
    assert lib.parent.parent.parent == tmp_path / "cache"
    assert [f.name for f in lib.parent.iterdir()] == ["fastloop.so"]  # no temporary left
    lib.unlink()
    third = ask()
    assert third[0] == first[0] and third[1] != first[1]
