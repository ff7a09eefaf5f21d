"""Issue 28: a sweep spec's torque budget comes from its own parameters; errors name spec keys."""

import pytest

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.spec_files import load_spec

SMALL_BEAM = {"study": {"controllers": ["openloop", "lqr"], "t_f": 1.0, "t_end": 6.5},
              "params": {"n_axial": 2, "n_transverse": 2, "tau_max": 1.5}}


def test_budget_defaults_to_the_specs_motor():
    spec = load_spec(SMALL_BEAM)
    assert spec.tau_max is None and spec.torque_budget == 1.5
    sc = spec.scenario_for(spec.params)
    assert sc.tau_max == 1.5
    # the Eq. 44 slew of the 1.5 N m motor: Theta = tau t_f^2 / (2 pi J)
    import math
    J = spec.params.total_inertia
    assert sc.task.angle == pytest.approx(1.5 * 1.0 ** 2 / (2 * math.pi * J), rel=1e-12)


def test_budget_above_the_motor_names_the_key_and_the_value_written():
    data = {**SMALL_BEAM, "study": {**SMALL_BEAM["study"], "tau_max": 2.0}}
    with pytest.raises(ParameterError) as err:
        load_spec(data)
    text = str(err.value)
    assert text.startswith("study.tau_max must be in (0, 1.5]") and text.endswith("got 2")
    assert "200" not in text


def test_scenario_errors_name_the_spec_key():
    data = {**SMALL_BEAM, "study": {**SMALL_BEAM["study"], "t_end": 1.5}}
    with pytest.raises(ParameterError, match=r"^study\.t_end must exceed"):
        load_spec(data)
