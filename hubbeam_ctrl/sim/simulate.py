"""Simulation of the nonlinear models, hub free (torque input) or prescribed.

The equations of motion are integrated in implicit form, ``M(q) a + c(q, v) = B tau``
with the accelerations ``a`` as algebraic unknowns, by SUNDIALS IDAS through CasADi
(variable-step BDF, order capped at 2 by default). Nothing is inverted symbolically and
the whole integration over an output chunk runs in compiled code. The order cap keeps
BDF A-stable: the stiff axial modes (up to ~1.4 kHz) are followed quasi-statically
instead of being resolved step by step, while the error control still resolves the
bending modes (see ``benchmarks/bench_plant.py`` for speed and accuracy).

Integration proceeds in chunks (``chunk_s``); after each chunk the tip deflection is
checked. A run that passes the models' validated range (``|v_tip| > range_limit * L``,
default 0.3 L) is flagged (``outside_validated_range``, with the time) and goes on; a run
that passes ``divergence_limit * L`` (default L, e.g. a TLAM above its critical speed) or
whose integrator fails stops with ``diverged = True`` and a message, returning what it
computed.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.budget import (
    SECONDS_PER_SAMPLE,
    T_END_MAX,
    WallClock,
    check_budget,
    model_build_seconds,
    simulation_bytes_per_sample,
)
from hubbeam_ctrl.core.compiled import OPT_COLD, OPT_HOT, compile_function, resolve_backend
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError, UserFunctionError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.maneuvers import ConstantSpin, SpinUp, TorquePulse, UserManeuver
from hubbeam_ctrl.plant.models import MODEL_SPECS, HubBeamModel, check_axial, jacobian_columns, resolve_model
from hubbeam_ctrl.plant.params import Params, check_spin
from hubbeam_ctrl.sim.results import Result, describe_input

__all__ = ["simulate", "Integrator", "SimulationSettings", "residual_function"]


@dataclass(frozen=True)
class SimulationSettings(Settings):
    """Settings of :func:`simulate` (IDAS, output grid, when to stop)."""

    dt: float = setting(0.01, unit="s", lo=1e-6, hi=10.0, doc="Output sample period.")
    rtol: float = setting(1e-8, lo=1e-12, hi=1e-2, doc="Relative tolerance of IDAS.")
    atol: float = setting(1e-8, unit="m, rad, m/s, rad/s", lo=1e-14, hi=1.0,
                          doc="Absolute tolerance of IDAS.")
    max_order: int = setting(2, lo=1, hi=5,
                             doc="Largest BDF order. 2 keeps the method A-stable for the stiff axial "
                                 "modes; 5 with tight tolerances resolves them (slow, for reference "
                                 "runs).")
    chunk_s: float = setting(10.0, unit="s", lo=1e-3, hi=1e4,
                             doc="Longest integration chunk between checks (divergence, wall time); "
                                 "shortened so that a chunk takes a fraction of a second of wall time.")
    range_limit: float = setting(0.3, lo=0.0, lo_open=True, hi=10.0,
                                 doc="The run is flagged (outside_validated_range) when "
                                     "abs(v_tip) > range_limit * L, and goes on.")
    divergence_limit: float = setting(1.0, lo=0.0, lo_open=True, hi=10.0,
                                      doc="The run stops when abs(v_tip) > divergence_limit * L.")
    max_wall_s: float = setting(600.0, unit="s", lo=1e-3, hi=1e7,
                                doc="The run stops (flagged) when it has taken longer than this; a "
                                    "run estimated to take longer is refused before it starts.")
    max_memory_mb: float = setting(2048.0, unit="MB", lo=1.0, hi=1e9,
                                   doc="A run whose results would need more memory than this is "
                                       "refused before it starts.")


class Integrator:
    """A model's equations of motion handed to IDAS over a fixed relative output grid.

    Built once, called many times: ``step(x0, z0, t0, u)`` integrates from absolute time
    ``t0`` over the grid and returns states and accelerations at the grid points.

    Parameters
    ----------
    model : HubBeamModel
    hub : {"free", "prescribed"}
    maneuver : callable or None
        Torque profile (free hub) or kinematic profile (prescribed hub) of absolute time;
        ``None`` for a free hub driven only by the held input ``u``.
    grid : array_like
        Output times relative to the start of a call [s], starting after 0.
    settings : SimulationSettings
    backend : {"auto", "compiled", "vm"}, optional
        How the implicit residual and its Jacobian are evaluated (see
        :func:`residual_function`); :attr:`backend` holds the one in use.
    """

    def __init__(self, model: HubBeamModel, hub: str, maneuver, grid, settings: SimulationSettings,
                 backend=None):
        self.model, self.hub, self.maneuver = model, hub, maneuver
        self.grid = np.asarray(grid, dtype=float)
        n = model.n_q
        self.n_x = 2 * n if hub == "free" else 2 * (n - 1)
        self.n_z = self.n_x // 2
        t = ca.MX.sym("t")
        p = ca.MX.sym("p", 2)                    # [t_offset, held torque]
        x = ca.MX.sym("x", self.n_x)
        z = ca.MX.sym("z", self.n_z)
        ta = t + p[0]
        residual, self.backend = residual_function(model, backend)
        p_model = ca.DM(model.p)
        inv = lambda q_, v_, a_: residual(q_, v_, a_, p_model)   # noqa: E731
        if hub == "free":
            tau = p[1] + (maneuver(ta) if maneuver is not None else 0)
            q, v = x[:n], x[n:]
            alg = inv(q, v, z) - ca.vertcat(tau, ca.MX.zeros(n - 1))
            ode = ca.vertcat(v, z)
        else:
            th, thd, thdd = maneuver(ta)
            ne = n - 1
            q = ca.vertcat(th, x[:ne])
            v = ca.vertcat(thd, x[ne:])
            alg = inv(q, v, ca.vertcat(thdd, z))[1:]
            ode = ca.vertcat(x[ne:], z)
        opts = dict(abstol=settings.atol, reltol=settings.rtol, max_order=settings.max_order,
                    max_num_steps=5000, suppress_algebraic=True, calc_ic=False,
                    show_eval_warnings=False)
        self._function = ca.integrator("plant", "idas", {"x": x, "z": z, "p": p, "t": t,
                                                         "ode": ode, "alg": alg},
                                       0.0, self.grid, opts)

    def step(self, x0, z0, t0: float, u: float = 0.0):
        """Integrate from absolute time ``t0`` with held torque ``u`` [N m].

        Parameters
        ----------
        x0 : ndarray
            Differential state ``[q, v]`` at ``t0`` (prescribed hub: without the hub).
        z0 : ndarray
            Algebraic state (accelerations) at ``t0`` [rad/s^2, m/s^2].
        t0 : float
            Absolute start time [s] (the maneuver is evaluated from there).
        u : float
            Held hub torque [N m] when the maneuver does not give one.

        Returns
        -------
        xs : ndarray (len(grid), n_x)
        zs : ndarray (len(grid), n_z)
        """
        out = self._function(x0=x0, z0=z0, p=[t0, u])
        return np.array(out["xf"]).T, np.array(out["zf"]).T

    @property
    def stats(self) -> dict:
        """Integrator statistics of the last call (steps, evaluations, times)."""
        return {k: v for k, v in self._function.stats().items() if not isinstance(v, dict)}


def residual_function(model: HubBeamModel, backend=None) -> tuple:
    """The model's inverse dynamics ``M(q) a + c(q, v)`` for IDAS, on a backend.

    IDAS evaluates the residual at every Newton iteration and its Jacobian whenever it
    refreshes its iteration matrix. On the compiled backend both are generated C in one
    library: the residual at -O1, the Jacobian (``jac_inverse_dynamics``, which CasADi
    uses when it differentiates the external function) at -O0.

    Parameters
    ----------
    model : HubBeamModel
    backend : {"auto", "compiled", "vm"}, optional

    Returns
    -------
    function : casadi.Function
        ``(q, v, a, p) -> f`` with ``p`` the model's parameter vector
        (:attr:`~hubbeam_ctrl.plant.models.HubBeamModel.p`): built and compiled once per
        model family and mode counts.
    backend : str
        ``"compiled"`` or ``"vm"``: the one in use.
    """
    pm = model.parametric
    jac = _residual_jacobian(pm)
    f = pm.__dict__.get("_residual_vm")
    if f is None:
        base = pm.inverse_dynamics
        args = [pm.sym.sym(name, base.size_in(i)) for i, name in enumerate(base.name_in())]
        f = ca.Function(base.name(), args, base.call(args), base.name_in(), base.name_out(),
                        {"custom_jacobian": jac, "jac_penalty": 0})
        pm.__dict__["_residual_vm"] = f
    if resolve_backend(backend) == "vm":
        return f, "vm"
    jac_opt = OPT_HOT if pm.sym is ca.MX else OPT_COLD    # MX: compact code, worth optimising
    g = compile_function(pm.inverse_dynamics, backend, opt=OPT_HOT, jacobian=jac_opt, jacobian_function=jac)
    return (f, "vm") if g is pm.inverse_dynamics else (g, "compiled")


def _residual_jacobian(pm) -> ca.Function:
    """``jac_inverse_dynamics``: the residual's Jacobian in ``q``, ``v``, ``a`` (none in ``p``).

    Both backends differentiate the residual through this one function: CasADi's AD would
    otherwise take directional derivatives of the VM function but the Jacobian of the
    compiled one, the same numbers up to rounding, which an error-controlled integrator
    turns into ~1e-7 differences. The parameters are constants inside IDAS, so their block
    is left structurally zero (it would be the largest and is never needed).
    """
    cached = pm.__dict__.get("_residual_jacobian")
    if cached is None:
        f = pm.inverse_dynamics
        q, v, a = (pm.sym.sym(k, pm.n_q) for k in ("q", "v", "a"))
        p = pm.sym.sym("p", pm.n_p)
        out = pm.sym.sym("out_f", pm.n_q)
        if pm.sym is ca.MX:      # column by column: an MX graph's jacobian copies it per direction
            # on the structural pattern CasADi finds for the VM function, so that both backends
            # hand IDAS the same sparse matrices
            blocks = [ca.project(jacobian_columns(f, [q, v, a, p], i), f.sparsity_jac(i, 0)) for i in range(3)]
        else:
            y = f(q, v, a, p)
            blocks = [ca.jacobian(y, q), ca.jacobian(y, v), ca.jacobian(y, a)]
        cached = ca.Function("jac_inverse_dynamics", [q, v, a, p, out], blocks + [pm.sym(pm.n_q, pm.n_p)],
                             ["q", "v", "a", "p", "out_f"], ["jac_f_q", "jac_f_v", "jac_f_a", "jac_f_p"],
                             {"cse": True})
        pm.__dict__["_residual_jacobian"] = cached
    return cached


def _cached_integrator(model, hub, maneuver, grid, settings, backend) -> Integrator:
    """Build an :class:`Integrator` once per model, hub, maneuver, grid and settings.

    Built-in maneuvers are frozen dataclasses and so can key the cache; user functions
    are built afresh every time.
    """
    cache = model.__dict__.setdefault("_integrator_cache", {})
    try:
        key = (hub, maneuver, len(grid), float(grid[0]), settings, backend)
        hash(key)
    except TypeError:
        return Integrator(model, hub, maneuver, grid, settings, backend)
    if key not in cache:
        if len(cache) > 16:
            cache.clear()
        cache[key] = Integrator(model, hub, maneuver, grid, settings, backend)
    return cache[key]


def _full_state(model, hub, maneuver, t, xs, zs):
    """Generalised coordinates, velocities and accelerations (N, n_q) from integrator output."""
    n = model.n_q
    if hub == "free":
        return xs[:, :n], xs[:, n:], zs
    values = maneuver.evaluate(t)[0] if isinstance(maneuver, UserManeuver) else maneuver(t)
    th, thd, thdd = (np.broadcast_to(np.asarray(a, dtype=float), t.shape) for a in values)
    if th.shape != t.shape:     # a user function that stopped early: NaN after its last good value
        th, thd, thdd = (np.concatenate([c, np.full(len(t) - len(c), np.nan)]) for c in (th, thd, thdd))
    ne = n - 1
    q = np.column_stack([th, xs[:, :ne]])
    v = np.column_stack([thd, xs[:, ne:]])
    a = np.column_stack([thdd, zs])
    return q, v, a


def simulate(model="foam", maneuver=None, t_end: float = 30.0, *, params: Params | None = None,
             hub: str | None = None, x0=None, settings: SimulationSettings | None = None,
             progress: bool = False, backend=None, axial: str | None = None,
             **setting_overrides) -> Result:
    """Simulate a hub-beam model.

    Parameters
    ----------
    model : str or HubBeamModel
        ``"cfoam"``, ``"foam"``, ``"tlam"``, ``"sfoam"`` or a built model.
    maneuver : SpinUp, TorquePulse, ConstantSpin, UserManeuver, callable or None
        Prescribed hub motion or hub torque. A plain callable is taken as a torque
        ``tau(t)`` [N m] (wrap it in :class:`UserManeuver` for a prescribed motion).
        ``None``: free hub, no torque (from ``x0``).
    t_end : float
        Final time [s], > 0.
    params : Params, optional
        Parameters when ``model`` is a name (default: Table 1).
    hub : {"free", "prescribed"}, optional
        Defaults to the maneuver's kind (prescribed for spin-ups, free for torques).
    x0 : array_like, optional
        Initial state ``[q, v]`` of the full model (free hub) or of the elastic part
        ``[q_e, v_e]`` (prescribed hub). Default: at rest, undeformed (free hub) or the
        elastic part at rest (prescribed hub).
    settings : SimulationSettings, optional
    progress : bool
        Show a progress bar on stderr (only when stderr is a terminal).
    backend : {"auto", "compiled", "vm"}, optional
        Evaluation of the residual and its Jacobian inside IDAS: CasADi's VM or generated
        C (see :mod:`hubbeam_ctrl.core.compiled`); default ``$HUBBEAM_BACKEND`` or
        ``"auto"``. Both give the same run to the integrator's tolerances.
    axial : {"dynamic", "quasi-static"}, optional
        With a model name: integrate the axial coordinates (default) or solve them from
        their static balance at every instant (no stiff axial modes in the state; ``q`` and
        ``v`` then hold the hub and bending coordinates only, and
        :meth:`~hubbeam_ctrl.plant.models.HubBeamModel.axial_coordinates` gives ``q1``).
    **setting_overrides
        Fields of :class:`SimulationSettings` (``dt``, ``rtol``, ...).

    Returns
    -------
    Result
        Of kind ``"open_loop"``: time series (``t``, ``q``, ``v``, ``a``, ``theta``,
        ``theta_dot``, ``v_tip``, ``u_tip``, ``tau``, ``q_theta``, ``energy``,
        ``angular_momentum``) with the parameters and settings that made them;
        ``diverged`` (same as ``stopped``) and ``message`` say how the run ended.

    Examples
    --------
    >>> from hubbeam_ctrl import Params, SpinUp, simulate
    >>> res = simulate("foam", SpinUp(w_f=2.8, t_f=30.0), t_end=5.0, params=Params(m_t=0.0))
    >>> res.diverged
    False
    """
    settings = _settings(settings, setting_overrides)
    dt = settings.dt
    t_end = check_in_range("t_end", t_end, "s", dt, T_END_MAX, "at least two samples: t_end >= dt")
    name, p, n = _model_plan(model, params, axial)
    maneuver, hub = _maneuver_and_hub(maneuver, hub)
    _check_maneuver_spin(maneuver, p)
    n_out = int(round(t_end / dt))
    cost = SECONDS_PER_SAMPLE[name] * (n / 11.0) ** 2
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({n_out + 1} samples of {name.upper()})",
                 memory_bytes=(n_out + 1) * simulation_bytes_per_sample(n),
                 seconds=n_out * cost + model_build_seconds(name, p.n_transverse),
                 max_memory_mb=settings.max_memory_mb, max_wall_s=settings.max_wall_s)
    x0 = _initial_state(x0, 2 * n if hub == "free" else 2 * (n - 1), hub)
    m = resolve_model(model, params, axial)
    if isinstance(maneuver, UserManeuver):
        maneuver.bind(t_end)

    # chunks of about 0.3 s of wall time (4 x the low estimate), so max_wall_s is checked often
    per_chunk = int(max(1, min(round(settings.chunk_s / dt), 0.3 / (4 * cost))))
    grid = dt * np.arange(1, per_chunk + 1)
    backend = resolve_backend(backend)
    integ = _cached_integrator(m, hub, maneuver, grid, settings, backend)
    z0 = _initial_accelerations(m, hub, maneuver, x0)
    n_out, user_stop = _user_function_limit(maneuver, n_out, dt)

    times, xs_all, zs_all = [np.array([0.0])], [x0[None, :]], []
    diverged, message = False, "completed"
    limit = settings.divergence_limit * m.params.L
    flag_at, outside_time = settings.range_limit * m.params.L, None
    start = time.perf_counter()
    clock = WallClock(settings.max_wall_s)
    done = 0
    bar = progress_bar(n_out, f"simulate {m.name}", enabled=progress)
    x, z = x0, z0
    failure = None
    while done < n_out:
        k = min(per_chunk, n_out - done)
        t0 = done * dt
        try:
            xs, zs = integ.step(x, z, t0)
        except RuntimeError as exc:
            if per_chunk > 10:   # retry the chunk in shorter pieces to get closer to the failure
                per_chunk = max(10, per_chunk // 10)
                integ = Integrator(m, hub, maneuver, dt * np.arange(1, per_chunk + 1), settings, backend)
                continue
            diverged = True
            message = _named_failure(maneuver, t0, t0 + per_chunk * dt, dt) or (
                f"{m.name.upper()}: integrator failed between t = {t0:.3f} s and "
                f"{t0 + per_chunk * dt:.3f} s ({str(exc).splitlines()[0][:100]})")
            message += f"; results end at t = {t0:.3f} s"
            break
        xs, zs = xs[:k], zs[:k]
        if not np.all(np.isfinite(xs)):
            bad = int(np.argmax(~np.all(np.isfinite(xs), axis=1)))
            xs, zs = xs[:bad], zs[:bad]
            diverged = True
            failure = _named_failure(maneuver, t0, t0 + k * dt, dt) or (
                f"{m.name.upper()}: the integrator returned a non-finite state at t = {t0 + (bad + 1) * dt:.3f} s")
        tk = t0 + dt * np.arange(1, len(xs) + 1)
        q_full = xs[:, :n] if hub == "free" else xs[:, : n - 1]
        qt = q_full if hub == "free" else np.column_stack([np.zeros(len(xs)), q_full])
        v_tip = qt[:, m.transverse_slice] @ m.basis.f2_tip
        flagged = np.nonzero(np.abs(v_tip) > flag_at)[0]
        if outside_time is None and flagged.size:
            outside_time = float(tk[flagged[0]])
        over = np.nonzero(np.abs(v_tip) > limit)[0]
        if over.size:
            cut = over[0] + 1
            xs, zs, tk = xs[:cut], zs[:cut], tk[:cut]
            diverged = True
        times.append(tk)
        xs_all.append(xs)
        zs_all.append(zs)
        done += len(xs)
        bar.update(len(xs))
        if diverged and failure:
            message = f"{failure}; results end at t = {tk[-1] if len(tk) else t0:.3f} s"
            break
        if diverged:
            message = (f"{m.name.upper()} left its range at t = {tk[-1] if len(tk) else t0:.3f} s: "
                       f"|v_tip| > {settings.divergence_limit:g} L = {limit:.3g} m"
                       + (" (e.g. above its critical speed)" if m.name == "tlam" else ""))
            break
        if done < n_out and clock.expired():
            diverged, message = True, clock.message(tk[-1])
            break
        x, z = xs[-1], zs[-1]
    bar.close()
    wall = time.perf_counter() - start

    t = np.concatenate(times)
    xs = np.vstack(xs_all)
    zs = np.vstack(zs_all) if zs_all else np.zeros((0, len(x0) // 2))
    zs = np.vstack([z0[None, :], zs])
    q, v, a = _full_state(m, hub, maneuver, t, xs, zs)
    if user_stop and not diverged:
        diverged, message = True, f"{user_stop}; results end at t = {t[-1]:.3f} s"
    keep, why = _finite_prefix(maneuver, t, q, v, a)
    if keep < len(t):
        t, q, v, a = t[:keep], q[:keep], v[:keep], a[:keep]
        diverged, message = True, f"{why}; results end at t = {t[-1]:.3f} s"
    if outside_time is not None and not diverged:
        message = (f"completed; |v_tip| passed {settings.range_limit:g} L = {flag_at:.3g} m (outside "
                   f"the models' validated range) at t = {outside_time:.3f} s")
    return _open_loop_result(m, t, q, v, a, hub=hub, maneuver=maneuver, settings=settings,
                             stopped=diverged, message=message, wall_s=wall,
                             outside_range_time_s=outside_time, backend=integ.backend)


def _open_loop_result(model: HubBeamModel, t, q, v, a, *, hub, maneuver, settings, stopped,
                      message, wall_s, outside_range_time_s=None, backend=None) -> Result:
    """A :class:`Result` of kind ``"open_loop"``, the model's outputs evaluated on all samples."""
    N = len(t)
    Q, V, A = q.T, v.T, a.T
    v_tip, u_tip = model.tip_series(q, v)
    tau = np.array(model.inverse_dynamics_function.map(N)(Q, V, A))[0]
    q_theta = np.array(model.q_theta_function.map(N)(Q, V)).ravel()
    energy = np.array(model.energy_function.map(N)(Q, V)[2]).ravel()
    momentum = np.array(model.momentum_function.map(N)(Q, V)).ravel()
    return Result(kind="open_loop", model=model.name, hub=hub, t=t, q=q, v=v, a=a,
                  v_tip=v_tip, u_tip=u_tip, tau=tau, q_theta=q_theta, energy=energy,
                  angular_momentum=momentum, params=model.params,
                  settings={"maneuver": describe_input(maneuver), **dataclasses.asdict(settings),
                            "backend": backend},
                  stats={"outside_range_time_s": outside_range_time_s},
                  stopped=stopped, message=message, wall_s=wall_s)


