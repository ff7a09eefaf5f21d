"""The exact-beam plant (hubbeam_ctrl.exact): Exudyn's ANCF beam against FOAM and the reference curve.

Short windows only (the 30 s runs are in benchmarks/bench_exact.py).
"""

from __future__ import annotations

import csv
from importlib.resources import files

import numpy as np
import pytest

from hubbeam_ctrl import Params, SpinUp, TorquePulse, simulate
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.exact import EXUDYN_INSTALL, ExactBeamPlant, element_rule, exudyn_available, highest_mode_hz
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop

needs_exudyn = pytest.mark.skipif(not exudyn_available(), reason=EXUDYN_INSTALL)


def _run(plant: ExactBeamPlant, t_end: float, tau=0.0) -> np.ndarray:
    """Rows ``[t, theta, v_tip, u_tip, root_moment, root_moment_from_curvature]``."""
    x = plant.initial_state()
    rows = [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]
    for k in range(int(round(t_end / plant.dt))):
        x = plant.step(x, tau)
        o = plant.outputs
        rows.append([(k + 1) * plant.dt, o["theta"], o["v_tip"], o["u_tip"], o["root_moment"],
                     plant.root_moment_from_curvature()])
    return np.array(rows)


def test_element_rule():
    assert element_rule(10) == 32          # the reference's count for the 10-mode plant of Table 1
    assert element_rule(5) == 16
    assert element_rule(11) == 40


@needs_exudyn
def test_bad_input_names_the_option():
    with pytest.raises(ParameterError, match=r"^n_elements must be an integer in \[20, 512\]"):
        ExactBeamPlant(Params(), n_elements=16, n_modes=10)
    with pytest.raises(ParameterError, match="^substeps"):
        ExactBeamPlant(Params(), n_elements=32, substeps=0)


def test_missing_exudyn_is_one_line(monkeypatch):
    import hubbeam_ctrl.exact.beam as beam
    monkeypatch.setattr(beam, "exudyn_available", lambda: False)
    with pytest.raises(ParameterError) as err:
        simulate_closed_loop("ancf", _Pulse(TorquePulse()), 0.05, params=Params(n_transverse=5))
    assert "pip install 'hubbeam-ctrl[exact]'" in str(err.value) and "\n" not in str(err.value)


@needs_exudyn
@pytest.mark.parametrize("tau_m, tol", [(2.0, 1e-3), (200.0, 1.2e-2)])
def test_eq44_peak_against_foam(tau_m, tol):
    """Eq. 44 (continuous torque) over the first 2 s, whose peak tip deflection is at 1.77 s.

    Small torque (linear range): the exact beam and FOAM agree to 0.05 % (measured). At the paper's
    200 N m (1.3 m = 0.16 L of tip deflection) the exact beam's peak is 0.90 % below FOAM's
    (measured -1.28834 m against -1.30004 m; CFOAM -1.3142 m): FOAM's geometric approximation.
    """
    pulse = TorquePulse(tau_m=tau_m)
    params = Params(n_transverse=10)
    exact = ExactBeamPlant(params, n_elements=32, dt=0.01, substeps=20, torque_function=pulse)
    rows = _run(exact, 2.0)
    foam = simulate("foam", pulse, 2.0, params=params)
    peak_exact = rows[np.argmax(np.abs(rows[:, 2])), 2]
    peak_foam = foam.v_tip[np.argmax(np.abs(foam.v_tip))]
    assert abs(peak_exact / peak_foam - 1) < tol
    # the hub angle at 2 s within 5e-4 of FOAM's (measured 2.2e-4 at 200 N m, during the peak deflection)
    assert rows[-1, 1] == pytest.approx(foam.theta[-1], rel=5e-4)
    # the root moment: the clamp reaction and the first element's curvature agree
    k = np.argmax(np.abs(rows[:, 4]))
    assert rows[k, 5] == pytest.approx(rows[k, 4], rel=2e-3)


