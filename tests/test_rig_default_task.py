"""A rig's default task (``hubbeam compare --rig R`` with no duration): a quarter turn in 1.5 x an
upper bound of the rig's time-optimal slew, from the drive's rigid bound and the first mode, instead
of the paper beam's Eq. 44 slew of 10 s (a 5658 rad slew on ``servo_link`` that failed every design);
and a failed integration says so in one line, with CasADi's dump of the rootfinder kept off the
terminal."""

import json
import math

import pytest

from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.study.yardstick import DEFAULT_RIG_PACE, rig_default_slew
from tests.conftest import ROOT

#: ``hubbeam optimal --rig R --slew-angle A`` of each preset (``benchmarks/bench_any_rig.py``).
OPTIMAL = json.loads((ROOT / "benchmarks" / "results" / "bench_any_rig.json").read_text())["rigs"]


@pytest.mark.parametrize("name", sorted(OPTIMAL))
def test_the_default_duration_bounds_the_time_optimal_slew(name):
    """The rigid drive bound plus one first-mode period is an upper bound of the time-optimal slew
    (the rigid bang-bang through a ZVD shaper on the first mode): at most 25 % above it."""
    rig = load_rig(name if name != "servo_link_delay1" else "servo_link")
    t_opt, angle = OPTIMAL[name]["t_opt_s"], OPTIMAL[name]["angle_rad"]
    task, note = rig_default_slew(rig, angle)
    bound = task.duration / DEFAULT_RIG_PACE
    assert task.angle == angle
    assert t_opt * (1 - 1e-3) <= bound <= 1.25 * t_opt, (name, bound, t_opt)
    assert f"{task.duration:.4g} s" in note and "\n" not in note


@pytest.mark.slow
def test_compare_on_a_rig_with_its_defaults_settles(tmp_path, capsys, fast_backend):
    out = tmp_path / "sl"
    assert main(["compare", "--rig", "servo_link", "--controllers", "openloop,lqr", "--out", str(out),
                 "--json"]) == 0
    cap = capsys.readouterr()
    rows = {r["controller"]: r for r in json.loads(cap.out)}
    task, _ = rig_default_slew(load_rig("servo_link"))
    assert task.angle == pytest.approx(math.pi / 2)
    assert rows["lqr"]["verdict"] == "settled", rows["lqr"]["verdict_reason"]
    assert abs(rows["lqr"]["final_angle_error_rad"]) <= 2 * 2 * math.pi / 4096    # within 2 counts
    assert rows["lqr"]["within_drive_limits"]
    assert "the rig's default slew, 1.571 rad in" in (out / "report.md").read_text()


def test_a_failed_rootfinder_step_is_one_error_without_casadis_dump(capsys):
    """The exact step's rootfinder on a state far outside the model's range fails: one HubbeamError,
    and CasADi's printout of the rootfinder's inputs (through sys.stderr) stays off the terminal.
    (``compare --rig servo_link --tf 10`` ran into it at 9.66 s and printed 250 lines.)"""
    import numpy as np

    from hubbeam_ctrl.core.errors import HubbeamError
    from hubbeam_ctrl.plant.models import build_model
    from hubbeam_ctrl.sim.stepper import PlantStepper
    stepper = PlantStepper(build_model("foam", load_rig("servo_link").plant_params.replace(n_transverse=2)),
                           backend="vm")
    state = np.full(len(stepper._s_in), 1e12)
    with pytest.raises(HubbeamError, match="the implicit step did not converge"):
        stepper._robust_step(state, np.zeros((1, stepper.settings.substeps)))
    err = capsys.readouterr().err
    assert "Function rf" not in err and "Input 0" not in err


