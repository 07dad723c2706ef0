"""FMI-LS-REF (issue 56): every FMU we build carries its experiments, valid by the official
schemas (vendored, validated offline); ``verify`` runs them, ours and an FMU glider-cosim
did not write; a file changed after the build is a named failure; ``add-experiments``."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

import glider_cosim
from glider_cosim.cli.main import main
from glider_cosim.fmus.lsref import LSREF_DIR, MANIFEST, shipped_folder
from glider_cosim.interop.lsref_write import Experiment, experiment_files
from glider_cosim.verify.lsref import verify_lsref
from glider_cosim.verify.lsref_add import AddExperimentsError, write_copy

pytestmark = pytest.mark.integration

SCHEMAS = Path(glider_cosim.__file__).parent / "verification" / "schemas"
#: where the official schemas import fmi-standard's from; mapped to the vendored copies
FMI_SCHEMA_URL = "https://raw.githubusercontent.com/modelica/fmi-standard/main/schema/"
MODELS = ("GliderPlant", "GliderObserver", "GliderController")


def _schema(name: str):
    """An official schema, offline: fmi-standard's URLs mapped to the vendored copies."""
    xmlschema = pytest.importorskip("xmlschema")
    text = (SCHEMAS / name).read_text()
    if name == "maHarmonizedSpecificationExperiments.xsd":
        # its <xs:import> of fmi3Annotation.xsd (no namespace into a schema without one)
        # is invalid XSD 1.0; fmi-ls-ref fixed the same line with <xs:include> (596a89d)
        text = text.replace("<xs:import schemaLocation=", "<xs:include schemaLocation=", 1)

    def local(uri: str) -> str:
        return str(SCHEMAS / uri[len(FMI_SCHEMA_URL) :]) if uri.startswith(FMI_SCHEMA_URL) else uri

    return xmlschema.XMLSchema(text, base_url=str(SCHEMAS), uri_mapper=local, allow="local")


def _ssv_schema():
    pyssp = pytest.importorskip("pyssp_standard")
    xmlschema = pytest.importorskip("xmlschema")
    xsd = Path(pyssp.__file__).parent / "resources" / "SystemStructureParameterValues.xsd"
    return xmlschema.XMLSchema(str(xsd))


@pytest.fixture(scope="module")
def schemas():
    return {
        "manifest": _schema("fmi3LayeredStandardReferenceManifest.xsd"),
        "experiments": _schema("maHarmonizedSpecificationExperiments.xsd"),
        "ssv": _ssv_schema(),
    }


#: our FMU sets: (fixture, key in it or None)
SETS = {"python-fmi2": ("fmu_dir", None), "native-fmi2": ("native_dir", None),
        "python-fmi3": ("fmi3_python", None), "native-fmi3": ("fmi3_dirs", "native")}  # fmt: skip


@pytest.fixture(scope="module")
def fmi3_python(tmp_path_factory) -> Path:
    """Our Python-flavor FMUs as FMI 3.0 (without the native build fmi3_dirs makes too)."""
    from glider_cosim.fmus.fmi3 import build_fmi3

    out = tmp_path_factory.mktemp("fmi3_python")
    build_fmi3(out, "python")
    return out


def _validate(z: zipfile.ZipFile, schemas) -> int:
    """Validate the manifest and every XML file it lists; how many files were checked."""
    schemas["manifest"].validate(z.read(MANIFEST).decode())
    n = 1
    for name in z.namelist():
        if name.startswith(LSREF_DIR) and name.endswith(".exp"):
            schemas["experiments"].validate(z.read(name).decode())
            n += 1
        elif name.startswith(LSREF_DIR) and name.endswith(".ssv"):
            schemas["ssv"].validate(z.read(name).decode())
            n += 1
    return n


