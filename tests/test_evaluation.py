"""The evaluation plant and its integration step (issue 10, items 1, 2 and 6).

The closed loop is judged on a plant with every bending mode below the sampling frequency
(plus one) and at least three more than the design model, integrated with a step that keeps
every bending frequency within 0.5 % of modal analysis.
"""

import json
import math

import numpy as np
import pytest
import scipy.linalg

from hubbeam_ctrl import Params, TorquePulse, build_model, simulate
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.linearization import second_order_linearization
from hubbeam_ctrl.plant.modal import converged_bending_hz, modal_analysis
from hubbeam_ctrl.sim import (
    ClosedLoopSettings,
    StepperSettings,
    default_plant_modes,
    evaluation_plant,
    period_error,
    simulate_closed_loop,
    simulate_fixed_step,
    substep_rule,
)

#: A 1 m aluminium lab arm (issue 10).
LAB_ARM = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05)
BEAMS = {"paper": Params(), "lab_arm": LAB_ARM}


def test_period_error_is_the_trapezoidal_rule_at_rho_inf_1():
    """At rho_inf = 1 the method is the trapezoidal rule, whose discrete frequency is
    ``2 atan(w h / 2) / h`` exactly."""
    for wh in (0.05, 0.3, 1.0):
        assert period_error(wh, 1.0) == pytest.approx(2 * math.atan(wh / 2) / wh - 1, abs=1e-12)
    # the figures for today's 5 ms step: mode 5 of the paper's beam (25 Hz), -4.7 %;
    # mode 3 of the lab arm (38 Hz), -10 %
    assert period_error(2 * np.pi * 24.96 * 0.005, 0.9) == pytest.approx(-0.047, abs=0.002)
    assert period_error(2 * np.pi * 37.88 * 0.005, 0.9) == pytest.approx(-0.10, abs=0.005)


def test_default_plant_modes():
    f = converged_bending_hz(Params())
    assert f[8] < 100.0 < f[9]                       # nine modes below 100 Hz ...
    assert default_plant_modes(Params(), 0.01, 5)[0] == 10     # ... and the first above
    f = converged_bending_hz(LAB_ARM)
    assert f[3] < 100.0 < f[4]                       # four below: design + 3 wins
    assert default_plant_modes(LAB_ARM, 0.01, 5)[0] == 8
    n, why = default_plant_modes(Params(), 0.001, 5)   # 1 kHz: capped at 20
    assert n == 20 and "capped" in why
    ev = evaluation_plant("foam", Params(m_t=0.3), 0.01, 5, plant_params=Params(m_t=0.5), plant_modes=7)
    assert ev.params.m_t == 0.5 and ev.modes == 7 and ev.design_modes == 5
    with pytest.raises(ParameterError, match="plant_modes"):
        evaluation_plant("foam", Params(), 0.01, 5, plant_modes=4)
    with pytest.raises(ParameterError, match="plant_modes"):
        evaluation_plant("foam", Params(), 0.01, 5, plant_modes=21)
    with pytest.raises(ParameterError, match="plant"):
        evaluation_plant("tlam")


def _mode_state(model, k, amplitude):
    """State at rest deflected in bending mode k of the free-hub linearisation (spin 0)."""
    lin = second_order_linearization(model, 0.0, "free")
    w2, V = scipy.linalg.eigh(lin.K, lin.M)
    sl2 = model.transverse_slice
    bending = [i for i in range(len(w2)) if w2[i] > 1e-6
               and V[sl2, i] @ (lin.M @ V[:, i])[sl2] > 0.5 * V[:, i] @ lin.M @ V[:, i]]
    phi = V[:, bending[k - 1]]
    x0 = np.zeros(2 * model.n_q)
    x0[:model.n_q] = amplitude * phi / np.max(np.abs(phi[sl2]))
    return x0


def _zero_crossing_frequency(t, y):
    s = np.signbit(y)
    i = np.nonzero(s[:-1] != s[1:])[0]
    tz = t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])
    return (len(tz) - 1) / (2 * (tz[-1] - tz[0]))


