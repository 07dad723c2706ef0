"""One-FMU export of the closed loop: valid for fmpy, runs under fmpy.simulate_fmu and
equals our master's Jacobi run (the container delays each link by one step)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from glider_cosim.onefmu import OneFMUError, export_one_fmu
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
    jacobi = simulate(None, None, fmu_dir=fmu_dir, build=False, coupling="jacobi")
    assert np.abs(th - jacobi.column("plant.theta_g")).max() < 1e-12
    gs = simulate(None, None, fmu_dir=fmu_dir, build=False)
    diff = np.degrees(np.abs(th - gs.column("plant.theta_g")).max())
    assert 0.1 < diff < 0.6  # 0.47 deg: one more sample of delay than Gauss-Seidel


def test_one_fmu_export_refuses_events(fmu_dir, tmp_path):
    with pytest.raises(OneFMUError, match=r"sec53-protocol.toml: key 'event'"):
        export_one_fmu(tmp_path / "x.fmu", "sec53-protocol", fmu_dir)
