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
bounds IPOPT's time. :class:`ReplanSolver` builds the NLP once for every payload of a beam
(the payload a parameter) so that a re-plan is IPOPT's iterations only: 0.1-0.4 s on 2-3 modes,
expanded.
"""

from __future__ import annotations

import dataclasses
import time

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.native import capture_native_output
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.limit.collocation import _nlp, _optimise_problem, _parameter_values, _problem, _rigid_guess
from hubbeam_ctrl.limit.ipopt_progress import _IterationCallback
from hubbeam_ctrl.limit.optimal import _check_inputs, _result, _source
from hubbeam_ctrl.limit.slew import OptimalSettings, OptimalSlew
from hubbeam_ctrl.plant.params import Params

__all__ = ["min_vibration_replan", "replan_coordinates", "ReplanSolver"]


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
    pb = _problem(params, slew_angle, settings, rig)
    x0 = _start(initial_state, pb.n)
    held = _held(hold, settings.intervals, pb.tau_max)
    pb = dataclasses.replace(pb, start=np.concatenate([x0[:pb.n] / pb.q_scale, x0[pb.n:] / pb.v_scale]), hold=held)
    quick = settings.replace(check=False)
    pb, w, stats, iterations, wall = _optimise_problem(pb, tolerance, duration, quick)
    return _result("min-vibration", params, slew_angle, tolerance, pb, w, stats, iterations, wall, quick)


def _start(initial_state, n: int) -> np.ndarray:
    """``initial_state`` checked: ``2 n`` finite numbers."""
    x0 = np.asarray(initial_state, dtype=float).ravel()
    if x0.shape != (2 * n,):
        raise ParameterError(f"initial_state must hold 2 n_q = {2 * n} numbers ([q, v] of the model's "
                             f"{n} coordinates), got {x0.size}")
    if not np.all(np.isfinite(x0)):
        raise ParameterError("initial_state must be finite numbers [rad, m, rad/s, m/s]")
    return x0


def _held(hold, intervals: int, tau_max: float):
    """``hold`` checked and scaled by ``tau_max`` (None: nothing held)."""
    if hold is None:
        return None
    held = np.asarray(hold, dtype=float).ravel()
    if not (held.size < intervals and np.all(np.isfinite(held)) and np.all(np.abs(held) <= tau_max * (1 + 1e-12))):
        raise ParameterError(f"hold must be fewer than {intervals} torques within +-{tau_max:g} N m, got "
                             f"{held.size} (largest {np.max(np.abs(held), initial=0):g})")
    return held / tau_max


class _Deadline:
    """Stops IPOPT once ``deadline`` (``time.perf_counter()``) is past (None: never)."""

    def __init__(self):
        self.deadline = None

    def __call__(self) -> bool:
        return self.deadline is not None and time.perf_counter() > self.deadline


class ReplanSolver:
    """:func:`min_vibration_replan` for any payload of one beam, its NLP built once.

    The payload enters the model's equations and the end conditions' modes only, so the NLP
    takes them as parameters (:func:`~hubbeam_ctrl.limit.collocation._parameter_values`); the start
    state, the held torques and the duration are bounds. Building is the slow part (0.1-0.3 s
    on 2-5 bending modes, seconds with ``expand``); a controller builds before the slew and each
    :meth:`solve` is IPOPT's iterations only, stopped at a deadline if asked.

    Parameters
    ----------
    params : Params or Rig
        The nominal beam (its scales scale every solve's NLP; a rig adds its drive's limits).
    slew_angle : float
        Hub angle to end at [rad].
    tolerance : float, optional
        Residual tip vibration the end conditions allow [m] (default 1e-3 L).
    settings : OptimalSettings
        Grid and model (``intervals``, ``degree``, ``modes``, ``axial``, ``max_iter``).
    expand : bool
        Expand the NLP to scalar expressions: slower to build, faster iterations.
    """

    def __init__(self, params, slew_angle: float, *, tolerance: float | None = None,
                 settings: OptimalSettings = OptimalSettings(check=False), expand: bool = False):
        params, rig = _source(params)
        self.slew_angle, self.tolerance = _check_inputs(params, slew_angle, tolerance, settings)
        self.params, self.settings, self.rig = params, settings.replace(check=False), rig
        start = time.perf_counter()
        self._pb = _problem(params, self.slew_angle, settings, rig)
        nlp, self._lbw, self._ubw, self._lbg, self._ubg, self._points = _nlp(
            self._pb, settings.intervals, settings.degree, self.tolerance, 1.0, parametric=True,
            smoothing=settings.torque_smoothing)
        self._stop = _Deadline()
        self._stop_callback = _IterationCallback(nlp, self._stop)
        ipopt = {"print_level": 0, "max_iter": settings.max_iter, "sb": "yes", "tol": 1e-8, "acceptable_tol": 1e-6}
        with capture_native_output():
            self._solver = ca.nlpsol("replan", "ipopt", nlp, {"print_time": False, "ipopt": ipopt,
                                                              "expand": bool(expand),
                                                              "iteration_callback": self._stop_callback})
        self.build_s = time.perf_counter() - start

    @property
    def n_q(self) -> int:
        """Generalised coordinates of the model (the initial state has ``2 n_q``)."""
        return self._pb.n

    def solve(self, params, initial_state, duration: float, *, hold=None,
              max_wall_s: float | None = None) -> OptimalSlew:
        """The rest of the slew for ``params`` (the nominal's family, any tip mass) from ``initial_state``.

        Parameters
        ----------
        params : Params
            The beam to plan for: the nominal's but for its tip mass ``m_t``.
        initial_state : array_like (2 n_q,)
            As :func:`min_vibration_replan`'s.
        duration : float
            Time left [s], > 0.
        hold : array_like, optional
            Torques of the first intervals [N m], as :func:`min_vibration_replan`'s.
        max_wall_s : float, optional
            Stop IPOPT this many seconds after the call [s]; the result is then its last
            iterate, not converged.

        Returns
        -------
        OptimalSlew
            As :func:`min_vibration_replan`'s (``solve_s``: this call's wall time).
        """
        start = time.perf_counter()
        duration = check_positive("duration", duration, "s")
        nominal, N, d = self._pb, self.settings.intervals, self.settings.degree
        if not isinstance(params, Params) or params.replace(m_t=self.params.m_t) != self.params:
            raise ParameterError("params must be the solver's beam (a Params) but for its tip mass m_t")
        own = _problem(params, self.slew_angle, self.settings, self.rig)
        x0 = _start(initial_state, nominal.n)
        held = _held(hold, N, nominal.tau_max)
        # the nominal's scales (those of the NLP), the payload's model and modes
        pb = dataclasses.replace(own, q_scale=nominal.q_scale, v_scale=nominal.v_scale, a_scale=nominal.a_scale,
                                 f_scale=nominal.f_scale, T_rigid=nominal.T_rigid, tau_max=nominal.tau_max,
                                 tip_limit=nominal.tip_limit, drive=nominal.drive,
                                 start=np.concatenate([x0[:nominal.n] / nominal.q_scale,
                                                       x0[nominal.n:] / nominal.v_scale]), hold=held)
        lbw, ubw = self._lbw.copy(), self._ubw.copy()
        lbw[0] = ubw[0] = duration
        if held is not None:
            lbw[1:1 + len(held)] = ubw[1:1 + len(held)] = held
        lbw[1 + N:1 + N + 2 * pb.n] = ubw[1 + N:1 + N + 2 * pb.n] = pb.start
        w0 = _rigid_guess(pb, N, d, self._points, duration)
        self._stop.deadline = None if max_wall_s is None else start + float(max_wall_s)
        with capture_native_output():
            sol = self._solver(x0=w0, lbx=lbw, ubx=ubw, lbg=self._lbg, ubg=self._ubg, p=_parameter_values(own))
        stats = self._solver.stats()
        self._stop.deadline = None
        w = np.array(sol["x"]).ravel()
        out = _result("min-vibration", params, self.slew_angle, self.tolerance, pb, w, stats,
                      int(stats["iter_count"]), time.perf_counter() - start, self.settings)
        return dataclasses.replace(out, rigid_bound_s=own.bound)
