"""Excitation signals for a calibration: chirp, PRBS, multisine and step, within limits.

:func:`excitation` makes an input record (``t [s]`` and ``V [V]`` for a DC-motor rig,
``tau [N m]`` for the torque drive) whose band runs from ``0.2 x`` the first clamped bending
mode to ``1.5 x`` the highest mode to identify (:func:`~hubbeam_ctrl.calibrate.model.clamped_modes`),
whose amplitude is within the drive's limit (``V_max``, or ``tau_max`` of the beam) and
whose predicted response, simulated on the rig's model with its hardware, keeps the tip
deflection and the hub travel within the caller's limits: the amplitude is scaled down
until both hold. Each signal starts and ends at zero (tapered), so the rig starts at rest
and ends in a free decay.
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.calibrate.model import ModelSettings, clamped_modes, simulate_sensors
from hubbeam_ctrl.calibrate.records import Record
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_in_range, check_integer, check_positive
from hubbeam_ctrl.linear.statespace import DT_RANGE
from hubbeam_ctrl.plant.params import MAX_MODES
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["excitation", "EXCITATION_KINDS", "excitation_band", "DEFAULT_TIP_FRACTION"]

#: The signal kinds of :func:`excitation`.
EXCITATION_KINDS = ("chirp", "prbs", "multisine", "step")

#: Most samples of an excitation record (ten million: an hour at 0.36 ms; the record and its
#: predicted response are simulated).
MAX_SAMPLES = 10_000_000
#: Largest ``max_hub_travel`` [rad] (a limit past it never binds).
MAX_HUB_TRAVEL = 1e6
#: Default bound on the excitation's predicted tip deflection, as a fraction of L. The fitted models
#: are first order in the deflection: their geometric error grows with its square, and on a long
#: record a small frequency error becomes a large phase error. Measured on records of the exact beam
#: (``benchmarks/bench_calibrate_exact.py``, a 10 s chirp, defaults otherwise): the 3 m steel link's
#: J_h comes out +3.7 % at 0.1 L, +0.93 % at 0.05 L and +0.22 % at 0.02 L (E +0.84 / +0.13 / -0.053 %);
#: the 1 m lab arm's +0.82 / +0.3 / +0.057 %.
DEFAULT_TIP_FRACTION = 0.05


def excitation_band(rig: Rig, n_modes: int = 2) -> tuple:
    """``(0.2 f_1, 1.5 f_n)`` [Hz] from the rig's clamped bending modes.

    Parameters
    ----------
    rig : Rig
    n_modes : int
        Highest mode to identify.

    Returns
    -------
    (float, float)
    """
    f, _ = clamped_modes(rig, n_modes)
    return 0.2 * float(f[0]), 1.5 * float(f[-1])


def _taper(t, duration, ramp):
    w = np.ones_like(t)
    a = t < ramp
    w[a] = 0.5 * (1 - np.cos(np.pi * t[a] / ramp))
    b = t > duration - ramp
    w[b] = 0.5 * (1 - np.cos(np.pi * (duration - t[b]) / ramp))
    return w


def _shape(kind, t, duration, band, rng):
    f0, f1 = band
    if kind == "chirp":                         # logarithmic sweep: equal time per octave
        k = math.log(f1 / f0) / duration
        return np.sin(2 * np.pi * f0 * (np.exp(k * t) - 1) / k)
    if kind == "multisine":                     # Schroeder phases on the record's frequency grid
        df = 1.0 / duration
        freqs = np.arange(math.ceil(f0 / df), math.floor(f1 / df) + 1) * df
        if freqs.size == 0:
            freqs = np.array([f0])
        n = freqs.size
        phases = -np.pi * np.arange(1, n + 1) * np.arange(n) / n
        s = np.sin(2 * np.pi * freqs[None, :] * t[:, None] + phases[None, :]).sum(axis=1)
        return s / np.max(np.abs(s))
    if kind == "prbs":                          # random binary, clock 2.5 f1: flat to about f1
        clock = 1.0 / (2.5 * f1)
        n = int(math.ceil(duration / clock)) + 1
        bits = rng.choice([-1.0, 1.0], size=n)
        return bits[np.minimum((t / clock).astype(int), n - 1)]
    # step: up for a third of the record, then zero (a free decay)
    return np.where(t < duration / 3, 1.0, 0.0)


def _check_limit(name: str, value, unit: str, hi: float, what: str) -> float:
    """``value`` checked > 0 (:func:`check_positive`) and at most ``hi`` (``what``, for the message)."""
    value = check_positive(name, value, unit)
    if value > hi:
        raise ParameterError(f"{name} must be in (0, {hi:g}] [{unit}] (at most {what}), got {value:g}")
    return value


def excitation(rig: Rig, kind: str = "chirp", duration: float = 10.0, *, dt: float | None = None,
               amplitude: float | None = None, band_hz=None, n_modes: int | None = None,
               max_tip_deflection: float | None = None, max_hub_travel: float | None = None,
               seed: int = 0, settings: ModelSettings | None = None) -> Record:
    """An input record for identification (see the module docstring).

    Parameters
    ----------
    rig : Rig
    kind : {"chirp", "prbs", "multisine", "step"}
    duration : float
        Record length [s], > 0.
    dt : float, optional
        Sample period [s] (default the rig's ``timing.dt``, else 1 ms).
    amplitude : float, optional
        Largest command [V or N m] before the response limits (default the drive's limit:
        ``V_max`` or ``tau_max``); at most that limit.
    band_hz : (float, float), optional
        Band [Hz] (default :func:`excitation_band`).
    n_modes : int, optional
        Modes to identify (sets the default band). Default: the rig's first 2, or the first alone
        when the second's band (1.5 f_2) is past the Nyquist frequency of ``dt`` (the record says so
        in its ``source``).
    max_tip_deflection : float, optional
        Largest predicted tip deflection [m] (default :data:`DEFAULT_TIP_FRACTION` L).
    max_hub_travel : float, optional
        Largest predicted hub angle from the start [rad] (default pi).
    seed : int
        PRBS seed.
    settings : ModelSettings, optional

    Returns
    -------
    Record
        ``t`` and the input, plus the predicted ``theta`` and ``v_tip``.
    """
    if kind not in EXCITATION_KINDS:
        raise ParameterError(f"kind must be one of {', '.join(EXCITATION_KINDS)}, got {kind!r}")
    duration = check_in_range("duration", duration, "s", 1e-3, 3600.0)
    dt = check_in_range("dt", dt if dt is not None else (rig.timing.dt or 1e-3), "s", *DT_RANGE)
    if duration / dt > MAX_SAMPLES:
        raise ParameterError(f"dt = {dt:g} s over duration = {duration:g} s makes {duration / dt:.3g} samples, "
                             f"at most {MAX_SAMPLES:.0e} (a longer dt or a shorter duration)")
    default_modes = n_modes is None
    n_modes = 2 if default_modes else check_integer("n_modes", n_modes, 1, MAX_MODES)
    seed = check_integer("seed", seed, 0, 2 ** 63 - 1)
    limit = rig.drive.V_max if not rig.drive.is_ideal else rig.beam.tau_max
    unit = "V" if not rig.drive.is_ideal else "N m"
    given = amplitude is not None
    if amplitude is None:
        amplitude = limit
    amplitude = check_in_range("amplitude", amplitude, unit, 0.0, limit, "within the drive's limit")
    if amplitude == 0:
        raise ParameterError(f"amplitude must be > 0 [{unit}], got 0")
    tip = DEFAULT_TIP_FRACTION * rig.beam.L if max_tip_deflection is None else _check_limit(
        "max_tip_deflection", max_tip_deflection, "m", rig.beam.L, "the beam length L")
    travel = math.pi if max_hub_travel is None else _check_limit("max_hub_travel", max_hub_travel, "rad",
                                                                 MAX_HUB_TRAVEL, "1e6 rad, far past any rig")
    band = excitation_band(rig, n_modes) if band_hz is None else tuple(float(b) for b in band_hz)
    fewer = ""
    while band_hz is None and default_modes and n_modes > 1 and band[1] >= 0.5 / dt:
        # found on a random rig (a 0.49 m aluminium strip sampled at 10 ms: mode 2 at 76 Hz): the default refused
        n_modes -= 1
        band = excitation_band(rig, n_modes)
        fewer = f" of the rig's first {n_modes} bending mode{'s' if n_modes > 1 else ''} (the next is past Nyquist)"
    if len(band) != 2 or not (0 < band[0] < band[1]) or not all(map(math.isfinite, band)):
        raise ParameterError(f"band_hz must be (lo, hi) with 0 < lo < hi [Hz], got {band_hz!r}")
    if band[1] >= 0.5 / dt:
        if band_hz is None:                # the default: the rig's modes, not a band the caller gave
            what = "first bending mode" if n_modes == 1 else f"first {n_modes} bending modes"
            hint = "a shorter --dt" if n_modes == 1 else "fewer modes, --modes"
            raise ParameterError(f"the default band of the rig's {what} reaches {band[1]:g} Hz, past the Nyquist "
                                 f"frequency {0.5 / dt:g} Hz of dt = {dt:g} s (check the rig's beam; or give a band, "
                                 f"--band, or {hint})")
        raise ParameterError(f"band_hz upper end {band[1]:g} Hz must be below the Nyquist frequency "
                             f"{0.5 / dt:g} Hz of dt = {dt:g} s")
    if duration < 2.0 / band[0] and kind != "step":
        raise ParameterError(f"duration must be >= {2.0 / band[0]:.4g} s (two periods of the band's lowest "
                             f"frequency {band[0]:.4g} Hz), got {duration:g}")
    t = dt * np.arange(int(round(duration / dt)) + 1)
    rng = np.random.default_rng(seed)
    shape = _shape(kind, t, duration, band, rng)
    if kind != "step":
        shape = shape * _taper(t, duration, min(0.1 * duration, 2.0 / band[0]))
    else:
        shape[0] = 0.0
    inp = "V" if not rig.drive.is_ideal else "tau"
    # a probe at 2 % of the amplitude, scaled (as if linear) to the limits: the start of the search
    y = simulate_sensors(rig, t, 0.02 * amplitude * shape, ("theta", "v_tip"), settings)
    ratio = max(float(np.max(np.abs(y["v_tip"]))) / tip, float(np.max(np.abs(y["theta"]))) / travel)
    a = amplitude if ratio <= 0 else min(amplitude, 0.02 * amplitude / ratio)
    binding = "hub"
    for _ in range(12):
        try:
            y = simulate_sensors(rig, t, a * shape, ("theta", "v_tip"), settings)
        except HubbeamError:           # far beyond the limits: the plant step failed; much less
            a = 0.25 * a
            continue
        peak_tip, peak_hub = float(np.max(np.abs(y["v_tip"]))), float(np.max(np.abs(y["theta"])))
        ratio = max(peak_tip / tip, peak_hub / travel)
        if ratio <= 1.0:
            break
        binding = "hub" if peak_hub / travel >= peak_tip / tip else "tip"
        a = a * 0.95 / ratio
    else:
        raise ParameterError(f"no amplitude keeps the tip within {tip:g} m and the hub within {travel:g} rad")
    # a record whose hub motion the angle sensor cannot see identifies nothing
    resolution = max(2.0 * rig.sensors.encoder_step, 2.0 * rig.sensors.angle_noise)
    if peak_hub <= resolution:
        seen = (f"2 counts of the encoder ({resolution:.3g} rad)" if rig.sensors.encoder_step >= rig.sensors.angle_noise
                else f"2 standard deviations of the angle sensor's noise ({resolution:.3g} rad)")
        if a < amplitude:            # the limits on the motion brought the amplitude down
            first = (f"max_hub_travel = {travel:g} rad" if binding == "hub"
                     else f"max_tip_deflection = {tip:g} m")
            raise ParameterError(f"{first} brings the amplitude down to {a:.3g} {unit} (from {amplitude:g} "
                                 f"{unit}, --amplitude), which moves the hub at most {peak_hub:.3g} rad (friction may "
                                 f"hold it), not more than {seen}: the record would show nothing to fit; allow "
                                 f"more motion (--max-hub, --max-tip) or excite another kind")
        if not given:                      # the drive's whole range: the rig cannot move its hub
            raise ParameterError(f"the drive's full amplitude {amplitude:.3g} {unit} moves the hub at most "
                                 f"{peak_hub:.3g} rad, not more than {seen}: the record would show nothing to fit "
                                 f"(check the rig's beam and drive)")
        raise ParameterError(f"amplitude = {amplitude:.3g} {unit} moves the hub at most {peak_hub:.3g} rad, not more "
                             f"than {seen}: the record would show nothing to fit; give a larger amplitude "
                             f"(at most {limit:g} {unit})")
    return Record(t=t, columns={inp: a * shape, "theta": y["theta"], "v_tip": y["v_tip"]},
                  source=f"{kind} excitation{fewer}")
