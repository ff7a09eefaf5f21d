"""The values compare() takes (issue 37, the house): each refuses a bad field in one line naming
it, compare_arguments routes flat options into them, and compare's entry points stay small."""

import inspect

import pytest

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.compare import compare, run_compare
from hubbeam_ctrl.study.compare_values import (
    CompareSettings,
    DesignChoice,
    PayloadChoice,
    PlantChoice,
    RunChoice,
    ScenarioChoice,
    compare_arguments,
)


@pytest.mark.parametrize("make, pattern", [
    (lambda: PlantChoice(plant_params={"L": 1.0}), r"^plant_params must be a Params .* got dict$"),
    (lambda: PlantChoice("foam", check_plant="foam"), r"^check_plant must be one of .*plant = 'foam'.*got 'foam'$"),
    (lambda: PlantChoice("foam", check_plant="tlam"), r"^check_plant must be one of .* got 'tlam'$"),
    (lambda: DesignChoice(design_params=3), r"^design_params must be a Params .* got int$"),
    (lambda: DesignChoice(design_modes=0), r"^design_modes must be an integer in 1\.\.20, got 0$"),
    (lambda: DesignChoice(design_modes=True), r"^design_modes must be an integer in 1\.\.20, got True$"),
    (lambda: DesignChoice(settings=["lqr"]), r"^settings must be a dict .* got list$"),
    (lambda: DesignChoice(reference="smooth"), r"^reference must be one of task, rigid, planned, optimal, "
                                               r"got 'smooth'$"),
    (lambda: DesignChoice(limit="fast"), r"^limit must be one of rigid, optimal, got 'fast'$"),
    (lambda: DesignChoice(schedule=0), r"^schedule must be an integer >= 1 and <= \d+ .* got 0$"),
    (lambda: RunChoice(sim_settings={"dtt": 1}), r"^sim_settings: unknown field\(s\) dtt of ClosedLoopSettings$"),
    (lambda: RunChoice(sim_settings=3), r"^sim_settings must be a ClosedLoopSettings or a dict, got int$"),
    (lambda: PayloadChoice(payload_learning=1), r"^payload_learning must be a PayloadLearningSettings, got int$"),
    (lambda: CompareSettings(run=DesignChoice()), r"^settings\.run must be a RunChoice, got DesignChoice$"),
    (lambda: compare_arguments(t_fin=1.0), r"^compare: unknown option\(s\) t_fin$"),
])
def test_a_bad_field_is_refused_in_one_line_naming_it(make, pattern):
    with pytest.raises(ParameterError, match=pattern) as err:
        make()
    assert "\n" not in str(err.value)


def test_compare_refuses_what_is_not_a_rig_or_settings():
    with pytest.raises(ParameterError, match=r"^rig must be a Rig .* got str; the plant is PlantChoice"):
        compare("foam", "slew", "lqr")
    with pytest.raises(ParameterError, match=r"^settings must be a CompareSettings .* got dict$"):
        compare(None, "slew", "lqr", {"t_end": 5.0})


def test_compare_arguments_routes_each_option_to_its_value():
    p = Params(n_axial=2, n_transverse=2)
    kw = compare_arguments("cfoam", "spinup", "lqr", params=p, t_end=16.0, horizon=20, w_f=2.0, payload_range=(0, 1),
                           plant_modes=4, progress=True)
    s = kw["settings"]
    assert kw["rig"] is p and kw["task"] == "spinup" and kw["controllers"] == "lqr" and kw["progress"] is True
    assert (s.plant.plant, s.plant.plant_modes, s.design.horizon, s.run.t_end, s.scenario.w_f,
            s.payload.payload_range) == ("cfoam", 4, 20, 16.0, 2.0, (0, 1))
    assert s.design == DesignChoice(horizon=20) and s.scenario == ScenarioChoice(w_f=2.0)


def test_the_entry_points_take_at_most_eight_parameters():
    assert len(inspect.signature(compare).parameters) == 7      # designed=: the CLI's loop figure starts early
    assert len(inspect.signature(run_compare).parameters) == 7