@needs_exudyn
def test_spinup_against_reference():
    """Fig. 6 spin-up (w_f = 5 rad/s, t_f = 30 s, no tip mass), prescribed hub, first 6 s, against the
    exact-beam reference curve (hubbeam_ctrl/data/spinup_w5_tf30_ancf.csv)."""
    with files("hubbeam_ctrl.data").joinpath("spinup_w5_tf30_ancf.csv").open() as fh:
        ref = np.array([[float(v) for v in row] for row in list(csv.reader(fh))[1:]])
    spin = SpinUp(w_f=5.0, t_f=30.0)
    t_end = 6.0
    plant = ExactBeamPlant(Params(m_t=0.0, n_transverse=10), n_elements=32, dt=0.05, substeps=100,
                           prescribed=lambda t: spin(t)[0])
    rows = _run(plant, t_end)
    keep = ref[:, 0] <= t_end + 1e-9
    assert np.allclose(rows[:, 0], ref[keep, 0])
    err = np.max(np.abs(rows[:, 2] - ref[keep, 3])) / np.max(np.abs(ref[keep, 3]))
    assert err < 0.01
    assert np.allclose(rows[:, 1], ref[keep, 1], atol=1e-9)


class _Pulse:
    """An open-loop 'controller': Eq. 44 sampled (zero-order hold)."""

    measurement = "sensors"
    name = "eq44"

    def __init__(self, pulse):
        self.pulse = pulse

    def __call__(self, t, y):
        return float(self.pulse(t))

    def reset(self):
        pass


@needs_exudyn
def test_closed_loop_on_the_exact_plant():
    """The sampled Eq. 44 through simulate_closed_loop: the exact plant against FOAM, same loop."""
    params = Params(n_transverse=5)
    settings = ClosedLoopSettings()
    ctrl = _Pulse(TorquePulse())
    ex = simulate_closed_loop("ancf", ctrl, 2.0, params=params, settings=settings)
    fo = simulate_closed_loop("foam", ctrl, 2.0, params=params, settings=settings)
    assert ex.model == "ancf" and ex.settings["plant_elements"] == 16
    assert ex.settings["substeps"] == fo.settings["substeps"]
    assert np.max(np.abs(ex.v_tip)) == pytest.approx(np.max(np.abs(fo.v_tip)), rel=1.2e-2)
    assert ex.q[-1, 0] == pytest.approx(fo.q[-1, 0], rel=5e-4)      # measured 2.2e-4
    # the projected modal state reproduces the exact tip to 1 %
    tip_projected = ex.q[:, 1 + params.n_axial:] @ _f2_tip(params)
    assert np.max(np.abs(tip_projected - ex.v_tip)) < 0.01 * np.max(np.abs(ex.v_tip))
    with pytest.raises(ParameterError, match="^n_elements"):
        simulate_closed_loop("foam", ctrl, 0.05, params=params, n_elements=16)


def _f2_tip(params):
    from hubbeam_ctrl.plant.basis import transverse_shapes
    return transverse_shapes([params.L], params.n_transverse, params.L)[0]


@needs_exudyn
@pytest.mark.slow
def test_halving_step_and_doubling_elements():
    """The rule's plant (32 elements, 20 steps per 10 ms) against 64 elements and 40 steps: Eq. 44's
    tip over 2 s within 1e-4 of its peak."""
    pulse = TorquePulse()
    a = _run(ExactBeamPlant(Params(), n_elements=32, dt=0.01, substeps=20, torque_function=pulse), 2.0)
    b = _run(ExactBeamPlant(Params(), n_elements=64, dt=0.01, substeps=40, torque_function=pulse), 2.0)
    assert np.max(np.abs(a[:, 2] - b[:, 2])) < 1e-4 * np.max(np.abs(b[:, 2]))


@needs_exudyn
def test_a_step_that_does_not_resolve_the_highest_mode_is_refused():
    """12 steps per period of bending mode n_modes at least: 10 modes of Table 1's beam (113.9 Hz free
    hub) at 10 ms need 14 substeps; the message names the option as the caller spelled it."""
    from hubbeam_ctrl.exact import min_substeps
    f = highest_mode_hz(Params(), 10)
    assert f == pytest.approx(113.94, rel=1e-3)
    assert min_substeps(0.01, f) == 14
    with pytest.raises(ParameterError, match=r"^substeps must be at least 14 for dt = 0.01 s \(bending mode 10 "):
        ExactBeamPlant(Params(), n_elements=32, n_modes=10, dt=0.01, substeps=13)
    with pytest.raises(ParameterError, match=r"^--substeps must be at least 14 for --dt = 0.01 s"):
        ExactBeamPlant(Params(), n_elements=32, n_modes=10, dt=0.01, substeps=13, substeps_option="--substeps",
                       dt_option="--dt")
    with pytest.raises(ParameterError, match=r"^dt must be at most 0.1463 s"):
        ExactBeamPlant(Params(), n_elements=32, n_modes=10, dt=0.2, substeps=200)
    assert ExactBeamPlant(Params(), n_elements=32, n_modes=10, dt=0.01, substeps=14).min_substeps == 14
    # the closed loop's substeps (ClosedLoopSettings.substeps) is checked likewise
    with pytest.raises(ParameterError, match=r"^substeps must be at least 3 for dt = 0.01 s \(bending mode 5 "):
        simulate_closed_loop("ancf", _Pulse(TorquePulse()), 0.05, params=Params(n_transverse=5),
                             settings=ClosedLoopSettings(substeps=2))


