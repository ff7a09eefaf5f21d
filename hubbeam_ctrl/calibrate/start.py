"""A start for the time-domain fit from the records' frequency responses.

A least-squares fit of simulated against measured time series has local minima wherever
the model's oscillation slips a period against the measured one: from a start 1.5x off in
E the fit of the tests' steel link "converged" to E +270 %. The frequency response does not
slip: where its resonances and anti-resonances lie is a smooth function of the parameters.

:func:`measured_response` estimates each sensor's response to the input (H1:
``S_uy / S_uu``, Welch) at the frequencies of the excited band where the coherence is
above 0.9; :func:`model_response` is the guessed rig's, from FOAM linearised at rest with
the hub free (:func:`~hubbeam_ctrl.plant.linearization.second_order_linearization`), the
drive's gain and back-EMF damping (:func:`~hubbeam_ctrl.calibrate.model.hub_damping`) and
at least :data:`FLOOR_DAMPING` structural damping (Coulomb friction is left out: it has no
linearisation at rest). :func:`frequency_start` fits the fields that change the linear
model to the log-magnitude of the measured responses: candidates spread over a factor
:data:`START_SPREAD` either way of the start (a fixed low-discrepancy set), then a
trust-region refinement from the best few. Each evaluation is a linearisation and a
batched solve: a few ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.calibrate.model import hub_damping, set_fields
from hubbeam_ctrl.calibrate.records import Record
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.rig import Rig

__all__ = ["FLOOR_DAMPING", "START_SPREAD", "FrequencyStart", "measured_response", "model_response",
           "frequency_start"]

#: Structural damping ratio the linear model carries at least (an undamped resonance has no finite level).
FLOOR_DAMPING = 0.005
#: The candidates of :func:`frequency_start` span this factor either way of the start.
START_SPREAD = 2.5
_CANDIDATES = 256
_COHERENCE = 0.9


def measured_response(record: Record, sensors, band_hz) -> dict:
    """H1 estimates of each sensor's response to the input, in the band where they are coherent.

    Parameters
    ----------
    record : Record
        Uniform in time.
    sensors : sequence of str
    band_hz : (float, float)
        The excited band [Hz].

    Returns
    -------
    dict
        Sensor -> ``(f [Hz], H [sensor unit per input unit], complex)``; sensors with fewer
        than 4 coherent frequencies are left out.
    """
    from scipy.signal import coherence, csd, welch
    u = record.input - np.mean(record.input)
    nperseg = int(min(len(u), 2 ** int(math.log2(max(len(u) // 4, 64)))))
    fs = 1.0 / record.dt
    f, puu = welch(u, fs=fs, nperseg=nperseg)
    out = {}
    for s in sensors:
        y = record.columns[s] - np.mean(record.columns[s])
        _, puy = csd(u, y, fs=fs, nperseg=nperseg)
        _, coh = coherence(u, y, fs=fs, nperseg=nperseg)
        keep = (f >= band_hz[0]) & (f <= band_hz[1]) & (coh >= _COHERENCE) & (puu > 0)
        if keep.sum() >= 4:
            out[s] = (f[keep], puy[keep] / puu[keep])
    return out


def model_response(rig: Rig, freqs, sensors, n_modes: int, damping: float = FLOOR_DAMPING) -> dict:
    """The rig's linear response of each sensor to its input at rest, hub free.

    Parameters
    ----------
    rig : Rig
    freqs : array_like (K,)
        Frequencies [Hz].
    sensors : sequence of str
        Any of ``theta``, ``theta_dot``, ``v_tip``, ``root_moment``, ``tip_accel``.
    n_modes : int
        Bending modes of the model.
    damping : float
        Structural damping ratio added to the model's own [-].

    Returns
    -------
    dict
        Sensor -> complex ndarray (K,) [sensor unit per N m, or per V for a DC motor].
    """
    from hubbeam_ctrl.plant.linearization import second_order_linearization
    from hubbeam_ctrl.plant.sensors import sensor_matrix
    p = rig.plant_params.replace(n_transverse=n_modes, n_axial=2)
    model = build_model("foam", p)
    lin = second_order_linearization(model, 0.0, "free")
    G = np.array(lin.G, dtype=float)
    G[0, 0] += hub_damping(rig)
    d = rig.drive
    gain = 1.0 if d.is_ideal else d.eta_forward * d.N * d.k_t / d.R
    K = np.array(lin.K, dtype=complex) * (1.0 + 2j * damping)
    w = 2 * np.pi * np.asarray(freqs, dtype=float)
    Z = -w[:, None, None] ** 2 * lin.M[None] + 1j * w[:, None, None] * G[None] + K[None]
    q = np.linalg.solve(Z, np.broadcast_to(gain * np.asarray(lin.B, dtype=float), (w.size, lin.M.shape[0]))[..., None])
    q = q[..., 0]
    theta = q[:, 0]
    v_tip = q[:, model.transverse_slice] @ model.basis.f2_tip
    arm = p.r + (p.L if p.l is None else p.l)
    rows = {"theta": theta, "theta_dot": 1j * w * theta, "v_tip": v_tip, "tip_accel": -w ** 2 * (arm * theta + v_tip)}
    if "root_moment" in sensors:
        rows["root_moment"] = q @ sensor_matrix(p, n_modes, 2)[2, :model.n_q]
    return {s: rows[s] for s in sensors}


@dataclass(frozen=True)
class FrequencyStart:
    """The start :func:`frequency_start` found.

    Attributes
    ----------
    values : ndarray (p,)
        Every fitted field [its unit] (those the linear model does not see: their start).
    varied : tuple of str
        The fields it moved.
    misfit : float
        RMS log-magnitude error of the responses at the start found [-] (natural log).
    misfit_start : float
        ... and at the caller's start.
    points : int
        Frequencies fitted (all records and sensors).
    """

    values: np.ndarray
    varied: tuple
    misfit: float
    misfit_start: float
    points: int


def frequency_start(rig: Rig, records, used, fit_fields, start, lo, hi, band_hz, n_modes: int):
    """Fit the fields the linear model sees to the records' frequency responses (module docstring).

    Parameters
    ----------
    rig : Rig
        The guess.
    records : sequence of Record
    used : sequence of tuple of str
        The sensors of each record.
    fit_fields : sequence of FitField
    start, lo, hi : ndarray (p,)
        The start and bounds of each field [its unit].
    band_hz : (float, float)
    n_modes : int

    Returns
    -------
    FrequencyStart or None
        None when no sensor is coherent with the input or no fitted field changes the
        linear model.
    """
    from scipy.optimize import least_squares
    from scipy.stats import qmc

    measured = []
    for r, ss in zip(records, used):
        for s, (f, h) in measured_response(r, ss, band_hz).items():
            measured.append((s, f, np.log(np.abs(h))))
    if not measured:
        return None
    freqs = np.unique(np.concatenate([f for _, f, _ in measured]))
    sensors = tuple(sorted({s for s, _, _ in measured}))
    idx = [np.searchsorted(freqs, f) for _, f, _ in measured]
    points = sum(len(f) for _, f, _ in measured)

    def residual(values, zeta=FLOOR_DAMPING):
        try:
            h = model_response(set_fields(rig, fit_fields, values), freqs, sensors, n_modes, zeta)
        except (HubbeamError, ParameterError, np.linalg.LinAlgError):
            return np.full(points, 10.0)
        parts = [np.log(np.abs(h[s][k]) + 1e-300) - m for (s, _, m), k in zip(measured, idx)]
        out = np.concatenate(parts)
        return np.where(np.isfinite(out), out, 10.0)

    base = residual(start)
    sees = [k for k, f in enumerate(fit_fields) if f.key not in ("coulomb",) and start[k] > 0]
    varied = []
    for k in sees:
        trial = start.copy()
        trial[k] = min(start[k] * 1.01, hi[k]) if start[k] * 1.01 <= hi[k] else start[k] * 0.99
        if np.max(np.abs(residual(trial) - base)) > 1e-6:
            varied.append(k)
    if not varied:
        return None
    log_lo = np.maximum(np.log(start[varied]) - math.log(START_SPREAD),
                        np.log(np.maximum(lo[varied], 1e-300)))
    log_hi = np.minimum(np.log(start[varied]) + math.log(START_SPREAD), np.log(hi[varied]))
    pts = qmc.Sobol(len(varied), scramble=False).random(_CANDIDATES)
    cands = [np.log(start[varied])] + [log_lo + (log_hi - log_lo) * u for u in pts]

    def full(z):
        v = start.copy()
        v[varied] = np.exp(z[:len(varied)])
        return v

    costs = [float(np.sum(residual(full(z)) ** 2)) for z in cands]
    best = None
    # the refinement also fits the structural damping: the window of the spectral estimate
    # smears an undamped resonance, and a damping held fixed would shift the fields instead
    z_lo, z_hi = np.append(log_lo - 1.0, math.log(1e-4)), np.append(log_hi + 1.0, math.log(0.2))
    for j in np.argsort(costs)[:3]:
        sol = least_squares(lambda z: residual(full(z), math.exp(z[-1])), np.append(cands[j], math.log(FLOOR_DAMPING)),
                            bounds=(z_lo, z_hi), method="trf", max_nfev=80, diff_step=1e-4)
        if best is None or sol.cost < best.cost:
            best = sol
    return FrequencyStart(full(best.x), tuple(fit_fields[k].name for k in varied),
                          float(np.sqrt(2 * best.cost / points)), float(np.sqrt(np.mean(base ** 2))), points)
