"""The native FMUs' ``sources/`` build alone, as an importer builds them, to the same bits.

For each native FMU of FMI 2.0 and 3.0:

- ``sources/`` ships no FMI header and includes only its own version's (an FMI 3 FMU's
  sources compile with only ``fmi3*.h`` on the include path, an FMI 2 FMU's with only
  ``fmi2*.h``: the header sets fmpy ships in ``fmpy/c-code``);
- built from ``sources/`` alone with an importer's flags (``-O3 -march=native -DNDEBUG
  -Wall -Wextra -Wpedantic``, as fmpy's CMake project has them, plus ``-march=native``) by
  gcc in ``-std=c99``, gcc in its default GNU mode, clang, and gcc with
  ``-ffp-contract=fast`` (the sources' pragma, not the compiler's mode, keeps contraction
  off), each build is warning-free, holds no fused multiply-add instruction, and, put in
  place of the shipped binary, gives our master's default and noise scenarios bit for bit
  (every column of 3001 rows, the three FMUs together);
- ``buildDescription.xml`` says ``compilerOptions="-ffp-contract=off"``.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from system_tools import require_tool

from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration

NAMES = ("GliderPlant", "GliderObserver", "GliderController")
HEADERS = Path(fmpy.__file__).parent / "c-code"
#: what an importer passes: fmpy's CMake project (-O3 -DNDEBUG, -Wall -Wextra -Wpedantic
#: for gcc and clang), and -march=native
IMPORTER_FLAGS = ["-O3", "-march=native", "-DNDEBUG", "-Wall", "-Wextra", "-Wpedantic",
                  "-fPIC", "-shared"]  # fmt: skip
COMPILERS = {
    "gcc-c99": ["gcc", "-std=c99"],
    "gcc-gnu": ["gcc"],
    "clang": ["clang"],
    "gcc-contract-fast": ["gcc", "-ffp-contract=fast"],
}
BINARY_DIR = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}
#: x86 FMA instructions (FMA3 and FMA4)
FMA = re.compile(r"\bv?f(n?m(add|sub)|maddsub|msubadd)\w*\b")


def cpu_has_fma() -> bool:
    try:
        return " fma " in Path("/proc/cpuinfo").read_text().replace("\n", " ")
    except OSError:
        return False


@pytest.fixture(scope="module")
def shipped(native_dir, fmi3_dirs) -> dict[int, Path]:
    """FMI version -> the folder of the shipped native FMUs."""
    return {2: native_dir, 3: fmi3_dirs["native"]}


@pytest.fixture(scope="module")
def header_sets(tmp_path_factory) -> dict[int, Path]:
    """FMI version -> a folder holding only that version's headers from fmpy."""
    out = {}
    for fmi in (2, 3):
        d = tmp_path_factory.mktemp(f"fmi{fmi}_headers")
        for h in HEADERS.glob(f"fmi{fmi}*.h"):
            shutil.copyfile(h, d / h.name)
        assert sorted(p.name for p in d.iterdir()), f"fmpy ships no fmi{fmi} headers"
        out[fmi] = d
    return out


def sources_of(fmu: Path, where: Path) -> Path:
    with zipfile.ZipFile(fmu) as z:
        for name in z.namelist():
            if name.startswith("sources/"):
                z.extract(name, where)
    return where / "sources"


def build(compiler: list[str], src: Path, headers: Path, out: Path) -> str:
    """Compile ``src/*.c`` with only ``headers`` on the include path; what it printed."""
    require_tool(compiler[0])
    cmd = [*compiler, *IMPORTER_FLAGS, f"-I{headers}", *map(str, sorted(src.glob("*.c"))),
           "-o", str(out), "-lm"]  # fmt: skip
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, f"{' '.join(cmd)}\n{p.stderr}"
    return (p.stdout + p.stderr).strip()


