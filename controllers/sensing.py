"""What a controller's estimator reads: the rig's own sensor set as linear output rows.

A rig measures the hub angle (an encoder or an absolute angle sensor such as a star tracker)
and any of: the hub rate (a tachometer or gyro, ``sensors.rate``), bending moments at strain
gauges anywhere on the beam (``sensors.strain_gauges``) and the tip's tangential
acceleration (``sensors.tip_accelerometer``). :class:`SensorLayout` names the signals an
estimator reads, in the closed loop's names (:func:`hubbeam_ctrl.plant.instruments.signal_names`),
and gives their rows on a linear SFOAM state ``x = [theta, q2, theta_dot, q2_dot]``:

* ``theta``, ``theta_dot``: the hub coordinates (deviation from the steady rotation);
* ``moment_i``: ``E I f2''(x_i) q2`` at gauge ``i`` (:func:`~hubbeam_ctrl.plant.instruments.moment_rows`);
* ``accel_tangential``: the second time derivative of the tip's inertial position, in hub
  axes, linearised about steady spin ``Omega``: ``(r + L) theta_ddot + v_tip_ddot - Omega^2 v_tip``
  (the linear part of the plant's accelerometer, :func:`~hubbeam_ctrl.plant.instruments.tip_acceleration`).
  The accelerations come from the model's own rows ``[theta_ddot; q2_ddot] = A_2 x + B_2 u``, so
  the accelerometer feeds the command through: its row has a ``D`` entry. It reads the
  acceleration of the command that acts at the sample instant, the previous one
  (the closed loop's convention, docs/rig.md).

The radial acceleration is left out: at rest its linear part is zero, so it observes nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.instruments import moment_rows

__all__ = ["SensorLayout", "DEFAULT_LAYOUT", "RIG_KEYS", "rig_key", "observability_defect", "with_anti_alias"]

#: The rig key that gives each signal (for messages that name what the user can change).
RIG_KEYS = {"theta": "sensors.encoder_counts / sensors.angle_noise (the hub angle)",
            "theta_dot": "sensors.rate (a tachometer or gyro)",
            "moment": "sensors.strain_gauges",
            "accel_tangential": "sensors.tip_accelerometer",
            "accel_radial": "sensors.tip_accelerometer"}


def rig_key(signal: str) -> str:
    """The rig key of a signal name (``moment_3`` -> ``sensors.strain_gauges``).

    Parameters
    ----------
    signal : str
        A measured signal: ``theta``, ``theta_dot``, ``moment_K``, ``accel_tangential``...

    Returns
    -------
    str
        The rig key and what it sets; an unknown name is returned as it is.
    """
    return RIG_KEYS.get(signal, RIG_KEYS["moment"] if signal.startswith("moment_") else signal)


@dataclass(frozen=True)
class SensorLayout:
    """The signals an estimator reads and where the strain gauges are.

    Attributes
    ----------
    signals : tuple of str
        Signal names in the order of the measurement vector: ``theta``, ``theta_dot``,
        ``moment_<i>`` (1-based gauge index), ``accel_tangential``.
    gauges : tuple of float
        Gauge positions from the root [m] (``moment_i`` reads ``gauges[i-1]``).
    anti_alias_hz : float or None
        Cutoff of the rig's first-order anti-alias filter [Hz] (``sensors.anti_alias_hz``);
        None: no filter.
    filtered : tuple of str
        The signals that pass through it (every analog one: not an encoder's count).
    """

    signals: tuple = ("theta", "theta_dot", "moment_1")
    gauges: tuple = (0.0,)
    anti_alias_hz: float | None = None
    filtered: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "signals", tuple(self.signals))
        object.__setattr__(self, "gauges", tuple(float(g) for g in self.gauges))
        object.__setattr__(self, "filtered", tuple(self.filtered) if self.anti_alias_hz is not None else ())
        if not self.signals:
            raise ParameterError("the rig's sensors must give at least the hub angle (sensors)")
        if not set(self.filtered) <= set(self.signals):
            raise ParameterError(f"filtered signals {self.filtered} must be among the signals {self.signals}")
        for s in self.signals:
            if s.startswith("moment_"):
                i = int(s[7:]) if s[7:].isdigit() else 0
                if not 1 <= i <= len(self.gauges):
                    raise ParameterError(f"signal {s!r} names a strain gauge the rig does not have "
                                         f"(sensors.strain_gauges has {len(self.gauges)})")
            elif s not in ("theta", "theta_dot", "accel_tangential"):
                raise ParameterError(f"an estimator cannot read signal {s!r}; it reads theta, theta_dot, "
                                     "moment_<i>, accel_tangential")

    @classmethod
    def from_rig(cls, sensors) -> "SensorLayout":
        """Every signal of a rig's :class:`~hubbeam_ctrl.plant.rig.Sensors` that an estimator uses.

        Parameters
        ----------
        sensors : hubbeam_ctrl.plant.rig.Sensors

        Returns
        -------
        SensorLayout
        """
        names = ["theta"]
        if getattr(sensors, "rate", True):
            names.append("theta_dot")
        names += [f"moment_{i + 1}" for i in range(len(sensors.strain_gauges))]
        if sensors.tip_accelerometer:
            names.append("accel_tangential")
        hz = getattr(sensors, "anti_alias_hz", None)
        counted = getattr(sensors, "encoder_counts", 0) > 0
        filtered = tuple(n for n in names if not (n == "theta" and counted)) if hz is not None else ()
        return cls(tuple(names), tuple(sensors.strain_gauges), hz, filtered)

    @property
    def is_default(self) -> bool:
        """Hub angle, hub rate and a root gauge: the beam alone's three sensors (unfiltered)."""
        return self.signals == DEFAULT_LAYOUT.signals and self.gauges[:1] == (0.0,) and not self.filtered

    def anti_alias_rows(self) -> list:
        """Indices of :attr:`signals` that pass through the anti-alias filter."""
        return [k for k, s in enumerate(self.signals) if s in self.filtered]

    @property
    def has_feedthrough(self) -> bool:
        """An accelerometer: the command reaches the measurement within the sample."""
        return "accel_tangential" in self.signals

    def kind(self, signal: str) -> str:
        """What a signal measures: ``angle``, ``rate``, ``moment`` or ``accel``.

        Parameters
        ----------
        signal : str
            One of :attr:`signals`.
        """
        return {"theta": "angle", "theta_dot": "rate", "accel_tangential": "accel"}.get(signal, "moment")

    def rows(self, A, B, params, spin: float = 0.0, C_tip=None) -> tuple:
        """Output rows ``y = C x + D u`` of the signals on a linear SFOAM.

        Parameters
        ----------
        A : ndarray (n, n)
            Continuous state matrix of ``x = [theta, q2, theta_dot, q2_dot]`` [1/s].
        B : ndarray (n, 1)
            Input matrix [per N m].
        params : Params
            The model's parameters (``EI``, ``L``, ``r``).
        spin : float
            Spin rate of the linearisation [rad/s].
        C_tip : ndarray (n,), optional
            Row of the tip deflection ``v_tip`` (default from the transverse shapes at ``L``).

        Returns
        -------
        C : ndarray (ny, n)
            In the signals' units per state unit.
        D : ndarray (ny, 1)
        """
        A = np.asarray(A, dtype=float)
        B = np.asarray(B, dtype=float).reshape(A.shape[0], 1)
        n = A.shape[0]
        h = n // 2
        C = np.zeros((len(self.signals), n))
        D = np.zeros((len(self.signals), 1))
        for k, s in enumerate(self.signals):
            if s == "theta":
                C[k, 0] = 1.0
            elif s == "theta_dot":
                C[k, h] = 1.0
            elif s.startswith("moment_"):
                C[k] = moment_rows(params, [self.gauges[int(s[7:]) - 1]], h - 1)[0]
            else:
                tip = _tip_row(params, h - 1) if C_tip is None else np.asarray(C_tip, dtype=float)[:h]
                arm = float(params.r + params.L)
                C[k] = arm * A[h] + tip[1:h] @ A[h + 1:]
                C[k, 1:h] -= spin ** 2 * tip[1:h]
                D[k, 0] = arm * B[h, 0] + tip[1:h] @ B[h + 1:, 0]
        return C, D


def with_anti_alias(A, B, C, layout, dt: float) -> tuple:
    """A sampled model ``z+ = A z + B u``, ``y = C z`` whose filtered signals are read through the
    rig's anti-alias filter, as the simulator's measurement chain does
    (:func:`hubbeam_ctrl.sim.measurement.anti_alias_coefficients`): one more state per filtered
    signal, ``f+ = decay f + b0 C_r (A z + B u) + b1 C_r z``, appended after ``z``; the filtered
    rows of the output read ``f``.

    Parameters
    ----------
    A : ndarray (n, n)
    B : ndarray (n, 1)
    C : ndarray (ny, n)
        The unfiltered signals' rows on ``z`` (any feedthrough carried as a state's row).
    layout : SensorLayout or None
        The signals and which are filtered (None or none filtered: the model itself).
    dt : float
        Sample time [s].

    Returns
    -------
    tuple of ndarray
        ``(A, B, C)`` with ``n + n_f`` states.
    """
    rows = [] if layout is None else layout.anti_alias_rows()
    if not rows:
        return A, B, C
    from hubbeam_ctrl.sim.measurement import anti_alias_coefficients
    decay, b0, b1 = anti_alias_coefficients(layout.anti_alias_hz, dt)
    n, nf = A.shape[0], len(rows)
    Cr = C[rows]
    Af = np.zeros((n + nf, n + nf))
    Af[:n, :n] = A
    Af[n:, :n] = b0 * Cr @ A + b1 * Cr
    Af[n:, n:] = decay * np.eye(nf)
    Bf = np.vstack([B, b0 * Cr @ B])
    Cf = np.hstack([C, np.zeros((C.shape[0], nf))])
    for j, r in enumerate(rows):
        Cf[r] = 0.0
        Cf[r, n + j] = 1.0
    return Af, Bf, Cf


def _tip_row(params, n_modes: int) -> np.ndarray:
    """``[0, f2_1(L), ..., f2_m(L)]``: the tip deflection on the position half of the state."""
    from hubbeam_ctrl.plant.basis import transverse_shapes
    return np.r_[0.0, transverse_shapes(np.array([params.L]), n_modes, params.L, 0)[0]]


#: The beam alone's sensors: hub angle, hub rate, root bending moment.
DEFAULT_LAYOUT = SensorLayout()


def observability_defect(Ad: np.ndarray, C: np.ndarray, names, tol: float = 1e-9) -> str | None:
    """Which state the sensors cannot see (the PBH eigenvector test on each mode of ``Ad``), or None.

    A mode ``Ad v = z v`` is unobservable when every sensor row misses it, ``C v = 0``. The test is
    made on unit eigenvectors and on sensor rows scaled to unit norm, so it does not depend on the
    sensors' units: a tip accelerometer's row (entries up to the square of the highest modelled
    frequency, 1e5-1e7) beside an encoder's (1) once made the rank test on ``[z I - Ad; C]``
    relative to its largest singular value refuse a rig whose encoder sees the rotation (a 1 m
    steel link with a 3.8 kg payload sampled at 5 ms: every mode's smallest singular value
    3-8e-10 of the largest).

    Parameters
    ----------
    Ad, C : ndarray
        The sampled model's state matrix (n, n) and the sensors' rows (ny, n).
    names : sequence of str
        State names (for the message).
    tol : float
        Threshold on the largest ``|c v|`` over the unit rows ``c`` [-].

    Returns
    -------
    str or None
        The state with the largest share in an unobservable mode.
    """
    C = np.atleast_2d(np.asarray(C, dtype=float))
    norms = np.linalg.norm(C, axis=1)
    Cn = C[norms > 0] / norms[norms > 0, None]
    _, V = np.linalg.eig(Ad)
    for i in range(V.shape[1]):
        v = V[:, i] / np.linalg.norm(V[:, i])
        if Cn.shape[0] == 0 or np.max(np.abs(Cn @ v)) <= tol:
            return str(names[int(np.argmax(np.abs(v)))])
    return None
