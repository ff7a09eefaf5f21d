"""Rigs of session 24's fuzzing whose defaults failed: a count that toggles at a bending mode (COUNT_SHARE), a star
tracker whose noise banged the command (NOISE_SHARE), a slow boom whose default plant was refused.

Random rig 6 of seed 34 (benchmarks/fuzz_rigs.py link 34: a 1.26 m aluminium link, 93.6 mm^2,
on a geared DC motor, 2000 counts, a root gauge, no tachometer, 5 ms and one sample of delay). With
COUNT_SHARE at 0.5 the filter kept the counts' own noise (one count moved the command by 33 % of
its limit): LQR, LQG and MPC rang at the first mode (3.2 Hz) for ever, the hub toggling between two
counts, a 1.5 mm RMS tip in the residual window, 1.6 times the open loop's, against a 0.16 mm band
("not settled"). With the noise raised until a count moves the command by at most 10 % (4x here)
they settle to about 1 um.
"""

import json
import math
import re

import pytest

from hubbeam_ctrl.plant.rig import rig_from_dict
from hubbeam_ctrl.study import compare
from hubbeam_ctrl.study.rig_loop import COUNT_SHARE, count_chatter

RING_LINK = {
    "beam": {"L": 1.26, "rho": 2700, "A": 9.3608e-05, "E": 6.9e10, "I": 3.3462e-11, "J_h": 0.042889, "r": 0.0,
             "m_t": 0.08608},
    "motor": {"kind": "dc_motor", "R": 4.456, "L": 0.0, "k_t": 0.02961, "k_e": 0.02961, "N": 1.9,
              "eta_forward": 0.9, "eta_backward": 0.9, "J_r": 6.69e-06, "V_max": 48.0, "I_max": 8.734},
    "damping": {"ratios": [0.01318]},
    "sensors": {"encoder_counts": 2000, "strain_gauges": [0.0], "rate": False},
    "timing": {"dt": 0.005, "delay": 1.0},
}


def _shares() -> dict:
    """The cases of ``benchmarks/results/bench_rig_shares.json``."""
    from tests.conftest import ROOT
    return json.loads((ROOT / "benchmarks" / "results" / "bench_rig_shares.json").read_text())["cases"]


def test_docs_quote_the_shares_benchmark():
    """docs/rig.md's numbers on the count and noise shares are ``bench_rig_shares.json``'s (the rule as it
    runs against the rule before, on this file's two rigs), and that file says what its ``before`` was."""
    from tests.conftest import ROOT
    doc = re.sub(r"\s+", " ", (ROOT / "docs" / "rig.md").read_text())
    ring, boom = _shares()["ring_link"], _shares()["noisy_boom"]
    assert ring["before"]["patch"] == {"COUNT_SHARE": 0.5} and boom["before"]["patch"] == {"NOISE_SHARE": 1e300}
    b, n = ring["before"], ring["now"]
    assert (f"a tip ringing at {b['rms_over_band']:.1f} times its band ({1e3 * b['residual_tip_rms_m']:.2f} mm RMS), "
            f"where the filter that trusts the counts {n['filter_noise_factor']}x less settles it to "
            f"{1e6 * n['residual_tip_rms_m']:.1f} um RMS") in doc
    assert b["verdict"] == "not settled" and n["verdict"] == "settled"
    b, n = boom["before"], boom["now"]
    assert (f"noise into {b['noise_share']:.1f} times the limit RMS and sat at the limits for "
            f"{b['time_at_limit_s']:.0f} s of the {b['t_end_s']:.0f} s run; with the torque weight raised "
            f"10^{round(math.log10(n['torque_weight_factor']))}x they settle with "
            f"{1e6 * n['residual_tip_rms_m']:.1f} um RMS at the tip") in doc
    assert b["verdict"] == "unstable" and n["verdict"] == "settled"