def test_design_and_codegen_on_a_rig_take_the_rigs_default_slew(tmp_path, capsys):
    """``hubbeam codegen --rig R`` (and ``design``) with no --tf design for the slew ``compare --rig R``
    runs, not the paper beam's 10 s Eq. 44 slew (5658 rad on ``servo_link``)."""
    from hubbeam_ctrl.study.design_task import task_and_design
    rig = load_rig("servo_link")
    task, _ = rig_default_slew(rig)
    sc, _ = task_and_design(rig.plant_params, "slew", rig=rig)
    assert sc.t_f == task.duration and (sc.task.angle, sc.task.duration) == (task.angle, task.duration)
    assert sc.reference.theta[-1] == pytest.approx(math.pi / 2)
    sc, _ = task_and_design(rig.plant_params, "slew", rig=rig, slew_angle=1.0)
    assert sc.t_f == rig_default_slew(rig, 1.0)[0].duration != task.duration
    assert sc.reference.theta[-1] == pytest.approx(1.0)
    # a duration given, an ideal rig or no rig: as before (10 s by default)
    given = task_and_design(rig.plant_params, "slew", rig=rig, t_f=2.0)[0]
    assert given.t_f == 2.0 and given.reference.theta[-1] == pytest.approx(math.pi / 2)
    assert task_and_design(load_rig("paper").plant_params, "slew", rig=load_rig("paper"))[0].t_f == 10.0
    out = tmp_path / "c"
    assert main(["codegen", "--controller", "lqr", "--rig", "servo_link", "--out", str(out)]) == 0
    assert f"Theta = 1.5708 rad in tf = {task.duration:g} s" in capsys.readouterr().out


def test_a_linear_plan_that_bends_the_tip_far_is_noted():
    """A slew planned on the linear design model that bends the tip past 10 % of L is noted, with the
    remedy; servo_link at 1.1 T* (0.332 s) is noted: the plan bends it by 30 % of L, the deflection
    bound of the plan (controllers.planning.DEFLECTION_LIMIT; the smoothest plan bent it by 47 %, the
    bound is active since the servo_payload fix of issue 36); the paper's beam at 2 T* of its 90
    degrees (8 % of L) is not."""
    import math

    from hubbeam_ctrl import Params
    from hubbeam_ctrl.plant.rig import load_rig
    from hubbeam_ctrl.study import Slew
    from hubbeam_ctrl.study.scenarios import make_scenario
    from hubbeam_ctrl.study.yardstick import LINEAR_PLAN_TIP_SHARE, linear_plan_note
    rig = load_rig("servo_link")
    fast = make_scenario(Slew(math.pi / 2, 1.1 * 0.30224), params=rig.beam, t_end=None)
    (note,) = linear_plan_note(fast.reference, rig.beam.L)
    share = int(note.split("bends the tip by ")[1].split(" %")[0])
    assert 29 <= share <= 30 and "--reference optimal" in note and LINEAR_PLAN_TIP_SHARE == 0.1
    slow = make_scenario(Slew(math.pi / 2, 2.0 * 3.0275), params=Params(), t_end=None)
    assert linear_plan_note(slow.reference, Params().L) == []
    rigid = make_scenario(Slew(math.pi / 2, 1.1 * 0.30224), params=rig.beam, t_end=None, reference="rigid")
    assert linear_plan_note(rigid.reference, rig.beam.L) == []


def test_a_duration_alone_on_a_rig_turns_the_rigs_default_angle():
    """``compare --rig R --tf T`` with no --slew-angle turns the rig's default quarter turn in T, as the
    default slew's note says ("give --tf for another"), not Eq. 44's ``tau_max T^2 / (2 pi J)``: found on
    a random 2.4 m aluminium link on a geared motor (``benchmarks/fuzz_rigs.py link 36``, rig 4), where
    --tf 4 asked 39.5 rad of a 27 N m drive and every run left FOAM's range at 0.24 s. On the beam
    alone (and an ideal rig) --tf still gives Eq. 44's angle."""
    from hubbeam_ctrl.study.compare_values import ScenarioChoice
    from hubbeam_ctrl.study.yardstick import DEFAULT_RIG_SLEW_RAD, task_on_rig
    rig = load_rig("servo_link")
    task, scenario, notes = task_on_rig(rig, "slew", ScenarioChoice(t_f=0.8))
    assert (task, scenario.t_f, scenario.slew_angle) == ("slew", 0.8, DEFAULT_RIG_SLEW_RAD)
    assert len(notes) == 1 and "default angle, 1.571 rad, in the given tf = 0.8 s" in notes[0]
    chosen = ScenarioChoice(t_f=0.8, slew_angle=1.0)
    assert task_on_rig(rig, "slew", chosen) == ("slew", chosen, [])
    ideal = ScenarioChoice(t_f=0.8)
    assert task_on_rig(load_rig("paper"), "slew", ideal) == ("slew", ideal, [])
    assert task_on_rig(None, "slew", ideal) == ("slew", ideal, [])