@pytest.mark.parametrize("beam", BEAMS)
def test_every_bending_mode_within_half_a_percent(beam):
    """Free vibration started in the highest modes of the default evaluation plant: the
    simulated frequency (zero crossings over 40 periods) is within 0.5 % of modal analysis
    and matches the method's predicted period error."""
    p = BEAMS[beam]
    ev = evaluation_plant("foam", p, 0.01, 5)
    model = build_model("foam", ev.params)
    f_modal = modal_analysis(model, 0.0, "free").bending_hz
    rule = substep_rule(f_modal, 0.01)
    assert rule.mode == ev.modes and abs(rule.frequency_error) <= 0.005
    # the fewest steps that do it: one step fewer would miss the tolerance
    assert abs(period_error(2 * np.pi * f_modal[-1] * 0.01 / (rule.substeps - 1))) > 0.005
    print(f"{beam}: {ev.modes} modes, {rule.substeps} substeps of {1e3 * rule.step_s:.4f} ms")
    for k in (ev.modes, ev.modes - 1):
        x0 = _mode_state(model, k, 1e-4 * p.L)
        run = simulate_fixed_step(model, lambda t: 0 * t, 40.0 / f_modal[k - 1], x0=x0,
                                  settings=StepperSettings(dt=rule.step_s, substeps=1))
        q = run.q[:, model.transverse_slice.start + k - 1]
        f_sim = _zero_crossing_frequency(run.t, q - q.mean())
        err = f_sim / f_modal[k - 1] - 1
        predicted = period_error(2 * np.pi * f_modal[k - 1] * rule.step_s)
        print(f"  mode {k}: modal {f_modal[k - 1]:.4f} Hz, simulated {f_sim:.4f} Hz ({100 * err:+.3f} %, "
              f"predicted {100 * predicted:+.3f} %)")
        assert abs(err) < 0.005
        assert err == pytest.approx(predicted, abs=2e-4)


def test_closed_loop_states_its_plant_and_step():
    class Hold:
        name, measurement = "hold", "state"
        n_modes, dt = 2, 0.01

        def reset(self):
            pass

        def __call__(self, t, y):
            return 0.0

    res = simulate_closed_loop("foam", Hold(), 0.05, design_params=LAB_ARM.replace(n_axial=2))
    s = res.settings
    assert s["plant_modes"] == 5 and s["design_modes"] == 2 and s["plant_model"] == "foam"
    assert res.params.n_transverse == 5 and res.params.m_t == LAB_ARM.m_t
    assert s["substeps"] == substep_rule(modal_analysis("foam", 0.0, "free", res.params).bending_hz, 0.01,
                                         tolerance=ClosedLoopSettings().frequency_tolerance).substeps
    assert "highest bending mode (5" in s["step_reason"] and s["step_s"] == pytest.approx(0.01 / s["substeps"])
    json.dumps(s)                                            # plain data
    with pytest.raises(ParameterError, match="not both"):
        simulate_closed_loop("foam", Hold(), 0.05, params=LAB_ARM, plant_modes=5)


