"""SSPs as the standard's schemas read them, and SSPs as other tools write them.

- FMI 2.0 systems are exported as SSP 1.0, FMI 3.0 ones as SSP 2.0 (FMI 3's types), each
  valid against its version's XSDs as pyssp-standard ships them, the SSD named by a plain
  identifier (OMSimulator's importer refuses others); ``run`` reads both versions.
- An SSP without our OSP annotations (as OMSimulator, pyssp-standard or a hand writes
  one) runs with ``--step``, with OMSimulator's step annotation or with its FMUs'
  ``DefaultExperiment stepSize``, equal to our SSP's run; else it is refused with one
  line naming ``--step`` (or ``--stop-time``).
"""

from __future__ import annotations

import io
import re
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
import xmlschema
from pyssp_standard.standard import ModelicaStandard

from glider_cosim.interop.ssp_common import NS
from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.interop.ssp_import import SSPError, load_ssp
from glider_cosim.runner import run_ssp, simulate

pytestmark = pytest.mark.integration
SCHEMAS = {"1.0": ("ssd", "ssv"), "2.0": ("ssd2", "ssv2")}


def schema(version: str) -> xmlschema.XMLSchema10:
    """The SSD schema of an SSP version with its parameter-values schema loaded too (the
    inline ssv:ParameterSet of our components is validated, not skipped)."""
    ssd, ssv = (str(ModelicaStandard.schemas[k]) for k in SCHEMAS[version])
    return xmlschema.XMLSchema10(ssd, locations=[(NS["ssv"], ssv)])


def ssd_of(ssp: Path) -> str:
    with zipfile.ZipFile(ssp) as z:
        return z.read("SystemStructure.ssd").decode()


@pytest.fixture(scope="module")
def ssps(native_dir, fmi3_dirs, tmp_path_factory) -> dict[int, Path]:
    """The default scenario exported with the native FMUs of each FMI version."""
    folder = tmp_path_factory.mktemp("ssp_versions")
    return {
        2: export_ssp(folder / "fmi2.ssp", None, native_dir),
        3: export_ssp(folder / "fmi3.ssp", None, fmi3_dirs["native"]),
    }


@pytest.mark.parametrize(("fmi", "version"), [(2, "1.0"), (3, "2.0")])
def test_export_is_valid_against_its_ssp_versions_schema(ssps, fmi, version):
    text = ssd_of(ssps[fmi])
    root = ET.fromstring(text)
    assert root.get("version") == version
    assert root.get("name") == "glider_cosim_default"
    assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", root.get("name"))
    schema(version).validate(text)
    connectors = {
        t.tag.rsplit("}", 1)[1]
        for t in root.iterfind(".//ssd:Connector/*", NS)
        if t.tag.startswith("{" + NS["ssc"])
    }
    values = {t.tag.rsplit("}", 1)[1] for t in root.iterfind(".//ssv:Parameter/*", NS)}
    if fmi == 3:
        assert connectors == {"Float64"} and values == {"Float64", "Int32"}
        # an SSP 2.0 document is not SSP 1.0: the version is what the types need
        assert not schema("1.0").is_valid(text)
    else:
        assert connectors == {"Real"} and values == {"Real", "Integer"}
    # the schema reads the inline parameter values: a bad one is caught
    bad = re.sub(r'(<ssv:(?:Real|Float64) value=")[^"]*', r"\1fast", text, count=1)
    assert bad != text and not schema(version).is_valid(bad)


def test_fmi3_model_descriptions_in_the_ssp_are_valid_fmi3(ssps):
    fmi3 = xmlschema.XMLSchema10(str(ModelicaStandard.schemas["fmi30"]))
    with zipfile.ZipFile(ssps[3]) as z:
        fmus = [n for n in z.namelist() if n.endswith(".fmu")]
        assert len(fmus) == 3
        for name in fmus:
            with zipfile.ZipFile(io.BytesIO(z.read(name))) as fmu:
                md = fmu.read("modelDescription.xml").decode()
            assert 'fmiVersion="3.0"' in md
            fmi3.validate(md)


