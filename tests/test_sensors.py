"""Sensor rows defined once: the linear models, the design model and the simulator read the same
``sensor_matrix``."""

import numpy as np
import pytest

from controllers import DesignModel
from hubbeam_ctrl import Params, build_model, linearize
from hubbeam_ctrl.plant.sensors import SENSOR_NAMES, sensor_matrix

P = Params(n_axial=3, n_transverse=4)


@pytest.mark.parametrize("model", ["foam", "cfoam", "tlam", "sfoam"])
def test_linear_sensor_outputs_are_the_sensor_rows(model):
    m = build_model(model, P)
    lm = linearize(model, 0.5, P, outputs=SENSOR_NAMES)
    C = sensor_matrix(P, m.n_transverse, m.n_axial)
    assert lm.output_names == list(SENSOR_NAMES)
    assert np.array_equal(lm.C, C)
    # root moment: EI f2''(0) on the transverse coordinates only
    assert np.array_equal(C[2, m.transverse_slice], P.EI * m.basis.f2pp_root)
    assert np.count_nonzero(C[2]) == m.n_transverse


def test_design_model_reads_the_sensor_rows():
    d = DesignModel.build(P, 0.0, 0.01, n_modes=2)
    assert np.array_equal(d.C_sensors, sensor_matrix(P.replace(n_transverse=2), 2))
    assert d.C_sensors[2, 1] == pytest.approx(P.EI * build_model("sfoam", P.replace(n_transverse=2)).basis.f2pp_root[0])
