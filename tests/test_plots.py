"""Plots: every figure function draws what it is given (non-GUI backend)."""

import numpy as np

from hubbeam_ctrl import Params, SpinUp, campbell, critical_speed_map, simulate
from hubbeam_ctrl.plots.plant import (
    plot_campbell,
    plot_critical_speed_map,
    plot_result,
    plot_tip_comparison,
    save_figure,
)


def test_figures_carry_the_data(tmp_path):
    res = simulate("foam", SpinUp(2.0, 5.0), 6.0, params=Params(m_t=0.0, n_axial=2, n_transverse=2))
    fig = plot_result(res)
    np.testing.assert_array_equal(fig.axes[0].lines[0].get_ydata(), res.v_tip)
    fig2 = plot_tip_comparison({"FOAM": res})
    assert fig2.axes[0].get_legend().get_texts()[0].get_text() == "FOAM"
    spins = [0.0, 1.0, 2.0]
    f = campbell("foam", spins, params=Params(n_axial=2, n_transverse=2))
    fig3 = plot_campbell(spins, f)
    np.testing.assert_allclose(fig3.axes[0].lines[0].get_ydata(), f[:, 0])
    speeds = critical_speed_map([0.0, 0.5], [0.0, 8.0])
    fig4 = plot_critical_speed_map([0.0, 0.5], [0.0, 8.0], speeds)
    assert len(fig4.axes[0].lines) == 2
    path = save_figure(fig4, tmp_path / "fig9.png")
    assert path.stat().st_size > 5000 and list(tmp_path.iterdir()) == [path]