def test_run_reads_both_versions_like_the_scenario(ssps, native_dir, fmi3_dirs, tmp_path):
    for fmi, folder in ((2, native_dir), (3, fmi3_dirs["native"])):
        a = run_ssp(ssps[fmi], None, stop_time=5.0)
        b = simulate(None, None, fmu_dir=folder, build=False, stop_time=5.0)
        assert a.status == b.status == "ok" and a.columns == b.columns
        assert np.array_equal(a.data, b.data), fmi
    # FMI 3 written as SSP 1.0 (export-ssp --ssp-version 1.0: for Ecos) reads the same
    v1 = export_ssp(tmp_path / "v1.ssp", None, fmi3_dirs["native"], ssp_version="1.0")
    assert 'version="1.0"' in ssd_of(v1) and "Float64" not in ssd_of(v1)
    schema("1.0").validate(ssd_of(v1))
    assert np.array_equal(run_ssp(v1, None, stop_time=5.0).data, a.data)


def test_another_ssd_version_is_refused(ssps, tmp_path):
    bad = rewrite(
        ssps[2], tmp_path / "v3.ssp", lambda t: t.replace('version="1.0"', 'version="3.0"')
    )
    with pytest.raises(SSPError, match=r"SSD version '3.0' is not supported: expected 1.0 or 2.0"):
        load_ssp(bad)


# ------------------------------------------------------------ SSPs from other tools
def rewrite(ssp: Path, out: Path, edit_ssd=None, edit_md=None) -> Path:
    """A copy of ``ssp`` with its SSD text edited, and each FMU's model description."""
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.namelist():
            data = zin.read(item)
            if item == "SystemStructure.ssd" and edit_ssd:
                data = edit_ssd(data.decode()).encode()
            if item.endswith(".fmu") and edit_md:
                buf = io.BytesIO()
                with zipfile.ZipFile(io.BytesIO(data)) as fin, zipfile.ZipFile(buf, "w") as fout:
                    for inner in fin.namelist():
                        content = fin.read(inner)
                        if inner == "modelDescription.xml":
                            content = edit_md(item, content.decode()).encode()
                        fout.writestr(inner, content)
                data = buf.getvalue()
            zout.writestr(item, data)
    return out


def without_our_annotations(text: str) -> str:
    """The SSD as a tool that knows nothing of OSP writes it: no ssd:Annotations."""
    root = ET.fromstring(text)
    for el in root.iter():
        for ann in el.findall("ssd:Annotations", NS):
            el.remove(ann)
    return ET.tostring(root, encoding="unicode")


def as_omsimulator(text: str) -> str:
    """OMSimulator's way: its FixedStepMaster on the top system, times as %f."""
    text = without_our_annotations(text)
    oms = (
        '<ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations>'
        '<oms:SimulationInformation><oms:FixedStepMaster description="oms-ma" '
        'stepSize="0.020000" absoluteTolerance="0.000100" relativeTolerance="0.000100" />'
        "</oms:SimulationInformation></oms:Annotations></ssc:Annotation></ssd:Annotations>"
    )
    text = text.replace("</ssd:Connections>", "</ssd:Connections>" + oms, 1)
    text = text.replace(
        f'xmlns:ssd="{NS["ssd"]}"', f'xmlns:ssd="{NS["ssd"]}" xmlns:oms="{NS["oms"]}"'
    )
    return text.replace(
        'startTime="0.0" stopTime="60.0"', 'startTime="0.000000" stopTime="60.000000"'
    )


def fmu_step(steps: dict[str, str]):
    """Each FMU's model description with a DefaultExperiment stepSize."""

    def edit(item: str, md: str) -> str:
        step = steps[Path(item).stem]
        return md.replace(
            "<ModelVariables>", f'<DefaultExperiment stepSize="{step}"/><ModelVariables>', 1
        )

    return edit


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "glider_cosim.cli", *args], capture_output=True,
                          text=True, timeout=300, cwd=cwd)  # fmt: skip


