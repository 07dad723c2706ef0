"""OSP-IS model descriptions: in each FMU and beside it, valid against the published
schema, consistent with the model description; in the SSP; read by libcosim."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest
import xmlschema
from fmpy import read_model_description

from glider_cosim.fmus import osp
from glider_cosim.interop.libcosim import simulate_libcosim_isolated
from glider_cosim.interop.ssp_common import NS
from glider_cosim.interop.ssp_export import export_ssp
from glider_cosim.interop.ssp_import import load_ssp
from glider_fmi.slave_base import _UNITS

pytestmark = pytest.mark.integration
FMUS = ("GliderPlant", "GliderObserver", "GliderController")
XSD = Path(__file__).parents[1] / "data" / "osp-is" / "OspModelDescription-1.0.1.xsd"
O = {"o": osp.NS}
EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

#: the groups each FMU must declare: name -> (OSP-IS type, variables in order)
EXPECTED = {
    "GliderPlant": {
        "disturbance_force": ("Force", ["F_x", "F_z"]),
        "disturbance_moment": ("Torque", ["M_y"]),
        "position": ("LinearDisplacement", ["x", "z"]),
        "V": ("LinearVelocity", ["V"]),
        "omega2": ("AngularVelocity", ["omega2"]),
        **{a: ("AngularDisplacement", [a]) for a in ("delta_cmd", "theta_meas", "theta")},
        **{a: ("AngularDisplacement", [a]) for a in ("theta_g", "alpha", "delta")},
    },
    "GliderObserver": {
        "V_hat": ("LinearVelocity", ["V_hat"]),
        "omega2_hat": ("AngularVelocity", ["omega2_hat"]),
        **{
            a: ("AngularDisplacement", [a])
            for a in ("theta_meas", "delta_cmd", "theta_filt", "theta_g_hat", "alpha_hat")
        },
        "theta_hat": ("AngularDisplacement", ["theta_hat"]),
    },
    "GliderController": {
        "V_hat": ("LinearVelocity", ["V_hat"]),
        "theta_g_hat": ("AngularDisplacement", ["theta_g_hat"]),
        "delta_cmd": ("AngularDisplacement", ["delta_cmd"]),
    },
}


@pytest.fixture(scope="module")
def schema() -> xmlschema.XMLSchema:
    return xmlschema.XMLSchema(str(XSD))


def _files(folder: Path, name: str) -> tuple[bytes, bytes]:
    """(the copy the FMU carries, the file beside it)."""
    with zipfile.ZipFile(folder / f"{name}.fmu") as z:
        carried = z.read(f"extra/com.opensimulationplatform/{name}_OspModelDescription.xml")
    return carried, (folder / f"{name}_OspModelDescription.xml").read_bytes()


@pytest.mark.parametrize("name", FMUS)
def test_each_fmu_carries_its_osp_description_and_has_it_beside(flavor_dir, name, schema):
    carried, beside = _files(flavor_dir, name)
    assert carried == beside
    schema.validate(beside.decode())  # the published OSP-IS 1.0.1 schema


@pytest.mark.parametrize("name", FMUS)
def test_osp_description_matches_the_model_description(flavor_dir, name):
    md = read_model_description(str(flavor_dir / f"{name}.fmu"))
    variables = {v.name: v for v in md.modelVariables}
    md_units = {u.name: u.baseUnit for u in md.unitDefinitions}
    root = ET.fromstring(_files(flavor_dir, name)[1])
    assert root.tag == f"{{{osp.NS}}}OspModelDescription" and root.get("version") == "1.0"

    # units: every unit our variables use, SI exponents as the model description and
    # glider_fmi's table give them, factor 1, offset 0
    units = {u.get("name"): u for u in root.iterfind("o:UnitDefinitions/o:Unit", O)}
    assert set(units) == {v.unit for v in variables.values() if v.unit}
    for uname, u in units.items():
        (base,) = u.findall("o:BaseUnit", O)
        got = {e: int(base.get(e)) for e in EXPONENTS}
        assert got == {e: int(getattr(md_units[uname], e)) for e in EXPONENTS}, uname
        assert got == {e: int(_UNITS[uname].get(e, "0")) for e in EXPONENTS}, uname
        assert (float(base.get("factor")), float(base.get("offset"))) == (1.0, 0.0)

    # groups: the expected ones, each variable an input or output of the FMU with the
    # group's unit, one causality per group, names unique
    groups = list(root.find("o:VariableGroups", O))
    names = [g.get("name") for g in groups]
    assert len(names) == len(set(names))
    found = {}
    for g in groups:
        refs = [v.get("ref") for v in g.findall("o:Variable", O)]
        found[g.get("name")] = (g.tag.split("}")[1], refs)
        assert len({variables[r].causality for r in refs}) == 1, g.get("name")
        for v in g.findall("o:Variable", O):
            fv = variables[v.get("ref")]
            assert fv.causality in ("input", "output")
            assert v.get("unit") == fv.unit
    assert found == EXPECTED[name]
    if name == "GliderPlant":
        force = root.find("o:VariableGroups/o:Force", O)
        assert [(v.get("ref"), v.get("axis")) for v in force] == [("F_x", "x"), ("F_z", "z")]
        assert {variables[v.get("ref")].causality for v in force} == {"input"}
        (moment,) = root.findall("o:VariableGroups/o:Torque/o:Variable", O)
        assert (moment.get("ref"), moment.get("axis")) == ("M_y", "y")


def test_the_schema_check_is_not_vacuous(fmu_dir, schema):
    """Wrong group order (VariableGroups is an xs:sequence), more than 3 components and a
    missing ref are all refused by the vendored schema."""
    text = (fmu_dir / "GliderPlant_OspModelDescription.xml").read_text()
    root = ET.fromstring(text)
    vg = root.find("o:VariableGroups", O)
    vg.insert(0, vg[-1])  # an AngularDisplacement before the Force
    assert not schema.is_valid(ET.tostring(root, encoding="unicode"))
    root = ET.fromstring(text)
    force = root.find("o:VariableGroups/o:Force", O)
    for _ in range(2):
        force.append(ET.fromstring(ET.tostring(force[0])))
    assert not schema.is_valid(ET.tostring(root, encoding="unicode"))
    assert not schema.is_valid(text.replace('ref="F_x"', 'name="F_x"'))


def test_generated_from_the_description_alone(fmu_dir, tmp_path):
    """An FMU of ours that lost the files gets them back from its model description."""
    fmu = shutil.copy(fmu_dir / "GliderPlant.fmu", tmp_path / "GliderPlant.fmu")
    with zipfile.ZipFile(fmu) as z:
        md = z.read("modelDescription.xml")
    assert (
        osp.write_beside(Path(fmu)).read_bytes()
        == osp.generate(md)
        == _files(fmu_dir, "GliderPlant")[1]
    )


# ------------------------------------------------------------------ SSP and libcosim
@pytest.fixture(scope="module")
def ssp(flavor_dir: Path, tmp_path_factory) -> Path:
    return export_ssp(tmp_path_factory.mktemp("osp_ssp") / "glider.ssp", None, flavor_dir)


def test_ssp_carries_the_osp_descriptions_beside_the_fmus(ssp, flavor_dir):
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
        root = ET.fromstring(z.read("SystemStructure.ssd"))
        for name in FMUS:
            path = f"resources/{name}_OspModelDescription.xml"
            assert {f"resources/{name}.fmu", path} <= names
            assert z.read(path) == _files(flavor_dir, name)[1]
    for comp in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
        ann = comp.findall("ssd:Annotations/ssc:Annotation", NS)
        assert [a.get("type") for a in ann] == ["org.glider-cosim.osp-model-description"]
        (ref,) = list(ann[0])
        assert ref.get("source") == comp.get("source").replace(".fmu", osp.SUFFIX)


def test_libcosim_runs_the_ssp_with_the_osp_files_as_without(ssp, tmp_path):
    """libcosim loads and runs the SSP with the OSP-IS files and annotations in it, and
    the results equal those of the same SSP stripped of them."""
    stripped = tmp_path / "stripped.ssp"
    with zipfile.ZipFile(ssp) as src, zipfile.ZipFile(stripped, "w") as dst:
        for item in src.infolist():
            if item.filename.endswith(osp.SUFFIX):
                continue
            data = src.read(item)
            if item.filename == "SystemStructure.ssd":
                root = ET.fromstring(data)
                for comp in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
                    comp.remove(comp.find("ssd:Annotations", NS))
                data = ET.tostring(root, xml_declaration=True, encoding="UTF-8")
            dst.writestr(item, data)
    variables = ["plant.theta_g", "plant.V", "controller.delta_cmd"]
    with_osp = simulate_libcosim_isolated(ssp, variables, stop_time=5.0, timeout=300)
    without = simulate_libcosim_isolated(stripped, variables, stop_time=5.0, timeout=300)
    assert with_osp.data.shape == (251, 4) and np.isfinite(with_osp.data).all()
    np.testing.assert_array_equal(with_osp.data, without.data)


_OSP_RUN = r"""
import json, sys
from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
log_output_level(CosimLogLevel.ERROR)
path, n, wanted = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
ex = CosimExecution.from_osp_config_file(path)
obs = CosimObserver.create_last_value()
ex.add_observer(obs)
assert ex.step(n)
out = {}
for name in wanted:
    inst, var = name.split(".", 1)
    idx = ex.slave_index_from_instance_name(inst)
    vr = next(v.reference for v in ex.slave_variables(idx) if v.name.decode() == var)
    out[name] = obs.last_real_values(idx, [vr])[0]
