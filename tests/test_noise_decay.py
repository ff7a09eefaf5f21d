"""The LQG's filter decay derived from the sensor noise (LQGSettings.tip_noise_budget_m, issue 22).

A faster filter forgets a slew's model error sooner and passes more sensor noise to the torque.
The default flows (``for_scenario``) give the filter a budget of a sixth of the task's tip band
for the tip's noise-driven standard deviation; the design picks the fastest decay of
``DECAY_LADDER`` within it, with the noise it is finally given (a rig's encoder included).
"""

import dataclasses
import math

import numpy as np
import pytest

from controllers import LQG, DesignModel, LQGSettings
from controllers.lqg import (
    DECAY_LADDER,
    NOISE_SHARE_OF_BAND,
    PROCESS_NOISE_LADDER,
    STEP_NOISE_SHARE,
    noise_limited_decay,
    noise_stds,
    noise_tip_std,
    quiet_process_noise,
)
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.study.rig_loop import rig_noise
from hubbeam_ctrl.study.scenarios import make_scenario
from hubbeam_ctrl.study.settings_table import controller_settings
from hubbeam_ctrl.study.tasks import Slew

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)


def _lab(decay: float = 0.3):
    sc = make_scenario(Slew(math.pi / 2, 1.5 * 0.8404), params=LAB)
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
    st = dataclasses.replace(LQGSettings.for_scenario(sc), error_decay=decay, tip_noise_budget_m=None)
    return sc, design, st


def _noisy_run(ctrl, design, st, n: int, seed: int) -> tuple:
    """``ctrl`` on its design model at rest for ``n`` samples of white sensor noise at the filter's
    levels: the tip deflection [m] and the command [N m] per sample."""
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n, 3)) * np.array([st.angle_noise_rad, st.rate_noise_rad_s, st.moment_noise_nm])
    x = np.zeros(design.n_x)
    tip, u = np.empty(n), np.empty(n)
    ctrl.reset()
    for k in range(n):
        u[k] = ctrl(k * design.dt, design.C_sensors @ x + noise[k])
        tip[k] = design.C_tip[0] @ x
        x = design.Ad @ x + design.Bd[:, 0] * float(u[k])
    return tip, u


def test_noise_tip_std_equals_a_long_noisy_run_of_the_controller_on_its_design_model():
    """The Lyapunov solve against the LQG object itself: 60 000 samples of white sensor noise at
    the filter's levels through ``ctrl(t, y)`` on the design model at rest (lab arm, 1.0 w_1).
    The sample standard deviation of the tip agrees within 2 % (measured 0.2-0.3 % over three
    seeds at 1.0 and 0.3 w_1; the tip's correlation falls to 1/e within 2-4 samples)."""
    sc, design, st = _lab(1.0)
    ctrl = LQG(design, st)
    predicted = noise_tip_std(ctrl)
    tip, _ = _noisy_run(ctrl, design, st, 60_000, seed=7)
    measured = float(np.std(tip[2000:]))
    assert predicted > 0 and measured == pytest.approx(predicted, rel=0.02), (measured, predicted)


def test_noise_step_std_equals_a_long_noisy_run_of_the_controller_on_its_design_model():
    """The command's change per sample that the sensor noise drives (noise_stds' third value, from
    the loop's lag-one covariance) against 40 000 samples through ``ctrl(t, y)`` on the design
    model at rest (lab arm, 0.3 w_1): within 3 %; and the command's own std within 3 %."""
    sc, design, st = _lab(0.3)
    ctrl = LQG(design, st)
    _, u_std, step_std = noise_stds(ctrl)
    _, u = _noisy_run(ctrl, design, st, 40_000, seed=11)
    assert float(np.std(np.diff(u[2000:]))) == pytest.approx(step_std, rel=0.03), step_std
    assert float(np.std(u[2000:])) == pytest.approx(u_std, rel=0.03), u_std
    assert step_std > u_std          # the noise reaches the command nearly white: steps exceed sqrt(2) x


def test_the_filter_trusts_its_model_more_until_the_noise_steps_fit_table_1s_limit():
    """Table 1's beam, the default Eq. 44 slew: at the default process noise the sensor noise moves
    the command by 4.67 N m a sample (std; its 4.6-sigma peak was issue 36's 21.5 N m against 20).
    The rule scales the process noise down to the first rung within STEP_NOISE_SHARE x 200 N m
    = 4 N m; the rung before it is over, the default is kept where it already fits (lab arm)."""
    sc = make_scenario("slew", params=Params())
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
    st = dataclasses.replace(LQGSettings.for_scenario(sc), error_decay=DECAY_LADDER[0])
    limit = STEP_NOISE_SHARE * 200.0

    def step(settings):
        return noise_stds(LQG(design, dataclasses.replace(settings, tip_noise_budget_m=None)))[2]

    assert step(st) > limit                                  # measured 4.67 N m
    quiet = quiet_process_noise(design, st)
    scale = quiet.torque_noise_nm / st.torque_noise_nm
    assert scale < 1.0 and step(quiet) <= limit
    assert quiet.modal_noise == pytest.approx(scale * st.modal_noise)
    rung = PROCESS_NOISE_LADDER.index(pytest.approx(scale))
    before = PROCESS_NOISE_LADDER[rung - 1]
    louder = dataclasses.replace(st, torque_noise_nm=before * st.torque_noise_nm, modal_noise=before * st.modal_noise,
                                 modal_rate_noise=before * (st.modal_rate_noise or st.modal_noise))
    assert step(louder) > limit
    # the default design takes it: LQG(design, for_scenario) carries the quieter filter
    assert LQG(design, LQGSettings.for_scenario(sc)).settings.torque_noise_nm == pytest.approx(quiet.torque_noise_nm)
    _, lab_design, lab_st = _lab(0.3)
    assert step(lab_st) <= STEP_NOISE_SHARE * LAB.tau_max and quiet_process_noise(lab_design, lab_st) is lab_st