@pytest.mark.slow
def test_a_link_whose_counts_rang_its_first_mode_settles(fast_backend):
    rig = rig_from_dict(RING_LINK)
    c = compare(rig, "slew", ["lqr"])
    m = c.metrics["lqr"]
    law = c.controllers["lqr"].inner            # the torque law behind the drive's volts
    assert COUNT_SHARE == 0.1 and law.count_noise_factor == 4
    assert count_chatter(law, rig) <= COUNT_SHARE and law.count_share == count_chatter(law, rig)
    assert m["verdict"] == "settled", m["verdict_reason"]
    assert m["residual_tip_rms_m"] < 0.02 * m["settle_tip_m"]          # 1.1e-6 m against 1.6e-4 m (was 1.5e-3 m)
    assert any(n.startswith("lqr: the filter's angle noise is raised 4x") for n in c.notes)
    now = _shares()["ring_link"]["now"]              # the benchmark docs/rig.md quotes is this run's
    assert law.count_noise_factor == now["filter_noise_factor"] and m["verdict"] == now["verdict"]
    assert m["residual_tip_rms_m"] == pytest.approx(now["residual_tip_rms_m"], rel=0.05)



#: Rig 0 of `benchmarks/fuzz_rigs.py space 1`: an 8.8 m CFRP tube on a 36 kg m^2
#: body, a 16 mN m actuator, a star tracker of 90 urad and a gyro of 21 urad/s (drifting) at 20 Hz, half a
#: sample of delay. The laws from the task's weights turned the star tracker's noise into a command of 5.6
#: times the limit RMS: LQR sat at +-tau_max for 1099 s of the 1355 s run (benchmarks/bench_rig_shares.py).
NOISY_BOOM = {
    "beam": {"L": 8.833, "rho": 1600, "A": 0.00012729, "E": 1.2e11, "I": 7.3868e-08, "J_h": 36.137, "r": 0.652,
             "m_t": 1.546, "tau_max": 0.01622},
    "damping": {"ratios": [0.005391]},
    "sensors": {"angle_noise": 8.99e-05, "rate_noise": 2.07e-05, "rate_bias": 3.04e-06, "rate_bias_walk": 3.84e-07,
                "strain_gauges": [0.0]},
    "timing": {"dt": 0.05, "delay": 0.5},
}


@pytest.mark.slow
def test_a_boom_whose_star_tracker_noise_banged_the_command_settles(fast_backend):
    from hubbeam_ctrl.study.rig_loop import NOISE_SHARE, SOFTER_LADDER, noise_chatter
    rig = rig_from_dict(NOISY_BOOM)
    c = compare(rig, "slew", ["lqr"])
    m, law = c.metrics["lqr"], c.controllers["lqr"]
    share = noise_chatter(law, rig)           # the loop with the rig's drive, which on_rig attaches after choosing
    assert law.count_softened in SOFTER_LADDER and share == pytest.approx(law.noise_share, rel=1e-3)
    assert law.noise_share <= NOISE_SHARE
    assert m["verdict"] == "settled", m["verdict_reason"]
    assert m["time_at_limit_s"] < 1.0 and m["residual_tip_rms_m"] < 0.02 * m["settle_tip_m"]   # 0.1 s; 5.8e-6 m
    assert any(n.startswith("lqr: the torque weight is raised") and "the sensors' stated noise moves it by" in n
               for n in c.notes)
    now = _shares()["noisy_boom"]["now"]             # the benchmark docs/rig.md quotes is this run's
    assert law.count_softened == now["torque_weight_factor"] and m["verdict"] == now["verdict"]
    assert m["residual_tip_rms_m"] == pytest.approx(now["residual_tip_rms_m"], rel=0.05)
    assert law.noise_share == pytest.approx(now["noise_share"], rel=1e-3)

    # noise_chatter is the command's spread in the loop driven by white noise of the stated sizes on every signal
    # the law reads (60 000 samples: the estimate within a few per cent)
    import numpy as np

    from hubbeam_ctrl.study.sampled_loop import AS_DESIGNED, closed_loop_matrix, loop_parts
    Ad, Bd, Cm, (Ak, Bk, Ck, Dk), _ = loop_parts(law, law.design.params, 0.0, 0.0, AS_DESIGNED)
    A = closed_loop_matrix(Ad, Bd, Cm, (Ak, Bk, Ck, Dk))
    sig = np.array([{"theta": 8.99e-05, "theta_dot": 2.07e-05}.get(n, 0.0) for n in law.feedback_matrices()[5]])
    B, c = np.vstack([Bd @ Dk, Bk]), np.hstack([Dk @ Cm, Ck])[0]
    rng = np.random.default_rng(1)
    x, u = np.zeros(A.shape[0]), np.empty(60_000)
    for k in range(u.size):
        n = rng.standard_normal(sig.size) * sig
        u[k] = c @ x + Dk[0] @ n
        x = A @ x + B @ n
    assert np.std(u[2000:]) / law.tau_max == pytest.approx(share, rel=0.05)


