"""The design of a fit from its records: the excited band, the plant's modes, the noise floor.

:func:`excited_band` reads the band a record's input excites from its spectrum: the
frequencies where the input's power per octave (``f S_uu(f)``, Welch) is within
:data:`BAND_DB` dB of its peak. :func:`record_design` turns the band into the fitted plant's
bending modes by the evaluation plant's rule
(:func:`~hubbeam_ctrl.sim.evaluation.modes_to_cover`: every free-hub mode of the guessed
beam below the band's top, plus the first above it) and names the modes whose frequency lies
inside the band: those the records can identify.

:func:`noise_level` estimates a sensor's noise standard deviation from its spectrum above
the band (the median of the Welch power density there, where the response has little left
but noise), at least an encoder's quantisation ``q / sqrt(12)`` (:func:`quantum`);
:func:`fit_ceiling` turns it into the highest fit percentage
(:func:`~hubbeam_ctrl.calibrate.fit.fit_percent`) a perfect model can reach on that series,
``100 (1 - sigma sqrt(N) / ||y - mean(y)||)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.calibrate.records import Record
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.sim.evaluation import modes_to_cover

__all__ = ["BAND_DB", "SHOW_DB", "quantum", "RecordDesign", "excited_band", "noise_level", "fit_ceiling",
           "record_design"]

#: The excited band starts where the input's power per octave is within this many dB of its peak.
BAND_DB = 20.0
#: ... and ends where no sensor's power density stands this many dB above its noise floor.
SHOW_DB = 10.0


def _welch(y, dt, x=None, segments: int = 8):
    from scipy.signal import csd, welch
    n = len(y)
    nperseg = int(min(n, max(64, 2 ** int(math.log2(max(n // segments, 64))))))
    if x is None:
        return welch(y - np.mean(y), fs=1.0 / dt, nperseg=nperseg)
    return csd(x - np.mean(x), y - np.mean(y), fs=1.0 / dt, nperseg=nperseg)


def excited_band(record: Record, sensors=None) -> tuple:
    """``(lo, hi)`` [Hz]: the band a record excites and shows.

    ``lo``: the lowest frequency where the input's power per octave (``f S_uu``) is within
    :data:`BAND_DB` dB of its peak. ``hi``: the highest frequency where a sensor's power
    density stands :data:`SHOW_DB` dB above its white-noise floor (:func:`noise_level`): the
    response the record shows, whatever the input's shape (a PRBS's spectrum has side lobes
    far above its clock, a tapered chirp stops short of its nominal top).

    Parameters
    ----------
    record : Record
        Uniform in time.
    sensors : sequence of str, optional
        Default every sensor of the record.

    Returns
    -------
    (float, float)
    """
    f, p = _welch(record.input, record.dt, segments=4)
    octave = f * p
    keep = np.nonzero(octave >= octave.max() * 10 ** (-BAND_DB / 10))[0]
    lo, hi_input = max(float(f[keep[0]]), float(f[1])), float(f[keep[-1]])
    hi = 0.0
    for s in (record.sensors if sensors is None else sensors):
        fs, ps = _welch(record.columns[s], record.dt)
        floor = 2.0 * record.dt * noise_level(record.columns[s], record.dt, hi_input) ** 2
        shows = np.nonzero(ps > floor * 10 ** (SHOW_DB / 10))[0] if floor > 0 else np.nonzero(ps > 0)[0]
        if shows.size:
            hi = max(hi, float(fs[shows[-1]]))
    return lo, max(hi, lo)


def quantum(y) -> float:
    """The quantisation step of a series whose values all lie on a grid (an encoder), else 0.

    Parameters
    ----------
    y : array_like (N,)

    Returns
    -------
    float
        The grid's step [unit of y]: the smallest difference between two distinct values,
        when every difference is a whole multiple of it and the series takes fewer than
        ``N / 2`` distinct values; 0 otherwise.
    """
    v = np.unique(np.asarray(y, dtype=float))
    if v.size < 2 or v.size > 0.5 * np.size(y):
        return 0.0
    d = np.diff(v)
    q = float(d.min())
    k = d / q
    return q if np.all(np.abs(k - np.round(k)) < 1e-6 * max(1.0, float(k.max()))) else 0.0


def noise_level(y, dt: float, f_above: float) -> float:
    """Noise standard deviation of a sensor series: white noise from its spectrum above ``f_above``,
    at least the quantisation's.

    The one-sided Welch power density of white noise of standard deviation ``sigma`` is
    ``2 sigma^2 dt``; its median over the frequencies above ``f_above`` (at least the top
    half of the Nyquist band) is robust to the few resonances left there. An encoder's
    rounding error (step ``q``, :func:`quantum`) is not white where the angle moves slowly
    (it stays on one count), so the spectrum sees only part of it: the level is at least
    ``q / sqrt(12)``. Measured on the servo link's 6 s chirp (4096 counts): the spectrum
    alone gave 0.22 mrad, the residual of the true rig is 0.40 mrad, ``q / sqrt(12)`` is
    0.44 mrad.

    Parameters
    ----------
    y : array_like (N,)
    dt : float
        Sample period [s].
    f_above : float
        The top of the excited band [Hz].

    Returns
    -------
    float
        [the series' unit]; 0 for a series with no noise (it has no spectrum above the band).
    """
    y = np.asarray(y, dtype=float)
    f, p = _welch(y, dt)
    nyquist = 0.5 / dt
    lo = min(max(2.0 * f_above, 0.5 * nyquist), 0.9 * nyquist)
    band = p[(f >= lo) & (f < nyquist)]
    white = float(math.sqrt(max(float(np.median(band)), 0.0) / (2.0 * dt))) if band.size else 0.0
    return max(white, quantum(y) / math.sqrt(12.0))


def fit_ceiling(y, sigma: float) -> float:
    """The highest fit percentage a perfect model reaches on ``y`` with white noise ``sigma`` [%].

    Parameters
    ----------
    y : array_like (N,)
    sigma : float
        The noise's standard deviation [unit of y].

    Returns
    -------
    float
        ``100 (1 - sigma sqrt(N) / ||y - mean(y)||)``.
    """
    y = np.asarray(y, dtype=float)
    spread = float(np.linalg.norm(y - y.mean()))
    if spread == 0.0:
        return math.nan
    return 100.0 * (1.0 - sigma * math.sqrt(y.size) / spread)


@dataclass(frozen=True)
class RecordDesign:
    """What the records excite, and the fitted plant that follows from it.

    Attributes
    ----------
    band_hz : (float, float)
        The excited band of the records together [Hz] (:func:`excited_band`).
    plant_modes : int
        Bending modes of the fitted plant (the modes below the band's top and the first above).
    mode_hz : tuple of float
        The guessed rig's free-hub bending frequencies of those modes [Hz].
    identifiable : tuple of int
        The 1-based modes whose frequency lies inside the band.
    noise : dict
        Record source -> sensor -> noise standard deviation [sensor unit] (:func:`noise_level`).
    ceiling : dict
        Record source -> sensor -> fit ceiling [%] (:func:`fit_ceiling`).
    reason : str
        One sentence for reports.
    """

    band_hz: tuple
    plant_modes: int
    mode_hz: tuple
    identifiable: tuple
    noise: dict
    ceiling: dict
    reason: str

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"band_hz": list(self.band_hz), "plant_modes": self.plant_modes, "mode_hz": list(self.mode_hz),
                "identifiable_modes": list(self.identifiable), "noise": self.noise,
                "fit_ceiling_percent": self.ceiling, "reason": self.reason}


def record_design(rig: Rig, records, used) -> RecordDesign:
    """The excited band, the plant's modes and the noise floor of records (module docstring).

    Parameters
    ----------
    rig : Rig
        The guess.
    records : sequence of Record
        Uniform in time.
    used : sequence of tuple of str
        The sensors fitted on each record.

    Returns
    -------
    RecordDesign
    """
    if not records:
        raise ParameterError("records must hold at least one Record")
    bands = [excited_band(r, ss) for r, ss in zip(records, used)]
    lo, hi = min(b[0] for b in bands), max(b[1] for b in bands)
    nyquist = min(0.5 / r.dt for r in records)
    hi = min(hi, nyquist)
    n, below, f = modes_to_cover(rig.plant_params, hi)
    inside = tuple(int(k + 1) for k in range(below) if f[k] >= lo)
    noise, ceiling = {}, {}
    for k, (r, ss) in enumerate(zip(records, used)):
        src = r.source or f"record {k + 1}"
        noise[src] = {s: noise_level(r.columns[s], r.dt, hi) for s in ss}
        ceiling[src] = {s: fit_ceiling(r.columns[s], noise[src][s]) for s in ss}
    names = ", ".join(f"{m} ({f[m - 1]:.4g} Hz)" for m in inside) or "none"
    reason = (f"the records excite {lo:.3g}-{hi:.3g} Hz (from the input's power per octave within {BAND_DB:g} dB "
              f"of its peak to the sensors' power {SHOW_DB:g} dB above their noise): {below} free-hub bending "
              f"modes of the guess lie below {hi:.3g} Hz; the plant keeps them and the first above it: {n} modes. "
              f"Modes inside the band (identifiable): {names}")
    return RecordDesign((lo, hi), n, tuple(float(v) for v in f[:n]), inside, noise, ceiling, reason)