def test_a_filter_that_would_lose_its_margin_keeps_the_default_noise():
    """accel_link (tip accelerometer, no tachometer): the noise moves the command by 0.076 of its
    limit a sample, over STEP_NOISE_SHARE, but the first quieter rung (0.7) drops the loop's disk
    margin from 0.51 to 0.36, below MARGIN_KEPT of it: the rule keeps the default filter."""
    from controllers.analysis import loop_margins
    from controllers.lqg import MARGIN_KEPT
    from hubbeam_ctrl.study.rig_loop import rig_design, rig_settings

    rig = load_rig("accel_link")
    sc = make_scenario(Slew(math.pi / 2, 1.317), params=rig.plant_params, dt=rig.timing.dt)
    design = rig_design(DesignModel.build(sc.params, sc.design_spin, sc.dt), rig)
    st = dataclasses.replace(rig_settings("lqg", LQGSettings.for_scenario(sc), rig), error_decay=DECAY_LADDER[0])
    base = LQG(design, dataclasses.replace(st, tip_noise_budget_m=None))
    assert noise_stds(base)[2] > STEP_NOISE_SHARE * base.tau_max            # measured 0.076 x tau_max
    rung = PROCESS_NOISE_LADDER[1]
    quieter = LQG(design, dataclasses.replace(st, tip_noise_budget_m=None, torque_noise_nm=rung * st.torque_noise_nm,
                                              modal_noise=rung * st.modal_noise,
                                              modal_rate_noise=rung * (st.modal_rate_noise or st.modal_noise)))
    assert (loop_margins(quieter, n_points=1000).disk_margin
            < MARGIN_KEPT * loop_margins(base, n_points=1000).disk_margin)   # 0.36 against 0.9 x 0.51
    assert quiet_process_noise(design, st) is st


@pytest.mark.parametrize("case, expected", [("paper", 1.0), ("lab", 0.3), ("link", 0.3)])
def test_the_rule_picks_the_fastest_decay_the_noise_allows(case, expected):
    """Paper beam: the tip's noise std is 0.09 of the band at every decay, so 1.0; lab arm and
    the servo link's beam: already above a sixth at 0.5, so 0.3. Checked against the stds of
    each decay on the ladder, computed here."""
    if case == "paper":
        sc = make_scenario(Slew(1.0, 1.5 * 2.6419525), params=Params())
    elif case == "lab":
        sc = make_scenario(Slew(math.pi / 2, 1.5 * 0.8404), params=LAB)
    else:
        sc = make_scenario(Slew(math.pi / 2, 0.4457), params=load_rig("servo_link").plant_params)
    st = LQGSettings.for_scenario(sc)
    band = sc.bands["settle_tip"]
    assert st.tip_noise_budget_m == pytest.approx(NOISE_SHARE_OF_BAND * band)
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
    ctrl = LQG(design, st)
    assert ctrl.settings.error_decay == expected and ctrl.settings.tip_noise_budget_m is None
    stds = [noise_tip_std(LQG(design, dataclasses.replace(st, error_decay=d, tip_noise_budget_m=None)))
            for d in DECAY_LADDER]
    within = [s <= st.tip_noise_budget_m for s in stds]
    # the ladder's answer: the last decay before the first one over budget
    first_over = within.index(False) if False in within else len(within)
    assert expected == DECAY_LADDER[max(first_over - 1, 0)], stds


def test_a_rigs_encoder_counts_in_the_noise_and_keeps_the_slow_filter():
    """servo_link: with the scenario's noise alone the rule would give 1.0 (the tip's std 0.14-0.15
    of its band); with the encoder's quantisation (rig_noise) it is 0.18-0.20 at every decay,
    over the budget, so the design keeps 0.3."""
    rig = load_rig("servo_link")
    sc = make_scenario(Slew(math.pi / 2, 0.4531), params=rig.plant_params, dt=rig.timing.dt)
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
    st = LQGSettings.for_scenario(sc)
    assert LQG(design, st).settings.error_decay == 1.0
    assert LQG(design, rig_noise(st, rig)).settings.error_decay == 0.3


def test_a_given_decay_integral_action_or_no_residual_modes_keep_error_decay():
    sc = make_scenario(Slew(1.0, 1.5 * 2.6419525), params=Params())
    design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
    assert LQGSettings.for_scenario(sc, error_decay=0.5).tip_noise_budget_m is None
    st = LQGSettings.for_scenario(sc)
    assert LQG(design, dataclasses.replace(st, integral=True)).settings.error_decay == 0.3
    assert LQG(design, dataclasses.replace(st, robust=False)).settings.error_decay == 0.3
    # a spec's [settings.lqg] error_decay is used as given
    assert controller_settings("lqg", {"error_decay": 0.5}, sc).tip_noise_budget_m is None
    assert LQG(design, controller_settings("lqg", {"error_decay": 0.5}, sc)).settings.error_decay == 0.5
    assert noise_limited_decay(design, st, 1e-12) == DECAY_LADDER[0]


def test_a_bad_budget_names_the_setting():
    with pytest.raises(ParameterError, match="tip_noise_budget_m"):
        LQGSettings(tip_noise_budget_m=0.0)
    with pytest.raises(ParameterError, match="tip_noise_budget_m"):
        LQGSettings(tip_noise_budget_m=-1e-3)

