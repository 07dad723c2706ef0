"""Issue 28 point 8: the benchmark without pyarrow, the FMU cache listing and pruning."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).parents[1] / "bench"


def _bench_module(name: str):
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    finally:
        sys.path.remove(str(BENCH))


def test_cosim_step_bench_skips_parquet_without_pyarrow(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow -> ImportError
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    bench = _bench_module("cosim_step")
    # no FMUs in tmp_path: the figure is skipped before anything is loaded
    assert bench.parquet_seconds_per_step(tmp_path / "missing", tmp_path, 1) is None
    err = capsys.readouterr().err
    assert err.strip() == (
        "note: native_parquet_us_per_macro_step skipped: pyarrow is not installed "
        "(pip install 'glider-cosim[parquet]')"
    )


def test_cosim_step_bench_keeps_parquet_with_pyarrow(monkeypatch, tmp_path):
    pytest.importorskip("pyarrow")
    bench = _bench_module("cosim_step")
    calls = []
    monkeypatch.setattr(bench, "run_seconds_per_step", lambda *a: calls.append(a) or 1e-5)
    assert bench.parquet_seconds_per_step(tmp_path, tmp_path, 2) == 1e-5
    assert len(calls) == 1


def _fake_cache(root: Path, version: str) -> None:
    """A cache with this version's set and two other versions' sets."""
    for ver, name, size in (
        (version, "python-0123456789abcdef", 3000),
        (version, "fastloop-00ff00ff00ff00ff", 500),
        ("0.0.1", "python-aaaaaaaaaaaaaaaa", 2_000_000),
        ("0.0.1", "native-fmi3-bbbbbbbbbbbbbbbb", 1500),
        ("0.0.2.dev3", "native-src", 10),
    ):
        folder = root / ver / name
        folder.mkdir(parents=True)
        (folder / "GliderPlant.fmu").write_bytes(b"x" * size)


def test_cache_lists_every_set_with_its_size(monkeypatch, tmp_path, capsys):
    from glider_cosim.cli import main
    from glider_cosim.fmus.files import package_version

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    version = package_version()
    _fake_cache(tmp_path, version)
    assert main(["cache"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{tmp_path} (glider-cosim {version}):"
    body = [" ".join(line.split()) for line in lines[1:-1]]
    assert body == sorted(body, key=lambda b: b.split()[0])
    assert "0.0.1/python-aaaaaaaaaaaaaaaa 2.0 MB python FMUs, FMI 2.0, other version" in body
    assert "0.0.1/native-fmi3-bbbbbbbbbbbbbbbb 1.5 kB native FMUs, FMI 3.0, other version" in body
    assert "0.0.2.dev3/native-src 10 B native sources' builds" in body
    assert f"{version}/python-0123456789abcdef 3.0 kB python FMUs, FMI 2.0, other sources" in body
    assert f"{version}/fastloop-00ff00ff00ff00ff 500 B compiled fast loop" in body
    assert lines[-1] == (
        "total 2.0 MB in 5 folder(s); 2 other version(s): glider-cosim cache --prune removes them"
    )


def test_cache_marks_the_set_of_the_current_sources(monkeypatch, tmp_path, capsys):
    from glider_cosim.cli import main
    from glider_cosim.fmus.folders import cache_dir

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    folder = cache_dir("python")
    folder.mkdir(parents=True)
    (folder / "GliderPlant.fmu").write_bytes(b"x" * 20)
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert f"{folder.parent.name}/{folder.name}  " in out
    assert "20 B  python FMUs, FMI 2.0, current sources\n" in out
    assert out.endswith("total 20 B in 1 folder(s)\n")


def test_cache_prune_removes_only_other_versions(monkeypatch, tmp_path, capsys):
    from glider_cosim.cli import main
    from glider_cosim.fmus.files import package_version

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    version = package_version()
    _fake_cache(tmp_path, version)
    assert main(["cache", "--prune"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"removed {tmp_path / '0.0.1'} (2.0 MB)",
        f"removed {tmp_path / '0.0.2.dev3'} (10 B)",
        f"pruned 2 version folder(s) of {tmp_path}, freed 2.0 MB",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == [version]
    assert len(list((tmp_path / version).iterdir())) == 2  # this version's sets are kept
    assert main(["cache", "--prune"]) == 0
    assert capsys.readouterr().out == (
        f"nothing to prune: {tmp_path} holds no other version than {version}\n"
    )


def test_cache_of_a_missing_folder_says_empty(monkeypatch, tmp_path, capsys):
    from glider_cosim.cli import main

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "none"))
    assert main(["cache"]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'none'}: empty\n"


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("flavor", ["python", "native"])
def test_gitignore_covers_every_folder_build_writes(flavor, fmi):
    """``glider-cosim build`` (each --flavor/--fmi) writes FMUs git does not list."""
    import shutil
    import subprocess

    from glider_cosim.fmus.folders import default_dir

    repo = Path(__file__).parents[1]
    if shutil.which("git") is None or not (repo / ".git").exists():
        pytest.skip("not a git checkout")
    fmu = default_dir(flavor, fmi) / "GliderPlant.fmu"
    p = subprocess.run(["git", "check-ignore", "--no-index", "-q", str(fmu)], cwd=repo)
    assert p.returncode == 0, f"{fmu} is not in .gitignore"


def test_cache_names_the_font_cache_of_the_command_line(monkeypatch, tmp_path, capsys):
    from glider_cosim.cli import main
    from glider_cosim.fmus.files import package_version

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    fonts = tmp_path / package_version() / "matplotlib"
    fonts.mkdir(parents=True)
    (fonts / "fontlist-v390.json").write_bytes(b"{}" * 50)
    assert main(["cache"]) == 0
    body = [" ".join(line.split()) for line in capsys.readouterr().out.splitlines()]
    assert (
        f"{package_version()}/matplotlib 100 B matplotlib's font cache "
        "(the sweep's and report's figures)" in body
    )
