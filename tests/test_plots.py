"""Plots: every public figure function draws what it is given (non-GUI backend)."""

import inspect
from pathlib import Path

import numpy as np
import pytest

import hubbeam_ctrl.plots as plots
from hubbeam_ctrl import Params, SpinUp, campbell, critical_speed_map, simulate
from hubbeam_ctrl.plots.closedloop import plot_hub_angle, plot_tip_deflection, plot_torque
from hubbeam_ctrl.plots.plant import (
    plot_campbell,
    plot_critical_speed_map,
    plot_result,
    plot_tip_comparison,
    save_figure,
    save_png,
)
from hubbeam_ctrl.plots.shaping import plot_shaper_sensitivity
from hubbeam_ctrl.sim import simulate_closed_loop


def test_figures_carry_the_data(tmp_path):
    res = simulate("foam", SpinUp(2.0, 5.0), 6.0, params=Params(m_t=0.0, n_axial=2, n_transverse=2))
    fig = plot_result(res)
    np.testing.assert_array_equal(fig.axes[0].lines[0].get_ydata(), res.v_tip)
    np.testing.assert_array_equal(fig.axes[1].lines[0].get_ydata(), 1e3 * res.u_tip)
    np.testing.assert_array_equal(fig.axes[3].lines[1].get_ydata(), res.q_theta)
    fig2 = plot_tip_comparison({"FOAM": res})
    assert fig2.axes[0].get_legend().get_texts()[0].get_text() == "FOAM"
    np.testing.assert_array_equal(fig2.axes[1].lines[0].get_ydata(), np.maximum(np.abs(res.v_tip), 1e-9))
    spins = [0.0, 1.0, 2.0]
    f = campbell("foam", spins, params=Params(n_axial=2, n_transverse=2))
    fig3 = plot_campbell(spins, f)
    np.testing.assert_allclose(fig3.axes[0].lines[0].get_ydata(), f[:, 0])
    np.testing.assert_allclose(fig3.axes[0].lines[-1].get_ydata(), np.array(spins) / (2 * np.pi))   # 1x spin
    speeds = critical_speed_map([0.0, 0.5], [0.0, 8.0])
    fig4 = plot_critical_speed_map([0.0, 0.5], [0.0, 8.0], speeds)
    assert len(fig4.axes[0].lines) == 2
    np.testing.assert_array_equal(fig4.axes[0].lines[1].get_ydata(), speeds[1])
    path = save_figure(fig4, tmp_path / "fig9.png")
    assert path.stat().st_size > 5000 and list(tmp_path.iterdir()) == [path]


class _Torque:
    """A constant hub torque that turns NaN at ``t_nan`` (stops the run)."""

    measurement = "state"

    def __init__(self, name, tau, t_nan=None):
        self.name, self.tau, self.t_nan = name, tau, t_nan

    def reset(self):
        pass

    def __call__(self, t, y):
        return float("nan") if self.t_nan is not None and t >= self.t_nan else self.tau


@pytest.fixture(scope="module")
def closed_loop_runs():
    """Two short closed-loop runs on a 1 + 1 mode FOAM: one complete, one stopped."""
    p = Params(n_axial=1, n_transverse=1)
    ref = (lambda t: 0.05 * t ** 2, lambda t: 0.1 * t)
    return {"lqr": simulate_closed_loop("foam", _Torque("lqr", 20.0), 2.0, params=p, reference=ref),
            "mine": simulate_closed_loop("foam", _Torque("mine", -10.0, 1.0), 2.0, params=p, reference=ref)}


