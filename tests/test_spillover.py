"""Spillover (issue 10, items 3 and 4): verdicts, and LQG with and without residual modes
on the paper's beam with ten modes and no structural damping."""

import numpy as np
import pytest

from controllers import LQG, LQR, PD, DesignModel, LQGSettings, make_controller
from controllers.residual import embedding, estimator_modes
from hubbeam_ctrl import Params
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.study import loop_poles, make_scenario
from hubbeam_ctrl.study.metrics import (
    GROWTH_LIMIT,
    closed_loop_metrics,
    residual_growth,
    saturated_fraction,
    verdict,
)


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(Params(), 0.0, 0.01, 5)


def test_verdict_rules():
    t = np.linspace(0, 10, 1001)
    ring = 0.2 * np.sin(2 * np.pi * 0.46 * t)
    assert residual_growth(ring) == pytest.approx(1.0, abs=0.01)
    assert residual_growth(np.exp(0.2 * t) * ring) == pytest.approx(np.exp(0.2 * 7.5), rel=0.05)
    assert saturated_fraction([200, -200, 10, 0], 200.0) == 0.5
    band = 1e-3
    assert verdict(True, 1.0, 0.0, 0.0, True, band) == "diverged"
    assert verdict(False, 5.0, 0.01, 0.0, False, band) == "unstable"       # growing
    assert verdict(False, 5.0, 1e-4, 0.0, True, band) == "settled"         # growing noise below the band
    assert verdict(False, 1.0, 0.01, 0.9, False, band) == "unstable"       # saturation limit cycle
    assert verdict(False, 1.0, 0.2, 0.0, False, band) == "not settled"     # the undamped open loop
    assert verdict(False, 0.5, 1e-4, float("nan"), True, band) == "settled"
    assert GROWTH_LIMIT == 2.0


def test_residual_modes_rule(design):
    # every mode below the 50 Hz Nyquist frequency (six, up to 37.3 Hz) and the first above it
    assert estimator_modes(design) == 7
    lab = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05)
    assert estimator_modes(DesignModel.build(lab, 0.0, 0.01, 5)) == 5   # its modes 4-5 are above Nyquist
    E = embedding(5, 7)
    x = np.arange(12.0)
    assert np.array_equal(E.T @ (E @ x), x) and (E @ x)[6:8].tolist() == [0, 0]
    assert LQG(design).filter_model.n_modes == 7
    assert LQG(design, LQGSettings(robust=False)).filter_model is design
    with pytest.raises(Exception, match="residual_modes"):
        LQG(design, LQGSettings(residual_modes=4))


def test_sampled_loop_poles_on_the_richer_model(design):
    """The sampled loop on the 10-mode linear SFOAM, no damping: the filter on the design
    modes alone folds mode 7 (52 Hz) to 48 Hz and grows ~1 % per sample; with the residual
    modes the loop is as close to the unit circle as the state-feedback LQR, and a
    structural damping ratio of 0.02 % makes it strictly stable (the naive one needs ~0.4 %)."""
    naive = LQG(design, LQGSettings(robust=False))
    robust = LQG(design)
    lqr = LQR(design)
    for lp in (loop_poles(c, 5) for c in (naive, robust, lqr)):
        assert lp.spectral_radius < 1.0                      # the design model itself
    n10 = loop_poles(naive, 10)
    assert n10.spectral_radius > 1.01 and n10.worst_hz == pytest.approx(47.6, abs=0.3)
    for plant_modes in (10, 13, 20):
        r = loop_poles(robust, plant_modes).spectral_radius
        assert r < 1.0006, plant_modes
        assert r <= loop_poles(lqr, plant_modes).spectral_radius
    assert loop_poles(robust, 10, damping_ratio=2e-4).spectral_radius < 1.0
    assert loop_poles(naive, 10, damping_ratio=2e-3).spectral_radius > 1.0
    assert loop_poles(PD(design), 10).spectral_radius < 1.0 + 1e-6


@pytest.mark.slow
def test_naive_lqg_is_unstable_on_the_evaluation_plant(design):
    """The default slew on the default evaluation plant (FOAM, 10 modes, no damping), 20 s:
    the filter on the design modes alone ends in a saturation limit cycle (verdict unstable),
    the default LQG settles (its full 30 s run is in test_compare)."""
    sc = make_scenario("slew", t_end=20.0)
    ref = sc.reference
    out = {}
    for label, st in (("naive", LQGSettings(robust=False)), ("robust", LQGSettings())):
        ctrl = make_controller("lqg", design, st, ref)
        res = simulate_closed_loop("foam", ctrl, sc.t_end, reference=(ref.theta_at, ref.theta_dot_at),
                                   settings=ClosedLoopSettings())
        assert res.params.n_transverse == 10 and res.params.damping_ratio == 0.0
        out[label] = closed_loop_metrics(res, sc.t_f, tau_max=sc.tau_max)
        m = out[label]
        print(f"{label}: {m['verdict']}, residual {m['residual_tip_max_m']:.3e} m, saturated "
              f"{100 * m['torque_saturated_fraction']:.0f} %")
    assert out["naive"]["verdict"] == "unstable"
    assert out["robust"]["verdict"] == "settled" and out["robust"]["torque_saturated_fraction"] == 0.0
    assert out["naive"]["torque_saturated_fraction"] > 0.5
    assert out["naive"]["residual_tip_max_m"] > 10 * out["robust"]["residual_tip_max_m"]
