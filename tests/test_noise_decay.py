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
from controllers.lqg import DECAY_LADDER, NOISE_SHARE_OF_BAND, noise_limited_decay, noise_tip_std
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


def test_noise_tip_std_equals_a_long_noisy_run_of_the_controller_on_its_design_model():
    """The Lyapunov solve against the LQG object itself: 60 000 samples of white sensor noise at
    the filter's levels through ``ctrl(t, y)`` on the design model at rest (lab arm, 1.0 w_1).
    The sample standard deviation of the tip agrees within 2 % (measured 0.2-0.3 % over three
    seeds at 1.0 and 0.3 w_1; the tip's correlation falls to 1/e within 2-4 samples)."""
    sc, design, st = _lab(1.0)
    ctrl = LQG(design, st)
    predicted = noise_tip_std(ctrl)
    rng = np.random.default_rng(7)
    n = 60_000
    sigma = np.array([st.angle_noise_rad, st.rate_noise_rad_s, st.moment_noise_nm])
    noise = rng.standard_normal((n, 3)) * sigma
    x = np.zeros(design.n_x)
    tip = np.empty(n)
    ctrl.reset()
    for k in range(n):
        tau = ctrl(k * design.dt, design.C_sensors @ x + noise[k])
        tip[k] = design.C_tip[0] @ x
        x = design.Ad @ x + design.Bd[:, 0] * float(tau)
    measured = float(np.std(tip[2000:]))
    assert predicted > 0 and measured == pytest.approx(predicted, rel=0.02), (measured, predicted)


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