def test_closed_loop_figures_carry_the_data(closed_loop_runs, tmp_path):
    runs = closed_loop_runs
    lqr, mine = runs["lqr"], runs["mine"]
    assert not lqr.stopped and mine.stopped
    fig = plot_tip_deflection(runs, t_f=1.0, residual_start=1.5, styles={"lqr": {"color": "tab:blue"}})
    ax1, ax2 = fig.axes
    np.testing.assert_array_equal(ax1.lines[0].get_ydata(), lqr.v_tip)
    np.testing.assert_array_equal(ax2.lines[1].get_ydata(), np.maximum(np.abs(mine.v_tip), 1e-9))
    assert [t.get_text() for t in ax1.get_legend().get_texts()] == ["lqr", "mine (stopped)"]
    assert ax1.lines[0].get_color() == "tab:blue"
    fig = plot_hub_angle(runs, t_f=1.0)
    ax1, ax2 = fig.axes
    # each run, and the reference drawn once
    assert [t.get_text() for t in ax1.get_legend().get_texts()] == ["lqr", "reference", "mine (stopped)"]
    np.testing.assert_allclose(ax2.lines[0].get_ydata(), 1e3 * (lqr.theta - lqr.theta_ref))
    fig = plot_torque(runs, tau_max=25.0)
    ax = fig.axes[0]
    np.testing.assert_array_equal(ax.lines[0].get_ydata(), lqr.tau)
    assert sorted(line.get_ydata()[0] for line in ax.lines[2:]) == [-25.0, 25.0]
    path = save_figure(fig, tmp_path / "torque.png")
    assert path.stat().st_size > 5000
    png = path.read_bytes()                       # the bytes of a figure drawn elsewhere, written as they are
    assert save_png(png, tmp_path / "copy.png").read_bytes() == png


def test_shaper_sensitivity_figure_carries_the_data(tmp_path):
    e = np.linspace(-0.3, 0.3, 7)
    curves = {"zv": np.abs(e), "ei": 0.05 + 0 * e}
    fig = plot_shaper_sensitivity(e, curves, [-0.2, 0.0], {"zv": [0.2, 0.01]}, tolerance=0.05,
                                  styles={"zv": {"color": "tab:purple", "label": "ZV shaped"}})
    ax = fig.axes[0]
    zv_line, zv_points, ei_line, tol = ax.lines
    np.testing.assert_allclose(zv_line.get_xdata(), 100 * e)
    np.testing.assert_allclose(zv_line.get_ydata(), 100 * np.abs(e))
    np.testing.assert_allclose(zv_points.get_ydata(), [20.0, 1.0])
    assert (zv_line.get_color(), zv_line.get_label()) == ("tab:purple", "ZV shaped (linear)")
    assert (ei_line.get_color(), ei_line.get_label()) == ("C1", "ei (linear)")     # no style: the cycle
    assert tol.get_ydata()[0] == pytest.approx(5.0)
    assert save_figure(fig, tmp_path / "s.png").stat().st_size > 5000


def test_record_fit_figure_carries_the_data(tmp_path):
    from hubbeam_ctrl.plots.calibration import plot_record_fit
    t = np.linspace(0, 1, 11)
    measured = {"theta": np.sin(t), "root_moment": np.cos(t)}
    model = {"theta": 0.9 * np.sin(t), "root_moment": np.cos(t)}
    fig = plot_record_fit(t, measured, model, {"theta": 90.0, "root_moment": 100.0}, title="rec")
    assert len(fig.axes) == 4
    meas, mod = fig.axes[0].lines
    np.testing.assert_allclose(meas.get_ydata(), np.sin(t))
    np.testing.assert_allclose(mod.get_ydata(), 0.9 * np.sin(t))
    assert "90.0 %" in mod.get_label()
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), 0.1 * np.sin(t))      # the residual
    assert fig.axes[2].get_ylabel() == "root_moment [N m]"
    assert save_figure(fig, tmp_path / "f.png").stat().st_size > 5000


def test_every_public_plot_function_is_tested_here():
    """A new public plot function needs a test in this module (or, for the loop plots, in
    test_loop_plots.py)."""
    source = Path(__file__).read_text() + (Path(__file__).parent / "test_loop_plots.py").read_text()
    public = [name for name in plots.__all__ if inspect.isfunction(getattr(plots, name))]
    assert len(public) >= 8
    assert [name for name in public if f"{name}(" not in source.replace(f"def {name}(", "")] == []
