"""Re-planning a slew from a moving state: the minimum-vibration rest of a slew on the nonlinear model.

A controller that learns something during a slew (the payload, say) must finish the slew from
where the beam is: turning, bent and vibrating. :func:`min_vibration_replan` solves the
minimum-vibration problem of :func:`~hubbeam_ctrl.limit.min_vibration_slew` (the same direct
collocation on the same nonlinear model, the same end conditions and limits) with the initial
state fixed to the given one instead of rest.

Measured (``benchmarks/explore_payload_learning.py``, docs/limit.md): identifying the payload at
25 % and 50 % of the slew and re-planning this way lets the nominal LQR of Table 1's beam meet
issue 22's targets at 0, 0.1, 0.3 and 0.5 kg, where a re-plan on the linear design model
misses at 0.5 kg (its 1 % model error on the 0.6 m bending amplitude mid-slew becomes residual
vibration). On 2-3 bending modes a re-plan takes 0.3-0.7 s on two cores (7-30 s on 10 modes),
so a controller must keep running the old plan meanwhile; ``OptimalSettings(max_wall_s=)``
bounds IPOPT's time.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.limit.optimal import (
    OptimalSettings,
    OptimalSlew,
    _check_inputs,
    _optimise_problem,
    _problem,
    _result,
    _source,
)

__all__ = ["min_vibration_replan", "replan_coordinates"]


def replan_coordinates(params, settings: OptimalSettings = OptimalSettings()) -> int:
    """Number of generalised coordinates ``n_q`` of the re-plan's model (the state has ``2 n_q``).

    Parameters
    ----------
    params : Params or Rig
        Beam (``n_transverse``) or rig.
    settings : OptimalSettings
        ``modes`` and ``axial`` decide the model (default: ``params.n_transverse`` bending modes,
        quasi-static axial, so ``n_q = 1 + n_transverse``).

    Returns
    -------
    int
    """
    params, _ = _source(params)
    n_modes = params.n_transverse if settings.modes is None else settings.modes
    return 1 + n_modes if settings.axial == "quasi-static" else _problem(params, 1.0, settings).n


def min_vibration_replan(params, initial_state, slew_angle: float, duration: float, *,
                         tolerance: float | None = None, hold=None,
                         settings: OptimalSettings = OptimalSettings(check=False)) -> OptimalSlew:
    """The rest of a slew from ``initial_state`` in ``duration``, with the smallest residual vibration.

    Parameters
    ----------
    params : Params or Rig
        Beam, hub and drive, as :func:`~hubbeam_ctrl.limit.min_vibration_slew` (a rig adds its
        drive's voltage and current limits and friction).
    initial_state : array_like (2 n_q,)
        ``[q, v]`` of the model's generalised coordinates at the start of the re-plan: hub angle
        [rad] and the bending coordinates [m] (the first ``n_transverse`` of a plant state in
        SFOAM order), then their rates [rad/s, m/s]; ``n_q`` from :func:`replan_coordinates`.
    slew_angle : float
        Hub angle to end at [rad] (absolute, not the rest of the turn), finite, not 0.
    duration : float
        Time left [s], > 0.
    tolerance : float, optional
        Residual tip vibration the end conditions allow [m], > 0 (default 1e-3 L).
    hold : array_like, optional
        Torques [N m] of the first intervals (``duration / settings.intervals`` each), fixed:
        what runs while the re-plan computes; each within ``tau_max``, fewer than the intervals.
    settings : OptimalSettings
        Grid and model (default: no evaluation-plant check, which runs from rest).

    Returns
    -------
    OptimalSlew
        ``kind="min-vibration"``; its times ``t`` start at 0 at the re-plan's start. Not
        converged: the last iterate, said in ``message``.

    Raises
    ------
    ParameterError
        ``initial_state`` of the wrong length or not finite, or a bad ``duration``,
        ``slew_angle``, ``tolerance`` or ``settings``.
    """
    params, rig = _source(params)
    slew_angle, tolerance = _check_inputs(params, slew_angle, tolerance, settings)
    duration = check_positive("duration", duration, "s")
    x0 = np.asarray(initial_state, dtype=float).ravel()
    pb = _problem(params, slew_angle, settings, rig)
    if x0.shape != (2 * pb.n,):
        raise ParameterError(f"initial_state must hold 2 n_q = {2 * pb.n} numbers ([q, v] of the model's "
                             f"{pb.n} coordinates), got {x0.size}")
    if not np.all(np.isfinite(x0)):
        raise ParameterError("initial_state must be finite numbers [rad, m, rad/s, m/s]")
    held = None
    if hold is not None:
        held = np.asarray(hold, dtype=float).ravel()
        if not (held.size < settings.intervals and np.all(np.isfinite(held))
                and np.all(np.abs(held) <= pb.tau_max * (1 + 1e-12))):
            raise ParameterError(f"hold must be fewer than {settings.intervals} torques within "
                                 f"+-{pb.tau_max:g} N m, got {held.size} (largest {np.max(np.abs(held), initial=0):g})")
        held = held / pb.tau_max
    pb = dataclasses.replace(pb, start=np.concatenate([x0[:pb.n] / pb.q_scale, x0[pb.n:] / pb.v_scale]), hold=held)
    quick = settings.replace(check=False)
    pb, w, stats, iterations, wall = _optimise_problem(pb, tolerance, duration, quick)
    return _result("min-vibration", params, slew_angle, tolerance, pb, w, stats, iterations, wall, quick)
