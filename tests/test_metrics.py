"""Closed-loop metrics (:mod:`hubbeam_ctrl.study.metrics`) on synthetic series with known answers."""

import math

import numpy as np
import pytest

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.results import Result
from hubbeam_ctrl.study.metrics import METRIC_UNITS, closed_loop_metrics, settling_time

DT, T_F, T_END = 0.01, 10.0, 30.0


def _run(residual_amp=5e-4, with_reference=True, cut=None, **extra):
    """A 30 s closed-loop result sampled at 100 Hz whose every metric has a closed form:

    * ``v_tip = 0.3 sin(2 pi t)`` before 15 s, ``residual_amp cos(2 pi t)`` from 15 s on;
    * torque ``100 sin(2 pi t / 10)`` up to ``t_f = 10 s``, then 0;
    * angle error ``0.05`` before ``t_f``, ``0.02 exp(-(t - t_f)/2)`` after;
    * controller call times evenly spaced from 0.01 to 1 ms.

    ``cut`` keeps only the first ``cut`` samples (a run that stopped early).
    """
    t = DT * np.arange(int(round(T_END / DT)) + 1)
    v_tip = np.where(t < 15.0 - 1e-9, 0.3 * np.sin(2 * np.pi * t), residual_amp * np.cos(2 * np.pi * t))
    tau = np.where(t <= T_F, 100.0 * np.sin(2 * np.pi * t / T_F), 0.0)
    err = np.where(t < T_F, 0.05, 0.02 * np.exp(-(t - T_F) / 2))
    ref = 0.1 * t
    q = np.zeros((len(t), 3))
    q[:, 0] = ref + err
    series = dict(t=t, q=q, v=np.zeros_like(q), v_tip=v_tip, u_tip=np.zeros_like(t), tau=tau,
                  root_moment=np.zeros_like(t), step_time_s=np.linspace(1e-5, 1e-3, len(t)),
                  theta_ref=ref if with_reference else None)
    series = {k: (v[:cut] if v is not None and cut else v) for k, v in series.items()}
    fields = dict(kind="closed_loop", model="foam", params=Params(n_axial=1, n_transverse=1),
                  settings={"t_end": T_END}, controller="toy", stopped=cut is not None,
                  message="completed" if cut is None else "stopped", wall_s=1.5,
                  controller_stats={"qp_fallbacks": 3, "matrix": np.eye(2)}, **series)
    fields.update(extra)
    return Result(**fields)


def test_metrics_against_closed_forms():
    m = closed_loop_metrics(_run(), T_F, tau_max=100.0)
    assert set(METRIC_UNITS) <= set(m)
    assert m["peak_tip_m"] == pytest.approx(0.3, rel=1e-12)           # sample at t = 0.25 s
    # residual window 15..30 s: 15 whole periods of a 1 Hz cosine (1500 samples) plus t = 30 s
    assert m["residual_tip_max_m"] == pytest.approx(5e-4, rel=1e-12)
    assert m["residual_tip_rms_m"] == pytest.approx(5e-4 * math.sqrt(751 / 1501), rel=1e-9)
    assert m["angle_error_tf_rad"] == pytest.approx(0.02, rel=1e-12)
    assert m["final_angle_error_rad"] == pytest.approx(0.02 * math.exp(-10.0), rel=1e-9)
    # error enters the 1 mrad band at t_f + 2 ln 20; the tip is inside 1 mm from 15 s on
    assert m["settling_time_s"] == pytest.approx(math.ceil((T_F + 2 * math.log(20)) / DT) * DT, abs=1e-9)
    assert m["peak_torque_nm"] == pytest.approx(100.0, rel=1e-12)
    # held torque over one sine period: tau_m^2 t_f / 2 (exact for whole-period sampling)
    assert m["torque_squared_integral_n2m2s"] == pytest.approx(100.0 ** 2 * T_F / 2, rel=1e-9)
    assert m["step_time_median_ms"] == pytest.approx(0.505, rel=1e-12)           # the middle sample
    assert m["step_time_p99_ms"] == pytest.approx(0.01 + 0.99 * 0.99, rel=1e-12)  # even spacing
    assert m["within_torque_limit"] is True and m["completed"] is True
    assert m["qp_fallbacks"] == 3 and "matrix" not in m             # scalar statistics only
    assert (m["controller"], m["plant"], m["wall_s"]) == ("toy", "foam", 1.5)


def test_metrics_options_move_the_window_and_bands():
    run = _run(residual_amp=4e-3)
    m = closed_loop_metrics(run, T_F, tau_max=99.0)
    assert m["within_torque_limit"] is False
    assert m["settling_time_s"] is None                            # 4 mm residual, 1 mm band
    m = closed_loop_metrics(run, T_F, settle_tip=5e-3, residual_delay=7.0)
    assert m["settling_time_s"] == pytest.approx(math.ceil((T_F + 2 * math.log(20)) / DT) * DT, abs=1e-9)
    assert m["residual_tip_rms_m"] == pytest.approx(4e-3 * math.sqrt(651 / 1301), rel=1e-9)
    assert "within_torque_limit" not in m


@pytest.mark.parametrize("kwargs,needle", [
    ({"t_f": 0.0}, "tf"),
    ({"t_f": T_F, "residual_delay": -1.0}, "residual_delay"),
    ({"t_f": T_F, "settle_angle": 0.0}, "settle_angle"),
    ({"t_f": T_F, "settle_tip": float("nan")}, "settle_tip"),
    ({"t_f": 26.0}, "t_end"),
])
def test_bad_metric_settings_are_named(kwargs, needle):
    t_f = kwargs.pop("t_f")
    with pytest.raises(ParameterError, match=needle):
        closed_loop_metrics(_run(), t_f, **kwargs)


def test_run_without_reference_is_rejected():
    with pytest.raises(ParameterError, match="reference"):
        closed_loop_metrics(_run(with_reference=False), T_F)


def test_stopped_run_has_nan_residual():
    m = closed_loop_metrics(_run(cut=750), T_F)                   # stopped at 7.49 s
    assert math.isnan(m["residual_tip_max_m"]) and math.isnan(m["angle_error_tf_rad"])
    assert m["completed"] is False and m["final_angle_error_rad"] == pytest.approx(0.05)


def test_open_loop_result_is_rejected():
    run = _run()
    with pytest.raises(ParameterError, match="closed-loop"):
        closed_loop_metrics(Result(kind="fixed_step", model="foam", t=run.t, q=run.q, v=run.v, v_tip=run.v_tip,
                                   u_tip=run.u_tip, tau=run.tau, params=run.params), T_F)


@pytest.mark.parametrize("angle,tip,expected", [
    ([0.5, 0.2, 0.05, 0.0, 0.0], [0.0] * 5, 2.0),         # enters the band for good at t[2]
    ([0.0, 0.2, 0.0, 0.2, 0.0], [0.0] * 5, 4.0),          # leaves and re-enters: the last entry
    ([0.0] * 5, [0.0, 0.0, 0.5, 0.0, 0.0], 3.0),          # the tip band counts too
    ([0.0] * 5, [0.0] * 5, 0.0),                          # inside from the start
    ([0.0, 0.0, 0.0, 0.0, 0.2], [0.0] * 5, None),         # outside at the end
])
def test_settling_time(angle, tip, expected):
    t = np.arange(5.0)
    assert settling_time(t, np.array(angle), np.array(tip), 0.1, 0.1) == expected


def test_settling_time_of_empty_series_is_none():
    assert settling_time(np.zeros(0), np.zeros(0), np.zeros(0), 0.1, 0.1) is None
