"""The physical limit of a slew: time-optimal and minimum-vibration rest-to-rest torques.

The hub turns by ``Theta`` from rest, within ``|tau| <= tau_max``, and ends with the beam's
residual vibration below a tolerance. The trajectory is computed on the nonlinear model
(FOAM by default, its axial coordinates condensed: :func:`~hubbeam_ctrl.plant.models.build_model`
with ``axial="quasi-static"``, which removes the stiff axial modes from the problem) by direct
collocation: ``N`` intervals of the free final time ``T`` (time scaling), the torque constant
on each, Radau collocation of the coordinates, rates and accelerations with the implicit
equations of motion ``M(q) a + c(q, v) = B tau`` at every collocation point, solved by IPOPT.

**End conditions.** At ``T`` the torque stops. The hub-free system linearised at rest,
``M0 q'' + K0 q = 0``, has one rigid mode and the bending modes ``phi_i`` (``K0 phi = w^2 M0
phi``, ``phi' M0 phi = 1``). The end state must carry no angular momentum (``(M0 v)_0 = 0``,
the hub does not drift), its mean angle ``(M0 q)_0 / M0_00`` must be ``Theta``, and the
residual amplitude of the tip deflection in the hub frame, ``sum_i |c_i| sqrt(eta_i^2 +
(eta_i'/w_i)^2)`` with ``eta = Phi' M0 q`` and ``c_i`` mode ``i``'s tip deflection, must
stay within the tolerance (imposed through Cauchy-Schwarz: ``n sum_i c_i^2 (eta_i^2 +
eta_i'^2/w_i^2) <= tol^2``, which implies it).

**Time-optimal.** The smallest ``T`` (objective ``T``), started from the rigid bang-bang
(``T_rigid = 2 sqrt(Theta J / tau_max)``, the angle of the rigid body) on a coarse grid and
warm-started on the fine one; its yardstick ``rigid_bound_s`` is :func:`rigid_bound` (on a DC
drive the rigid bang-bang within the voltage limit through back-EMF, the current limit and
friction, :mod:`hubbeam_ctrl.limit.bound`). **Minimum vibration.** For a given ``T >= T_rigid``: the
smallest residual (objective: the residual's modal energy).

**Check.** The optimal torque (piecewise constant, zero after ``T``) is applied to the
evaluation plant (FOAM with dynamic axial coordinates and more bending modes,
:func:`~hubbeam_ctrl.sim.stepper.simulate_fixed_step`), and the residual is the largest
``|v_tip|`` over two periods of the first bending mode after ``T``.

The values (settings, result) are :mod:`hubbeam_ctrl.limit.slew`, the nonlinear program
:mod:`hubbeam_ctrl.limit.collocation`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_finite, check_in_range, check_positive
from hubbeam_ctrl.limit.bound import rigid_bound
from hubbeam_ctrl.limit.collocation import _optimise, _Problem, _trajectory
from hubbeam_ctrl.limit.slew import (
    MAX_DURATION,
    MIN_SLEW_ANGLE,
    MIN_TOLERANCE,
    OptimalSettings,
    OptimalSlew,
    default_tolerance,
)
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["time_optimal_slew", "min_vibration_slew"]


def _plant_check(params: Params, result: "OptimalSlew", settings: OptimalSettings, design_modes: int) -> tuple:
    """Largest ``|v_tip|`` and the mean hub angle of the evaluation plant after ``T``."""
    from hubbeam_ctrl.plant.modal import natural_frequencies
    from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step
    modes = settings.plant_modes or min(design_modes + 3, MAX_MODES)
    plant = params.replace(n_transverse=modes)
    hz = natural_frequencies("foam", 0.0, "free", params=plant)
    period = 1.0 / hz[0]
    dt = min(result.duration_s / (4 * len(result.tau)), 0.05 / hz[-1], period / 40)
    t_end = result.duration_s + 2 * period
    dt = t_end / math.ceil(t_end / dt)
    what = f"FOAM, {modes} transverse and {plant.n_axial} axial modes (dynamic), dt = {dt:.3g} s"
    try:
        run = simulate_fixed_step("foam", result.torque, t_end, params=plant, settings=StepperSettings(dt=dt))
    except HubbeamError as exc:      # the slew is kept; its check failed (found on a random rig: exit 2 before)
        return None, None, f"the check FAILED on {what}: {str(exc).splitlines()[0]}"
    after = run.t >= result.duration_s
    return float(np.max(np.abs(run.v_tip[after]))), float(np.mean(run.q[after, 0])), what


def _source(params) -> tuple:
    """``(Params, Rig or None)`` of the first argument: a beam, or a rig (its plant parameters)."""
    if isinstance(params, Rig):
        return params.plant_params, params
    return params, None


def _check_inputs(params: Params, slew_angle, tolerance, settings) -> tuple:
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params or a Rig, got {type(params).__name__}")
    slew_angle = check_finite("slew_angle", slew_angle, "rad")
    if slew_angle == 0.0:
        raise ParameterError("slew_angle must be a finite number != 0 [rad], got 0")
    if tolerance is not None:
        tolerance = check_in_range("tolerance", check_positive("tolerance", tolerance, "m"), "m",
                                   MIN_TOLERANCE * params.L, params.L,
                                   f"{MIN_TOLERANCE:g} L to the beam length L")
    else:
        tolerance = default_tolerance(params)
    if not isinstance(settings, OptimalSettings):
        raise ParameterError(f"settings must be an OptimalSettings, got {type(settings).__name__}")
    return slew_angle, tolerance


def _check_slew(params: Params, slew_angle: float, duration: float | None = None, name: str = "duration") -> float:
    """Refuse a slew from rest the models cannot describe; returns the checked ``duration`` (or None).

    The slew's rigid peak rate must stay within ``Params.max_spin`` (the 1 % root-strain spin,
    as :func:`~hubbeam_ctrl.study.scenarios.make_scenario` requires): ``sqrt(|Theta| tau_max /
    J_total)`` for the time-optimal (bang-bang) slew, ``2 |Theta| / T`` in a given time ``T``;
    ``|Theta| >= 1e-6 rad``; ``T <= MAX_DURATION``.
    """
    if abs(slew_angle) < MIN_SLEW_ANGLE:
        raise ParameterError(f"slew_angle must be a finite number with |slew_angle| >= {MIN_SLEW_ANGLE:g} [rad], "
                             f"got {slew_angle:g}")
    J = params.total_inertia
    if duration is not None:
        duration = check_positive(name, duration, "s")
        if duration > MAX_DURATION:
            raise ParameterError(f"{name} must be in (0, {MAX_DURATION:g}] [s], got {duration:g}")
        if 2 * abs(slew_angle) / duration > params.max_spin:
            raise ParameterError(f"{name} must be >= {2 * abs(slew_angle) / params.max_spin:.5g} s (a slew by "
                                 f"{slew_angle:g} rad in T reaches the rigid peak rate 2 |Theta| / T, at most "
                                 f"Params.max_spin = {params.max_spin:.4g} rad/s), got {duration:g} s")
        return duration
    peak, how = math.sqrt(abs(slew_angle) * params.tau_max / J), "sqrt(|Theta| tau_max / J_total), bang-bang"
    if peak > params.max_spin:
        raise ParameterError(f"slew_angle = {slew_angle:g} rad spins the hub up to {peak:.4g} rad/s ({how}), above "
                             f"Params.max_spin = {params.max_spin:.4g} rad/s (1 % centrifugal strain at the root)")
    return duration


def _result(kind: str, params: Params, slew_angle: float, tolerance: float, pb: _Problem, w, stats,
            iterations: int, wall: float, settings: OptimalSettings) -> OptimalSlew:
    N = settings.intervals
    tr = _trajectory(pb, w, N)
    converged = bool(stats["success"])
    message = str(stats["return_status"])
    if not converged:
        message += "; the last iterate is kept (" + (
            "feasible" if abs(tr["angle_error"]) < 1e-3 * abs(slew_angle) and tr["residual"] <= 1.01 * tolerance
            else "NOT feasible") + f": residual {tr['residual']:.3g} m, angle error {tr['angle_error']:.3g} rad)"
    m = pb.model
    design = f"{m.name.upper()}, {m.n_transverse} transverse modes, {m.axial} axial, {N} x {settings.degree} Radau"
    out = OptimalSlew(kind=kind, slew_angle=slew_angle, duration_s=tr["T"], t=tr["t"], tau=tr["tau"],
                      theta=tr["theta"], theta_dot=tr["theta_dot"], v_tip=tr["v_tip"], q2=tr["q2"], q2_dot=tr["q2_dot"],
                      tolerance=tolerance,
                      residual_design=tr["residual"], residual_plant=None, final_angle_plant=None,
                      rigid_bound_s=pb.bound, converged=converged, message=message, solve_s=wall,
                      iterations=iterations, design=design, plant="", params=params)
    if settings.check:
        residual, angle, plant = _plant_check(params, out, settings, m.n_transverse)
        out = _replace(out, residual_plant=residual, final_angle_plant=angle, plant=plant)
    return out


def _replace(result: OptimalSlew, **changes) -> OptimalSlew:
    return dataclasses.replace(result, **changes)


def time_optimal_slew(params: Params, slew_angle: float, *, tolerance: float | None = None,
                      settings: OptimalSettings = OptimalSettings(), progress: bool = False) -> OptimalSlew:
    """The minimum-time rest-to-rest slew within ``|tau| <= tau_max`` and the residual tolerance.

    Parameters
    ----------
    params : Params or Rig
        Beam, hub and drive (``tau_max``); or a rig: its plant parameters, and with a DC motor
        the voltage limit through back-EMF, the current limit and the friction the drive must
        overcome (:func:`~hubbeam_ctrl.limit.bound._drive_terms`).
    slew_angle : float
        Theta [rad], finite, not 0.
    tolerance : float, optional
        Allowed residual tip vibration [m], > 0 (default :func:`default_tolerance`, 1e-3 L).
    settings : OptimalSettings
        Grid, design model and check.
    progress : bool
        Show IPOPT's iterations on a progress bar (on a terminal only; default False).

    Returns
    -------
    OptimalSlew
        ``kind="time-optimal"``; ``converged`` False (with the message) if IPOPT did not
        converge, the last iterate kept.
    """
    params, rig = _source(params)
    slew_angle, tolerance = _check_inputs(params, slew_angle, tolerance, settings)
    _check_slew(params, slew_angle)
    pb, w, stats, iterations, wall = _optimise(params, slew_angle, tolerance, None, settings, rig, progress)
    return _result("time-optimal", params, slew_angle, tolerance, pb, w, stats, iterations, wall, settings)


def min_vibration_slew(params: Params, slew_angle: float, duration: float, *, tolerance: float | None = None,
                       settings: OptimalSettings = OptimalSettings(), name: str = "duration",
                       progress: bool = False) -> OptimalSlew:
    """The rest-to-rest slew in a given time with the smallest residual vibration.

    Parameters
    ----------
    params, slew_angle
        As :func:`time_optimal_slew`.
    duration : float
        Slew time T [s], at least the time-optimal one.
    tolerance : float, optional
        Allowed residual tip vibration [m], > 0 (default 1e-3 L): a result above it raises.
    settings : OptimalSettings
        Grid, design model and check.
    name : str
        The duration's name as the caller spelled it (``--duration`` on the command line).
    progress : bool
        Show IPOPT's iterations on a progress bar (on a terminal only; default False).

    Returns
    -------
    OptimalSlew
        ``kind="min-vibration"``.

    Raises
    ------
    ParameterError
        ``duration`` so short that the smallest residual exceeds ``tolerance`` (below the
        time-optimal duration): one line naming ``name`` and the shortest feasible duration,
        found by :func:`time_optimal_slew`.
    """
    source = params
    params, rig = _source(params)
    slew_angle, tolerance = _check_inputs(params, slew_angle, tolerance, settings)
    duration = _check_slew(params, slew_angle, duration, name)
    quick = settings.replace(check=False)

    def refuse():
        fastest = time_optimal_slew(source, slew_angle, tolerance=tolerance, settings=quick)
        if duration < fastest.duration_s:
            raise ParameterError(f"{name} must be >= {fastest.duration_s:.5g} s (the time-optimal slew with "
                                 f"residual <= {tolerance:.3g} m; the rigid bang-bang bound is "
                                 f"{fastest.rigid_bound_s:.5g} s), got {duration:g} s")

    if duration < rigid_bound(params, slew_angle, rig):          # below the rigid bound: hardly ever feasible
        refuse()
    pb, w, stats, iterations, wall = _optimise(params, slew_angle, tolerance, duration, settings, rig, progress)
    out = _result("min-vibration", params, slew_angle, tolerance, pb, w, stats, iterations, wall, quick)
    if out.residual_design > tolerance * 1.0001:
        refuse()
    if settings.check:
        residual, angle, plant = _plant_check(params, out, settings, pb.model.n_transverse)
        out = _replace(out, residual_plant=residual, final_angle_plant=angle, plant=plant)
    return out