del obs, ex  # free the instances before the interpreter finalizes
print(json.dumps(out))
"""

#: the closed loop as OSP-IS variable-group connections (group names of our files)
GROUP_CONNECTIONS = (
    ("controller", "delta_cmd", "plant", "delta_cmd"),
    ("controller", "delta_cmd", "observer", "delta_cmd"),
    ("plant", "theta_meas", "observer", "theta_meas"),
    ("observer", "V_hat", "controller", "V_hat"),
    ("observer", "theta_g_hat", "controller", "theta_g_hat"),
)


def _osp_system_structure(ssp: Path, folder: Path) -> Path:
    """The SSP's system as an OspSystemStructure.xml wired by variable groups only, with
    the FMUs and their OSP-IS files copied beside it."""
    system, step, _ = load_ssp(ssp)
    sims = []
    for inst, fmu in system.fmus.items():
        shutil.copy(fmu, folder / fmu.name)
        shutil.copy(fmu.with_name(fmu.stem + osp.SUFFIX), folder / (fmu.stem + osp.SUFFIX))
        types = {v.name: v.type for v in read_model_description(str(fmu)).modelVariables}
        values = "".join(
            f'<InitialValue variable="{k}"><{types[k]} value="{str(v).lower()}"/></InitialValue>'
            for k, v in system.parameters.get(inst, {}).items()
        )
        sims.append(
            f'<Simulator name="{inst}" source="{fmu.name}"><InitialValues>{values}'
            "</InitialValues></Simulator>"
        )
    conns = "".join(
        f'<VariableGroupConnection><VariableGroup simulator="{a}" name="{ga}"/>'
        f'<VariableGroup simulator="{b}" name="{gb}"/></VariableGroupConnection>'
        for a, ga, b, gb in GROUP_CONNECTIONS
    )
    path = folder / "OspSystemStructure.xml"
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure"'
        f' version="0.1"><BaseStepSize>{step!r}</BaseStepSize><Algorithm>fixedStep</Algorithm>'
        f"<Simulators>{''.join(sims)}</Simulators><Connections>{conns}</Connections>"
        "</OspSystemStructure>\n"
    )
    return path


def test_libcosim_wires_the_loop_from_our_variable_groups(ssp, tmp_path):
    """libcosim's OspSystemStructure loader reads our files beside the FMUs: the loop
    wired by variable-group connections alone runs like the SSP's scalar connections."""
    config = _osp_system_structure(ssp, tmp_path)
    wanted = ["plant.theta_g", "plant.V", "controller.delta_cmd"]
    p = subprocess.run(
        [sys.executable, "-c", _OSP_RUN, str(config), "250", json.dumps(wanted)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads([ln for ln in p.stdout.splitlines() if ln.startswith("{")][-1])
    ref = simulate_libcosim_isolated(ssp, wanted, stop_time=5.0, timeout=300)
    for j, name in enumerate(wanted, start=1):
        assert got[name] == pytest.approx(ref.data[-1, j], abs=1e-12), name
    # and without our files the group connections cannot be made
    for f in tmp_path.glob(f"*{osp.SUFFIX}"):
        f.unlink()
    p = subprocess.run(
        [sys.executable, "-c", _OSP_RUN, str(config), "1", json.dumps(wanted)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert p.returncode != 0
    assert "Cannot find extended model description" in p.stderr