@pytest.mark.parametrize("kind", SETS)
def test_every_fmu_we_build_carries_valid_experiments(kind, request, schemas):
    from fmpy.validation import validate_fmu

    fixture, key = SETS[kind]
    folder = request.getfixturevalue(fixture)
    folder = folder[key] if key else folder
    for model in MODELS:
        fmu = folder / f"{model}.fmu"
        with zipfile.ZipFile(fmu) as z:
            # the folder is the shipped one, byte for byte, in every flavor and version
            own = shipped_folder(model)  # the component's lsref/
            shipped = {f"{LSREF_DIR}/{p.relative_to(own).as_posix()}": p.read_bytes()
                       for p in own.rglob("*") if p.is_file()}  # fmt: skip
            carried = {n: z.read(n) for n in z.namelist() if n.startswith(LSREF_DIR)}
            assert carried == shipped, (kind, model)
            assert _validate(z, schemas) >= 4
        assert validate_fmu(str(fmu)) == [], (kind, model)
        report = verify_lsref(fmu)
        assert report is not None and report.passed, report.table()
        roles = {e.role for e in report.experiments}
        assert roles == {"experiment/smoke-test", "experiment/validation"}
        assert not report.checksum_failures and len(report.checksums) >= 5


def test_the_shipped_folders_are_up_to_date(fmu_dir, tmp_path):
    from glider_cosim.verify.lsref_ours import stale_files, write_folders

    written = write_folders(fmu_dir, tmp_path)
    assert {p.relative_to(tmp_path).parts[0] for p in written} == set(MODELS)
    for model in MODELS:
        assert stale_files(tmp_path / model, shipped_folder(model)) == [], model


def test_the_paper_cases_travel_as_parameter_sets(fmu_dir):
    with zipfile.ZipFile(fmu_dir / "GliderController.fmu") as z:
        manifest = z.read(MANIFEST).decode()
        kc = z.read(f"{LSREF_DIR}/parameters/fig3-4-kc.ssv").decode()
        pi = z.read(f"{LSREF_DIR}/parameters/paper-pi-gains.ssv").decode()
    assert 'role="parameter"' in manifest and 'role="document"' in manifest
    assert '<ssv:Parameter name="K_c">' in kc and 'value="6.0"' in kc
    assert '<ssv:Parameter name="K_P">' in pi and 'value="2.0"' in pi


def _rewrite(src: Path, dst: Path, member: str, change) -> None:
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as b:
        for item in a.infolist():
            data = a.read(item)
            b.writestr(item, change(data) if item.filename == member else data)


