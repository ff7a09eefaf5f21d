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
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.plant.sensors import sensor_matrix
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step, substep_rule

__all__ = ["ModelSettings", "simulate_sensors", "synthetic_record", "rig_sensors", "clamped_modes"]


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
    n : int

    Returns
    -------
    (ndarray, ndarray)
    """
    p = rig.plant_params.replace(n_transverse=min(n + 2, 20), n_axial=2)
    r = modal_analysis("foam", 0.0, "prescribed", p)
    return np.asarray(r.bending_hz[:n]), np.asarray(r.damping_ratios[:n])


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
    return model, StepperSettings(dt=dt, substeps=rule.substeps)


def _bending_hz(params, model_name):
    """Free-hub bending frequencies of the plant (with the clamped ones as an upper bound)."""
    r = modal_analysis(model_name, 0.0, "prescribed", params)
    return np.asarray(r.bending_hz) * 1.05


def simulate_sensors(rig: Rig, t, u, sensors, settings: ModelSettings | None = None) -> dict:
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
    res = simulate_fixed_step(model, command, dt * n_s, settings=st, hardware=hw)
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
    if "tip_accel" in sensors:
        p = model.params
        arm = p.r + (p.L if p.l is None else p.l)
        out["tip_accel"] = arm * res.a[:, 0] + res.a[:, model.transverse_slice] @ model.basis.f2_tip
    return out


def synthetic_record(rig: Rig, t, u, sensors=None, seed: int = 0, settings: ModelSettings | None = None,
                     source: str = "synthetic") -> Record:
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

    Returns
    -------
    Record
    """
    if sensors is None:
        sensors = tuple(s for s in rig_sensors(rig) if s not in ("v_tip", "theta_dot"))
    y = simulate_sensors(rig, t, u, sensors, settings)
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