#: Rig 3 of `benchmarks/fuzz_rigs.py space 1`: a 5.3 m CFRP tube on a 290 kg m^2
#: body at 10 Hz (bending modes 3.5, 21, 58, 114 Hz). Every default run was refused: the 1-mode design's
#: plant (design + 3 modes) needed 207 integration steps per sample, past the 200 the integrator takes.
SLOW_BOOM = {
    "beam": {"L": 5.334, "rho": 1600, "A": 0.00031658, "E": 1.2e11, "I": 1.2082e-07, "J_h": 290.61, "r": 0.48,
             "m_t": 0.0, "tau_max": 0.02949},
    "damping": {"ratios": [0.004729]},
    "timing": {"dt": 0.1},
}


def test_the_default_plant_of_a_slow_boom_keeps_what_the_integrator_resolves():
    from hubbeam_ctrl.sim.evaluation import default_design_modes, default_plant_modes
    rig = rig_from_dict(SLOW_BOOM)
    modes, note = default_design_modes(rig.plant_params, 0.1)
    assert modes == 1 and "not the beam's 5" in note
    n, reason = default_plant_modes(rig.plant_params, 0.1, 1)
    assert n == 3 and "4 would need more than 180 integration steps per sample of 100 ms, so 3" in reason


@pytest.mark.slow
def test_a_slow_boom_is_compared_with_its_defaults(fast_backend):
    c = compare(rig_from_dict(SLOW_BOOM), "slew", ["lqr"])
    assert c.plant.modes == 3 and c.metrics["lqr"]["design_modes"] == 1
    assert c.metrics["lqr"]["verdict"] == "settled", c.metrics["lqr"]["verdict_reason"]


#: Rig 5 of `benchmarks/fuzz_rigs.py space 2`: a 3.4 m CFRP tube on a 3.9 kg m^2 body, a star tracker and a gyro at
#: 10 Hz; its first flexible mode (13.6 Hz, free hub) lies above the sampling frequency.
FAST_MODE_BOOM = {
    "beam": {"L": 3.354, "rho": 1600, "A": 0.00016911, "E": 1.2e11, "I": 7.4018e-08, "J_h": 3.9245, "r": 0.754,
             "m_t": 0.0, "tau_max": 0.01832},
    "damping": {"ratios": [0.003203]},
    "sensors": {"angle_noise": 2.5e-05, "rate_noise": 4.43e-05, "rate_bias": 2.11e-06, "rate_bias_walk": 3.58e-07,
                "strain_gauges": []},
    "timing": {"dt": 0.1},
}


def test_the_filter_asks_no_more_than_halving_its_error_a_sample():
    """0.3 w_1 asked this boom's filter to shrink its error 12.9-fold a sample; the Riccati equation of
    that model could not be solved and every default LQG was refused. Now capped at ln 2 / dt."""
    import math

    from controllers import DesignModel, KalmanNoise
    from controllers.estimator import MAX_DECAY_PER_SAMPLE, error_decay_rate
    from controllers.scaling import first_mode
    rig = rig_from_dict(FAST_MODE_BOOM)
    design = DesignModel.build(rig.plant_params, 0.0, 0.1, 1)
    assert first_mode(design) / (2 * math.pi) > 10.0                           # 13.6 Hz, above the 10 Hz sampling
    assert error_decay_rate(design, KalmanNoise()) == MAX_DECAY_PER_SAMPLE / 0.1 == math.log(2) / 0.1
    paper = DesignModel.build(n_modes=2)
    assert error_decay_rate(paper, KalmanNoise()) == pytest.approx(0.3 * first_mode(paper))   # far below the cap