def test_a_file_changed_after_the_build_is_named(fmu_dir, tmp_path, capsys):
    member = f"{LSREF_DIR}/smoke-test/reference-references.csv"
    changed = tmp_path / "GliderPlant.fmu"
    _rewrite(fmu_dir / "GliderPlant.fmu", changed, member, lambda d: d.replace(b"0.2,", b"0.3,", 1))
    assert main(["verify", str(changed)]) == 1
    out = capsys.readouterr().out
    assert f"checksum FAIL  {member}: " in out and "changed after the FMU was built" in out
    assert main(["verify", str(changed), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    bad = [c for c in doc["checksums"] if c["result"] == "fail"]
    assert [c["file"] for c in bad] == [member]
    assert "changed after the FMU was built" in bad[0]["message"]


# ------------------------------------------------------------------ an FMU not ours
FOREIGN = """from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Doubler(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u, self.y, self.gain = 0.0, 0.0, 2.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("gain", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.y = self.gain * self.u
        return True
"""


@pytest.fixture(scope="module")
def foreign(tmp_path_factory) -> Path:
    """A ten-line pythonfmu slave, built by pythonfmu alone (its own binaries)."""
    from pythonfmu.builder import FmuBuilder

    out = tmp_path_factory.mktemp("foreign")
    (out / "Doubler.py").write_text(FOREIGN)
    return Path(FmuBuilder.build_FMU(out / "Doubler.py", dest=out / "built"))


def _doubler_experiment(moved: bool = False) -> list:
    """u steps at each communication point; y = gain * u of the step before (gain 3)."""
    t = np.arange(0, 21) * 0.1
    u = np.sin(t)
    y = np.concatenate([[0.0], 3.0 * u[:-1]])
    if moved:
        y[7] += 10 * 1e-6 * (1 + abs(y[7]))  # ten tolerances off
    ex = Experiment("steps", "u held, y = gain * u one step late", 0.0, 2.0, 0.1, 1e-6,
                    (["time", "y"], np.column_stack([t, y])),
                    (["time", "u"], np.column_stack([t, u])), {"gain": 3.0})  # fmt: skip
    types = {"u": "Real", "y": "Real", "gain": "Real"}
    return experiment_files("doubler", [ex], types, "experiment/smoke-test", "Doubler", "d")


def test_an_fmu_we_did_not_write_passes_and_fails(foreign, tmp_path, capsys, schemas):
    assert main(["verify", str(foreign)]) == 2
    assert "carries no FMI-LS-REF experiments" in capsys.readouterr().err
    good = write_copy(foreign, tmp_path / "Doubler-good.fmu", _doubler_experiment())
    bad = write_copy(foreign, tmp_path / "Doubler-bad.fmu", _doubler_experiment(moved=True))
    with zipfile.ZipFile(good) as z:
        _validate(z, schemas)
    assert main(["verify", str(good)]) == 0, capsys.readouterr().out
    capsys.readouterr()
    assert main(["verify", str(bad), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    (ex,) = doc["experiments"]
    assert ex["result"] == "fail" and ex["variables"][0]["name"] == "y"
    assert ex["variables"][0]["time"] == pytest.approx(0.7)
    # the user's FMU itself is never written over
    with pytest.raises(AddExperimentsError, match="is the FMU itself"):
        write_copy(good, good, _doubler_experiment())


MINE = """from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class MyController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.V_hat, self.theta_g_hat, self.delta_cmd = 0.2, -0.6, 0.0
        for name in ("V_hat", "theta_g_hat"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        self.register_variable(Real("delta_cmd", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.delta_cmd = max(-0.5, min(0.5, 0.8 * (self.theta_g_hat + 0.394)))
        return True
"""


def test_add_experiments_writes_a_copy_that_carries_its_loop(tmp_path, fmu_dir, capsys):
    from pythonfmu.builder import FmuBuilder

    (tmp_path / "MyController.py").write_text(MINE)
    fmu = Path(FmuBuilder.build_FMU(tmp_path / "MyController.py", dest=tmp_path / "built"))
    scenario = tmp_path / "mine.toml"
    scenario.write_text(f'name = "mine"\nstop_time = 5.0\n[fmus]\ncontroller = "{fmu}"\n')
    before = fmu.read_bytes()
    out = tmp_path / "MyController-tested.fmu"
    args = ["add-experiments", str(fmu), "--from", str(scenario), "--out", str(out),
            "--fmu-dir", str(fmu_dir)]  # fmt: skip
    assert main(args) == 0, capsys.readouterr().err
    assert fmu.read_bytes() == before  # the user's FMU is untouched
    with zipfile.ZipFile(fmu) as a, zipfile.ZipFile(out) as b:
        assert all(a.read(n) == b.read(n) for n in a.namelist())  # every file kept
    capsys.readouterr()
    assert main(["verify", str(out)]) == 0, capsys.readouterr()
    # again onto the file it wrote: allowed; onto the input or a file not ours: refused
    assert main(args) == 0
    assert main([*args[:5], str(fmu), *args[6:]]) == 2
    assert "is the FMU itself" in capsys.readouterr().err
    foreign = tmp_path / "theirs.fmu"
    shutil.copyfile(fmu, foreign)
    assert main([*args[:5], str(foreign), *args[6:]]) == 2
    assert "is not a file glider-cosim wrote there" in capsys.readouterr().err
    assert foreign.read_bytes() == before


def test_the_one_fmu_export_carries_its_loop(fmu_dir, tmp_path, schemas, capsys):
    from glider_cosim.interop.onefmu import export_one_fmu

    fmu = export_one_fmu(tmp_path / "GliderLoop.fmu", "default", fmu_dir)
    with zipfile.ZipFile(fmu) as z:
        assert _validate(z, schemas) >= 3
    report = verify_lsref(fmu)
    assert report is not None and report.passed, report.table()
    assert [e.role for e in report.experiments] == ["experiment/smoke-test",
                                                    "experiment/validation"]  # fmt: skip
    assert {v.name for v in report.experiments[0].variables} >= {
        "plant.theta_g",
        "controller.delta_cmd",
    }