def _settings(settings, overrides: dict) -> SimulationSettings:
    """The run's settings: ``settings`` (default) with ``overrides`` applied, validated."""
    settings = SimulationSettings() if settings is None else settings
    if not isinstance(settings, SimulationSettings):
        raise ParameterError(f"settings must be a SimulationSettings, got {type(settings).__name__}")
    if overrides:
        unknown = sorted(set(overrides) - set(SimulationSettings.__dataclass_fields__))
        if unknown:
            raise ParameterError(f"unknown simulation setting(s) {', '.join(unknown)[:200]}; allowed: "
                                 f"{', '.join(SimulationSettings.__dataclass_fields__)}")
        settings = dataclasses.replace(settings, **overrides)
    return settings


def _model_plan(model, params, axial=None) -> tuple:
    """``(name, params, n_q)`` of the model to simulate, without building it (checks come first)."""
    if isinstance(model, HubBeamModel):
        resolve_model(model, params, axial)    # the one-line errors for a mismatch
        return model.name, model.params, model.n_q
    if isinstance(model, str) and model.lower() in MODEL_SPECS:
        p = params if params is not None else Params()
        if not isinstance(p, Params):
            raise ParameterError(f"params must be a Params, got {type(p).__name__}")
        spec = MODEL_SPECS[model.lower()]
        n_axial = p.n_axial if spec.axial else 0
        if check_axial(axial or "dynamic", model.lower(), n_axial) == "quasi-static":
            n_axial = 0
        return model.lower(), p, 1 + n_axial + p.n_transverse
    m = resolve_model(model, params, axial)   # raises the one-line error for a bad model
    return m.name, m.params, m.n_q