def test_an_ssp_without_a_step_runs_with_step_and_is_refused_without(ssps, tmp_path):
    ours = ssps[2]
    foreign = rewrite(ours, tmp_path / "foreign.ssp", without_our_annotations)
    assert "osp:" not in ssd_of(foreign) and "Annotation" not in ssd_of(foreign)
    p = cli("run", str(foreign), "--no-plots", "--stop-time", "2", "--out", "f", cwd=tmp_path)
    assert p.returncode == 2, p.stderr
    (line,) = p.stderr.strip().splitlines()
    assert line.startswith("glider-cosim run: error: ") and line.endswith("give one with --step")
    assert not (tmp_path / "f").exists()
    p = cli("run", str(foreign), "--no-plots", "--stop-time", "2", "--step", "0.02", "--out", "f",
            cwd=tmp_path)  # fmt: skip
    assert p.returncode == 0, p.stderr
    p = cli("run", str(ours), "--no-plots", "--stop-time", "2", "--out", "o", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    a, b = ((tmp_path / d / "results.csv").read_bytes() for d in ("f", "o"))
    assert a == b and a.count(b"\n") == 102


def test_an_omsimulator_ssp_runs_with_its_step(ssps, tmp_path):
    oms = rewrite(ssps[2], tmp_path / "oms.ssp", as_omsimulator)
    assert "oms:FixedStepMaster" in ssd_of(oms) and "osp:" not in ssd_of(oms)
    system, step, stop = load_ssp(oms)
    assert (step, stop) == (0.02, 60.0)
    a = run_ssp(oms, None, stop_time=5.0)
    assert np.array_equal(a.data, run_ssp(ssps[2], None, stop_time=5.0).data)


def test_the_fmus_default_step_serves_when_they_agree(ssps, tmp_path):
    names = ("GliderPlant", "GliderObserver", "GliderController")
    same = rewrite(ssps[2], tmp_path / "same.ssp", without_our_annotations,
                   fmu_step(dict.fromkeys(names, "0.02")))  # fmt: skip
    assert load_ssp(same)[1] == 0.02
    assert np.array_equal(run_ssp(same, None, stop_time=2.0).data,
                          run_ssp(ssps[2], None, stop_time=2.0).data)  # fmt: skip
    differ = rewrite(ssps[2], tmp_path / "differ.ssp", without_our_annotations,
                     fmu_step({**dict.fromkeys(names, "0.02"), "GliderPlant": "0.01"}))  # fmt: skip
    with pytest.raises(SSPError, match=r"DefaultExperiment stepSize values differ .*plant 0.01.* "
                       r"give the communication step with --step"):  # fmt: skip
        load_ssp(differ)
    assert load_ssp(differ, step=0.02)[1] == 0.02


def test_an_ssp_without_a_stop_time_needs_stop_time(ssps, tmp_path):
    bare = rewrite(ssps[2], tmp_path / "bare.ssp",
                   lambda t: re.sub(r"<ssd:DefaultExperiment.*?</ssd:DefaultExperiment>", "", t,
                                    flags=re.S))  # fmt: skip
    assert "DefaultExperiment" not in ssd_of(bare)
    with pytest.raises(SSPError, match=r"no ssd:DefaultExperiment: give the end of the run with "
                       r"--stop-time"):  # fmt: skip
        load_ssp(bare, step=0.02)
    assert load_ssp(bare, step=0.02, stop_time=3.0)[1:] == (0.02, 3.0)


@pytest.mark.parametrize("fmi", [2, 3])
def test_our_master_reads_the_fmus_messages_by_the_hash_rule(ssps, tmp_path, fmi):
    """An instance named with a '#' (an SSP component may be): the FMU writes it '##'
    (FMI's rule), our master reads it back as one '#' in the run's failure message."""

    def edit(text: str) -> str:
        text = text.replace('name="observer"', 'name="observer#1"')
        text = text.replace('Element="observer"', 'Element="observer#1"')
        return re.sub(r'(<ssv:Parameter name="K_c">\s*<ssv:(?:Real|Float64) value=")[^"]*',
                      r"\g<1>2.0", text)  # fmt: skip  # K_c = 2: the observer stalls

    r = run_ssp(rewrite(ssps[fmi], tmp_path / "hash.ssp", edit), None, stop_time=20.0)
    assert r.status == "stopped"
    assert "Discard] observer#1: observer estimate glider stalled" in r.message, r.message
