"""Payload learning: identify the tip mass during a slew and finish the slew re-planned for it.

A design for a payload range cannot settle Table 1's beam within its 1 mm tip band: that needs
the payload to about 1 % (issue 22, docs/limit.md). :class:`PayloadLearning` wraps a
state-feedback controller (LQR, MPC) or an LQG designed for the nominal payload. At each switch
time it

1. identifies the payload (:func:`identify_payload`): of the design models of the payloads on a
   grid over the range, driven from rest by the torques applied so far, the one whose hub rate
   fits the measured rate best (least squares, refined by a parabola through the best three);
2. re-plans the rest of the slew on that payload's nonlinear model from the measured state, or
   the LQG filter's estimate (:func:`hubbeam_ctrl.limit.min_vibration_replan`), its first
   ``allowance_s`` seconds held at the old plan's feedforward: the re-plan's computing time,
   during which the wrapper plays that feedforward without feedback, so that the plant ends the
   allowance where the plan predicted;
3. continues with the controller designed on that payload, along the new plan (reference and
   feedforward, :func:`controllers.optimal_reference`); a new LQG's filter starts from the old
   one's estimate and follows the measurements, with the torques played, while the re-plan
   computes (:meth:`controllers.lqg.LQG.start_estimate`, :meth:`Controller.applied`), and does
   not predict along the re-plan, which carries fewer modes than the filter.

The re-plan keeps the bending modes its torque grid can shape (:func:`shapeable_modes` on the
heaviest payload, the free-hub modes at or below the grid's Nyquist frequency; faster ones are
left to the feedback)
and, by default, runs in real time: IPOPT gets what identification left of the allowance less
:data:`RESERVE_SHARE`, and a re-plan not converged by then is dropped, the controller keeping
its plan and gain.

Measured on Table 1's beam, 1 rad in 4.614 s (1.5 x the 0.5 kg beam's time-optimal slew), all
defaults (switches at 25 % and 50 %, 1 s allowance; ``benchmarks/bench_limit_targets.py --cases
payload_learning``): the LQR settles at 4.54 / 4.56 / 4.96 / 7.19 s with 0 / 0.1 / 0.3 / 0.5 kg,
the MPC at 4.54 / 4.57 / 4.63 / 4.58 s and the LQG at 4.59 / 4.58 / 5.58 / 6.57 s (targets
6.59 / 6.79 / 7.11 / 7.37 s; at most 0.015 % of L): 12 of 12 meet. Each re-plan's NLP is built
before the slew (:class:`hubbeam_ctrl.limit.ReplanSolver`, the payload a parameter, scaled for
the heaviest payload, the torque's steps weighted by ``smoothing``), so each switch
(identification, IPOPT on 2 then 3 modes, new design) took 0.19-0.39 s of the 1 s allowed, none
dropped. A re-plan on all 10 of the plant's modes took 7-30 s.

It does not transfer in real time to the lab arm's 1.79 s slew (0-0.2 kg): the allowance is
capped at 0.45 s there, and 5 of 12 meet with all defaults; re-planned at once on the design's
5 modes 12 of 12 meet, but each re-plan takes 0.36-0.95 s (``--cases payload_learning_lab``,
docs/limit.md).
:attr:`PayloadLearning.log` records each switch's times, modes and whether it was dropped.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.signal import dlsim

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.params import Params

from .base import Controller, DesignModel, Reference

__all__ = ["PayloadLearningSettings", "PayloadLearning", "identify_payload", "shapeable_modes"]


#: Intervals of the identification's payload grid over the range by default (``grid_kg=None``):
#: on the lab arm (0-0.2 kg) a 20 g step identified 0.05 kg as 0.0511 kg and the re-planned LQR
#: missed; 4 g gave 0.0501 kg.
GRID_POINTS = 50

#: Share of the allowance kept for identification's overrun and designing the new controller
#: (0.05-0.1 s of the 1 s default on Table 1's beam); IPOPT gets the rest.
RESERVE_SHARE = 0.3


@dataclass(frozen=True)
class PayloadLearningSettings(Settings):
    """How :class:`PayloadLearning` identifies the payload and re-plans."""

    payload_min_kg: float = setting(0.0, unit="kg", lo=0.0, doc="Lightest payload of the range.")
    payload_max_kg: float = setting(0.5, unit="kg", lo="payload_min_kg",
                                    doc="Heaviest payload of the range.")
    switch_at: tuple = setting((0.25, 0.5), kind=tuple,
                               doc="Fractions of the slew's duration at which the payload is identified "
                                   "and the slew re-planned, increasing, each in (0, 1).")
    grid_kg: float | None = setting(None, unit="kg", lo=0.0, lo_open=True, kind=float,
                                    doc="Step of the identification's payload grid (None: a fiftieth of the "
                                        "range).")
    intervals: int = setting(40, lo=4, hi=400, doc="Collocation intervals of each re-plan.")
    max_iter: int = setting(100, lo=1, doc="IPOPT iterations per re-plan at most (a re-plan that stops there "
                                           "keeps its last iterate; the log says so).")
    modes: int | None = setting(None, lo=1, hi=20, kind=int,
                                doc="Bending modes of the re-plan's nonlinear model (None: those the re-plan's torque "
                                    "grid can shape, free-hub frequency at most intervals / (2 x time left), "
                                    "at least 1).")
    smoothing: float = setting(1e-3, lo=0.0, doc="Weight of the re-plan's torque steps "
                                                 "(OptimalSettings.torque_smoothing): one plan among those "
                                                 "that leave the model at rest, and better-conditioned solves.")
    allowance_s: float = setting(1.0, unit="s", lo=0.0,
                                 doc="Computing time allowed for a re-plan (at most until the next switch and "
                                     "half the time left): its first intervals covering it are held at the "
                                     "old plan's feedforward, played without feedback.")
    real_time: bool = setting(True, doc="Hold each re-plan to the allowance on this computer's clock: IPOPT stops "
                                        "at what identification left of it less RESERVE_SHARE, and a re-plan "
                                        "not converged by then is dropped (the controller keeps its plan and "
                                        "gain). False: wait for every re-plan (results the same on any "
                                        "computer). Only with allowance_s > 0.")

    def __post_init__(self):
        super().__post_init__()
        s = tuple(float(f) for f in self.switch_at)
        if not s or not all(0.0 < f < 1.0 for f in s) or any(b <= a for a, b in zip(s, s[1:])):
            raise ParameterError(f"switch_at must be increasing fractions of the slew in (0, 1), "
                                 f"got {self.switch_at!r}")
        object.__setattr__(self, "switch_at", s)


def identify_payload(params: Params, dt: float, n_modes: int, torque, rate, masses) -> float:
    """The payload [kg] whose design model's hub rate fits the measured one best.

    Parameters
    ----------
    params : Params
        The beam (its ``m_t`` is replaced by each candidate).
    dt : float
        Sample time [s].
    n_modes : int
        Bending modes of the candidates' design models.
    torque : array_like (k,)
        Torques applied so far [N m], held over each sample.
    rate : array_like (k + 1,)
        Hub rate measured at the samples [rad/s], the first at rest.
    masses : array_like
        Candidate payloads [kg], increasing, evenly spaced.

    Returns
    -------
    float
        The best candidate refined by a parabola through it and its neighbours, within the
        candidates' range.
    """
    torque, rate, masses = (np.asarray(a, dtype=float) for a in (torque, rate, masses))
    cost = np.empty(len(masses))
    for i, m in enumerate(masses):
        d = _candidate(params.replace(m_t=float(m)), float(dt), int(n_modes))
        # the hub rate after each held torque, from rest: one compiled linear filter per candidate
        _, y, _ = dlsim((d.Ad, d.Bd, np.eye(d.n_x)[[d.n_x // 2]], np.zeros((1, 1)), dt),
                        np.append(torque, 0.0)[:, None], x0=np.zeros(d.n_x))
        predicted = np.concatenate([[0.0], y[1:len(torque) + 1, 0]]) if len(torque) else np.zeros(1)
        cost[i] = float(np.sum((predicted[:len(rate)] - rate) ** 2))
    i = int(np.argmin(cost))
    if 0 < i < len(masses) - 1:
        c0, c1, c2 = cost[i - 1:i + 2]
        if c0 - 2 * c1 + c2 > 0:
            step = masses[1] - masses[0]
            return float(np.clip(masses[i] + 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2) * step, masses[0], masses[-1]))
    return float(masses[i])


@functools.lru_cache(maxsize=32)
def _replan_solver(params: Params, slew_angle: float, intervals: int, max_iter: int, modes: int, smoothing: float):
    """The re-plan's NLP for ``params``' family, expanded (built once per beam, slew and settings)."""
    from hubbeam_ctrl.limit import OptimalSettings, ReplanSolver
    settings = OptimalSettings(intervals=intervals, max_iter=max_iter, modes=modes, check=False,
                               torque_smoothing=smoothing)
    return ReplanSolver(params, slew_angle, settings=settings, expand=True)


@functools.lru_cache(maxsize=256)
def _candidate(params: Params, dt: float, n_modes: int) -> DesignModel:
    """A candidate payload's design model, built once per run of switches."""
    return DesignModel.build(params, 0.0, dt, n_modes)


