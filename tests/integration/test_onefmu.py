"""One-FMU export of the closed loop: valid for fmpy, runs under fmpy.simulate_fmu."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from glider_cosim.onefmu import export_one_fmu
from glider_cosim.runner import simulate
from glider_plant.model import equilibrium
from glider_plant.params import GliderParams

pytestmark = pytest.mark.integration


def test_closed_loop_as_one_fmu(fmu_dir, tmp_path):
    fmu = export_one_fmu(tmp_path / "GliderLoop.fmu", None, fmu_dir)
    assert validate_fmu(str(fmu)) == []
    r = simulate_fmu(str(fmu), stop_time=60.0, output_interval=0.02,
                     output=["plant.theta_g", "controller.delta_cmd"])  # fmt: skip
    assert len(r) == 3001
    th = r["plant.theta_g"]
    assert th[0] == pytest.approx(math.radians(-35.0), abs=1e-12)
    assert abs(th[-1] - equilibrium(GliderParams()).theta_g) < math.radians(0.01)
    ours = simulate(None, None, fmu_dir=fmu_dir, build=False).column("plant.theta_g")
    # the container schedules and delays the links its own way: close, not identical
    assert np.degrees(np.max(np.abs(th - ours))) < 1.0
