"""Loop plots of a sampled linear feedback loop broken at the plant input (the hub torque).

The plots take data, never controllers: a :class:`LoopResponse` holds the loop gain's
frequency response, the closed loop's step and disturbance responses and its poles, as
computed by the caller (:func:`hubbeam_ctrl.study.loops.loop_response` does it for the
toolbox's linear controllers; any python-control user can fill one from their own systems).
:func:`plot_loop` draws one figure with, for one or more loops overlaid (e.g. the design
model and a richer evaluation model):

* Bode of the loop gain ``L`` at the plant input (magnitude [dB], phase [deg]);
* Nyquist of ``L`` with the critical point and the disk-margin disk the curve must avoid;
* ``|S|`` and ``|T|`` [dB] with their peaks marked (``S = 1/(1+L)``, ``T = L/(1+L)``);
* closed-loop responses of the hub angle and tip deflection to a reference step of the hub
  angle and to a torque step at the plant input (disturbance);
* the sampled closed-loop poles in the z-plane with the unit circle; poles of modes above the
  Nyquist frequency (aliased into ``0..f_s/2``) are ringed and labelled with their true
  frequency.

Sign convention: ``L = -C P`` with the controller's output added to the plant input, so the
closed loop is stable when the Nyquist curve of ``L`` does not encircle ``-1`` (counting the
open-loop poles outside the unit circle) and ``S = 1/(1+L)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plots.figure import new_figure

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["LoopResponse", "disk_margin_disk", "plot_loop", "plot_loop_comparison", "sensitivity_peaks",
           "plain_log_ticks"]

_COLORS = ("C0", "C3", "C2", "C1", "C4")
_STYLES = ("-", "--", "-.", ":", "-")
_MARKERS = ("x", "+", "1", "2", "3")


@dataclass(frozen=True)
class LoopResponse:
    """One sampled linear loop broken at the plant input, as data for :func:`plot_loop`.

    Attributes
    ----------
    label : str
        Legend entry (e.g. ``"design model (5 modes)"``).
    dt : float
        Sample time [s].
    w : ndarray
        Frequencies [rad/s], increasing, in ``(0, pi/dt]``.
    L : ndarray of complex
        Loop gain at the plant input at ``w`` [-] (``L = -C P``).
    t : ndarray
        Times of the closed-loop responses [s] (samples ``k dt``).
    step_theta : ndarray
        Hub angle [rad] after a 1 rad step of the hub-angle reference.
    step_tip : ndarray
        Tip deflection [m] after the same step.
    dist_theta : ndarray
        Hub angle [rad] after a 1 N m step of torque added at the plant input.
    dist_tip : ndarray
        Tip deflection [m] after the same torque step.
    poles : ndarray of complex
        Closed-loop poles (z-plane) [-].
    aliased_hz : ndarray
        Per pole: the continuous-time frequency [Hz] of the plant mode it belongs to when that
        mode lies above the Nyquist frequency ``1/(2 dt)`` (so the pole's angle shows it folded),
        else NaN.
    disk_margin : float, optional
        Balanced disk margin alpha [-] to draw on the Nyquist plot (None: not drawn).
    """

    label: str
    dt: float
    w: np.ndarray
    L: np.ndarray
    t: np.ndarray
    step_theta: np.ndarray
    step_tip: np.ndarray
    dist_theta: np.ndarray
    dist_tip: np.ndarray
    poles: np.ndarray
    aliased_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    disk_margin: float | None = None

    @property
    def S(self) -> np.ndarray:
        """Sensitivity ``1 / (1 + L)`` at :attr:`w` [-]."""
        return 1.0 / (1.0 + self.L)

    @property
    def T(self) -> np.ndarray:
        """Complementary sensitivity ``L / (1 + L)`` at :attr:`w` [-]."""
        return self.L / (1.0 + self.L)



def _loop_list(loops) -> list:
    """``loops`` (one :class:`LoopResponse` or a sequence of them) as a non-empty list."""
    loops = [loops] if isinstance(loops, LoopResponse) else list(loops)
    if not loops or not all(isinstance(lp, LoopResponse) for lp in loops):
        raise ParameterError("loops must be a LoopResponse or a non-empty sequence of them")
    return loops

def sensitivity_peaks(loop: LoopResponse) -> dict:
    """Peaks of ``|S|`` and ``|T|`` on the loop's frequency grid.

    Parameters
    ----------
    loop : LoopResponse
        The loop.

    Returns
    -------
    dict
        ``{"S": (peak [-], frequency [rad/s]), "T": (peak [-], frequency [rad/s])}``.

    Examples
    --------
    >>> w = np.array([1.0, 2.0, 3.0])
    >>> lp = LoopResponse("x", 0.01, w, np.array([1.0, -0.5, 0.25]), *([np.zeros(1)] * 5), poles=np.zeros(1))
    >>> sensitivity_peaks(lp)["S"]
    (2.0, 2.0)
    """
    out = {}
    for name, values in (("S", np.abs(loop.S)), ("T", np.abs(loop.T))):
        i = int(np.argmax(values))
        out[name] = (float(values[i]), float(loop.w[i]))
    return out


def disk_margin_disk(alpha: float) -> tuple:
    """The disk of the Nyquist plane that the loop gain avoids with balanced disk margin ``alpha``.

    ``|S - 1/2| < 1/alpha`` at every frequency keeps ``L`` out of the disk whose diameter on
    the real axis runs from ``-(1 - a)/(1 + a)`` to ``-(1 + a)/(1 - a)``, ``a = alpha/2``:
    the gains ``1/|L|`` there are the disk gain margins.

    Parameters
    ----------
    alpha : float
        Balanced disk margin [-], ``0 <= alpha < 2``.

    Returns
    -------
    tuple of float
        ``(centre, radius)`` on the real axis [-].

    Examples
    --------
    >>> c, r = disk_margin_disk(1.0)
    >>> round(c - r, 6), round(c + r, 6)     # -3 and -1/3: gains 1/3..3 tolerated
    (-3.0, -0.333333)
    """
    if not (isinstance(alpha, (int, float, np.floating)) and 0.0 <= alpha < 2.0):
        raise ParameterError(f"alpha must be a number in [0, 2), got {alpha!r}")
    a = alpha / 2.0
    near, far = -(1.0 - a) / (1.0 + a), -(1.0 + a) / (1.0 - a)
    return (near + far) / 2.0, (near - far) / 2.0


def _db(x) -> np.ndarray:
    return 20.0 * np.log10(np.maximum(np.abs(x), 1e-300))


def _bode(ax_mag, ax_ph, loops) -> None:
    for lp, color, ls in zip(loops, _COLORS, _STYLES):
        hz = lp.w / (2 * np.pi)
        ax_mag.semilogx(hz, _db(lp.L), color=color, ls=ls, lw=1.2, label=lp.label)
        ax_ph.semilogx(hz, np.degrees(np.unwrap(np.angle(lp.L))), color=color, ls=ls, lw=1.2, label=lp.label)
    db = np.concatenate([_db(lp.L) for lp in loops])
    ax_mag.set_ylim(max(float(np.min(db)), -100.0) - 5.0, min(float(np.max(db)), 100.0) + 5.0)
    ax_mag.axhline(0.0, color="k", lw=0.8, ls=":")
    nyq = 1.0 / (2 * loops[0].dt)
    for ax in (ax_mag, ax_ph):
        ax.axvline(nyq, color="0.4", lw=0.8, ls="--")
    ax_mag.text(nyq, ax_mag.get_ylim()[1], " f_s/2", va="top", ha="right", fontsize=8, color="0.3")
    ax_mag.set_ylabel("|L| [dB]")
    ax_mag.set_title("Loop gain L at the plant input (Bode; resonance peaks clipped)")
    ax_mag.legend(loc="lower left", fontsize=8)
    ax_ph.set_ylabel("phase of L [deg]")
    ax_ph.set_xlabel("frequency [Hz]")


def _break_jumps(L: np.ndarray, step: float) -> np.ndarray:
    """``L`` with a NaN between neighbours more than ``step`` apart (the jump over an undamped resonance)."""
    jumps = np.nonzero(np.abs(np.diff(L)) > step)[0] + 1
    return np.insert(L.astype(complex), jumps, np.nan)


def _nyquist(ax, loops, radius: float = 3.0) -> None:
    ax.plot([-1.0], [0.0], "k+", ms=12, mew=2, label="-1", zorder=5)
    for lp, color, ls in zip(loops, _COLORS, _STYLES):
        L = _break_jumps(np.where(np.abs(lp.L) < 10.0 * radius, lp.L, np.nan), radius)
        ax.plot(L.real, L.imag, color=color, ls=ls, lw=1.2, label=f"{lp.label}")
        ax.plot(L.real, -L.imag, color=color, lw=0.6, ls=":")
        if lp.disk_margin is not None and 0.0 < lp.disk_margin < 2.0:
            c, r = disk_margin_disk(lp.disk_margin)
            phi = np.linspace(0.0, 2 * np.pi, 361)
            ax.fill(c + r * np.cos(phi), r * np.sin(phi), color=color, alpha=0.15, lw=1.0, ec=color,
                    label=f"disk margin {lp.disk_margin:.3f}")
    ax.set_xlim(-1.0 - radius, -1.0 + radius)
    ax.set_ylim(-radius, radius)
    ax.set_aspect("equal", adjustable="box")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.axvline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel("Re L [-]")
    ax.set_ylabel("Im L [-]")
    ax.set_title("Nyquist of L (dotted: w < 0); shaded: disk to avoid")
    ax.legend(loc="lower left", fontsize=7, framealpha=0.9)


def _sensitivities(ax, loops) -> None:
    for k, (lp, color) in enumerate(zip(loops, _COLORS)):
        hz = lp.w / (2 * np.pi)
        peaks = sensitivity_peaks(lp)
        ax.semilogx(hz, _db(lp.S), color=color, lw=1.2, label=f"|S| {lp.label}")
        ax.semilogx(hz, _db(lp.T), color=color, lw=0.9, ls=(0, (4, 2)), label=f"|T| {lp.label}")
        for key, marker in (("S", "o"), ("T", "s")):
            peak, w_peak = peaks[key]
            ax.plot([w_peak / (2 * np.pi)], [_db(peak)], marker, color=color, mfc="none", ms=8, mew=1.5)
            ax.annotate(f"max|{key}| = {peak:.2f} ({_db(peak):.1f} dB) at {w_peak / (2 * np.pi):.3g} Hz",
                        (w_peak / (2 * np.pi), _db(peak)), textcoords="offset points",
                        xytext=(-8, 6 + 11 * (2 * k + (key == "T"))), ha="right", fontsize=7, color=color)
    ax.axhline(0.0, color="k", lw=0.8, ls=":")
    low = min(float(np.min(_db(lp.T))) for lp in loops)
    high = max(float(np.max(_db(np.concatenate([lp.S, lp.T])))) for lp in loops)
    ax.set_ylim(max(low, -60.0), high + 10.0 + 8.0 * len(loops))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("magnitude [dB]")
    ax.set_title("|S| (solid) and |T| (dashed), peaks marked")
    ax.legend(loc="lower left", fontsize=7)


def _time(ax, loops, attr: str, scale: float, ylabel: str, title: str) -> None:
    for lp, color, ls in zip(loops, _COLORS, _STYLES):
        ax.plot(lp.t, scale * getattr(lp, attr), color=color, ls=ls, lw=1.2, label=lp.label)
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)


def _zplane(ax, loops, zoom: bool) -> None:
    phi = np.linspace(0.0, 2 * np.pi, 721)
    ax.plot(np.cos(phi), np.sin(phi), color="0.5", lw=0.8)
    for lp, color, marker in zip(loops, _COLORS, _MARKERS):
        z = np.asarray(lp.poles)
        ax.plot(z.real, z.imag, marker, color=color, ms=7, mew=1.3, label=f"{lp.label}: max|z| "
                f"{np.max(np.abs(z)):.4f}")
        al = np.asarray(lp.aliased_hz, dtype=float)
        if al.size == z.size and np.any(np.isfinite(al)):
            m = np.isfinite(al)
            ax.plot(z[m].real, z[m].imag, "o", mfc="none", mec=color, ms=12, mew=1.2,
                    label=f"{lp.label}: aliased modes")
            if not zoom:
                shown = set()
                for zi, f in zip(z[m], al[m]):
                    if zi.imag >= 0 and round(f, 1) not in shown:
                        shown.add(round(f, 1))
                        folded = abs(np.angle(zi)) / (2 * np.pi * lp.dt)
                        right = zi.real < 0
                        ax.annotate(f"{f:.1f} Hz -> {folded:.1f} Hz", (zi.real, zi.imag),
                                    textcoords="offset points", xytext=(14 if right else -14, -14),
                                    ha="left" if right else "right", fontsize=7, color=color,
                                    arrowprops=dict(arrowstyle="-", color=color, lw=0.6))
    if zoom:
        ax.set_xlim(0.9, 1.01)
        ax.set_ylim(-0.055, 0.055)
        ax.set_title("z-plane, near z = 1 (low-frequency modes)")
    else:
        ax.set_xlim(-1.15, 1.15)
        ax.set_ylim(-1.15, 1.15)
        ax.set_title("Closed-loop poles (z-plane), unit circle; ringed: aliased")
        ax.legend(loc="lower left", fontsize=7)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("Re z [-]")
    ax.set_ylabel("Im z [-]")


def _clear(ax) -> None:
    """Remove what :func:`plot_loop` drew on its panels, keeping the axes (and their ticks)."""
    for a in ax.flat:
        for artist in [*a.lines, *a.patches, *a.texts, *a.collections, *a.images]:
            artist.remove()
        if a.get_legend() is not None:
            a.get_legend().remove()
        a.set_title("")
        a.relim()
        a.ignore_existing_data_limits = True
        a.set_autoscale_on(True)


def plot_loop(loops, title: str = "", fig: Figure | None = None) -> Figure:
    """Bode, Nyquist, sensitivities, step and disturbance responses and z-plane poles of loops.

    Parameters
    ----------
    loops : LoopResponse or sequence of LoopResponse
        One or more loops (same sample time), overlaid in colour order.
    title : str
        Figure title.
    fig : Figure, optional
        A figure this function drew before, to draw into again (its previous loops are removed):
        the panels, their axes and ticks are reused, which saves about a fifth of drawing several
        loop figures one after the other (the report's); the image is the same as a new figure's.
        Default: a new figure.

    Returns
    -------
    Figure
        Five rows of two panels, 12 x 19 in.
    """
    loops = _loop_list(loops)
    ax = getattr(fig, "_loop_axes", None) if fig is not None else None
    if ax is None:
        fig = new_figure(figsize=(12, 19))             # fixed margins: constrained layout costs seconds here
        ax = fig.subplots(5, 2, gridspec_kw=dict(left=0.07, right=0.98, bottom=0.03, top=0.94, hspace=0.32,
                                                 wspace=0.2))
        ax[1, 0].sharex(ax[0, 0])
        fig._loop_axes = ax
    else:
        _clear(ax)
    _bode(ax[0, 0], ax[1, 0], loops)
    _nyquist(ax[0, 1], loops)
    _sensitivities(ax[1, 1], loops)
    _time(ax[2, 0], loops, "step_theta", 1.0, "hub angle theta [rad]",
          "Closed loop: hub angle after a 1 rad reference step")
    _time(ax[2, 1], loops, "step_tip", 1.0, "tip deflection [m]",
          "Closed loop: tip deflection after a 1 rad reference step")
    _time(ax[3, 0], loops, "dist_theta", 1e3, "hub angle theta [mrad]",
          "Input disturbance: hub angle after a 1 N m torque step")
    _time(ax[3, 1], loops, "dist_tip", 1e3, "tip deflection [mm]",
          "Input disturbance: tip deflection after a 1 N m torque step")
    _zplane(ax[4, 0], loops, zoom=False)
    _zplane(ax[4, 1], loops, zoom=True)
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=13, y=0.985)
    return fig


def plain_log_ticks(axis) -> None:
    """Label a logarithmic axis in plain text (``1e-04``, ``0.001``, ``1``, ``10``), major ticks only.

    Matplotlib's default labels of a log axis are mathtext (``10^-1`` typeset) and its minor
    ticks (eight a decade) are made anew at every draw: together about a tenth of a second per
    axis; plain labels at the decades (with the major grid) draw several times faster.

    Parameters
    ----------
    axis : matplotlib.axis.Axis
        A log-scaled axis (``ax.xaxis`` or ``ax.yaxis``).
    """
    from matplotlib.ticker import FuncFormatter, NullLocator
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}" if 1e-3 <= abs(v) < 1e5 else f"{v:.0e}"))
    axis.set_minor_locator(NullLocator())


def _peak_label(lp, name: str) -> str:
    s_peak, w_s = sensitivity_peaks(lp)["S"]
    margin = f", disk margin {lp.disk_margin:.3f}" if lp.disk_margin else ", unstable"
    return f"{name}: max|S| {s_peak:.2f} at {w_s / (2 * np.pi):.3g} Hz{margin}"


def plot_loop_comparison(loops, title: str = "", colors=None) -> Figure:
    """Several controllers' loops overlaid in one figure: the report's loop figure.

    One colour and line style per loop (its legend entry is the loop's label). Six panels: ``|L|`` [dB]
    (Bode magnitude), Nyquist of ``L`` near -1 with each stable loop's disk-margin disk,
    ``|S|`` [dB] with its peak marked, the closed-loop poles in the z-plane (aliased plant modes
    ringed, their true frequencies written once), and the tip deflection after a 1 rad
    hub-angle reference step and after a 1 N m torque step at the plant input. Fewer panels
    and texts than :func:`plot_loop` (which draws one controller's loops in full: phase, ``|T|``,
    the hub angle, a zoom near ``z = 1``), so several controllers compare at a glance and the
    figure draws in a fraction of the time; log axes are labelled in plain text
    (:func:`plain_log_ticks`).

    Parameters
    ----------
    loops : sequence of LoopResponse
        One loop per controller (same sample time), in drawing order.
    title : str
        Figure title.
    colors : sequence of str, optional
        Matplotlib colours, one per loop (default ``C0, C1, ...``).

    Returns
    -------
    Figure
        Three rows of two panels, 12 x 12 in.
    """
    loops = _loop_list(loops)
    colors = list(colors) if colors is not None else [f"C{i}" for i in range(len(loops))]
    if len(colors) != len(loops):
        raise ParameterError(f"colors must have one entry per loop ({len(loops)}), got {len(colors)}")
    fig = new_figure(figsize=(12, 12))                 # fixed margins: constrained layout costs seconds here
    ax = fig.subplots(3, 2, gridspec_kw=dict(left=0.07, right=0.98, bottom=0.05, top=0.93, hspace=0.3,
                                             wspace=0.2))
    ax_l, ax_nyq, ax_s, ax_z, ax_step, ax_dist = ax.flat
    nyq = 1.0 / (2 * loops[0].dt)
    db_all = []
    styles = [("-", "--", "-.", ":")[k % 4] for k in range(len(loops))]     # equal loops stay visible
    for lp, color, ls in zip(loops, colors, styles):
        hz = lp.w / (2 * np.pi)
        db = _db(lp.L)
        db_all.append(db)
        ax_l.semilogx(hz, db, color=color, ls=ls, lw=1.1, label=lp.label)
        # Nyquist near -1, broken at the jumps over undamped resonances
        L = _break_jumps(np.where(np.abs(lp.L) < 8.0, lp.L, np.nan), 1.0)
        ax_nyq.plot(L.real, L.imag, color=color, ls=ls, lw=1.1)
        if lp.disk_margin is not None and 0.0 < lp.disk_margin < 2.0:
            c, r = disk_margin_disk(lp.disk_margin)
            phi = np.linspace(0.0, 2 * np.pi, 181)
            ax_nyq.fill(c + r * np.cos(phi), r * np.sin(phi), color=color, alpha=0.12, lw=1.0, ec=color)
        s_db = _db(lp.S)
        i = int(np.argmax(s_db))
        ax_s.semilogx(hz, s_db, color=color, ls=ls, lw=1.1, label=_peak_label(lp, lp.label))
        ax_s.plot([hz[i]], [s_db[i]], "o", color=color, mfc="none", ms=7, mew=1.3)
        z = np.asarray(lp.poles)
        ax_z.plot(z.real, z.imag, "x", color=color, ms=6, mew=1.1,
                  label=f"{lp.label}: max|z| {np.max(np.abs(z)):.5f}")
        ax_step.plot(lp.t, lp.step_tip, color=color, ls=ls, lw=1.1, label=lp.label)
        ax_dist.plot(lp.t, 1e3 * lp.dist_tip, color=color, ls=ls, lw=1.1, label=lp.label)
    # aliased plant modes: ringed for every loop, their frequencies written once
    written = set()
    for lp, color in zip(loops, colors):
        z, al = np.asarray(lp.poles), np.asarray(lp.aliased_hz, dtype=float)
        if al.size != z.size or not np.any(np.isfinite(al)):
            continue
        m = np.isfinite(al)
        ax_z.plot(z[m].real, z[m].imag, "o", mfc="none", mec=color, ms=11, mew=1.0)
        for zi, f in zip(z[m], al[m]):
            if zi.imag >= 0 and round(f) not in written:
                written.add(round(f))
                ax_z.annotate(f"{f:.1f} Hz", (zi.real, zi.imag), textcoords="offset points", xytext=(6, 6),
                              fontsize=7, color="0.25")
    db = np.concatenate(db_all)
    ax_l.set_ylim(max(float(np.min(db)), -100.0) - 5.0, min(float(np.max(db)), 100.0) + 5.0)
    ax_l.axhline(0.0, color="k", lw=0.8, ls=":")
    for a in (ax_l, ax_s):
        a.axvline(nyq, color="0.4", lw=0.8, ls="--")
        plain_log_ticks(a.xaxis)
        a.set_xlabel("frequency [Hz] (dashed: f_s/2)")
    ax_l.set_ylabel("|L| [dB]")
    ax_l.set_title("Loop gain L at the plant input (resonance peaks clipped)")
    ax_l.legend(loc="lower left", fontsize=8)
    ax_nyq.plot([-1.0], [0.0], "k+", ms=12, mew=2, zorder=5)
    ax_nyq.set_xlim(-4.0, 2.0)
    ax_nyq.set_ylim(-3.0, 3.0)
    ax_nyq.set_aspect("equal", adjustable="box")
    ax_nyq.set_xlabel("Re L [-]")
    ax_nyq.set_ylabel("Im L [-]")
    ax_nyq.set_title("Nyquist of L (w > 0), + at -1; shaded: disk to avoid")
    ax_s.axhline(0.0, color="k", lw=0.8, ls=":")
    ax_s.set_ylim(bottom=max(min(float(np.min(_db(lp.S))) for lp in loops), -60.0) - 3.0)
    ax_s.set_ylabel("|S| [dB]")
    ax_s.set_title("Sensitivity S = 1/(1 + L), peaks ringed")
    ax_s.legend(loc="lower right", fontsize=7)
    phi = np.linspace(0.0, 2 * np.pi, 361)
    ax_z.plot(np.cos(phi), np.sin(phi), color="0.5", lw=0.8)
    ax_z.set_xlim(-1.15, 1.15)
    ax_z.set_ylim(-1.15, 1.15)
    ax_z.set_aspect("equal", adjustable="box")
    ax_z.set_xlabel("Re z [-]")
    ax_z.set_ylabel("Im z [-]")
    ax_z.set_title("Closed-loop poles (z-plane); ringed: aliased plant modes")
    ax_z.legend(loc="lower left", fontsize=7)
    for a, ylabel, what in ((ax_step, "tip deflection [m]", "a 1 rad hub-angle reference step"),
                            (ax_dist, "tip deflection [mm]", "a 1 N m torque step at the input")):
        a.axhline(0.0, color="0.6", lw=0.6)
        a.set_xlabel("t [s]")
        a.set_ylabel(ylabel)
        a.set_title(f"Tip deflection after {what}")
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=12, y=0.985)
    return fig