def _maneuver_and_hub(maneuver, hub) -> tuple:
    """The maneuver (a plain callable becomes a torque :class:`UserManeuver`) and the hub."""
    if maneuver is not None and not hasattr(maneuver, "kind"):
        if not callable(maneuver):
            raise ParameterError(f"maneuver must be a maneuver or a function of time, got "
                                 f"{type(maneuver).__name__}")
        maneuver = UserManeuver(maneuver, "torque")
    kind = maneuver.kind if maneuver is not None else "torque"
    hub = hub or ("prescribed" if kind == "prescribed" else "free")
    if hub not in ("free", "prescribed"):
        raise ParameterError(f"hub must be 'free' or 'prescribed', got {hub!r}"[:200])
    if (hub == "prescribed") != (kind == "prescribed"):
        raise ParameterError(f"hub={hub!r} does not fit a maneuver of kind {kind!r}")
    return maneuver, hub


def _check_maneuver_spin(maneuver, params: Params) -> None:
    """Refuse a built-in maneuver that spins the hub beyond ``params.max_spin``."""
    if isinstance(maneuver, SpinUp):
        check_spin("w_f", maneuver.w_f, params)
    elif isinstance(maneuver, ConstantSpin):
        check_spin("spin", maneuver.spin, params)
    elif isinstance(maneuver, TorquePulse):
        peak = maneuver.tau_m * maneuver.t_f / (math.pi * params.total_inertia)
        if peak > params.max_spin:
            raise ParameterError(
                f"tau_m = {maneuver.tau_m:g} N m over t_f = {maneuver.t_f:g} s spins the hub up to "
                f"{peak:.4g} rad/s (tau_m t_f / (pi J_total)), above Params.max_spin = "
                f"{params.max_spin:.4g} rad/s (1 % centrifugal strain at the root)")


