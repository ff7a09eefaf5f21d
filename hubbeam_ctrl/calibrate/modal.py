"""Modal identification from records: frequencies, damping ratios and their uncertainty.

Free decay (:func:`identify_modes` with ``kind="free_decay"``): the record after its input
has gone to zero is the response of the linear(ised) system to an initial state, so its
samples are Markov parameters of ``(A, x0, C)`` and the Eigensystem Realization Algorithm
(ERA, Juang and Pappa 1985) applies directly: the block Hankel matrices ``H0``, ``H1`` of the
outputs, the SVD ``H0 = U S V'`` truncated to the model order, ``A = S^-1/2 U' H1 V S^-1/2``,
and the eigenvalues ``z`` of ``A`` give ``s = ln(z) / dt``, the frequency ``|s| / 2 pi`` and
the damping ratio ``-Re(s) / |s|``, in NumPy (``docs/calibration.md`` says why not a
package). Forced responses (``kind="forced"``): the system's Markov parameters (its pulse
response) are first estimated from input and output by observer/Kalman filter identification
(OKID, Juang, Phan, Horta and Longman 1993: a least-squares ARX model whose observer Markov
parameters give the system's), then ERA as above. OKID assumes a linear system: on a rig
with Coulomb friction or a gear whose efficiency switches with the power flow it is an
approximation (``docs/calibration.md``).

Uncertainty: the identification is repeated on :data:`N_WINDOWS` overlapping windows of the
record and at two model orders; each mode's estimate is the median over those runs and its
uncertainty their standard deviation (a spread, not a formal interval). Mode-shape signs:
the sign of each sensor's modal component relative to the first sensor's.

The hub of a geared servo with friction sticks when it stops (Karnopp), so a free decay
shows the modes of the beam on a held hub: compare with
:func:`~hubbeam_ctrl.calibrate.model.clamped_modes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.calibrate.records import SENSOR_COLUMNS, Record
from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["ModalEstimate", "identify_modes", "era", "okid_markov", "free_decay_start", "N_WINDOWS"]

#: Overlapping windows over which each identification is repeated (for the uncertainty).
N_WINDOWS = 5


@dataclass
class ModalEstimate:
    """Identified modes, ascending in frequency.

    Attributes
    ----------
    frequency_hz, frequency_std_hz : ndarray (n,)
        Undamped natural frequency [Hz] and its spread over windows and orders.
    damping, damping_std : ndarray (n,)
        Damping ratio [-] and its spread.
    shape_signs : dict
        Sensor -> ndarray (n,) of +1/-1: sign of the sensor's modal component relative to
        the first sensor's (empty with one sensor).
    sensors : tuple of str
    kind : str
        ``"free_decay"`` or ``"forced"``.
    t_start : float
        Start of the analysed part of the record [s].
    """

    frequency_hz: np.ndarray
    frequency_std_hz: np.ndarray
    damping: np.ndarray
    damping_std: np.ndarray
    shape_signs: dict
    sensors: tuple
    kind: str
    t_start: float

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {"kind": self.kind, "sensors": list(self.sensors), "t_start_s": self.t_start,
                "modes": [{"mode": k + 1, "frequency_hz": float(f), "frequency_std_hz": float(fs),
                           "damping": float(z), "damping_std": float(zs),
                           "shape_signs": {s: int(v[k]) for s, v in self.shape_signs.items()}}
                          for k, (f, fs, z, zs) in enumerate(zip(self.frequency_hz, self.frequency_std_hz,
                                                                 self.damping, self.damping_std))]}


def era(markov, dt: float, order: int, rows: int | None = None):
    """Eigensystem Realization Algorithm on output samples or Markov parameters.

    Parameters
    ----------
    markov : ndarray (N, ny)
        Free-decay outputs (or impulse response) at uniform samples.
    dt : float
        Sample period [s].
    order : int
        Model order (twice the number of modes wanted, or more).
    rows : int, optional
        Block rows of the Hankel matrix (default ``N // 3``).

    Returns
    -------
    (ndarray, ndarray, ndarray)
        Continuous-time eigenvalues ``s`` [1/s] (one per conjugate pair, ``Im s > 0``),
        their modal output components ``(ny, n)`` and each mode's output amplitude.
    """
    y = np.asarray(markov, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_t, ny = y.shape
    rows = rows or min(max(order, n_t // 3), max(order, 100 // ny))
    cols = min(n_t - rows - 1, 3000)
    if cols < order:
        raise ParameterError(f"ERA: {n_t} samples are too few for model order {order}")
    idx = np.arange(rows)[:, None] + np.arange(cols)[None, :]
    H0 = y[idx].transpose(0, 2, 1).reshape(rows * ny, cols)
    H1 = y[idx + 1].transpose(0, 2, 1).reshape(rows * ny, cols)
    # the leading singular triplets from the small Gram matrix H0 H0' (rows << cols)
    lam, U = np.linalg.eigh(H0 @ H0.T)
    top = np.argsort(lam)[::-1][:order]
    S = np.sqrt(np.maximum(lam[top], 1e-300))
    U = U[:, top]
    Vt = (U.T @ H0) / S[:, None]
    Sh = 1.0 / np.sqrt(S)
    A = (Sh[:, None] * (U.T @ H1 @ Vt.T)) * Sh[None, :]
    C = (U[:ny] * np.sqrt(S)[None, :])
    x0 = (np.sqrt(S)[:, None] * Vt)[:, 0]
    z, W = np.linalg.eig(A)
    keep = z.imag > 1e-12
    z, W = z[keep], W[:, keep]
    s = np.log(z) / dt
    phi = C @ W
    amp = np.abs(np.linalg.solve(np.linalg.eig(A)[1], x0)[keep]) * np.linalg.norm(phi, axis=0)
    return s, phi, amp


def okid_markov(u, y, observer_order: int, n_markov: int) -> np.ndarray:
    """System Markov parameters (pulse response) from input and output by OKID.

    The ARX model ``y(k) = D u(k) + sum_{i=1..p} Ybar_i [u(k-i); y(k-i)]`` is fitted by least
    squares; its observer Markov parameters ``Ybar_i = [Ybar_i_u, Ybar_i_y]`` give the
    system's, ``Y_0 = D``, ``Y_k = Ybar_k_u + sum_{i=1..min(k, p)} Ybar_i_y Y_{k-i}``.

    Parameters
    ----------
    u : ndarray (N,)
        Input (one channel).
    y : ndarray (N, ny)
        Outputs.
    observer_order : int
        ``p``, the ARX order.
    n_markov : int
        Markov parameters returned.

    Returns
    -------
    ndarray (n_markov, ny)
        ``Y_1 .. Y_n_markov``: the output ``k`` samples after a unit pulse of the input.
    """
    u = np.asarray(u, dtype=float).reshape(-1, 1)
    y = np.asarray(y, dtype=float)
    n_t, ny = y.shape
    p = int(observer_order)
    if n_t < 4 * p * (1 + ny):
        raise ParameterError(f"OKID: {n_t} samples are too few for observer order {p}")
    v = np.hstack([u, y])
    Phi = np.hstack([u[p:]] + [v[p - i:n_t - i] for i in range(1, p + 1)])
    theta = np.linalg.lstsq(Phi, y[p:], rcond=None)[0].T
    blocks = [theta[:, 1 + (i - 1) * (1 + ny):1 + i * (1 + ny)] for i in range(1, p + 1)]
    Y = [theta[:, :1]]
    for k in range(1, n_markov + 1):
        yk = blocks[k - 1][:, :1].copy() if k <= p else np.zeros((ny, 1))
        for i in range(1, min(k, p) + 1):
            yk = yk + blocks[i - 1][:, 1:] @ Y[k - i]
        Y.append(yk)
    return np.array(Y[1:])[:, :, 0]


def free_decay_start(record: Record, settle: float = 0.05) -> float:
    """Time after which the input stays at zero (plus ``settle`` [s]) [s].

    Parameters
    ----------
    record : Record
    settle : float
        Time skipped after the input's last non-zero sample [s].

    Returns
    -------
    float
    """
    u = record.input
    tol = 1e-9 * max(1.0, float(np.max(np.abs(u))))
    nz = np.nonzero(np.abs(u) > tol)[0]
    if nz.size == 0:
        return float(record.t[0])
    k = int(nz[-1]) + 1
    if k >= len(record.t) - 1:
        raise ParameterError(f"record {record.source}: the input never returns to zero: no free decay "
                             "(use kind='forced')")
    return float(record.t[k] + settle)


def _decimation(dt: float, max_hz: float) -> int:
    return max(1, int(math.floor(1.0 / (dt * 12.0 * max_hz))))


def _one_run(y, dt, order, n_modes, band, max_damping=0.2):
    s, phi, amp = era(y, dt, order)
    f = np.abs(s) / (2 * np.pi)
    z = -s.real / np.abs(s)
    ok = (f >= band[0]) & (f <= band[1]) & (z > 0) & (z < max_damping)
    idx = np.nonzero(ok)[0]
    idx = idx[np.argsort(-amp[idx])][:n_modes]
    idx = idx[np.argsort(f[idx])]
    return f[idx], z[idx], phi[:, idx]


def identify_modes(record: Record, sensors=None, *, n_modes: int = 2, kind: str = "free_decay",
                   band_hz=(0.1, None), t_start: float | None = None, order: int | None = None,
                   observer_horizon: float = 0.16) -> ModalEstimate:
    """Frequencies and damping ratios of the first modes from a record (see the module docstring).

    Parameters
    ----------
    record : Record
    sensors : sequence of str, optional
        Sensors to use (default the record's oscillating ones: ``root_moment``, ``v_tip``,
        ``tip_accel``).
    n_modes : int
        Modes wanted, 1..10.
    kind : {"free_decay", "forced"}
        ``free_decay``: the part of the record after the input has gone to zero;
        ``forced``: the whole record, input and output (OKID, then ERA).
    band_hz : (float, float or None)
        Frequencies considered [Hz] (None: up to a quarter of the sampling rate).
    t_start : float, optional
        Start of a free decay [s] (default :func:`free_decay_start`).
    order : int, optional
        Model order (default ``4 n_modes + 4``).
    observer_horizon : float
        ``forced``: the ARX model's memory [s] (its order is this over the sample period);
        repeated at 1.5 times it for the spread.

    Returns
    -------
    ModalEstimate

    Raises
    ------
    ParameterError
        Too short a record, no usable sensor, fewer modes found than asked.
    """
    if not isinstance(n_modes, int) or not 1 <= n_modes <= 10:
        raise ParameterError(f"n_modes must be an integer in 1..10, got {n_modes!r}")
    if kind not in ("free_decay", "forced"):
        raise ParameterError(f"kind must be 'free_decay' or 'forced', got {kind!r}")
    record = record.resampled()
    if sensors is None:
        sensors = tuple(s for s in ("root_moment", "v_tip", "tip_accel") if s in record.columns)
    sensors = tuple(sensors)
    for s in sensors:
        if s not in SENSOR_COLUMNS or s not in record.columns:
            raise ParameterError(f"sensor {str(s)[:40]!r}: record {record.source} has no such column; it holds "
                                 f"{', '.join(record.sensors) or 'no sensor'}")
    if not sensors:
        raise ParameterError(f"record {record.source}: no sensor that shows the beam's modes (root_moment, "
                             "v_tip, tip_accel)")
    dt = record.dt
    hi = band_hz[1] if band_hz[1] is not None else 0.25 / dt
    band = (float(band_hz[0]), float(hi))
    if kind == "forced":
        record.check_input_varies()
        t0, part = float(record.t[0]), record
    else:
        t0 = free_decay_start(record) if t_start is None else float(t_start)
        part = record.window(t0)
    order = order or 4 * n_modes + 4
    dec = _decimation(dt, band[1])
    y = np.column_stack([part.columns[s] for s in sensors])
    u = part.input
    # anti-alias before decimating: average over each block of dec samples
    if dec > 1:
        n_b = len(y) // dec
        y = y[:n_b * dec].reshape(n_b, dec, -1).mean(axis=1)
        u = u[:n_b * dec].reshape(n_b, dec).mean(axis=1)
    ddt = dt * dec
    # no detrending: an offset is a real pole of its own (left out); a median would bias slow modes
    scale = np.std(y, axis=0)
    scale[scale == 0] = 1.0
    y = y / scale
    n = len(y)
    if n < 6 * order:
        raise ParameterError(f"record {record.source}: {part.duration:.3g} s of "
                             f"{'free decay' if kind == 'free_decay' else 'record'} ({n} samples at "
                             f"{1 / ddt:.4g} Hz) are too few for {n_modes} modes")
    runs = []
    if kind == "forced":
        y = y - y.mean(axis=0)
        u = (u - u.mean()) / max(float(np.std(u)), 1e-300)
        p0 = max(4, int(round(observer_horizon / ddt)))
        data = [okid_markov(u, y, p, min(n // 4, max(8 * p, 6 * order))) for p in (p0, int(1.5 * p0))]
    else:
        length = int(0.7 * n)
        data = [y[k0:k0 + length] for k0 in np.linspace(0, n - length, N_WINDOWS).astype(int)]
    for markov in data:
        for o in (order, order + 4):
            # a forced servo's first mode can be heavily damped by the drive (0.36 on the servo link)
            f, z, phi = _one_run(markov, ddt, o, n_modes, band, 0.7 if kind == "forced" else 0.2)
            if len(f) == n_modes:
                runs.append((f, z, phi))
    if not runs:
        raise ParameterError(f"record {record.source}: fewer than {n_modes} modes found in "
                             f"{band[0]:g}..{band[1]:g} Hz")
    F = np.array([r[0] for r in runs])
    Z = np.array([r[1] for r in runs])
    ref = np.median(F, axis=0)
    good = np.all(np.abs(F / ref - 1) < 0.05, axis=1)
    F, Z = F[good], Z[good]
    phis = [r[2] for r, g in zip(runs, good) if g]
    signs = {}
    if len(sensors) > 1:
        phi = phis[0]
        rel = np.real(phi / phi[0:1])
        signs = {s: np.sign(rel[j]).astype(int) for j, s in enumerate(sensors)}
    return ModalEstimate(np.median(F, axis=0), F.std(axis=0), np.median(Z, axis=0), Z.std(axis=0), signs,
                         sensors, kind, t0)
