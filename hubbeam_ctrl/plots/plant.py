"""Plots of simulation results (Matplotlib, object-oriented API, no pyplot state).

Plotting is kept apart from computing: every function takes results and returns a
``matplotlib.figure.Figure``; :func:`save_figure` writes it atomically.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.plots.figure import new_figure

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["plot_result", "plot_tip_comparison", "plot_campbell", "plot_critical_speed_map",
           "save_figure", "save_png"]


def plot_result(result, title: str | None = None) -> Figure:
    """Tip deflection, axial tip displacement, hub rate and torque of one run.

    Parameters
    ----------
    result : Result
        Any kind; ``Q_theta`` is drawn when the result has it (open-loop runs).
    title : str, optional
        Default: the model, the hub condition and whether the run ended early.

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(8, 7), constrained_layout=True)
    axes = fig.subplots(4, 1, sharex=True)
    axes[0].plot(result.t, result.v_tip)
    axes[0].set_ylabel("v_tip [m]")
    axes[1].plot(result.t, 1e3 * result.u_tip)
    axes[1].set_ylabel("u_tip [mm]")
    axes[2].plot(result.t, result.theta_dot)
    axes[2].set_ylabel("hub rate [rad/s]")
    axes[3].plot(result.t, result.tau, label="tau")
    if result.q_theta is not None:
        axes[3].plot(result.t, result.q_theta, label="Q_theta")
    axes[3].set_ylabel("[N m]")
    axes[3].legend(loc="best")
    axes[3].set_xlabel("t [s]")
    fig.suptitle(title or f"{result.model.upper()} ({result.hub} hub)"
                 + (f", {result.controller}" if result.controller else "")
                 + ("  DIVERGED" if result.diverged else ""))
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig


def plot_tip_comparison(results: dict, title: str = "") -> Figure:
    """Overlay the tip deflections of several runs.

    Parameters
    ----------
    results : dict
        Label -> Result (any kind).
    title : str

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(8, 6.5), constrained_layout=True)
    ax, ax_log = fig.subplots(2, 1, sharex=True)
    styles = ["-", "--", ":", "-."]
    for k, (label, res) in enumerate(results.items()):
        style = styles[k % len(styles)]
        name = label + (" (diverged)" if res.diverged else "")
        ax.plot(res.t, res.v_tip, style, label=name)
        ax_log.semilogy(res.t, np.maximum(np.abs(res.v_tip), 1e-9), style, lw=0.9, label=name)
    ax.set_ylabel("tip deflection v_tip [m]")
    ax.set_title(title)
    ax.legend(loc="best")
    ax_log.set_ylabel("|v_tip| [m] (log)")
    ax_log.set_xlabel("t [s]")
    for a in (ax, ax_log):
        a.grid(True, alpha=0.3)
    return fig


def save_figure(fig: Figure, path, dpi: int = 120, option: str = "out"):
    """Save a figure atomically (PNG by the file's extension).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        Output file (the extension sets the format).
    dpi : int
        Resolution [dots per inch].
    option : str
        The path's name as the caller spelled it, starting the one-line errors (``"plot"``
        for ``--plot``).

    Notes
    -----
    PNGs are written with zlib level 1 instead of Pillow's 6: the same pixels (lossless),
    files about a third larger, and the encoding, which took a quarter of a report's plotting
    time, about three times faster.
    """
    extra = {"pil_kwargs": {"compress_level": 1}} if str(path).lower().endswith(".png") else {}
    return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, **extra), option=option)


def save_png(png: bytes, path, option: str = "out"):
    """Write a PNG's bytes atomically (e.g. from :func:`hubbeam_ctrl.plots.worker.render`).

    Parameters
    ----------
    png : bytes
        The image file's contents.
    path : str or Path
        Output file.
    option : str
        The path's name as the caller spelled it, starting the one-line errors.
    """
    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(png)
    return atomic_write(path, write, option=option)


def plot_campbell(spins, frequencies_hz, title: str = "Campbell diagram") -> Figure:
    """Bending frequencies against spin rate (output of :func:`hubbeam_ctrl.campbell`).

    Parameters
    ----------
    spins : array_like (m,)
        Spin rates [rad/s].
    frequencies_hz : array_like (m, n)
        Frequencies [Hz] (NaN where a mode has lost its stiffness).
    title : str

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(7, 4.5), constrained_layout=True)
    ax = fig.subplots()
    f = np.asarray(frequencies_hz)
    for k in range(f.shape[1]):
        ax.plot(spins, f[:, k], marker=".", label=f"mode {k + 1}")
    ax.plot(spins, np.asarray(spins) / (2 * np.pi), "k--", lw=0.8, label="1x spin")
    ax.set_xlabel("spin rate [rad/s]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(loc="best", fontsize="small")
    return fig


def plot_critical_speed_map(tip_masses, tip_positions, speeds, title: str = "") -> Figure:
    """TLAM critical speed against tip-mass position, one line per tip mass (Fig. 9).

    Parameters
    ----------
    tip_masses : array_like (m,)
        [kg]
    tip_positions : array_like (k,)
        [m]
    speeds : array_like (m, k)
        Critical speeds [rad/s] from :func:`hubbeam_ctrl.critical_speed_map`.
    title : str

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(7, 4.5), constrained_layout=True)
    ax = fig.subplots()
    for mt, row in zip(tip_masses, speeds):
        ax.plot(tip_positions, row, label=f"m_t = {mt:g} kg")
    ax.set_xlabel("tip-mass position l [m]")
    ax.set_ylabel("TLAM critical speed [rad/s]")
    ax.set_title(title or "TLAM critical speed (Fig. 9)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    return fig