def _initial_state(x0, n_x: int, hub: str) -> np.ndarray:
    """``x0`` as a float array of ``n_x`` finite numbers (zeros when ``None``)."""
    if x0 is None:
        return np.zeros(n_x)
    try:
        x = np.asarray(x0, dtype=float).ravel()
    except (TypeError, ValueError, OverflowError):
        x = None
    if x is None or x.shape != (n_x,) or not np.all(np.isfinite(x)):
        raise ParameterError(f"x0 must hold {n_x} finite numbers for hub={hub!r}, got "
                             f"{'shape ' + str(x.shape) if x is not None else type(x0).__name__}")
    return x


def _user_function_limit(maneuver, n_out: int, dt: float) -> tuple:
    """Samples to compute, and why fewer than asked: a tabulated user function that fails
    (raises, or returns a non-finite value) before the end stops the run where it did."""
    stop = getattr(maneuver, "valid_until", None) if isinstance(maneuver, UserManeuver) else None
    if stop is None or stop >= n_out * dt:
        return n_out, None
    k = int(math.floor(stop / dt + 1e-9))
    if k < 1:
        raise UserFunctionError(maneuver.failure)
    return k, maneuver.failure


def _named_failure(maneuver, t0: float, t1: float, dt: float) -> str | None:
    """The message naming a user function that fails between ``t0`` and ``t1`` [s], if one does."""
    if not isinstance(maneuver, UserManeuver):
        return None
    _, error = maneuver.evaluate(np.arange(t0, t1 + 0.5 * dt, dt))
    return None if error is None else str(error)


