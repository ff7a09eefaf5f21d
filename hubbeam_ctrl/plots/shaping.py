"""Plots of input shapers: residual vibration against frequency error (nothing computed here).

Colours and labels come from ``styles`` (``name -> {"color", "label"}``, e.g.
:func:`controllers.controller_styles` of ``zv, zvd, ei``); without them, Matplotlib's
colour cycle and the names are used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.plots.figure import new_figure

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["plot_shaper_sensitivity"]

#: Markers of the measured points, one per curve in order.
MARKERS = ("o", "s", "^", "D", "v")


def plot_shaper_sensitivity(errors, curves: dict, measured_errors=None, measured: dict | None = None,
                            tolerance: float | None = None, title: str = "",
                            styles: dict | None = None) -> Figure:
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
    styles : dict, optional
        Shaper name -> ``{"color": ..., "label": ...}``.

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(7, 4.5), constrained_layout=True)
    ax = fig.subplots()
    e = 100 * np.asarray(errors, dtype=float)
    for i, (name, v) in enumerate(curves.items()):
        style = (styles or {}).get(name, {})
        color, label = style.get("color") or f"C{i}", style.get("label") or name
        ax.plot(e, 100 * np.asarray(v), color=color, lw=1.5, label=f"{label} (linear)")
        if measured is not None and name in measured:
            ax.plot(100 * np.asarray(measured_errors, dtype=float), 100 * np.asarray(measured[name]),
                    ls="none", marker=MARKERS[i % len(MARKERS)], color=color, mfc="none", ms=8,
                    label=f"{label} (nonlinear plant)")
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