@pytest.mark.slow
def test_a_boom_whose_first_mode_is_above_the_sampling_frequency_gets_its_lqg(fast_backend):
    c = compare(rig_from_dict(FAST_MODE_BOOM), "slew", ["lqg"])
    assert c.metrics["lqg"]["verdict"] == "settled", c.metrics["lqg"]["verdict_reason"]


@pytest.mark.slow
def test_a_slow_boom_whose_noise_the_old_ladder_could_not_quieten(fast_backend):
    """SLOW_BOOM with its star tracker (21 urad) and gyro (28 urad/s, drifting bias): at 10^4x the torque weight
    (the old ladder's last) the sensors moved the command by 15 % of the limit RMS and it sat at the limit
    11.6 s of the slew; the ladder goes on to 10^5x (5 %)."""
    from hubbeam_ctrl.study.rig_loop import NOISE_SHARE
    d = dict(SLOW_BOOM, sensors={"angle_noise": 2.14e-05, "rate_noise": 2.83e-05, "rate_bias": 3.52e-06,
                                 "rate_bias_walk": 3.37e-07, "strain_gauges": [0.0]})
    c = compare(rig_from_dict(d), "slew", ["lqr"])
    m, law = c.metrics["lqr"], c.controllers["lqr"]
    assert law.count_softened == 1e5 and law.noise_share <= NOISE_SHARE
    assert m["verdict"] == "settled" and m["time_at_limit_slew_s"] < 1.0, m["verdict_reason"]     # 0.1 s


#: Rig 4 of `benchmarks/fuzz_rigs.py space 4`: a 3.8 m CFRP tube on a 3.6 kg m^2 body, a 0.3 mN m actuator, a
#: star tracker and a gyro at 5 Hz; its bending modes (about 10 and 62 Hz) lie above the sampling frequency.
#: Its fewest default plant modes, one more than the 1-mode design, needed 226 integration steps per sample,
#: past the 200 the integrator then took: every default run was refused (session 25).
STIFF_BOOM_5HZ = {
    "beam": {"L": 3.782, "rho": 1600, "A": 0.00022379, "E": 1.2e11, "I": 1.619e-07, "J_h": 3.55, "r": 0.896,
             "m_t": 0.0, "tau_max": 0.0002976},
    "damping": {"ratios": [0.007077]},
    "sensors": {"angle_noise": 3.61e-05, "rate_noise": 1.75e-05, "rate_bias": 1.61e-06, "rate_bias_walk": 7.65e-08,
                "strain_gauges": [0.0]},
    "timing": {"dt": 0.2, "delay": 1.0},
}


def test_the_fewest_default_plant_modes_are_integrated_past_the_preferred_budget():
    """The default plant's rules prefer 180 steps a sample (90 % of SUBSTEP_BUDGET) and drop modes for it; where
    the fewest they allow need more, the integrator takes them (a 2-mode plant up to substep_cap(2) = 1000, the
    work of a 20-mode plant at 200) instead of refusing the run."""
    from hubbeam_ctrl.sim.evaluation import default_design_modes, default_plant_modes, modes_to_cover
    from hubbeam_ctrl.sim.step_rule import SUBSTEP_BUDGET, substep_cap, substep_rule
    rig = rig_from_dict(STIFF_BOOM_5HZ)
    assert default_design_modes(rig.plant_params, 0.2)[0] == 1
    n, reason = default_plant_modes(rig.plant_params, 0.2, 1)
    assert n == 2 and "so 2" in reason
    f = modes_to_cover(rig.plant_params, 5.0)[2]
    assert f[0] > 5.0 and 60 < f[1] < 65                          # both bending modes above the 5 Hz sampling
    rule = substep_rule(f[:2], 0.2, tolerance=0.01)
    assert SUBSTEP_BUDGET < rule.substeps <= substep_cap(2) == 1000          # 226 steps of 0.88 ms
    assert substep_cap(20) == SUBSTEP_BUDGET == 200


