"""The compiled step of the fixed-step plant integrator: its settings and its CasADi functions.

:class:`StepperSettings` and the functions one sample of the generalized-alpha scheme is made
of (:func:`step_functions`: the fast modified-Newton step, the iteration matrix, the robust
rootfinder step and the hold of a stuck hub), each built once per model family, size and
settings. The integrator that drives them sample by sample is
:class:`~hubbeam_ctrl.sim.stepper.PlantStepper` (:mod:`hubbeam_ctrl.sim.stepper`, which explains
the method and re-exports these names).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca

from hubbeam_ctrl.core.compiled import OPT_COLD, OPT_HOT
from hubbeam_ctrl.core.recipes import compile_recipe
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.models import HubBeamModel, ParametricModel, jacobian_columns
from hubbeam_ctrl.sim.hardware import (
    HW_LAYOUT,
    drive_torque,
    friction_torque,
    hub_torque,
    inductive_current,
    motor_torque,
)
from hubbeam_ctrl.sim.step_rule import MAX_SUBSTEPS, generalized_alpha_coefficients

__all__ = ["StepperSettings", "step_functions", "model_recipe"]

@dataclass(frozen=True)
class StepperSettings(Settings):
    """Settings of the fixed-step plant integrator :class:`PlantStepper`."""

    dt: float = setting(0.01, unit="s", lo=1e-6, hi=10.0,
                        doc="Sample period: one call of the stepper advances the plant by dt.")
    substeps: int = setting(2, lo=1, hi=MAX_SUBSTEPS,
                            doc="Integration steps per sample; the step is dt / substeps. Two steps of "
                                "5 ms reproduce a tight IDAS run of the Eq. 44 slew on the 5-mode plant to "
                                "~0.04 % of the peak deflection; substep_rule gives the count that "
                                "resolves every bending mode.")
    rho_inf: float = setting(0.9, lo=0.0, hi=1.0,
                             doc="Spectral radius at infinity of the generalized-alpha method.")
    newton_iterations: int = setting(3, lo=1, hi=20, doc="Newton iterations per step in the fast path.")
    newton_tol: float = setting(1e-6, unit="m/s^2, rad/s^2", lo=1e-14, hi=1.0,
                                doc="Largest accepted last Newton correction of the accelerations; a "
                                    "step above it is recomputed by the exact rootfinder.")


def _substep_expressions(model: ParametricModel, settings: StepperSettings, hardware: bool | str = False):
    """Symbolic generalized-alpha update: residual and new state as functions of ``a``.

    With ``hardware``, three more items: ``hw`` (:data:`~hubbeam_ctrl.sim.hardware.HW_LAYOUT`),
    the residual without the hardware's torque and ``d_hub``, the derivative of the hardware's
    part of the hub row in ``a_0``. The hub row of the residual is ``f_0 - (drive -
    friction)(tau, thd_1)`` when sliding, ``J (a_0 - a_stick)`` when held (``a_stick`` brings
    the hub rate to zero at the end of the substep; ``J = J_h + J`` of the parameters scales
    the row like the mass matrix).
    """
    n = model.n_q
    h = settings.dt / settings.substeps
    am, af, gamma, beta = generalized_alpha_coefficients(settings.rho_inf)
    sym = model.sym                      # MX for CFOAM (see ParametricModel), else SX
    inductive = hardware == "inductive"
    s = sym.sym("s", 4 * n + (1 if inductive else 0))
    tau = sym.sym("tau")
    a = sym.sym("a", n)
    p = sym.sym("p", model.n_p)
    q0, v0, a0, p0 = s[:n], s[n:2 * n], s[2 * n:3 * n], s[3 * n:4 * n] if inductive else s[3 * n:]
    p1 = ((1 - af) * a + af * a0 - am * p0) / (1 - am)
    q1 = q0 + h * v0 + h * h * (0.5 - beta) * p0 + h * h * beta * p1
    v1 = v0 + h * (1 - gamma) * p0 + h * gamma * p1
    if hardware:
        hw = sym.sym("hw", len(HW_LAYOUT))
        f = model.inverse_dynamics(q1, v1, a, p)
        stick = hw[-1] > 0.5
        if inductive:                    # the current at the end of the substep (backward Euler)
            current = inductive_current(tau, v1[0], s[4 * n], h, hw)
            hub = motor_torque(current, v1[0], hw) - friction_torque(v1[0], hw)
            new = (q1, v1, p1, current)
        else:
            hub = hub_torque(tau, v1[0], hw)
            new = (q1, v1, p1)
        p1_stick = -(v0[0] + h * (1 - gamma) * p0[0]) / (h * gamma)
        a_stick = ((1 - am) * p1_stick - af * a0[0] + am * p0[0]) / (1 - af)
        held = (p[0] + p[1]) * (a[0] - a_stick)
        residual = ca.vertcat(ca.if_else(stick, held, f[0] - hub), f[1:])
        mechanical = ca.vertcat(ca.if_else(stick, held, f[0]), f[1:])
        d_hub = ca.if_else(stick, 0, -ca.jacobian(hub, a)[0])
        return s, tau, a, p, new, residual, hw, mechanical, d_hub
    force = ca.vertcat(tau, sym.zeros(n - 1))
    residual = model.inverse_dynamics(q1, v1, a, p) - force
    return s, tau, a, p, (q1, v1, p1), residual


@lru_cache(maxsize=16)
def _iteration_matrix_function(model: ParametricModel, settings: StepperSettings,
                               hardware: bool | str = False) -> ca.Function:
    """Jacobian of the step residual in the new accelerations, at the predictor ``a = a_n``."""
    n = model.n_q
    s, tau, a, p, _, residual, *hw = _substep_expressions(model, settings, hardware)
    if hardware:        # the hardware's derivative is added in each Newton iteration (_fast_step_function)
        hw, residual = hw[:1], hw[1]
    if model.sym is ca.MX:
        R = ca.Function("residual", [a, s, tau, p, *hw], [residual])
        J = ca.densify(jacobian_columns(R, [s[2 * n:3 * n], s, tau, p, *hw], 0))
    else:
        J = ca.densify(ca.substitute(ca.jacobian(residual, a), a, s[2 * n:3 * n]))
    # no common-subexpression pass: it found 2 % on CFOAM 10+10 and took 2.6 s of its 8.4 s build
    return ca.Function("iteration_matrix", [s, tau, p, *hw], [J], ["s", "tau", "p"] + ["hw"] * len(hw), ["J"])


def step_functions(model: HubBeamModel, settings: StepperSettings, backend=None, hardware: bool | str = False) -> tuple:
    """The plant step and its iteration matrix on a backend.

    Both take the model's parameter vector ``p`` (:attr:`HubBeamModel.p`) as their last
    input, so they are built (and compiled) once per model family, mode counts and
    settings, whatever the tip mass, tip position, material or geometry.

    Parameters
    ----------
    model : HubBeamModel
    settings : StepperSettings
    backend : {"auto", "compiled", "vm"}, optional
    hardware : bool or "inductive"
        Functions with a last input ``hw`` (:data:`~hubbeam_ctrl.sim.hardware.HW_LAYOUT`):
        ``tau`` is then the command and the hub torque the hardware's; ``"inductive"``: the
        armature current is one more state, the last entry of ``s``
        (:func:`~hubbeam_ctrl.sim.hardware.inductive_current`).

    Returns
    -------
    step : casadi.Function
        ``(s, tau (1, substeps), J_inv, p) -> (s_next, err)``, compiled at -O1 when compiled.
    iteration_matrix : casadi.Function
        ``(s, tau, p) -> J`` (dense), compiled at -O0 (refreshed only now and then; MX models,
        whose code is compact, at the hot functions' level).
    backend : str
        ``"compiled"`` or ``"vm"``: the backend the step runs on.
    """
    extra = (hardware,) if hardware else ()    # the ideal functions exactly as before (same cache keys)
    pm = model.parametric
    step = compile_recipe(model_recipe(pm, "plant_step", settings, hardware),
                          lambda: _fast_step_function(pm, settings, *extra), backend, opt=OPT_HOT)
    # SX: a large scalar graph, rarely called (-O0); MX: compact code whose products are worth -O3
    jac_opt = OPT_HOT if pm.sym is ca.MX else OPT_COLD
    jac = compile_recipe(model_recipe(pm, "iteration_matrix", settings, hardware),
                         lambda: _iteration_matrix_function(pm, settings, *extra), backend, opt=jac_opt)
    return step, jac, "compiled" if step.is_a("External") else "vm"


def model_recipe(model: ParametricModel, kind: str, *more) -> tuple:
    """What a function of a model family is built from, for :func:`~hubbeam_ctrl.core.recipes.compile_recipe`.

    Parameters
    ----------
    model : ParametricModel
    kind : str
        Which function (e.g. ``"plant_step"``).
    *more
        Its other arguments (settings, hardware variant), values with a stable ``repr``.

    Returns
    -------
    tuple
    """
    return (kind, model.name, model.n_axial_modes, model.n_transverse, model.axial, model.sym.__name__, *more)


@lru_cache(maxsize=16)
def _fast_step_function(model: ParametricModel, settings: StepperSettings, hardware: bool | str = False) -> ca.Function:
    """One sample: ``substeps`` steps of modified Newton with the inverse iteration matrix given."""
    n = model.n_q
    s, tau, a, p, new, residual, *hw = _substep_expressions(model, settings, hardware)
    n_s = s.shape[0]
    opts = {"cse": True}
    HW = [ca.MX.sym("hw", len(HW_LAYOUT))] if hardware else []
    if hardware:
        hw, d_hub = hw[:1], hw[2]
        R = ca.Function("residual", [a, s, tau, p, *hw], [residual, d_hub], opts)
    else:
        R = ca.Function("residual", [a, s, tau, p, *hw], [residual], opts)
    more = [tau, *hw] if hardware == "inductive" else []     # the new current depends on them
    update = ca.Function("update", [a, s, *more], [ca.vertcat(*new[:2], a, *new[2:])], opts)
    S = ca.MX.sym("s", n_s)
    T = ca.MX.sym("tau")
    P = ca.MX.sym("p", model.n_p)
    Jm = ca.MX.sym("J_inv", n, n)           # inverse of the iteration matrix: no factorisation per step
    A = S[2 * n:3 * n]
    delta = ca.MX.zeros(n)
    for _ in range(settings.newton_iterations):
        if hardware:
            # Jm inverts the mechanical iteration matrix; the hardware adds d e0 e0' to it, whose
            # inverse is Sherman-Morrison's: an exact Newton step in the drive's and friction's
            # derivative (stiff near zero rate), at no factorisation
            r, d = R(A, S, T, P, *HW)
            y = ca.mtimes(Jm, r)
            delta = y - Jm[:, 0] * (d * y[0] / (1 + d * Jm[0, 0]))
        else:
            delta = ca.mtimes(Jm, R(A, S, T, P, *HW))
        A = A - delta
    sub = ca.Function("substep", [S, T, Jm, P, *HW], [update(A, S, *([T, *HW] if more else [])), ca.norm_inf(delta)])
    k = settings.substeps
    accum = sub.mapaccum("substeps", k)
    X = ca.MX.sym("x", n_s)
    U = ca.MX.sym("u", 1, k)
    xs, errs = accum(X, U, Jm, P, *HW)
    name = {False: "plant_step", True: "plant_step_hw", "inductive": "plant_step_hw_l"}[hardware]
    return ca.Function(name, [X, U, Jm, P, *HW],
                       [xs[:, -1], ca.mmax(errs)], ["s", "tau", "J_inv", "p"] + ["hw"] * len(HW),
                       ["s_next", "err"])


@lru_cache(maxsize=16)
def _hold_function(model: ParametricModel, inductive: bool = False) -> ca.Function:
    """``(s, tau, p, hw) -> hold``: the friction torque that holds the hub in state ``s`` [N m].

    ``hold = drive(tau, 0) - f_0(q, v, a)``, the hub row of the equations of motion at the
    state's accelerations: what friction must supply for the hub to stay at rest. With
    ``inductive`` the drive's torque is that of the state's current (its last entry).
    """
    n = model.n_q
    sym = model.sym
    s, tau, p = sym.sym("s", 4 * n + (1 if inductive else 0)), sym.sym("tau"), sym.sym("p", model.n_p)
    hw = sym.sym("hw", len(HW_LAYOUT))
    f = model.inverse_dynamics(s[:n], s[n:2 * n], s[2 * n:3 * n], p)
    drive = motor_torque(s[4 * n], 0.0 * tau, hw) if inductive else drive_torque(tau, 0.0 * tau, hw)
    hold = drive - f[0]
    return ca.Function("hub_hold", [s, tau, p, hw], [hold], ["s", "tau", "p", "hw"], ["hold"], {"cse": True})


@lru_cache(maxsize=16)
def _robust_step_function(model: ParametricModel, settings: StepperSettings,
                          hardware: bool | str = False) -> ca.Function:
    n = model.n_q
    s, tau, a, p, new, residual, *hw = _substep_expressions(model, settings, hardware)
    n_s = s.shape[0]
    hw = hw[:1]
    n_hw = len(HW_LAYOUT) if hardware else 0
    R = ca.Function("R", [a, s, tau, p, *hw], [residual])
    A_, W = ca.MX.sym("a", n), ca.MX.sym("w", n_s + 1 + model.n_p + n_hw)   # an MX input must be one symbol
    k_p = n_s + 1 + model.n_p
    G = ca.Function("G", [A_, W], [R(A_, W[:n_s], W[n_s], W[n_s + 1:k_p], *([W[k_p:]] if hardware else []))])
    rf = ca.rootfinder("rf", "newton", G, {"abstol": 1e-9, "abstolStep": 1e-13, "max_iter": 50,
                                          "line_search": bool(hardware), "error_on_fail": True})
    more = [tau, *hw] if hardware == "inductive" else []
    update = ca.Function("update", [a, s, *more], [ca.vertcat(*new[:2], a, *new[2:])])
    S = ca.MX.sym("s", n_s)
    T = ca.MX.sym("tau")
    P = ca.MX.sym("p", model.n_p)
    HW = [ca.MX.sym("hw", n_hw)] if hardware else []
    A = rf(S[2 * n:3 * n], ca.vertcat(S, T, P, *HW))
    sub = ca.Function("substep", [S, T, P, *HW], [update(A, S, *([T, *HW] if more else []))])
    k = settings.substeps
    X = ca.MX.sym("x", n_s)
    U = ca.MX.sym("u", 1, k)
    xs = sub.mapaccum("substeps", k)(X, U, P, *HW)
    return ca.Function("plant_step_robust", [X, U, P, *HW], [xs[:, -1]])