def _finite_prefix(maneuver, t, q, v, a) -> tuple:
    """Number of leading samples whose ``q``, ``v``, ``a`` are all finite, and why it ends there.

    A result never holds NaN or infinity: the run is cut before the first such sample and the
    message names the cause (the user function when it returned the bad value).
    """
    finite = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(v), axis=1) & np.all(np.isfinite(a), axis=1)
    if finite.all():
        return len(t), None
    keep = int(np.argmin(finite))
    why = _named_failure(maneuver, t[keep], t[keep], 1.0) or f"non-finite state at t = {t[keep]:.3f} s"
    if keep == 0:
        raise HubbeamError(why)
    return keep, why


def _initial_accelerations(m: HubBeamModel, hub, maneuver, x0):
    n = m.n_q
    if hub == "free":
        tau = float(maneuver(0.0)) if maneuver is not None else 0.0
        return m.accelerations(x0[:n], x0[n:], tau)
    th, thd, thdd = (float(np.asarray(a)) for a in maneuver(np.array(0.0)))
    ne = n - 1
    q = np.concatenate([[th], x0[:ne]])
    v = np.concatenate([[thd], x0[ne:]])
    M = m.mass_matrix(q, v)
    rhs = -m.bias(q, v)[1:] - M[1:, 0] * thdd
    return np.linalg.solve(M[1:, 1:], rhs)

