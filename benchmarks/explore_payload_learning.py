"""Exploration, not a feature: does learning the payload during the slew meet issue 22's range target?

Run: ``.venv/bin/python benchmarks/explore_payload_learning.py [--switch-at 0.25,0.5]
[--stiffened-weight 100] [--torque-share 1.0] [--continuous] [--known-payload KG]
[--replan linear|nonlinear] [--controller lqr|mpc] [--intervals 40] [--latency S] [--open-prefix]
[--masses 0,0.1,0.3,0.5] [--out F.json]`` (10-30 s). Prints JSON.

The task: Table 1's beam, 1 rad in 1.5 x the time-optimal slew of its heaviest payload (0.5 kg,
4.614 s), where designs that know their payload meet every target (``bench_limit_targets.py
--cases matched_range``) and the range designs leave 0.2-3.4 % of L. Here the default LQR
(designed for the nominal 0.1 kg, on the slew planned for it) runs on the FOAM plant with the
true payload, wrapped so that at each ``--switch-at`` fraction of ``t_f`` it

1. identifies the payload: the design models of payloads 0-0.5 kg (0.02 kg grid, parabolic
   refinement) driven from rest by the torques applied so far; the one whose hub rate fits the
   measured rate best in least squares;
2. re-plans the rest of the slew from the measured state on that payload's model: the smoothest
   torque within ``--torque-share`` x ``tau_max`` that ends at the angle at rest with every
   resolved mode of the model at rest (hard rows) and of the model linearised at the plan's
   peak rate nearly at rest (``--stiffened-weight``: their rows in the objective; as hard rows
   they conflict with the rest model's from a moving state); ``--continuous``: starting at the
   old plan's torque;
3. continues with the LQR designed on that payload along the old plan up to now and the new
   plan after.

``--replan nonlinear`` re-plans instead on the nonlinear FOAM model of the identified payload:
:func:`hubbeam_ctrl.limit.min_vibration_replan` (IPOPT, 0.4-4.7 s) from the measured state (its
first modes) to rest at the angle in the remaining time, as reference
and feedforward (:func:`controllers.optimal_reference`). By default the run applies it at the
switch sample itself, as if the optimisation took no time; ``--latency S`` holds the plan's
first S seconds at the old plan's feedforward and switches after them (``--open-prefix``: that
prefix runs without feedback, so the plant ends it where the plan predicted); the IPOPT wall
time of each solve is in the JSON to compare with S. ``--controller mpc`` wraps the MPC
instead (state feedback too; the LQG would need its filter's estimate and a warm start, not
tried). ``--known-payload`` replaces step 1's estimate (an oracle: what re-planning alone can
do). It monkeypatches ``compare``'s controller factory, so the verdicts are compare's own. The
toolbox's version of the nonlinear route is :mod:`controllers.payload_learning`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, comma_floats, emit  # noqa: E402

import controllers.planning as planning  # noqa: E402
import hubbeam_ctrl.study.compare as compare_module  # noqa: E402
from controllers import DesignModel, Reference  # noqa: E402
from controllers.mpc import DirectDAQP  # noqa: E402
from controllers.payload_learning import identify_payload  # noqa: E402
from controllers.scaling import first_mode  # noqa: E402
from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice  # noqa: E402
from hubbeam_ctrl.study.scenarios import make_scenario  # noqa: E402
from hubbeam_ctrl.study.tasks import Slew  # noqa: E402

NOMINAL = Params()
RANGE = (0.0, 0.5)
GRID = np.linspace(*RANGE, 26)
T_OPT_HEAVIEST = 3.0763           # s, hubbeam optimal on the 0.5 kg beam (docs/limit.md)


def _model(mass: float, dt: float, n_modes: int, spin: float = 0.0, _cache={}) -> DesignModel:
    key = (round(mass, 9), dt, n_modes, round(spin, 9))
    if key not in _cache:
        _cache[key] = DesignModel.build(NOMINAL.replace(m_t=mass), spin, dt, n_modes)
    return _cache[key]


def _run(model: DesignModel, torque, x0=None) -> np.ndarray:
    x = np.zeros(model.n_x) if x0 is None else np.array(x0, float)
    out = [x]
    for u in torque:
        x = model.Ad @ x + model.Bd[:, 0] * u
        out.append(x)
    return np.array(out)


def _scaled_modal_rows(model: DesignModel, n: int, x0, P, tau_max: float):
    """Rows ``E v = e``: the resolved modes of ``model`` at rest after ``n`` samples from ``x0``."""
    W = planning._modal_rows(model, planning.RESOLVED_FRACTION / model.dt)
    E = W @ planning.terminal_map(model, n) * tau_max @ P
    e = -(W @ np.linalg.matrix_power(model.Ad, n) @ x0)
    scale = np.linalg.norm(E, axis=1) + 1e-300
    return E / scale[:, None], e / scale


def replan(model, stiffened, x0, angle, n, tau_max, options, torque_now=None):
    """The rest of the slew from ``x0``: torques [N m] (n,), or None if the QP fails."""
    half = model.n_x // 2
    m = min(n, planning.MAX_UNKNOWNS)
    P = planning._knots(n, m)
    D = planning._second_differences(P)
    free = np.linalg.matrix_power(model.Ad, n) @ x0
    G = planning.terminal_map(model, n) * tau_max
    weight = np.array([1.0, n * model.dt])
    rows = [weight[:, None] * (G[[0, half]] @ P)]
    rhs = [weight * np.array([angle - free[0], -free[half]])]
    E, e = _scaled_modal_rows(model, n, x0, P, tau_max)
    rows.append(E)
    rhs.append(e)
    if torque_now is not None:
        rows.append(P[:1])
        rhs.append(np.array([torque_now / tau_max]))
    H = D.T @ D
    H = H / np.abs(H).max()
    f = np.zeros(m)
    if stiffened is not None and options.stiffened_weight > 0:
        Es, es = _scaled_modal_rows(stiffened, n, x0, P, tau_max)
        H = H + options.stiffened_weight * Es.T @ Es
        f = -options.stiffened_weight * Es.T @ es
    b = options.torque_share
    qp = DirectDAQP(H + 1e-12 * np.eye(m), np.vstack(rows), np.full(m, -b), np.full(m, b))
    r = np.concatenate(rhs)
    try:
        return tau_max * (P @ qp.solve(f, lba=r, uba=r))
    except RuntimeError:
        return None


def nonlinear_replan(mass: float, y, duration: float, dt: float, intervals: int = 40, prefix=None):
    """The minimum-vibration rest of the slew on the nonlinear model with payload ``mass`` from the
    measured state ``y`` (SFOAM order, its first ``n_transverse`` modes) to rest at 1 rad in
    ``duration`` (:func:`hubbeam_ctrl.limit.min_vibration_replan`); ``prefix``: torques [N m] per
    interval held fixed at the start (what runs while it computes). Returns (slew, IPOPT wall s)."""
    from hubbeam_ctrl.limit import OptimalSettings, min_vibration_replan, replan_coordinates
    params = NOMINAL.replace(m_t=mass)
    n = replan_coordinates(params)
    h = len(y) // 2
    x0 = np.concatenate([y[:n], y[h:h + n]])
    opt = min_vibration_replan(params, x0, 1.0, duration, hold=prefix if prefix else None,
                               settings=OptimalSettings(intervals=intervals, check=False))
    return opt, opt.solve_s


class PayloadLearning:
    """Wraps a state-feedback controller: identify, re-plan and re-design at the switch samples."""

    def __init__(self, inner, name, settings, scenario, options, factory):
        self._first, self._name, self._settings, self._options, self._factory = inner, name, settings, options, factory
        self._switch_at = [int(round(f * scenario.t_f / inner.dt)) for f in options.switch_at]
        self._k_f = int(round(scenario.t_f / inner.dt))
        self._tau_max = scenario.tau_max
        self.log = []
        self.reset()

    def __getattr__(self, attr):              # margins, certificates: the controller of the moment
        return getattr(self.__dict__["inner"], attr)

    def reset(self):
        self.inner = self._first
        self.inner.reset()
        self._torque, self._rate, self._stage, self._pending = [], [], 0, None

    def __call__(self, t, y):
        y = np.asarray(y, float)
        k = int(round(t / self.inner.dt))
        self._rate.append(y[len(y) // 2])
        if self._stage < len(self._switch_at) and k == self._switch_at[self._stage]:
            self._stage += 1
            self._switch(k, y)
        if self._pending is not None and k >= self._pending[0]:
            self.inner, self._pending = self._pending[1], None
        if self._pending is not None and self._options.open_prefix:
            self.inner(t, y)                                   # keeps its clock; the plan's prefix runs
            tau = float(self._pending[1].reference.torque[k])
        else:
            tau = float(self.inner(t, y))
        self._torque.append(tau)
        return tau

    def _switch(self, k, y):
        dt, n_modes, old = self.inner.dt, self.inner.n_modes, self.inner.reference
        o = self._options
        mass = o.known_payload if o.known_payload is not None else identify_payload(
            NOMINAL, dt, n_modes, np.array(self._torque[:k]), np.array(self._rate[:k + 1]), GRID)
        model = _model(mass, dt, n_modes)
        if o.replan == "nonlinear":
            self.log.append({})
            self._switch_nonlinear(k, y, mass, model)
            return
        half, h_y = model.n_x // 2, len(y) // 2
        x0 = np.concatenate([y[:half], y[h_y:h_y + half]])      # the plant's first modes, measured
        spin = float(np.max(np.abs(old.theta_dot)))
        n = self._k_f - k
        torque = replan(model, _model(mass, dt, n_modes, spin), x0, float(old.theta[-1]), n, self._tau_max, o,
                        float(old.torque[k]) if o.continuous else None)
        self.log.append({"t_s": k * dt, "payload_kg": mass, "replanned": torque is not None})
        if torque is None:
            return
        X = _run(model, torque, x0)
        K = len(old.theta)
        end = min(K, k + n + 1)
        theta, rate, ff = old.theta.copy(), old.theta_dot.copy(), old.torque.copy()
        elastic = old.elastic.copy()
        theta[k:end], rate[k:end] = X[:end - k, 0], X[:end - k, half]
        elastic[k:end] = X[:end - k][:, np.r_[1:half, half + 1:model.n_x]]
        theta[end:], rate[end:], elastic[end:] = X[-1, 0], 0.0, 0.0
        ff[k:k + n], ff[k + n:] = torque[:max(0, min(n, K - k))], 0.0
        accel = np.zeros(K)
        accel[:-1] = np.diff(rate) / dt
        ref = Reference(dt, theta, rate, accel, ff, "re-planned on the identified payload", elastic=elastic,
                        planned_on_design=True)
        self.inner = self._factory(self._name, model, self._settings, ref)

    def _switch_nonlinear(self, k, y, mass, model):
        from controllers import optimal_reference
        old, dt = self.inner.reference, self.inner.dt
        o = self._options
        duration = (self._k_f - k) * dt
        h = duration / o.intervals                       # the optimisation's interval [s]
        n_fixed = int(math.ceil(o.latency / h - 1e-9))   # intervals that run while it computes
        edges = np.round(np.arange(n_fixed + 1) * h / dt).astype(int) + k
        prefix = [float(np.mean(old.torque[a:max(b, a + 1)])) for a, b in zip(edges[:-1], edges[1:])]
        opt, wall = nonlinear_replan(mass, y, duration, dt, o.intervals, prefix)
        self.log[-1] = {"t_s": k * dt, "payload_kg": mass, "replanned": True, "ipopt_s": wall,
                        "converged": opt.converged, "residual_design_m": opt.residual_design}
        new = optimal_reference(opt, dt, (len(old.theta) - 1 - k) * dt)
        m = min(len(old.theta) - k, len(new.theta))
        theta, rate, accel, ff = (a.copy() for a in (old.theta, old.theta_dot, old.theta_ddot, old.torque))
        for full, part in ((theta, new.theta), (rate, new.theta_dot), (accel, new.theta_ddot), (ff, new.torque)):
            full[k:k + m] = part[:m]
        elastic = np.zeros((len(theta), new.elastic.shape[1]))
        if old.elastic is not None and old.elastic.shape[1] == new.elastic.shape[1]:
            elastic[:k] = old.elastic[:k]
        elastic[k:k + m] = new.elastic[:m]
        ref = Reference(dt, theta, rate, accel, ff, "re-planned on the identified payload's nonlinear model",
                        elastic=elastic)
        if n_fixed:        # the old controller runs on until the plan is ready (the plan's prefix)
            ready = int(edges[-1])
            self._pending = (ready, self._factory(self._name, model, self._settings, ref))
            self.log[-1]["applied_at_s"] = ready * dt
            return
        self.inner = self._factory(self._name, model, self._settings, ref)


def _fractions(text: str) -> list:
    """``--switch-at``: increasing fractions of the slew in [0, 1)."""
    return comma_floats(text, lambda vs: all(0.0 <= v < 1.0 for v in vs) and all(b > a for a, b in zip(vs, vs[1:])),
                        "increasing fractions of t_f in [0, 1)")


def _masses(text: str) -> str:
    """``--masses``: comma-separated payloads [kg] in the range (the text, checked)."""
    comma_floats(text, lambda vs: all(RANGE[0] <= v <= RANGE[1] for v in vs),
                 f"comma-separated payloads in [{RANGE[0]:g}, {RANGE[1]:g}] kg")
    return text


def _bounded(lo: float, hi: float, lo_open: bool = False):
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        if not ((v > lo if lo_open else v >= lo) and v <= hi):
            left = "(" if lo_open else "["
            raise argparse.ArgumentTypeError(f"must be a number in {left}{lo:g}, {hi:g}], got {text!r}")
        return v
    return parse


def main(argv=None) -> int:
    ap = bench_parser(__doc__)
    ap.add_argument("--switch-at", type=_fractions, default="0.25,0.5",
                    help="fractions of t_f (default %(default)s)")
    ap.add_argument("--stiffened-weight", type=_bounded(0.0, 1e12), default=100.0)
    ap.add_argument("--torque-share", type=_bounded(0.0, 1.0, lo_open=True), default=1.0,
                    help="re-plan within this share of tau_max")
    ap.add_argument("--continuous", action="store_true", help="the re-plan starts at the old plan's torque")
    ap.add_argument("--known-payload", type=_bounded(*RANGE), default=None, help="skip identification (oracle) [kg]")
    ap.add_argument("--masses", type=_masses, default="0,0.1,0.3,0.5")
    ap.add_argument("--replan", choices=("linear", "nonlinear"), default="linear",
                    help="re-plan on the identified payload's design model (linear) or its nonlinear "
                         "model (IPOPT)")
    ap.add_argument("--controller", choices=("lqr", "mpc"), default="lqr")
    ap.add_argument("--intervals", type=lambda t: int(_bounded(4, 2000)(t)), default=40,
                    help="collocation intervals of the nonlinear re-plan")
    ap.add_argument("--open-prefix", action="store_true",
                    help="while the re-plan computes, apply its prefix torque without feedback (the plan "
                         "then starts where it predicted)")
    ap.add_argument("--latency", type=_bounded(0.0, 60.0), default=0.0,
                    help="seconds the nonlinear re-plan takes: the old controller runs on meanwhile, the plan "
                         "holds its feedforward over those intervals and starts after them")
    o = ap.parse_args(argv)
    tf = 1.5 * T_OPT_HEAVIEST
    scenario = make_scenario(Slew(1.0, tf), params=NOMINAL)
    factory = compare_module.make_controller
    wrappers = []

    def learning(name, design, settings, reference, **kw):
        ctrl = factory(name, design, settings, reference, **kw)
        if name == o.controller:
            ctrl = PayloadLearning(ctrl, name, settings, scenario, o, factory)
            wrappers.append(ctrl)
        return ctrl

    compare_module.make_controller = learning
    out = {"options": {k: v for k, v in vars(o).items() if k != "out"}, "t_f_s": tf, "runs": {}}
    for mass in (float(m) for m in o.masses.split(",")):
        t0 = time.perf_counter()
        wrappers.clear()
        c = compare_module.compare(NOMINAL, Slew(1.0, tf), o.controller,
                                   CompareSettings(plant=PlantChoice(plant_params=NOMINAL.replace(m_t=mass))))
        m = c.metrics[o.controller]
        period = 2 * math.pi / first_mode(DesignModel.build(NOMINAL.replace(m_t=mass), 0.0, c.scenario.dt, 1))
        settle = m.get("settling_time_s")
        out["runs"][f"{mass:g}"] = {
            "verdict": m["verdict"], "settling_time_s": settle, "settle_target_s": tf + period,
            "residual_pct_of_L": m["residual_pct_of_L"], "final_angle_error_rad": m["final_angle_error_rad"],
            "peak_torque_nm": m["peak_torque_nm"],
            "met": bool(m["verdict"] == "settled" and settle is not None and settle <= tf + period
                        and m["residual_pct_of_L"] <= 0.1 and abs(m["final_angle_error_rad"]) <= 1e-3
                        and m["peak_torque_nm"] <= NOMINAL.tau_max * (1 + 1e-9)),
            "switches": wrappers[-1].log if wrappers else [], "wall_s": time.perf_counter() - t0}
        print(f"{mass:g} kg: {m['verdict']} {settle}/{tf + period:.3g} s {m['residual_pct_of_L']:.3g} %L "
              f"{out['runs'][f'{mass:g}']['switches']}", file=sys.stderr)
    emit(out, o.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