@pytest.fixture(scope="module")
def rebuilt(shipped, header_sets, tmp_path_factory) -> dict:
    """(FMI version, compiler) -> (folder of the FMUs with the rebuilt binaries, what the
    compiler printed per FMU, FMA instructions per FMU)."""
    result = {}
    for fmi, folder in shipped.items():
        for key, compiler in COMPILERS.items():
            out = tmp_path_factory.mktemp(f"rebuilt{fmi}_{key}")
            printed, fma = {}, {}
            for name in NAMES:
                fmu = folder / f"{name}.fmu"
                src = sources_of(fmu, out / f"{name}_src")
                so = out / f"{name}.so"
                printed[name] = build(compiler, src, header_sets[fmi], so)
                require_tool("objdump", install="apt-get install binutils")
                dis = subprocess.run(["objdump", "-d", str(so)], capture_output=True,
                                     text=True, check=True).stdout  # fmt: skip
                fma[name] = len(FMA.findall(dis))
                with zipfile.ZipFile(fmu) as z, zipfile.ZipFile(out / fmu.name, "w") as w:
                    for item in z.infolist():
                        if item.filename == f"{BINARY_DIR[fmi]}/{name}.so":
                            w.write(so, item.filename)
                        else:
                            w.writestr(item, z.read(item))
            result[fmi, key] = (out, printed, fma)
    return result


@pytest.mark.parametrize("fmi", [2, 3])
def test_sources_ship_no_fmi_header_and_include_only_their_version(shipped, fmi, tmp_path):
    other = 5 - fmi
    for name in NAMES:
        src = sources_of(shipped[fmi] / f"{name}.fmu", tmp_path / name)
        files = sorted(p.name for p in src.iterdir())
        assert not [f for f in files if re.fullmatch(r"fmi\d\w*\.h", f)], files  # no FMI header
        text = "".join(p.read_text() for p in src.glob("*.[ch]"))
        includes = set(re.findall(r'#include\s*[<"](fmi\w*)\.h', text))
        assert f"fmi{fmi}Functions" in includes, includes  # the front end takes its own
        assert not {i for i in includes if i.startswith(f"fmi{other}")}, includes


@pytest.mark.parametrize("key", list(COMPILERS))
@pytest.mark.parametrize("fmi", [2, 3])
def test_sources_build_alone_warning_free_without_fma(rebuilt, fmi, key):
    _, printed, fma = rebuilt[fmi, key]
    print(f"FMI {fmi} {key}: FMA instructions {fma} (CPU has FMA: {cpu_has_fma()})")
    assert printed == {n: "" for n in NAMES}
    assert fma == {n: 0 for n in NAMES}


@pytest.mark.parametrize("scenario", ["default", "fig5-6-observer-noise"])
@pytest.mark.parametrize("key", list(COMPILERS))
@pytest.mark.parametrize("fmi", [2, 3])
def test_rebuilt_from_sources_equals_shipped_bit_for_bit(shipped, rebuilt, fmi, key, scenario):
    a = simulate(scenario, None, fmu_dir=shipped[fmi], build=False)
    b = simulate(scenario, None, fmu_dir=rebuilt[fmi, key][0], build=False)
    assert a.status == b.status == "ok"
    assert a.columns == b.columns and a.data.shape == b.data.shape == (3001, len(a.columns))
    diff = np.abs(a.data - b.data).max()
    worst = a.columns[int(np.argmax(np.abs(a.data - b.data).max(axis=0)))] if diff else "-"
    print(f"FMI {fmi} {key} {scenario}: max |rebuilt - shipped| = {diff:.3g} (column {worst})")
    assert np.array_equal(a.data, b.data)


@pytest.mark.parametrize("fmi", [2, 3])
def test_build_description_turns_contraction_off(shipped, fmi):
    from xml.etree import ElementTree as ET

    for name in NAMES:
        with zipfile.ZipFile(shipped[fmi] / f"{name}.fmu") as z:
            root = ET.fromstring(z.read("sources/buildDescription.xml"))
        sets = root.findall("BuildConfiguration/SourceFileSet")
        assert sets and all(s.get("compilerOptions") == "-ffp-contract=off" for s in sets)
