"""What a run does before its first step, done once rather than at every run (issue 48):
the native variable tables made once and kept in the cache, the cache's FMUs unpacked
once for every process, the run's table kept as it is written rather than read back from
``results.csv``. Checked by what is done (calls, files), not by a clock: the figures are
``bench/whole_run.py``'s."""

from __future__ import annotations

import os
import zipfile

import pytest

from glider_cosim.fmus import native, native_vars
from glider_cosim.fmus.files import package_version
from glider_cosim.inputs import archives
from glider_cosim.master import instance

PLANT = native.NATIVE_COMPONENTS[0]


def test_a_variable_table_is_made_once_then_read_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    made = []
    real = native_vars.make_vars_header
    monkeypatch.setattr(native_vars, "make_vars_header", lambda c: made.append(c.name) or real(c))
    first = native.vars_header(PLANT)
    assert made == ["GliderPlant"]
    (kept,) = (tmp_path / package_version() / "native-vars").iterdir()
    assert kept.name.startswith("GliderPlant-") and kept.read_text() == first
    assert native.vars_header(PLANT) == first  # read back, not made again
    assert made == ["GliderPlant"]
    assert first == real(PLANT)  # the same text the slave makes


def test_a_variable_table_is_made_anew_when_its_sources_change(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    native.vars_header(PLANT)
    made = []
    real = native_vars.make_vars_header
    monkeypatch.setattr(native_vars, "make_vars_header", lambda c: made.append(c.name) or real(c))
    monkeypatch.setattr(native_vars, "_header_key", lambda c: "another-key")  # an edited slave
    native.vars_header(PLANT)
    assert made == ["GliderPlant"]
    assert len(list((tmp_path / package_version() / "native-vars").iterdir())) == 2


def test_a_native_hash_is_made_once_within_same_sources_and_on_every_file_change(
    tmp_path, monkeypatch
):
    """Issue 48: a run's preparation asks for each FMU's hash 3 times; within
    ``same_sources`` it is made once. Outside, an edited source (another modification time
    or size) gives another hash, the same bytes the same one."""
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path))
    made = []
    real = native._native_digest
    monkeypatch.setattr(native, "_native_digest", lambda *a: made.append(a) or real(*a))
    with native.same_sources():
        hashes = {native.native_hash(PLANT) for _ in range(3)}
    assert len(hashes) == 1 and len(made) == 1
    source = tmp_path / "plant_model.c"
    source.write_text("int x;\n")
    monkeypatch.setattr(native, "source_files", lambda c, fmi=2: [source])
    first = native.native_hash(PLANT)
    source.write_text("int y;\n")  # the same size, another time (or the same time: the bytes)
    os.utime(source, ns=(1, 1))
    assert native.native_hash(PLANT) != first
    source.write_text("int x;\n")
    os.utime(source, ns=(2, 2))
    assert native.native_hash(PLANT) == first


def test_listing_the_cache_adds_no_table_to_it(tmp_path, monkeypatch, capsys):
    from glider_cosim.cli.main import main

    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    assert main(["cache"]) == 0
    assert not (tmp_path / "cache").exists()
    with native_vars.tables_not_kept():
        assert native.vars_header(PLANT) == native.make_vars_header(PLANT)
    assert not (tmp_path / "cache").exists()


def test_an_unwritable_cache_still_gives_the_table(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(blocker))
    assert native.vars_header(PLANT) == native.make_vars_header(PLANT)


def _fmu(path, payload: bytes = b"\x7fELF binary"):
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", "<fmiModelDescription/>")
        z.writestr("binaries/linux64/M.so", payload)
    return path


def test_an_fmu_of_the_cache_is_unpacked_once_for_every_process(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    fmu = _fmu(tmp_path / "cache" / package_version() / "native-x" / "M.fmu")
    folder = instance.unpacked_in_cache(fmu)
    assert folder is not None
    assert os.path.dirname(folder) == str(tmp_path / "cache" / package_version() / "unpacked")
    assert (tmp_path / folder / "binaries" / "linux64" / "M.so").read_bytes() == b"\x7fELF binary"

    def no_unpacking(*args, **kwargs):
        raise AssertionError("unpacked again")

    monkeypatch.setattr(instance, "safe_extract", no_unpacking)
    assert instance.unpacked_in_cache(fmu) == folder  # another process: the same folder
    monkeypatch.undo()
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    _fmu(fmu, b"\x7fELF rebuilt")  # another build: another folder, never the old one
    again = instance.unpacked_in_cache(fmu)
    assert again != folder
    assert (tmp_path / again / "binaries" / "linux64" / "M.so").read_bytes() == b"\x7fELF rebuilt"


def test_an_fmu_outside_the_cache_is_not_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    assert instance.unpacked_in_cache(_fmu(tmp_path / "mine" / "M.fmu")) is None
    assert not (tmp_path / "cache").exists()


def test_a_bad_fmu_of_the_cache_leaves_no_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("GLIDER_COSIM_CACHE", str(tmp_path / "cache"))
    fmu = tmp_path / "cache" / package_version() / "native-x" / "M.fmu"
    fmu.parent.mkdir(parents=True)
    fmu.write_bytes(b"not a zip")
    with pytest.raises(archives.InputFileError, match="not a readable zip"):
        instance.unpacked_in_cache(fmu)
    assert list((tmp_path / "cache" / package_version() / "unpacked").iterdir()) == []


def test_a_reference_is_parsed_once():
    from glider_cosim.master.errors import SystemSpecError
    from glider_cosim.master.spec import VarRef

    ref = VarRef.parse("controller.K_c")
    assert VarRef.parse("controller.K_c") is ref  # a sweep resolves its names at every run
    assert (ref.instance, ref.variable) == ("controller", "K_c")
    for bad in ("K_c", "controller.", ".K_c"):
        with pytest.raises(SystemSpecError, match="is not a variable reference"):
            VarRef.parse(bad)