def test_hub_torque_scalar_equals_hub_torque():
    import dataclasses

    from hubbeam_ctrl.plant.rig import Friction, load_rig
    from hubbeam_ctrl.sim.hardware import Hardware
    hw = Hardware.from_rig(load_rig("servo_link"))
    stribeck = dataclasses.replace(hw, friction=Friction(viscous=1e-3, coulomb=0.01, breakaway=0.02,
                                                         stribeck_velocity=0.05))
    rng = np.random.default_rng(0)
    for h in (hw, stribeck):
        for u, thd in zip(rng.uniform(-15, 15, 300), rng.normal(0, 1, 300) * rng.choice([1e-4, 1e-2, 1, 10], 300)):
            assert h.hub_torque_scalar(u, thd) == pytest.approx(float(h.hub_torque(u, thd)), abs=1e-14)


@needs_exudyn
def test_rig_friction_inside_the_step_sticks_as_the_stepper():
    """The servo link's DC drive with 50 mN m of Coulomb friction: 3 V for 0.1 s, then 0 V, 0.8 s. The drive
    and the sliding friction act inside every step at the current hub rate, and the hub sticks (Karnopp)
    inside the step (Exudyn's discontinuous iteration repeats a step held or sliding). Against FOAM's
    PlantStepper, which decides per sample: measured 5 stick events against 6, 150 held samples against 151,
    the first hold at sample 132 against 119 (at the first reversal, sample 119, the stepper holds the whole
    sample; held for one step, the beam pulls the hub harder than breakaway), the hub angle within 0.40 %."""
    import dataclasses

    from hubbeam_ctrl.plant.modal import modal_analysis
    from hubbeam_ctrl.plant.models import build_model
    from hubbeam_ctrl.plant.rig import Friction, load_rig
    from hubbeam_ctrl.sim.hardware import Hardware
    from hubbeam_ctrl.sim.stepper import PlantStepper, substep_rule
    rig = load_rig("servo_link")
    hw = dataclasses.replace(Hardware.from_rig(rig), friction=Friction(viscous=4e-3, coulomb=0.05))
    p = rig.plant_params.replace(n_transverse=4, n_axial=2)
    dt, model = rig.timing.dt, build_model("foam", p)
    n_sub = substep_rule(modal_analysis(model, 0.0, "free").bending_hz, dt).substeps
    foam = PlantStepper(model, ClosedLoopSettings(dt=dt).stepper_settings(n_sub), hardware=hw)
    exact = ExactBeamPlant(p, n_elements=16, dt=dt, substeps=n_sub, n_modes=4, n_axial=2, hardware=hw)
    x, s = foam.initial_state(np.zeros(2 * model.n_q), 3.0), exact.initial_state()
    rows = []
    for k in range(800):
        volts = 3.0 if k < 100 else 0.0
        x, s = foam.step(x, volts), exact.step(s, volts)
        rows.append((x[0], exact.outputs["theta"], foam.stuck, exact.stuck, exact.hold_torque,
                     exact.outputs["theta_dot"]))
    th_f, th_e, stuck_f, stuck_e, hold, thd_e = (np.array(c) for c in zip(*rows))
    assert abs(exact.stick_events - foam.stick_events) <= 1 and exact.stick_events >= 3
    assert abs(int(stuck_e.sum()) - int(stuck_f.sum())) <= 0.05 * stuck_f.sum()
    assert 0 <= np.argmax(stuck_e) - np.argmax(stuck_f) <= 15
    assert np.all(np.abs(hold[stuck_e]) <= hw.friction.static) and np.all(np.abs(thd_e[stuck_e]) < 1e-9)
    assert np.max(np.abs(th_e - th_f)) < 5e-3 * np.max(np.abs(th_f))
