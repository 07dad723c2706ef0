"""Our model description reader against fmpy's on every FMU of the project (issue 48):
the three FMUs in both flavors, FMI 2.0 and 3.0, every attribute glider-cosim reads; and
fmpy's checks still refuse a user's FMU whose description only fmpy's schema rejects."""

from __future__ import annotations

import zipfile

import pytest
from fmpy import read_model_description
from md_summary import summary

from glider_cosim.inputs.archives import InputFileError, read_description, read_fmu
from glider_cosim.master.errors import SystemSpecError
from glider_cosim.master.instance import Instance, in_cache

pytestmark = pytest.mark.integration
NAMES = ("GliderPlant", "GliderObserver", "GliderController")


@pytest.fixture(scope="module")
def project_fmus(fmu_dir, native_dir, fmi3_dirs):
    folders = {"python FMI 2": fmu_dir, "native FMI 2": native_dir}
    folders.update({f"{flavor} FMI 3": folder for flavor, folder in fmi3_dirs.items()})
    return {f"{kind} {n}": folder / f"{n}.fmu" for kind, folder in folders.items() for n in NAMES}


def test_every_fmu_of_the_project_reads_as_fmpy_reads_it(project_fmus):
    assert len(project_fmus) == 12
    versions = set()
    for label, fmu in project_fmus.items():
        theirs = summary(read_model_description(str(fmu)))
        assert summary(read_description(fmu)) == theirs, label
        assert summary(read_fmu(fmu, label, schema=False)) == theirs, label
        assert len(theirs["variables"]) > 10 and theirs["outputs"], label
        versions.add(theirs["model"][0])
    assert versions == {"2.0", "3.0"}


def test_the_master_reads_the_cache_without_fmpy_and_a_users_fmu_with_it(native_dir, tmp_path):
    fmu = native_dir / "GliderController.fmu"
    assert in_cache(fmu)
    user = tmp_path / "GliderController.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(user, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml":  # an attribute FMI 2.0 has not
                data = data.replace(b'<ScalarVariable name="V_hat"',
                                    b'<ScalarVariable name="V_hat" unknown="1"', 1)  # fmt: skip
            dst.writestr(info, data)
    assert not in_cache(user)
    assert read_fmu(user, None, schema=False).modelName == "GliderController"
    with pytest.raises(InputFileError, match="has no readable model description .*unknown"):
        read_fmu(user, "instance c")
    with pytest.raises(SystemSpecError, match="instance c: FMU 'GliderController.fmu' has no"):
        Instance("c", user)
    assert Instance("c", fmu).md.modelName == "GliderController"