def test_too_many_substeps_names_the_mode_and_the_options(capsys, tmp_path):
    with pytest.raises(ParameterError) as exc:
        substep_rule(converged_bending_hz(LAB_ARM), 0.01)
    msg = str(exc.value)
    assert "mode 20" in msg and "2573" in msg and "plant-modes" in msg and "dt" in msg
    toml = tmp_path / "lab.toml"
    toml.write_text("\n".join(f"{k} = {v}" for k, v in LAB_ARM.to_dict().items() if v is not None))
    rc = main(["compare", "--params", str(toml), "--plant-modes", "20", "--controllers", "lqr",
               "--t-end", "16", "--tau-max", "1.5", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "mode 20" in err


@pytest.mark.parametrize("argv, words", [
    (["--plant-modes", "4"], "plant-modes"),           # fewer than the design's 5
    (["--plant-modes", "21"], "plant-modes"),
    (["--design-modes", "7", "--plant-modes", "6"], "plant-modes"),
    (["--design-modes", "0"], "design-modes"),
    (["--plant-tip-mass", "-1"], "plant-tip-mass"),
    (["--range-limit", "0"], "range-limit"),
])
def test_cli_plant_options_bad_input(tmp_path, capsys, argv, words):
    rc = main(["compare", "--out", str(tmp_path / "x")] + argv)
    err = capsys.readouterr().err
    assert rc == 2 and words in err and err.count("\n") == 1


def test_range_limit_is_a_flag_and_only_the_divergence_limit_stops():
    """The Eq. 44 slew (peak |v_tip| 1.30 m = 0.16 L) passes 0.1 L and goes on; with the
    divergence limit at 0.1 L it stops there, keeping what it computed."""
    p = Params(n_axial=1, n_transverse=2)
    res = simulate("foam", TorquePulse(200, 10), 12.0, params=p, range_limit=0.1)
    first = res.t[np.argmax(np.abs(res.v_tip) > 0.8)]
    assert not res.diverged and res.t[-1] == pytest.approx(12.0)
    assert res.outside_validated_range and res.outside_range_time_s == pytest.approx(first)
    assert "0.1 L" in res.message
    stop = simulate("foam", TorquePulse(200, 10), 12.0, params=p, divergence_limit=0.1)
    assert stop.diverged and "left its range" in stop.message
    assert stop.t[-1] == pytest.approx(first) and abs(stop.v_tip[-1]) > 0.8

    class Eq44:
        name, measurement, dt = "eq44", "state", 0.01

        def reset(self):
            pass

        def __call__(self, t, y):
            return 200.0 * math.sin(2 * math.pi * t / 10.0) if t <= 10 else 0.0

    cl = simulate_closed_loop("foam", Eq44(), 12.0, params=p, settings=ClosedLoopSettings(range_limit=0.1))
    assert not cl.stopped and cl.outside_validated_range and cl.t[-1] == pytest.approx(12.0)
    assert cl.outside_range_time_s == pytest.approx(cl.t[np.argmax(np.abs(cl.v_tip) > 0.8)])
    cut = simulate_closed_loop("foam", Eq44(), 12.0, params=p, settings=ClosedLoopSettings(divergence_limit=0.1))
    assert cut.stopped and "left its range" in cut.message and cut.t[-1] == pytest.approx(cl.outside_range_time_s)


def test_comparison_keeps_its_baseline_outside_the_range(tmp_path, capsys):
    """CLI with a plant that differs from the design and a range limit the open loop passes:
    the baseline is flagged, finishes and stays the reference of the % column."""
    out = tmp_path / "cmp"
    rc = main(["compare", "--controllers", "openloop,lqr", "--design-modes", "2", "--plant-modes", "5",
               "--plant-tip-mass", "0.12", "--n-modes", "2", "--range-limit", "0.1", "--t-end", "16",
               "--out", str(out), "--json"])
    captured = capsys.readouterr()
    data = {d["controller"]: d for d in json.loads(captured.out)}
    assert rc == 0 and "openloop" in captured.err and "0.1 L" in captured.err
    ol, lqr = data["openloop"], data["lqr"]
    assert ol["completed"] and ol["outside_validated_range"] and ol["outside_range_time_s"] > 0
    assert lqr["residual_pct_of_openloop"] == pytest.approx(
        100 * lqr["residual_tip_max_m"] / ol["residual_tip_max_m"])
    assert lqr["plant_modes"] == 5 and lqr["design_modes"] == 2
    assert lqr["plant_params"]["m_t"] == 0.12 and lqr["plant_params"]["n_transverse"] == 5
    report = (out / "report.md").read_text()
    assert "Evaluation plant: FOAM with 2 axial and 5 transverse modes" in report
    assert "m_t = 0.12" in report and "0.2747 m" in report