@pytest.mark.slow
def test_a_boom_sampled_below_its_first_mode_is_compared_with_its_defaults(fast_backend):
    c = compare(rig_from_dict(STIFF_BOOM_5HZ), "slew", ["lqr"])
    m = c.metrics["lqr"]
    assert c.plant.modes == 2 and m["substeps"] > 200
    assert m["verdict"] == "settled", m["verdict_reason"]


#: Rig 2 of `benchmarks/fuzz_rigs.py link 37`: a 1.01 m aluminium link with a 91 g tip mass on a 0.44 N m torque
#: source, Coulomb and viscous friction, 1024 counts, a root gauge and a tip accelerometer, 2 ms. After the slew
#: the tip fell e-fold every 3.1 s (the loop's slowest pole) and the default window ended at 0.44 mm against a
#: 0.13 mm band: "not settled", with only the counts named, which can move the tip by 0.2 mm at most.
SLOW_POLE_LINK = {
    "beam": {"L": 1.011, "rho": 2700, "A": 5.8881e-05, "E": 6.9e10, "I": 6.0939e-12, "J_h": 0.011429, "r": 0.0,
             "m_t": 0.0913, "tau_max": 0.44406},
    "friction": {"viscous": 0.006369, "coulomb": 0.0171},
    "damping": {"ratios": [0.005835]},
    "sensors": {"encoder_counts": 1024, "strain_gauges": [0.0], "tip_accelerometer": True, "accel_noise": 0.01},
    "timing": {"dt": 0.002, "delay": 0.0},
}


@pytest.mark.slow
def test_a_run_ended_before_its_slowest_pole_decayed_names_it_and_a_longer_run_settles(fast_backend):
    from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice
    from hubbeam_ctrl.study.judge import SLOW_POLE_SPANS
    rig = rig_from_dict(SLOW_POLE_LINK)
    c = compare(rig, "slew", ["lqr"])
    m = c.metrics["lqr"]
    window = c.scenario.t_end - c.scenario.t_f - c.scenario.bands["residual_delay"]
    assert m["verdict"] == "not settled" and m["loop_certificate"] == "stable" and m["tip_growth_rate_per_s"] < 0
    assert m["slow_pole_s"] == m["loop_slowest_decay_s"] and SLOW_POLE_SPANS * m["slow_pole_s"] > window
    assert m["residual_tip_max_m"] > m["count_tip_bound_m"]          # the counts alone do not explain it
    assert "cause: the loop's slowest pole decays e-fold in 3.08 s" in m["verdict_reason"]
    longer = compare(rig, "slew", ["lqr"], CompareSettings(run=RunChoice(
        t_end=c.scenario.t_end + SLOW_POLE_SPANS * m["slow_pole_s"]))).metrics["lqr"]
    assert longer["verdict"] == "settled", longer["verdict_reason"]


def test_the_slow_pole_is_named_only_for_a_stable_loop_that_did_not_settle():
    from hubbeam_ctrl.study.judge import slow_pole_cause
    base = {"verdict": "not settled", "verdict_reason": "r", "loop_certificate": "stable", "loop_slowest_decay_s": 3.0,
            "tip_growth_rate_per_s": -0.16}
    m = dict(base)
    slow_pole_cause(m, 4.0)
    assert m["slow_pole_s"] == 3.0 and "5 s longer" in m["verdict_reason"]
    assert m["verdict_reason"].startswith("r; cause: the loop's slowest pole decays e-fold in 3 s")
    for change, window in (({}, 9.5), ({"verdict": "settled"}, 4.0), ({"verdict": "unstable"}, 4.0),
                           ({"loop_certificate": "grows"}, 4.0), ({"loop_slowest_decay_s": None}, 4.0),
                           ({"tip_growth_rate_per_s": 0.45}, 4.0)):       # a count cycle building up (s36/4)
        m = {**base, **change}
        slow_pole_cause(m, window)
        assert m["verdict_reason"] == "r" and "slow_pole_s" not in m, change
