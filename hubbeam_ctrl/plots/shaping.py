"""Plots of input shapers: residual vibration against frequency error (nothing computed here)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_shaper_sensitivity"]

#: Fixed styles so that the shapers look the same in every figure.
SHAPER_STYLES = {"zv": ("tab:purple", "o"), "zvd": ("tab:cyan", "s"), "ei": ("tab:olive", "^")}


def plot_shaper_sensitivity(errors, curves: dict, measured_errors=None, measured: dict | None = None,
                            tolerance: float | None = None, title: str = "") -> Figure:
    """Residual vibration [%] against the relative error of the mode's frequency [%].

    Parameters
    ----------
    errors : array_like
        Relative frequency errors of the curves [-].
    curves : dict
        Shaper name -> residual vibration at ``errors`` [-] (e.g. of the linear model).
    measured_errors : array_like, optional
        Errors of the points measured on the nonlinear plant [-].
    measured : dict, optional
        Shaper name -> measured residual ratio at ``measured_errors`` [-] (markers).
    tolerance : float, optional
        A residual level to mark (e.g. EI's 5 %) [-].
    title : str

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(7, 4.5), constrained_layout=True)
    ax = fig.subplots()
    e = 100 * np.asarray(errors, dtype=float)
    for name, v in curves.items():
        color, marker = SHAPER_STYLES.get(name, (None, "x"))
        ax.plot(e, 100 * np.asarray(v), color=color, lw=1.5, label=f"{name} (linear)")
        if measured is not None and name in measured:
            ax.plot(100 * np.asarray(measured_errors, dtype=float), 100 * np.asarray(measured[name]),
                    ls="none", marker=marker, color=color, mfc="none", ms=8, label=f"{name} (nonlinear plant)")
    if tolerance is not None:
        ax.axhline(100 * tolerance, color="k", ls=":", lw=0.8)
    ax.set_xlabel("frequency error [%]")
    ax.set_ylabel("residual vibration [%]")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", fontsize=8, ncol=2)
    if title:
        ax.set_title(title)
    return fig
