"""Figures of a calibration: measured against model series, and their residuals (nothing computed)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.plots.figure import new_figure

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["plot_record_fit"]

_UNITS = {"theta": "rad", "theta_dot": "rad/s", "v_tip": "m", "root_moment": "N m", "tip_accel": "m/s^2"}


def plot_record_fit(t, measured: dict, model: dict, fit_percent: dict | None = None, title: str = "") -> Figure:
    """Measured and model series of each sensor (top of each pair) and their residual (below).

    Parameters
    ----------
    t : array_like (N,)
        Times [s].
    measured, model : dict
        Sensor name -> ndarray (N,) [the sensor's unit].
    fit_percent : dict, optional
        Sensor name -> fit [%] (shown in the legends).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = [k for k in measured if k in model]
    fig = new_figure(figsize=(8, 2.2 * 2 * max(len(names), 1)))
    axes = fig.subplots(2 * max(len(names), 1), 1, sharex=True, squeeze=False)[:, 0]
    t = np.asarray(t)
    for k, name in enumerate(names):
        unit = _UNITS.get(name, "")
        ax, ar = axes[2 * k], axes[2 * k + 1]
        ax.plot(t, measured[name], lw=0.8, label="measured")
        fit = "" if not fit_percent or name not in fit_percent else f" (fit {fit_percent[name]:.1f} %)"
        ax.plot(t, model[name], lw=0.8, ls="--", label=f"model{fit}")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.legend(loc="upper right", fontsize=8)
        ar.plot(t, np.asarray(measured[name]) - np.asarray(model[name]), lw=0.6, color="C3")
        ar.set_ylabel(f"residual [{unit}]")
    axes[-1].set_xlabel("t [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
