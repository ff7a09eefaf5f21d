"""The report's section on the rig: drive, friction, damping, sensors, timing, integral action."""

from __future__ import annotations

import numpy as np

__all__ = ["rig_lines", "damping_text"]


def damping_text(p) -> str:
    """The plant's structural damping as it applies: per mode when the rig gives ratios.

    Parameters
    ----------
    p : Params
        The plant's parameters.

    Returns
    -------
    str
    """
    ratios = p.transverse_damping(p.n_transverse)
    if ratios.size and np.ptp(ratios) > 0:
        more = " ..." if ratios.size > 4 else ""
        return "structural damping ratios " + ", ".join(f"{z:.3g}" for z in ratios[:4]) + more
    return f"structural damping ratio {float(ratios[0]) if ratios.size else p.damping_ratio:g}"


def rig_lines(comparison) -> list:
    """The report's section on the rig the controllers ran on: hardware, damping (a warning without
    any), how they read it.

    Parameters
    ----------
    comparison : Comparison

    Returns
    -------
    list of str
        Markdown lines (a warning alone for the beam without damping; none for a damped beam).
    """
    rig = getattr(comparison, "rig", None)
    p = comparison.plant.params if comparison.plant is not None else comparison.scenario.params
    ratios = p.transverse_damping(p.n_transverse)
    damped = bool(ratios.size and ratios.max() > 0)
    lines = []
    if rig is None or rig.is_ideal:
        if not damped:
            lines = ["warning: the plant has no structural damping (every mode rings until a controller damps "
                     "it); give the measured ratios ([damping] in a rig file, or damping_ratio).", ""]
        return lines
    d, f, sn, tm = rig.drive, rig.friction, rig.sensors, rig.timing
    first = next(iter(comparison.results.values()), None)
    hw = (first.settings.get("hardware") or {}) if first is not None else {}
    lines = ["## The rig", ""]
    if d.is_ideal:
        lines.append("- Drive: ideal torque source; the commands are hub torques [N m].")
    else:
        lines.append(f"- Drive: DC motor R = {d.R:g} ohm, k_t = {d.k_t:g} N m/A, k_e = {d.k_e:g} V s/rad, gear "
                     f"{d.N:g}:1 (efficiency {d.eta_forward:g} driving, {d.eta_backward:g} back-driven"
                     + (f"; motor efficiency {d.eta_motor:g}" if d.eta_motor != 1.0 else "") + "), "
                     f"{d.V_max:g} V, {d.I_max:g} A; the commands are voltages (the torque designs through "
                     "the drive's static inverse with the measured hub rate, controllers.drive).")
    lines.append("- Friction at the hub: " + ("none." if f.is_ideal else
                 f"viscous {f.viscous:g} N m s/rad, Coulomb {f.coulomb:g} N m, breakaway {f.static:g} N m "
                 f"(stick events in the first run: {hw.get('stick_events', 0)})."))
    lines.append(f"- Damping: ratios {', '.join(f'{z:.3g}' for z in ratios[:4])}"
                 + (" ..." if len(ratios) > 4 else "") + " of the plant's first modes."
                 if damped else "- warning: the rig has no damping; every mode rings until a controller damps it.")
    lines += _sensor_lines(sn, comparison)
    lines.append(f"- Timing: sample {comparison.scenario.dt * 1e3:g} ms, computation delay {tm.delay:g} of a sample "
                 "(the command acts that much after the sample it was computed from"
                 + ("; the design model, the filters and the certificate carry it)." if tm.delay else ")."))
    integral = {n: c.settings.integral if hasattr(getattr(c, "settings", None), "integral")
                else getattr(c, "integral", None) for n, c in getattr(comparison, "controllers", {}).items()}
    on = [n for n, v in integral.items() if v]
    lines.append("- Integral action (disturbance estimation, controllers.integral): "
                 + (", ".join(on) if on else "none") + ".")
    return lines + [""]


def _sensor_lines(sn, comparison) -> list:
    """What the rig measures, sensor by sensor, and what the estimators read of it."""
    if sn.encoder_counts:
        angle = f"hub angle by an encoder of {sn.encoder_counts} counts/rev (the filters count its quantisation " \
                "as angle noise)"
    elif sn.angle_noise:
        angle = f"hub angle by an absolute angle sensor, noise {sn.angle_noise:.3g} rad"
    else:
        angle = "hub angle exact"
    if sn.angle_bias:
        angle += f", bias {sn.angle_bias:.3g} rad"
    if not sn.rate:
        rate = "no hub-rate sensor (the estimators derive the rate)"
    else:
        parts = [f"noise {sn.rate_noise:.3g} rad/s"] if sn.rate_noise else ["exact"]
        if sn.rate_bias:
            parts.append(f"bias {sn.rate_bias:.3g} rad/s")
        if sn.rate_bias_walk:
            parts.append(f"bias drifting {sn.rate_bias_walk:.3g} rad/s/sqrt(s)")
        if sn.rate_bias or sn.rate_bias_walk:
            parts.append("the filters estimate the bias as a state")
        rate = "hub rate " + ", ".join(parts)
    gauges = ("strain gauges at " + ", ".join(f"{x:g} m" for x in sn.strain_gauges)
              + (f" (noise {sn.strain_noise:.3g} N m)" if sn.strain_noise else "")) if sn.strain_gauges \
        else "no strain gauge"
    accel = (f"a tip accelerometer (noise {sn.accel_noise:.3g} m/s^2)" if sn.tip_accelerometer
             else "no tip accelerometer")
    filt = f"; anti-alias filter at {sn.anti_alias_hz:g} Hz" if sn.anti_alias_hz else ""
    reads = sorted({tuple(s) for c in getattr(comparison, "controllers", {}).values()
                    if (s := getattr(c, "signals", None))})
    read = ("; the estimators (LQG, and the Kalman filter through which LQR and MPC run) read "
            + " / ".join(", ".join(r) for r in reads)) if reads else ""
    return [f"- Sensors: {angle}; {rate}; {gauges}; {accel}{filt}{read}."]
