"""Open-loop torque runs on the compiled fixed-step path, with an error estimate.

``hubbeam simulate --maneuver torque`` used IDAS, which took 14 times longer than the
compiled fixed-step generalized-alpha path (:func:`~hubbeam_ctrl.sim.stepper.simulate_fixed_step`)
for the same peak deflection (30 s Eq. 44 run, FOAM 5 + 5 modes: 181 ms against 12.6 ms).
A fixed step carries no error control, so :func:`simulate_estimated` runs the maneuver twice:
with the step ``h`` and with ``2 h``. The method is second order, so the error of the ``h`` run
is about a third of the difference of the two (Richardson); the step is halved until the
estimated error of the peak tip deflection is within ``tolerance`` (default 1e-4, relative).
The coarse run costs half the fine one.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hubbeam_ctrl.core.budget import T_END_MAX, check_budget
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.maneuvers import SpinUp, UserManeuver
from hubbeam_ctrl.plant.models import resolve_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.results import Result
from hubbeam_ctrl.sim.simulate import _check_maneuver_spin
from hubbeam_ctrl.sim.step_rule import SUBSTEP_BUDGET
from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step

__all__ = ["simulate_estimated"]

#: Lower bound of the wall time per output sample of the two runs together [s], up to 11
#: coordinates (scaled by (n_q / 11)^2 above): measured 3.3 us (FOAM 2 + 2), 4.0 us (SFOAM
#: 5), 5.9 us (FOAM 5 + 5), 19.5 us (CFOAM 5 + 5), compiled backend, shared 2-core machine.
SECONDS_PER_SAMPLE = 3e-6


def _peak_and_series_error(fine: Result, coarse: Result, stride: int) -> tuple:
    """Estimated relative errors of the fine run: of its peak |v_tip| and of the whole series."""
    vf = fine.v_tip[::stride]
    n = min(len(vf), len(coarse.v_tip))
    vf, vc = vf[:n], coarse.v_tip[:n]
    peak = float(np.max(np.abs(fine.v_tip)))
    scale = max(peak, 1e-300)
    peak_err = abs(float(np.max(np.abs(vf))) - float(np.max(np.abs(vc)))) / 3.0 / scale
    series_err = float(np.max(np.abs(vf - vc))) / 3.0 / scale
    return peak_err, series_err


def _with_outputs(model, res: Result) -> Result:
    """The outputs an IDAS run carries (``q_theta``, ``energy``, ``angular_momentum``), so that
    the saved files have the same columns."""
    N = len(res.t)
    Q, V = res.q.T, res.v.T
    return dataclasses.replace(
        res, q_theta=np.array(model.q_theta_function.map(N)(Q, V)).ravel(),
        energy=np.array(model.energy_function.map(N)(Q, V)[2]).ravel(),
        angular_momentum=np.array(model.momentum_function.map(N)(Q, V)).ravel())


def _flags(res: Result, range_limit: float, divergence_limit: float) -> Result:
    """The range flag and the divergence stop of :func:`~hubbeam_ctrl.sim.simulate.simulate`,
    applied to a finished fixed-step run (cut at the first bad sample)."""
    L = res.params.L
    bad = ~np.isfinite(res.v_tip) | ~np.all(np.isfinite(res.q), axis=1) | (np.abs(res.v_tip) > divergence_limit * L)
    stopped, message = False, "completed"
    if bad.any():
        k = int(np.argmax(bad))
        keep = max(k, 1)
        what = ("a non-finite state" if not np.isfinite(res.v_tip[k]) or not np.all(np.isfinite(res.q[k]))
                else f"|v_tip| > {divergence_limit:g} L")
        message = f"{res.model.upper()} left its range: {what} at t = {res.t[k]:.3f} s"
        stopped = True
        cut = {f.name: getattr(res, f.name)[:keep] for f in dataclasses.fields(res)
               if isinstance(getattr(res, f.name), np.ndarray) and getattr(res, f.name).ndim >= 1
               and len(getattr(res, f.name)) == len(res.t)}
        res = dataclasses.replace(res, **cut)
    over = np.nonzero(np.abs(res.v_tip) > range_limit * L)[0]
    outside = float(res.t[over[0]]) if over.size else None
    if outside is not None and not stopped:
        message = (f"completed; |v_tip| passed {range_limit:g} L = {range_limit * L:.3g} m (outside "
                   f"the models' validated range) at t = {outside:.3f} s")
    return dataclasses.replace(res, stopped=stopped, message=message,
                               stats={**res.stats, "outside_range_time_s": outside})


def simulate_estimated(model="foam", maneuver=None, t_end: float = 30.0, *, params: Params | None = None,
                       tolerance: float = 1e-4, dt: float = 0.01, rho_inf: float = 0.9,
                       range_limit: float = 0.3, divergence_limit: float = 1.0, backend=None,
                       axial: str | None = None, max_memory_mb: float = 2048.0,
                       max_wall_s: float = 600.0, outputs: bool = False) -> Result:
    """A free-hub torque run on the compiled fixed-step path, refined until its estimated
    peak error is within ``tolerance``.

    Parameters
    ----------
    model : str
        ``"foam"``, ``"cfoam"``, ``"tlam"`` or ``"sfoam"``.
    maneuver : TorquePulse or callable
        Hub torque ``tau(t)`` [N m] (a prescribed motion needs :func:`~hubbeam_ctrl.sim.simulate.simulate`).
    t_end : float
        Final time [s], at least ``2 dt``.
    params : Params, optional
        Default: Table 1.
    tolerance : float
        Largest accepted estimated relative error of the peak ``|v_tip|`` [-], in [1e-8, 0.1].
    dt : float
        Output sample period [s]; the first step tried (the coarse run uses ``2 dt``).
    rho_inf : float
        Spectral radius at infinity of the generalized-alpha method [-].
    range_limit, divergence_limit : float
        As in :class:`~hubbeam_ctrl.sim.simulate.SimulationSettings` [-] (fractions of L).
    backend : {"auto", "compiled", "vm"}, optional
        See :class:`~hubbeam_ctrl.sim.stepper.PlantStepper`.
    axial : {"dynamic", "quasi-static"}, optional
        See :func:`~hubbeam_ctrl.plant.models.build_model`.
    max_memory_mb : float
        A run whose two result series would need more memory than this [MB] is refused
        before it starts.
    outputs : bool
        Also evaluate ``q_theta``, ``energy`` and ``angular_momentum`` on every sample, as an
        IDAS run has them (what a saved file needs; it costs more than the two runs: 45 ms
        on the 30 s FOAM run, 110 ms on CFOAM).
    max_wall_s : float
        A run estimated (from below) to take longer than this [s] is refused before it
        starts (the run itself is not timed: it is one compiled loop per step size).

    Returns
    -------
    Result
        Of kind ``"fixed_step"`` on the ``dt`` grid (with ``outputs``: ``q_theta``, ``energy``
        and ``angular_momentum``); ``stats`` adds ``peak_error_estimate`` and
        ``series_error_estimate`` (relative, [-]), ``substeps`` and ``integrator``; ``wall_s``
        is the time of both runs [s].

    Raises
    ------
    ParameterError
        For a prescribed-hub maneuver, or when 200 substeps per sample do not meet ``tolerance``.
    """
    if maneuver is None or isinstance(maneuver, SpinUp) or \
            (isinstance(maneuver, UserManeuver) and getattr(maneuver, "kind", "torque") != "torque") or \
            not callable(maneuver):
        raise ParameterError("maneuver must be a hub torque for the fixed-step path (a prescribed hub "
                             "motion runs on IDAS: simulate)")
    tolerance = check_in_range("tolerance", tolerance, "-", 1e-8, 0.1)
    range_limit = check_in_range("range_limit", range_limit, "-", 1e-6, 10.0)
    divergence_limit = check_in_range("divergence_limit", divergence_limit, "-", 1e-6, 10.0)
    max_wall_s = check_in_range("max_wall_s", max_wall_s, "s", 1e-3, 1e7)
    max_memory_mb = check_in_range("max_memory_mb", max_memory_mb, "MB", 1.0, 1e9)
    dt = check_in_range("dt", dt, "s", 1e-5, 1.0)
    t_end = check_in_range("t_end", t_end, "s", dt, T_END_MAX, "at least two samples: t_end >= dt")
    if t_end < 2 * dt:
        raise ParameterError(f"t_end must be at least 2 dt = {2 * dt:g} s on the fixed-step path (its coarse "
                             f"run takes steps of 2 dt), got {t_end:g} s")
    m = resolve_model(model, params, axial)
    _check_maneuver_spin(maneuver, m.params)
    n_samples = int(round(t_end / dt)) + 1
    check_budget(f"t_end = {t_end:g} s at dt = {dt:g} s ({n_samples} samples)",
                 memory_bytes=1.5 * 8.0 * n_samples * (1 + 4 * m.n_q + 4),
                 seconds=n_samples * SECONDS_PER_SAMPLE * max(1.0, (m.n_q / 11.0) ** 2),
                 max_memory_mb=max_memory_mb, max_wall_s=max_wall_s)
    if isinstance(maneuver, UserManeuver):
        maneuver.bind(t_end)
    start = time.perf_counter()

    def run(step_dt, substeps):
        return simulate_fixed_step(m, maneuver, t_end, settings=StepperSettings(dt=step_dt, substeps=substeps,
                                                                                rho_inf=rho_inf),
                                   backend=backend, max_memory_mb=max_memory_mb)

    coarse, stride, substeps = run(2 * dt, 1), 2, 1
    while True:
        fine = run(dt, substeps)
        peak_err, series_err = _peak_and_series_error(fine, coarse, stride)
        if peak_err <= tolerance or not np.isfinite(peak_err):
            break
        if 2 * substeps > SUBSTEP_BUDGET:
            raise ParameterError(f"tolerance {tolerance:g} is not met with {substeps} steps per {dt:g} s sample "
                                 f"(estimated peak error {peak_err:.2g}); use a larger tolerance or simulate (IDAS)")
        coarse, stride, substeps = fine, 1, 2 * substeps
    if outputs:
        fine = _with_outputs(m, fine)
    wall = time.perf_counter() - start
    fine = dataclasses.replace(fine, wall_s=wall, stats={
        **fine.stats, "integrator": "fixed-step", "substeps": substeps, "peak_error_estimate": peak_err,
        "series_error_estimate": series_err, "tolerance": tolerance})
    return _flags(fine, range_limit, divergence_limit)
