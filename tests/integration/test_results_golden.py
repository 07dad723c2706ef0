"""The default run's results.csv, byte for byte: its first rows and its last, and the
SHA-256 of the whole file, as main wrote them (`8583e5c`, Python flavor; the native
flavor writes the same bytes) before the text moved from a C formatter to the standard
library (issue 53). A change of the text (or of the bits) fails here."""

from __future__ import annotations

import hashlib

import pytest

from glider_cosim.runner import simulate

pytestmark = pytest.mark.integration

HEADER = (
    "time,plant.theta_meas,plant.theta,plant.V,plant.theta_g,plant.alpha,"
    "plant.omega2,plant.delta,plant.x,plant.z,observer.theta_filt,observer.V_hat,"
    "observer.theta_g_hat,observer.alpha_hat,observer.omega2_hat,observer.theta_hat,"
    "controller.delta_cmd"
)
FIRST = (
    "0.0,-0.593411945678072,-0.593411945678072,0.2,-0.6108652381980153,"
    "0.017453292519943295,0.0,0.0,0.0,0.0,-0.593411945678072,0.23712728209303024,"
    "-0.3940432938639892,0.02653061224489796,0.0,-0.36751268161909123,-0.0"
)
SECOND = (
    "0.02,-0.5933995270413053,-0.5933995270413053,0.2003033762227153,"
    "-0.6126453726329654,0.019245845591660076,0.0011968363620585179,0.0,"
    "0.0032770040060912994,0.0022990282987539364,-0.593411945678072,"
    "0.23415054152420128,-0.4019426039686332,0.026249179868598902,"
    "-0.0030053280150095178,-0.37569342410003426,0.007336544590692266"
)
LAST = (
    "60.0,-0.3675112294857015,-0.3675112294857015,0.23711992886047534,"
    "-0.39404334109944317,0.026532111613741676,-2.317472385259667e-07,"
    "1.4869739461496636e-06,12.885881090067285,5.393495238707467,-0.3675112203450294,"
    "0.2371199380394992,-0.3940433337042454,0.026532109504146844,"
    "-2.337268713648917e-07,-0.3675112242000985,1.4823390105782396e-06"
)
SHA256 = "be2c4fbafde8b27bce6f6b284308867737db4c82f34cf4ceeb689417488c38fb"


def test_the_default_runs_results_csv_is_the_golden_text(fmu_dir, tmp_path):
    simulate("default", out=tmp_path, fmu_dir=fmu_dir, build=False, plots=False)
    data = (tmp_path / "results.csv").read_bytes()
    lines = data.decode().splitlines()
    assert len(lines) == 3002
    assert lines[0] == HEADER
    assert lines[1:3] == [FIRST, SECOND]
    assert lines[-1] == LAST
    assert hashlib.sha256(data).hexdigest() == SHA256
