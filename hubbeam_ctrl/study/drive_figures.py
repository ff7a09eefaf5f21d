"""Metrics of the command and of the drive, each in its own unit.

The controller's command is a hub torque [N m] on a torque source and a voltage [V] on a DC
motor (:attr:`hubbeam_ctrl.sim.hardware.Hardware.command`). :func:`drive_metrics` keeps the
two apart: the command's own figures (``peak_command``, ``peak_command_step``,
``time_at_limit_s``) carry its unit in ``command_unit``; the drive's voltage, current and hub
torque are computed from the recorded command and hub rate by the drive's relations of
:mod:`hubbeam_ctrl.sim.hardware` and each is checked against its own limit (``V_max``,
``I_max``, ``tau_max``).
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Drive, Friction
from hubbeam_ctrl.sim.hardware import Hardware, drive_torque

__all__ = ["drive_of", "friction_of", "drive_metrics", "command_limit", "AT_LIMIT", "COMMAND_UNITS"]

#: A command within this fraction of its limit is at the limit (``time_at_limit_s``) [-].
AT_LIMIT = 1e-3
#: The command's unit of each drive kind (``command_unit``).
COMMAND_UNITS = {"torque": "N m", "dc_motor": "V"}
#: Relative slack of the limit checks (round-off of a clipped command) [-].
_SLACK = 1e-9


def drive_of(result) -> Drive:
    """The drive a closed-loop run was made with (``result.settings["hardware"]``).

    Parameters
    ----------
    result : Result
        A closed-loop run; one without hardware ran on the ideal torque source.

    Returns
    -------
    Drive
    """
    spec = (result.settings or {}).get("hardware") or {}
    drive = spec.get("drive")
    if drive is None:
        return Drive()
    if isinstance(drive, Drive):
        return drive
    if not isinstance(drive, dict):
        raise ParameterError(f"result.settings['hardware']['drive'] must be a table of motor keys, "
                             f"got {type(drive).__name__}")
    return Drive(**drive)


def friction_of(result) -> Friction:
    """The hub friction a closed-loop run was made with (its ``v_eps`` smooths the gear's switch).

    Parameters
    ----------
    result : Result
        A closed-loop run (its ``settings["hardware"]["friction"]``).

    Returns
    -------
    Friction
        None recorded: no friction.
    """
    spec = ((result.settings or {}).get("hardware") or {}).get("friction")
    if spec is None:
        return Friction()
    return spec if isinstance(spec, Friction) else Friction(**spec)


def command_limit(drive: Drive, tau_max: float | None) -> float | None:
    """The command's limit: ``V_max`` [V] on a DC motor, ``tau_max`` [N m] on a torque source.

    Parameters
    ----------
    drive : Drive
    tau_max : float or None
        The task's torque limit [N m] (None: the torque source's own ``motor.tau_max``, if any).

    Returns
    -------
    float or None
    """
    if not drive.is_ideal:
        return float(drive.V_max)
    if tau_max is not None:
        return float(tau_max)
    own = getattr(drive, "tau_max", None)
    return None if own is None else float(own)


def drive_metrics(t, u, thd, t_f: float, drive: Drive, tau_max: float | None = None,
                  friction: Friction | None = None) -> dict:
    """The command's and the drive's figures of one run, each in its own unit.

    Parameters
    ----------
    t : ndarray
        Sample times [s] (uniform).
    u : ndarray
        The commands [N m on a torque source, V on a DC motor], one per sample (non-finite
        samples are left out).
    thd : ndarray
        Hub rate at each sample [rad/s].
    t_f : float
        End of the slew [s] (``time_at_limit_slew_s`` counts up to it).
    drive : Drive
    tau_max : float, optional
        Hub-torque limit [N m] (the task's; on a DC motor its stall torque).
    friction : Friction, optional
        The hub friction: its ``v_eps`` smooths the gear's switch (the friction torque itself
        is not the drive's and is left out). Default none.

    Returns
    -------
    dict
        ``command_unit`` ("N m" or "V"), ``command_limit`` (in that unit, None: none),
        ``peak_command``, ``peak_command_step`` (largest change between samples),
        ``hub_torque_squared_integral`` (of the held hub torque [N^2 m^2 s]),
        ``time_at_limit_s`` and ``time_at_limit_slew_s`` (samples within :data:`AT_LIMIT` of
        the limit times the sample time, over the run and up to ``t_f``), ``peak_voltage_v``
        (``|clip(u, +-V_max)|``) and ``peak_current_a`` (``|clip((V - k_e N thd) / R,
        +-I_max)|`` at the recorded hub rate, the resistive circuit's current: with an armature
        inductance it leaves out the current's lag of ``L / R``; both None on a torque source),
        ``peak_hub_torque_nm`` (the drive's torque
        on the hub, friction aside: the command on a torque source, ``N eta_motor k_t i``
        times the gear factor on a DC motor), ``within_voltage_limit``, ``within_current_limit``
        (None on a torque source), ``within_torque_limit`` (hub torque within ``tau_max``;
        on a DC motor within the largest torque its current limit gives, back-driven included)
        and ``within_drive_limits`` (all of them).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4) * 0.01
    >>> m = drive_metrics(t, np.array([0.0, 10.0, 10.0, -2.0]), np.zeros(4), 0.02,
    ...                   Drive(kind="dc_motor", R=2.6, k_t=7.68e-3, k_e=7.68e-3, N=70.0, eta_forward=0.9))
    >>> m["command_unit"], m["peak_voltage_v"], round(m["peak_current_a"], 4), round(m["peak_hub_torque_nm"], 4)
    ('V', 10.0, 3.8462, 1.8609)
    >>> m["peak_command_step"], m["time_at_limit_s"]
    (12.0, 0.02)
    """
    t, u, thd = (np.asarray(x, dtype=float) for x in (t, u, thd))
    ok = np.isfinite(u) & np.isfinite(thd)
    u_ok, thd_ok = u[ok], thd[ok]
    dt = float(t[1] - t[0]) if t.size > 1 else 0.0
    nan = float("nan")
    limit = command_limit(drive, tau_max)
    hw = Hardware(drive, Friction() if friction is None else friction)
    torque_all = np.where(ok, drive_torque(np.where(ok, u, 0.0), np.where(ok, thd, 0.0), hw.values()), np.nan)
    torque = torque_all[ok]
    held = torque_all[:-1] if torque_all.size > 1 else torque_all      # the last sample's command is not applied
    steps = np.diff(u)
    steps = steps[np.isfinite(steps)]
    out = {
        "command_unit": COMMAND_UNITS[drive.kind],
        "command_limit": limit,
        "peak_command": float(np.max(np.abs(u_ok))) if u_ok.size else nan,
        "peak_command_step": float(np.max(np.abs(steps))) if steps.size else 0.0,
        "peak_hub_torque_nm": float(np.max(np.abs(torque))) if torque.size else nan,
        "hub_torque_squared_integral": float(np.sum(held[np.isfinite(held)] ** 2) * dt),
    }
    if limit is not None and math.isfinite(limit):
        at = ok & (np.abs(np.where(ok, u, 0.0)) >= (1.0 - AT_LIMIT) * limit)
        out["time_at_limit_s"] = float(np.count_nonzero(at) * dt)
        out["time_at_limit_slew_s"] = float(np.count_nonzero(at & (t <= t_f + 1e-9)) * dt)
    else:
        out["time_at_limit_s"] = out["time_at_limit_slew_s"] = None
    if drive.is_ideal:
        out.update(peak_voltage_v=None, peak_current_a=None, within_voltage_limit=None,
                   within_current_limit=None)
        torque_bound = limit
    else:
        V = np.clip(u_ok, -drive.V_max, drive.V_max)
        i = np.clip((V - drive.k_e * drive.N * thd_ok) / drive.R, -drive.I_max, drive.I_max)
        out["peak_voltage_v"] = float(np.max(np.abs(V))) if V.size else nan
        out["peak_current_a"] = float(np.max(np.abs(i))) if i.size else nan
        out["within_voltage_limit"] = bool(out["peak_command"] <= drive.V_max * (1 + _SLACK))
        out["within_current_limit"] = bool(out["peak_current_a"] <= drive.I_max * (1 + _SLACK))
        torque_bound = drive.peak_hub_torque
    if torque_bound is None:
        out["within_torque_limit"] = None
    else:
        out["within_torque_limit"] = bool(out["peak_hub_torque_nm"] <= torque_bound * (1 + _SLACK))
    checks = [out[k] for k in ("within_voltage_limit", "within_current_limit", "within_torque_limit")
              if out[k] is not None]
    out["within_drive_limits"] = bool(all(checks)) if checks else None
    return out
