"""The model side of a calibration: a rig's simulated sensors for a record's input.

:func:`simulate_sensors` runs the nonlinear plant (FOAM by default) with the rig's hardware
(:class:`~hubbeam_ctrl.sim.hardware.Hardware`: DC motor, friction with Karnopp sticking) on
the fixed-step integrator (:func:`~hubbeam_ctrl.sim.stepper.simulate_fixed_step`) from rest,
under the record's input held over each sample (zero-order hold, as a digital controller
applies it), and returns the sensor series the record holds (:data:`SENSOR_COLUMNS`).
:func:`synthetic_record` does the same and adds what the rig's sensors do to a measurement:
Gaussian noise and bias of :class:`~hubbeam_ctrl.plant.rig.Sensors` and the encoder's
quantisation: the records of the tests and the notebook.

The compiled step functions take the model's parameters as an input
(:class:`~hubbeam_ctrl.plant.models.ParametricModel`), so a simulation with other beam or
hardware values reuses them: a 3 s record at 1 kHz on the servo link costs tens of ms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.calibrate.records import SENSOR_COLUMNS, Record
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.rig import _ATTR as _RIG_ATTR
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.plant.sensors import sensor_matrix
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step, substep_rule

__all__ = ["ModelSettings", "simulate_sensors", "synthetic_record", "rig_sensors", "clamped_modes",
           "sliding_hub_modes", "hub_damping"]


@dataclass(frozen=True)
class ModelSettings(Settings):
    """The plant a calibration simulates (model, modes, integration step)."""

    model: str = setting("foam", choices=("foam", "cfoam", "tlam"),
                         doc="Plant model: the nonlinear FOAM (default), CFOAM or TLAM.")
    n_transverse: int = setting(2, lo=1, hi=20, doc="Transverse (bending) modes of the plant.")
    n_axial: int = setting(1, lo=1, hi=20, doc="Axial modes of the plant (condensed, quasi-static).")
    frequency_tolerance: float = setting(2e-4, lo=1e-6, hi=0.05,
                                         doc="Largest relative frequency error of the integrator on the "
                                             "highest bending mode: sets the substeps per sample.")
    newton_iterations: int = setting(3, lo=1, hi=20, doc="Newton iterations per step of the plant integrator.")
    newton_tol: float = setting(1e-6, unit="m/s^2, rad/s^2", lo=1e-14, hi=1.0,
                                doc="Largest accepted last Newton correction of the plant integrator: the "
                                    "simulated sensors are smooth in the parameters to about this level, "
                                    "which sets the useful difference step of the fit's Jacobian.")
    residual_moment: bool = setting(False, doc="Add to ``root_moment`` the quasi-static root moment of the "
                                               "bending modes the plant leaves out (up to 20) under the "
                                               "inertial load of the kept coordinates' accelerations: the "
                                               "mode-acceleration correction of the truncated modes (issue 38; "
                                                "off by default until measured on every fit).")


def rig_sensors(rig: Rig) -> tuple:
    """The sensor columns the rig has: ``theta`` (encoder), ``theta_dot``, ``v_tip``, plus
    ``root_moment`` with a strain gauge at the root and ``tip_accel`` with an accelerometer.

    ``theta_dot`` and ``v_tip`` are accepted from any rig (a tachometer, a camera); the others
    need the rig's sensor.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    tuple of str
    """
    out = ["theta", "theta_dot", "v_tip"]
    if 0.0 in rig.sensors.strain_gauges:
        out.append("root_moment")
    if rig.sensors.tip_accelerometer:
        out.append("tip_accel")
    return tuple(k for k in SENSOR_COLUMNS if k in out)


def clamped_modes(rig: Rig, n: int = 2) -> tuple:
    """Frequencies [Hz] and damping ratios [-] of the first ``n`` bending modes with the hub
    held (clamped root, at rest), FOAM with ``n + 2`` transverse modes.

    The hub of a geared servo with friction is held between motions (Karnopp), so these are
    the modes a free-decay record shows.

    Parameters
    ----------
    rig : Rig
        Its beam (``plant_params``).
    n : int
        Bending modes wanted, >= 1.

    Returns
    -------
    (ndarray, ndarray)
        Frequencies [Hz] and damping ratios [-], ascending in frequency.
    """
    p = rig.plant_params.replace(n_transverse=min(n + 2, 20), n_axial=2)
    r = modal_analysis("foam", 0.0, "prescribed", p)
    return np.asarray(r.bending_hz[:n]), np.asarray(r.damping_ratios[:n])


def hub_damping(rig: Rig) -> float:
    """Linear damping of the hub at zero command [N m s/rad]: viscous friction plus, for a DC
    motor, the back-EMF through the shorted amplifier ``eta_forward N^2 k_t k_e / R``.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    float
    """
    return Hardware.from_rig(rig).hub_damping()


def sliding_hub_modes(rig: Rig, n: int = 2) -> tuple:
    """Frequencies [Hz] and damping ratios [-] of the first ``n`` bending modes with the hub free
    and sliding at zero command: FOAM linearised at rest (``n + 2`` transverse modes) with the
    hub damped by :func:`hub_damping` (Coulomb friction, which cannot be linearised at rest,
    left out): the modes a free decay shows while the hub turns.

    Parameters
    ----------
    rig, n
        As :func:`clamped_modes` (the rig's drive and friction damp the hub here).
    """
    from hubbeam_ctrl.plant.linearization import first_order_matrices, second_order_linearization
    p = rig.plant_params.replace(n_transverse=min(n + 2, 20), n_axial=2)
    lin = second_order_linearization(build_model("foam", p), 0.0, "free")
    lin.G[0, 0] += hub_damping(rig)
    A, _, _ = first_order_matrices(lin)
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 1e-9 * np.abs(lam).max()]
    w = np.abs(lam)
    bending = np.argsort(w)
    f = w[bending] / (2 * np.pi)
    z = -lam.real[bending] / w[bending]
    return f[:n], z[:n]


def _check_sensors(rig: Rig, sensors) -> tuple:
    sensors = tuple(sensors)
    have = rig_sensors(rig)
    for s in sensors:
        if s not in SENSOR_COLUMNS:
            raise ParameterError(f"sensor {str(s)[:40]!r} is not one of {', '.join(SENSOR_COLUMNS)}")
        if s not in have:
            need = {"root_moment": "a strain gauge at the root (sensors.strain_gauges = [0.0])",
                    "tip_accel": "a tip accelerometer (sensors.tip_accelerometer = true)"}[s]
            raise ParameterError(f"sensor {s}: the rig does not have it (needs {need}); it has "
                                 f"{', '.join(have)}")
    return sensors


def _plant(rig: Rig, settings: ModelSettings, dt: float):
    params = rig.plant_params.replace(n_transverse=settings.n_transverse, n_axial=settings.n_axial)
    model = build_model(settings.model, params, axial="quasi-static")
    hz = _bending_hz(params, settings.model)
    rule = substep_rule(hz, dt, tolerance=settings.frequency_tolerance)
    return model, StepperSettings(dt=dt, substeps=rule.substeps, newton_iterations=settings.newton_iterations,
                                  newton_tol=settings.newton_tol)


_RESIDUAL: dict = {}


def residual_moment(params, model_name: str = "foam") -> np.ndarray:
    """Root moment of the omitted bending modes per acceleration of the kept coordinates [N m s^2].

    The root moment of a plant with ``params.n_transverse`` modes is the modes' displacements
    times their curvature at the root (mode displacement), which converges slowly: each omitted
    mode k deflects quasi-statically under the inertial load of the hub's and the kept modes'
    accelerations ``a``, ``q_k = -K_kk^-1 M_k a``, and adds ``C_k q_k`` (the mode-acceleration
    correction; :data:`~hubbeam_ctrl.plant.params.MAX_MODES` modes stand for the beam's). The
    vector ``w`` returned gives ``root_moment += a @ w``; it depends on neither E (the curvature
    and the stiffness scale together) nor J_h, so it is cached without them.

    Parameters
    ----------
    params : Params
        The plant (``n_transverse`` kept modes).
    model_name : str
        ``foam``, ``cfoam`` or ``tlam``.

    Returns
    -------
    ndarray (1 + n_transverse,)
        Zero when the plant keeps :data:`~hubbeam_ctrl.plant.params.MAX_MODES` modes.
    """
    from hubbeam_ctrl.plant.linearization import second_order_linearization
    from hubbeam_ctrl.plant.params import MAX_MODES
    n = params.n_transverse
    if n >= MAX_MODES:
        return np.zeros(n + 1)
    p = params.replace(E=1e9, J_h=1.0, n_transverse=MAX_MODES, n_axial=1)
    key = (model_name, n, repr(p))
    if key not in _RESIDUAL:
        big = build_model(model_name, p, axial="quasi-static")
        lin = second_order_linearization(big, 0.0, "free")
        M, K = np.asarray(lin.M, dtype=float), np.asarray(lin.K, dtype=float)
        C = sensor_matrix(big.params, big.n_transverse, big.n_axial)[2, :big.n_q]
        kept, omitted = slice(0, n + 1), slice(n + 1, big.n_q)
        _RESIDUAL[key] = -C[omitted] @ np.linalg.solve(K[omitted, omitted], M[omitted, kept])
        if len(_RESIDUAL) > 256:
            _RESIDUAL.pop(next(iter(_RESIDUAL)))
    return _RESIDUAL[key]


def _bending_hz(params, model_name):
    """Free-hub bending frequencies of the plant (with the clamped ones as an upper bound)."""
    r = modal_analysis(model_name, 0.0, "prescribed", params)
    return np.asarray(r.bending_hz) * 1.05


def simulate_sensors(rig: Rig, t, u, sensors, settings: ModelSettings | None = None, q2_0=None) -> dict:
    """The rig's sensor series for an input record, from rest (see the module docstring).

    Parameters
    ----------
    rig : Rig
    t : array_like (N,)
        Uniform sample times [s].
    u : array_like (N,)
        Input at each sample: torque [N m] (torque drive) or voltage [V] (DC motor), held
        until the next sample.
    sensors : sequence of str
        Which series (:data:`SENSOR_COLUMNS`, those the rig has: :func:`rig_sensors`).
    settings : ModelSettings, optional
    q2_0 : array_like, optional
        Initial transverse modal coordinates [m] (a beam released from a deflected shape,
        e.g. plucked by hand; at most ``settings.n_transverse`` values); default at rest.

    Returns
    -------
    dict
        Sensor name -> ndarray (N,), noise-free; ``"stats"`` -> the stepper's statistics.
    """
    settings = settings or ModelSettings()
    sensors = _check_sensors(rig, sensors)
    t = np.asarray(t, dtype=float)
    u = np.asarray(u, dtype=float)
    dt = float(np.median(np.diff(t)))
    model, st = _plant(rig, settings, dt)
    n_s = len(t) - 1

    def command(times):
        k = np.clip(np.ceil(np.asarray(times) / dt - 1e-9).astype(int) - 1, 0, n_s - 1)
        return u[k] if np.ndim(times) else u[0]

    hw = Hardware.from_rig(rig)
    x0 = None
    if q2_0 is not None:
        q2_0 = np.atleast_1d(np.asarray(q2_0, dtype=float))
        if q2_0.size > model.n_transverse or not np.all(np.isfinite(q2_0)):
            raise ParameterError(f"q2_0 must hold at most {model.n_transverse} finite values [m], got {q2_0.size}")
        x0 = np.zeros(2 * model.n_q)
        x0[model.transverse_slice.start:model.transverse_slice.start + q2_0.size] = q2_0
    res = simulate_fixed_step(model, command, dt * n_s, settings=st, hardware=hw, x0=x0)
    out = {"stats": res.stats}
    if "theta" in sensors:
        out["theta"] = res.q[:, 0]
    if "theta_dot" in sensors:
        out["theta_dot"] = res.v[:, 0]
    if "v_tip" in sensors:
        out["v_tip"] = res.v_tip
    if "root_moment" in sensors:
        C = sensor_matrix(model.params, model.n_transverse, model.n_axial)
        out["root_moment"] = res.q @ C[2, :model.n_q]
        if settings.residual_moment:
            out["root_moment"] = out["root_moment"] + res.a[:, :model.n_q] @ residual_moment(model.params,
                                                                                            settings.model)
    if "tip_accel" in sensors:
        p = model.params
        arm = p.r + (p.L if p.l is None else p.l)
        out["tip_accel"] = arm * res.a[:, 0] + res.a[:, model.transverse_slice] @ model.basis.f2_tip
    return out


def synthetic_record(rig: Rig, t, u, sensors=None, seed: int = 0, settings: ModelSettings | None = None,
                     source: str = "synthetic", q2_0=None) -> Record:
    """A measured-like record: :func:`simulate_sensors` plus the rig's sensor noise, bias and encoder.

    Noise (Gaussian, seeded) and bias from :class:`~hubbeam_ctrl.plant.rig.Sensors`:
    ``angle_noise``/``angle_bias`` on ``theta`` (then rounded to the encoder's counts),
    ``rate_noise``/``rate_bias``, ``strain_noise``/``strain_bias`` on ``root_moment``,
    ``accel_noise``/``accel_bias``; ``v_tip`` is exact.

    Parameters
    ----------
    rig : Rig
        The "true" rig.
    t, u : array_like (N,)
        Uniform times [s] and input [N m or V].
    sensors : sequence of str, optional
        Default: the rig's own sensors: ``theta`` (encoder), ``root_moment`` with a root strain
        gauge, ``tip_accel`` with an accelerometer.
    seed : int
    settings : ModelSettings, optional
    source : str
    q2_0 : array_like, optional
        Initial transverse modal coordinates [m] (see :func:`simulate_sensors`).

    Returns
    -------
    Record
    """
    if sensors is None:
        sensors = tuple(s for s in rig_sensors(rig) if s not in ("v_tip", "theta_dot"))
    y = simulate_sensors(rig, t, u, sensors, settings, q2_0=q2_0)
    rng = np.random.default_rng(seed)
    s = rig.sensors
    noise = {"theta": (s.angle_noise, s.angle_bias), "theta_dot": (s.rate_noise, s.rate_bias),
             "root_moment": (s.strain_noise, s.strain_bias), "tip_accel": (s.accel_noise, s.accel_bias),
             "v_tip": (0.0, 0.0)}
    cols = {}
    for name in sensors:
        sd, bias = noise[name]
        cols[name] = y[name] + bias + (sd * rng.standard_normal(len(t)) if sd > 0 else 0.0)
    if "theta" in cols and s.encoder_step > 0:
        cols["theta"] = s.encoder_step * np.round(cols["theta"] / s.encoder_step)
    inp = "tau" if rig.drive.is_ideal else "V"
    return Record(t=np.asarray(t, dtype=float), columns={inp: np.asarray(u, dtype=float), **cols}, source=source)


def set_fields(rig: Rig, fit_fields, values) -> Rig:
    """A copy of ``rig`` with the fields set to ``values`` (validated as a rig).

    Parameters
    ----------
    rig : Rig
    fit_fields : sequence of FitField
    values : sequence of float

    Returns
    -------
    Rig
    """
    changes: dict = {}
    for f, v in zip(fit_fields, values):
        part = changes.setdefault(f.table, {})
        if f.index is None:
            part[f.key] = float(v)
        else:
            ratios = list(part.get("ratios", rig.damping.ratios) or [rig.beam.damping_ratio])
            while len(ratios) <= f.index:
                ratios.append(ratios[-1])
            ratios[f.index] = float(v)
            part["ratios"] = tuple(ratios)
    parts = {_RIG_ATTR[t]: getattr(rig, _RIG_ATTR[t]).replace(**c) for t, c in changes.items()}
    if "damping" in changes and rig.beam.damping_ratio > 0:
        parts["beam"] = parts.get("beam", rig.beam).replace(damping_ratio=0.0)
    return rig.replace(**parts)
