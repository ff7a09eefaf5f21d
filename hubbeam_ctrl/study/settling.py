"""When a closed-loop run has settled: inside its bands, and for long enough before the end.

A run that re-enters its bands a few samples before its end (a count cycle or a lightly damped
mode passing through zero at the last sample) is not settled: whether it is would depend on the
phase at which the run stops. A run is called settled only when it has stayed inside both bands
for the *hold* (:func:`settle_hold`) before its end. Measured on random rigs
(``benchmarks/fuzz_rigs.py``, link seeds 31-38 and space seeds 1-5: 412 runs, 311 "settled" by
the last sample alone): 13 of the settled runs had been inside for less than 0.1 s, among them
open loops that ring on (3 ms inside) and, on one link, an LQR and an LQG in a count cycle whose
tip ripple was 2.3 x the band over the window while MPC's equal ripple was "not settled"
(``tests/test_settling.py``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["SETTLE_HOLD_SHARE", "SETTLE_HOLD_PERIODS", "settle_hold", "settling_time", "time_inside_at_end",
           "describe_end"]

#: Share of the residual window (from ``t_f`` + the residual delay to the end) that a run must
#: spend inside both bands before its end to be called settled [-].
SETTLE_HOLD_SHARE = 0.1
#: And at least this many periods of the first bending mode: one period holds every phase of a
#: ringing first mode, so a mode that leaves the band once a period is seen leaving it [-].
SETTLE_HOLD_PERIODS = 1.0


def settle_hold(window_s: float, first_mode_period_s: float | None = None) -> float:
    """The time a run must stay inside its bands before its end to be called settled.

    Parameters
    ----------
    window_s : float
        Length of the residual window [s], >= 0.
    first_mode_period_s : float, optional
        Period of the design's first bending mode [s] (None: not used).

    Returns
    -------
    float
        ``max(SETTLE_HOLD_SHARE * window_s, SETTLE_HOLD_PERIODS * first_mode_period_s)`` [s].

    Examples
    --------
    >>> settle_hold(20.0, 0.5)
    2.0
    >>> settle_hold(2.0, 0.5)
    0.5
    """
    hold = SETTLE_HOLD_SHARE * max(float(window_s), 0.0)
    if first_mode_period_s is not None and np.isfinite(first_mode_period_s):
        hold = max(hold, SETTLE_HOLD_PERIODS * float(first_mode_period_s))
    return hold


def _inside(angle_error, v_tip, angle_band: float, tip_band: float) -> np.ndarray:
    return (np.abs(angle_error) <= angle_band) & (np.abs(v_tip) <= tip_band)


def time_inside_at_end(t, angle_error, v_tip, angle_band: float, tip_band: float) -> float:
    """How long the run has been inside both bands at its end.

    Parameters
    ----------
    t, angle_error, v_tip, angle_band, tip_band
        As :func:`settling_time` ([s], [rad], [m], [rad], [m]).

    Returns
    -------
    float
        ``t[-1]`` minus the first time after which both stay inside [s]; 0 when the last
        sample is outside (or there are no samples).

    Examples
    --------
    >>> t = np.arange(5.0)
    >>> time_inside_at_end(t, np.array([1, 1, 0, 0, 0]), np.zeros(5), 0.5, 0.5)
    2.0
    """
    settle = settling_time(t, angle_error, v_tip, angle_band, tip_band)
    return 0.0 if settle is None else float(t[-1]) - settle


def settling_time(t, angle_error, v_tip, angle_band: float, tip_band: float, hold: float = 0.0):
    """First time after which both ``|angle_error| <= angle_band`` and ``|v_tip| <= tip_band``.

    Parameters
    ----------
    t : ndarray
        Times [s].
    angle_error : ndarray
        Hub-angle error [rad].
    v_tip : ndarray
        Tip deflection [m].
    angle_band : float
        [rad], > 0.
    tip_band : float
        [m], > 0.
    hold : float
        The run must have stayed inside for at least this long at its end [s], >= 0
        (:func:`settle_hold`; default 0: inside at the last sample is enough).

    Returns
    -------
    float or None
        [s]; None if the response is outside the bands at the last sample, or inside for less
        than ``hold``.
    """
    inside = _inside(angle_error, v_tip, angle_band, tip_band)
    if not inside.size or not inside[-1]:
        return None
    outside = np.nonzero(~inside)[0]
    settle = float(t[0]) if not outside.size else float(t[outside[-1] + 1])
    if float(t[-1]) - settle < hold:
        return None
    return settle


def describe_end(settled: bool, inside_at_end_s: float | None, hold_s: float) -> str:
    """Where a run ends with respect to its bands, and for how long: a clause of a verdict's reason.

    Parameters
    ----------
    settled : bool
        Inside both bands for the hold before the end.
    inside_at_end_s : float or None
        Time inside both bands at the end [s] (:func:`time_inside_at_end`; None: not measured).
    hold_s : float
        The hold [s] (:func:`settle_hold`).

    Returns
    -------
    str

    Examples
    --------
    >>> describe_end(False, 0.04, 0.5)[:52]
    'inside the settling bands only for the last 0.04 s, '
    """
    if settled:
        return "inside the settling bands at the end"
    if inside_at_end_s and inside_at_end_s < hold_s:
        digits = next((d for d in range(3, 7) if f"{inside_at_end_s:.{d}g}" != f"{hold_s:.{d}g}"), 7)
        return (f"inside the settling bands only for the last {inside_at_end_s:.{digits}g} s, short of the "
                f"{hold_s:.{digits}g} s hold (a tenth of the residual window, at least one period of the first "
                "bending mode): a run that passes through its bands is not settled")
    return "outside the settling bands at the end"