class PayloadLearning(Controller):
    """A controller that learns the payload during a slew and re-plans for it.

    Parameters
    ----------
    inner : Controller
        The controller designed for the nominal payload, on the slew's reference: state
        feedback (``measurement == "state"``, e.g. LQR or MPC) or an
        :class:`~controllers.lqg.LQG` without integral action (the re-plan starts from its
        estimate).
    settings : PayloadLearningSettings
    slew_angle : float
        The slew's end angle [rad].
    duration : float
        The slew's duration ``t_f`` [s].
    factory : callable
        ``factory(name, design, settings, reference)`` building the controller for the learned
        payload (:func:`controllers.make_controller`).

    Attributes
    ----------
    log : list of dict
        One entry per switch: ``t_s`` [s], the identified ``payload_kg`` [kg], the re-plan's
        ``modes``, ``identify_wall_s``, ``replan_wall_s`` and ``wall_s`` (the whole switch) [s]
        against ``allowance_s`` [s] (``within_allowance``), IPOPT's ``iterations`` and
        ``converged``, ``dropped`` (too late: the controller kept its plan and gain) and
        ``applied_s``, when the new plan took over [s] (None if dropped).
    """

    def __init__(self, inner: Controller, settings: PayloadLearningSettings, slew_angle: float, duration: float,
                 factory):
        from .lqg import LQG
        output = isinstance(inner, LQG) and not inner.settings.integral and inner.design.spin == 0.0
        if getattr(inner, "measurement", None) != "state" and not output:
            raise ParameterError(f"PayloadLearning wraps a state-feedback controller (measurement 'state') or an "
                                 f"LQG without integral action, got {getattr(inner, 'name', type(inner).__name__)!r}")
        if not isinstance(settings, PayloadLearningSettings):
            raise ParameterError(f"settings must be a PayloadLearningSettings, got {type(settings).__name__}")
        m_t = inner.design.params.m_t
        if not settings.payload_min_kg <= m_t <= settings.payload_max_kg:
            raise ParameterError(f"payload_min_kg..payload_max_kg must hold the design's m_t = {m_t:g} kg, got "
                                 f"{settings.payload_min_kg:g}..{settings.payload_max_kg:g}")
        super().__init__(inner.design, inner.settings, inner.reference)
        self.first, self.learning, self.factory = inner, settings, factory
        self.name, self.n_modes, self.state_modes = inner.name, inner.n_modes, inner.state_modes
        self.measurement = inner.measurement
        # the hub rate: the state's or the sensors' [theta, theta_dot, M_root]
        self._rate_at = None if inner.measurement == "state" else 1
        self.slew_angle, self.duration = float(slew_angle), float(duration)
        self._switch = [int(round(f * duration / self.dt)) for f in settings.switch_at]
        span = settings.payload_max_kg - settings.payload_min_kg
        step = settings.grid_kg if settings.grid_kg is not None else span / GRID_POINTS
        n = max(2, int(round(span / step)) + 1) if span > 0 else 1
        self._masses = np.linspace(settings.payload_min_kg, settings.payload_max_kg, n)
        # each switch's re-plan: its modes (the torque grid's rule on the heaviest payload, whose
        # modes are the slowest) and its NLP, built now, before the slew, scaled for the heaviest
        # payload (its deflections the largest; scaled for the nominal 0.1 kg, a re-plan for 0.5 kg
        # took 24 iterations and missed its deadline, 7 scaled for 0.5 kg)
        base, steps = inner.design.params, round(duration / self.dt)
        heaviest = _candidate(base.replace(m_t=settings.payload_max_kg), float(self.dt), int(inner.design.n_modes))
        self._plan_modes = [min(settings.modes if settings.modes is not None else
                                shapeable_modes(heaviest, settings.intervals, (steps - k) * self.dt), base.n_transverse)
                            for k in self._switch]
        scaled = base.replace(m_t=settings.payload_max_kg)
        self._solvers = [_replan_solver(scaled, self.slew_angle, settings.intervals, settings.max_iter, m,
                                        settings.smoothing) for m in self._plan_modes]
        self.reset()

    def reset(self) -> None:
        """Back to the nominal controller and plan."""
        self.inner = self.first
        self.inner.reset()
        self.log, self._torque, self._rate, self._stage, self._pending = [], [], [], 0, None

    def feedback_matrices(self):
        """The current controller's (:meth:`Controller.feedback_matrices`)."""
        return self.inner.feedback_matrices()

    def __call__(self, t: float, y) -> float:
        y = np.asarray(y, dtype=float)
        k = int(round(t / self.dt))
        self._rate.append(float(y[len(y) // 2 if self._rate_at is None else self._rate_at]))
        if self._pending is not None and k >= self._pending[0]:
            self.inner, self._pending = self._pending[1], None
        elif self._pending is not None and self._pending[1].measurement != "state":
            self._pending[1](t, y)             # the new controller's filter follows the measurements
        tau = float(self.inner(t, y))
        if self._stage < len(self._switch) and k == self._switch[self._stage]:
            self._stage += 1
            self._relearn(k, y)
        if self._pending is not None:          # the re-plan computes: its held prefix, no feedback
            tau = float(self._pending[1].reference.torque[k])
            self.inner.applied(tau)
            self._pending[1].applied(tau)
        self._torque.append(tau)
        return tau

    def _allowance(self, k: int) -> float:
        """The re-plan's computing time [s] at sample ``k``: ``allowance_s``, but at most until the
        next switch and half the time left (a fast task cannot wait for a slow computer)."""
        left = round(self.duration / self.dt) - k
        later = [s for s in self._switch if s > k]
        cap = min(0.5 * left, later[0] - k if later else left) * self.dt
        return min(self.learning.allowance_s, cap)

    def _relearn(self, k: int, y: np.ndarray) -> None:
        st, old, dt = self.learning, self.inner.reference, self.dt
        base = self.first.design.params
        clock = time.perf_counter()
        mass = identify_payload(base, dt, self.first.design.n_modes, self._torque[:k], self._rate[:k + 1],
                                self._masses)
        identified = time.perf_counter()
        params = base.replace(m_t=mass)
        remaining = (round(self.duration / dt) - k) * dt
        allowance = self._allowance(k)
        edges, hold = _held_prefix(old, k, remaining / st.intervals, allowance, min(self.tau_max, base.tau_max))
        solver, modes = self._solvers[self._stage - 1], self._plan_modes[self._stage - 1]
        deadline = None
        if st.real_time and allowance > 0:     # IPOPT's share: what identification left, less the reserve
            deadline = max((1.0 - RESERVE_SHARE) * allowance - (time.perf_counter() - clock), 1e-3)
        z = y if self.measurement == "state" else self.inner.x_hat       # the state, or the filter's estimate
        n, half = solver.n_q, len(z) // 2
        plan = solver.solve(params, np.concatenate([z[:n], z[half:half + n]]), remaining, hold=hold or None,
                            max_wall_s=deadline)
        entry = {"t_s": k * dt, "payload_kg": mass, "modes": modes, "identify_wall_s": identified - clock,
                 "replan_wall_s": time.perf_counter() - identified, "iterations": plan.iterations,
                 "converged": plan.converged, "allowance_s": allowance}
        dropped = deadline is not None and not plan.converged   # too late: keep the plan and gain, with feedback
        ready = max(int(edges[-1]), k + 1)     # from the next sample at the earliest
        if not dropped:
            ref = _spliced(old, plan, k, mass)
            design = DesignModel.build(params, self.first.design.spin, dt, self.first.design.n_modes)
            ctrl = self.factory(self.name, design, _along_partial_plan(self.first.settings, modes, design), ref)
            if self.measurement != "state":    # the new filter starts from the old one's estimate
                ctrl.start_estimate(z, float(ref.torque[k]))
            self._pending = (ready, ctrl)
        wall = time.perf_counter() - clock
        self.log.append({**entry, "applied_s": None if dropped else ready * dt, "wall_s": wall,
                         "within_allowance": wall <= allowance, "dropped": dropped})


def _held_prefix(old: Reference, k: int, interval: float, allowance: float, tau_max: float) -> tuple:
    """The re-plan's first intervals (``interval`` [s] each) covering ``allowance`` [s] from sample ``k``:
    their edges [samples] and the old plan's mean feedforward over each, within ``tau_max`` [N m]
    (what the drive plays: a feedforward at full torque differs from it by round-off)."""
    dt = old.dt
    n_hold = int(math.ceil(allowance / interval - 1e-9)) if allowance > 0 else 0
    edges = k + np.round(np.arange(n_hold + 1) * interval / dt).astype(int)
    return edges, [float(np.clip(np.mean(old.torque[a:max(b, a + 1)]), -tau_max, tau_max))
                   for a, b in zip(edges[:-1], edges[1:])]


def _spliced(old: Reference, plan, k: int, mass: float) -> Reference:
    """``old`` up to sample ``k``, then the re-plan ``plan`` (hub, feedforward and planned modes)."""
    from .reference import optimal_reference
    dt = old.dt
    new = optimal_reference(plan, dt, (len(old.theta) - 1 - k) * dt)
    m = min(len(old.theta) - k, len(new.theta))
    arrays = [a.copy() for a in (old.theta, old.theta_dot, old.theta_ddot, old.torque)]
    for full, part in zip(arrays, (new.theta, new.theta_dot, new.theta_ddot, new.torque)):
        full[k:k + m] = part[:m]
    width = max(new.elastic.shape[1], 0 if old.elastic is None else old.elastic.shape[1]) // 2
    elastic = np.zeros((len(arrays[0]), 2 * width))
    if old.elastic is not None:
        elastic[:k] = _modes(old.elastic[:k], width)
    elastic[k:k + m] = _modes(new.elastic[:m], width)
    return Reference(dt, *arrays, f"re-planned at {k * dt:.3g} s for {mass:.4g} kg", elastic=elastic)


def _modes(elastic: np.ndarray, width: int) -> np.ndarray:
    """Planned ``[q2, q2_dot]`` columns (:attr:`Reference.elastic`) padded with zeros to ``width`` modes."""
    m = elastic.shape[1] // 2
    out = np.zeros((len(elastic), 2 * width))
    out[:, :m], out[:, width:width + m] = elastic[:, :m], elastic[:, m:]
    return out


def _along_partial_plan(settings, plan_modes: int, design: DesignModel):
    """An LQG's settings for a re-plan of ``plan_modes`` modes: no prediction along it if it has fewer
    modes than the design's and ``plan_prediction`` is left to the LQG (None).

    The re-plan's reference carries its few modes only and would tell the filter that the others
    stay at rest; the filter then misreads the beam (Table 1's beam at 0.5 kg: settled at 8.57 s
    predicting along the plan, 5.46 s not). State feedback has no filter: its settings are kept.
    """
    if getattr(settings, "plan_prediction", False) is not None or plan_modes >= design.n_modes:
        return settings
    return settings.replace(plan_prediction=False)


def shapeable_modes(design: DesignModel, intervals: int, duration: float) -> int:
    """Bending modes a torque held over ``intervals`` steps of ``duration`` can shape (at least 1).

    Those whose free-hub natural frequency is at most the torque grid's Nyquist frequency
    ``intervals / (2 duration)`` [Hz]: faster modes are left to the feedback.

    Parameters
    ----------
    design : DesignModel
        Its free-hub second-order matrices ``M2``, ``K2`` give the frequencies.
    intervals : int
        Torque steps of the plan.
    duration : float
        The plan's duration [s].

    Returns
    -------
    int
    """
    w2 = np.sort(np.abs(sla.eigvalsh(design.K2, design.M2)))[1:]      # the rigid mode first
    return max(1, int(np.count_nonzero(np.sqrt(w2) / (2 * math.pi) <= intervals / (2.0 * duration))))
