"""Plots of closed-loop comparisons (Matplotlib object API; nothing computed here).

Each function takes a mapping ``controller name -> Result`` (closed-loop runs) and returns a
:class:`matplotlib.figure.Figure`; :func:`hubbeam_ctrl.plots.plant.save_figure` writes it.
Colours and legend labels come from ``styles`` (``name -> {"color", "label"}``), which the
study layer reads from the controller registry; without them, Matplotlib's colour cycle
and the names are used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.plots.figure import new_figure
from hubbeam_ctrl.plots.loops import plain_log_ticks

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["plot_tip_deflection", "plot_hub_angle", "plot_torque"]

#: Fixed margins [figure fractions] of the two-panel (9 x 6.5 in) and one-panel (9 x 4.5 in)
#: figures, as constrained layout chose them for the paper's slew with a little room for wider
#: tick labels: constrained layout recomputed them on every save, half of a figure's drawing time.
_TWO_PANELS = dict(left=0.085, right=0.99, bottom=0.075, top=0.96, hspace=0.06)
_ONE_PANEL = dict(left=0.09, right=0.99, bottom=0.105, top=0.94)


def _colors(results, styles) -> dict:
    """Colour of each run: its style's, else the i-th of Matplotlib's cycle."""
    return {name: (styles or {}).get(name, {}).get("color") or f"C{i}" for i, name in enumerate(results)}


def _label(name, res, styles):
    label = (styles or {}).get(name, {}).get("label") or name
    return label + ("" if not res.stopped else " (stopped)")


def plot_tip_deflection(results: dict, t_f: float | None = None, residual_start: float | None = None,
                        title: str = "", styles: dict | None = None) -> Figure:
    """Tip deflection of every run: linear scale, and ``|v_tip|`` on a log scale.

    Parameters
    ----------
    results : dict
        Controller name -> Result.
    t_f : float, optional
        Maneuver time [s] (dashed line).
    residual_start : float, optional
        Start of the residual-vibration window [s] (shaded).
    title : str
    styles : dict, optional
        Controller name -> ``{"color": ..., "label": ...}``.

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(9, 6.5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw=_TWO_PANELS)
    color = _colors(results, styles)
    for name, res in results.items():
        ax1.plot(res.t, res.v_tip, color=color[name], lw=1.2, label=_label(name, res, styles))
        ax2.semilogy(res.t, np.maximum(np.abs(res.v_tip), 1e-9), color=color[name], lw=0.9)
    ax1.set_ylabel("tip deflection v_tip [m]")
    ax2.set_ylabel("|v_tip| [m] (log)")
    ax2.set_xlabel("t [s]")
    for ax in (ax1, ax2):
        if t_f is not None:
            ax.axvline(t_f, color="k", ls="--", lw=0.8)
        if residual_start is not None:
            ax.axvspan(residual_start, max(r.t[-1] for r in results.values()),
                       color="0.9", zorder=0)
        ax.grid(True, alpha=0.3)
    ax2.set_ylim(bottom=1e-7)
    plain_log_ticks(ax2.yaxis)                     # 1e-05 rather than mathtext: a third of the drawing time
    ax1.legend(loc="best", ncol=min(5, len(results)))
    ax1.set_title(title or "Tip deflection (shaded: residual-vibration window)")
    return fig


def plot_hub_angle(results: dict, t_f: float | None = None, title: str = "",
                   styles: dict | None = None) -> Figure:
    """Hub angle with the task's reference, and the angle error.

    Parameters
    ----------
    results : dict
        Controller name -> Result (with ``theta_ref``).
    t_f : float, optional
        Maneuver time [s] (dashed line).
    title : str
    styles : dict, optional
        Controller name -> ``{"color": ..., "label": ...}``.

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(9, 6.5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw=_TWO_PANELS)
    ref_drawn = False
    color = _colors(results, styles)
    for name, res in results.items():
        ax1.plot(res.t, res.theta, color=color[name], lw=1.2, label=_label(name, res, styles))
        if res.theta_ref is not None:
            if not ref_drawn:
                ax1.plot(res.t, res.theta_ref, "k:", lw=1.0, label="reference")
                ref_drawn = True
            ax2.plot(res.t, 1e3 * (res.theta - res.theta_ref), color=color[name], lw=1.0)
    ax1.set_ylabel("hub angle [rad]")
    ax2.set_ylabel("angle error [mrad]")
    ax2.set_xlabel("t [s]")
    for ax in (ax1, ax2):
        if t_f is not None:
            ax.axvline(t_f, color="k", ls="--", lw=0.8)
        ax.grid(True, alpha=0.3)
    lim = max((np.max(np.abs(1e3 * (r.theta - r.theta_ref))[r.t >= (t_f or 0)])
               for r in results.values() if r.theta_ref is not None and np.any(r.t >= (t_f or 0))),
              default=None)
    if lim:
        ax2.set_ylim(-1.2 * lim, 1.2 * lim)
    ax1.legend(loc="best", ncol=min(6, len(results) + 1))
    ax1.set_title(title or "Hub angle (error axis scaled to t >= t_f)")
    return fig


def plot_torque(results: dict, tau_max: float | None = None, title: str = "",
                styles: dict | None = None, ylabel: str = "hub torque [N m]") -> Figure:
    """The command of every run (held between samples), with its limit: the hub torque on a
    torque source, the voltage on a DC motor (say so with ``ylabel``).

    Parameters
    ----------
    results : dict
        Controller name -> Result.
    tau_max : float, optional
        The command's limit, in its unit (dotted lines): ``tau_max`` [N m], or ``V_max`` [V].
    title : str
    styles : dict, optional
        Controller name -> ``{"color": ..., "label": ...}``.
    ylabel : str
        The axis label, with the command's unit (default ``"hub torque [N m]"``).

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(9, 4.5))
    ax = fig.subplots(gridspec_kw=_ONE_PANEL)
    color = _colors(results, styles)
    for name, res in results.items():
        ax.step(res.t, res.tau, where="post", color=color[name], lw=1.0,
                label=_label(name, res, styles))
    if tau_max is not None:
        for s in (-1, 1):
            ax.axhline(s * tau_max, color="k", ls=":", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", ncol=min(5, len(results)))
    ax.set_title(title or "Hub torque (dotted: limit)")
    return fig
