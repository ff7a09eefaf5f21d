"""The rig's measurement chain in the closed loop: sensor, bias, noise, anti-alias filter, encoder.

:class:`MeasurementChain` turns the plant's integrator state at a sample into the signals a
controller reads (:func:`~hubbeam_ctrl.plant.instruments.signal_names`): hub angle and rate,
the bending moment at each strain gauge, and the tip accelerometer's two in-plane axes. Each
signal passes, in this order,

1. the sensor itself (exact: the plant's angle, rate, ``E I f2''(x) q2``, the tip acceleration
   from the model's kinematics by automatic differentiation);
2. its constant bias and its zero-mean Gaussian white noise (standard deviations and biases
   per sensor from :class:`~hubbeam_ctrl.plant.rig.Sensors`, drawn from one seeded generator:
   runs are reproducible);
3. the optional first-order anti-alias filter ``tau_f y_f' = y - y_f``, ``tau_f = 1 / (2 pi
   anti_alias_hz)``, on every analog signal (not on an encoder's count), discretised exactly
   per sample (:class:`AntiAliasFilter`);
4. the encoder: the hub angle rounded to the nearest count (``encoder_counts``).
"""

from __future__ import annotations

import math

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.instruments import moment_rows, signal_names, tip_kinematics_function
from hubbeam_ctrl.plant.models import HubBeamModel
from hubbeam_ctrl.plant.rig import Sensors

__all__ = ["AntiAliasFilter", "MeasurementChain"]


class AntiAliasFilter:
    """First-order low-pass ``y_f' = w_c (y - y_f)`` on sampled signals, discretised exactly.

    Between two samples the input is taken as the straight line through them (first-order
    hold), for which the update is exact:
    ``y_f[k] = y[k] - s / w_c + e^(-w_c dt) (y_f[k-1] - y[k-1] + s / w_c)`` with
    ``s = (y[k] - y[k-1]) / dt``. The first sample sets the filter at rest on it
    (``y_f[0] = y[0]``).

    Parameters
    ----------
    cutoff_hz : float
        Cutoff frequency ``w_c / (2 pi)`` [Hz], > 0 (``sensors.anti_alias_hz``).
    dt : float
        Sample time [s], > 0.

    Examples
    --------
    >>> f = AntiAliasFilter(10.0, 1e-3)
    >>> [round(float(f(np.array([t]))[0]), 9) for t in (0.0, 1e-3, 2e-3)]   # a ramp lags by 1/w_c
    [0.0, 3.14e-07, 0.000743016]
    """

    def __init__(self, cutoff_hz: float, dt: float):
        if not (isinstance(cutoff_hz, (int, float)) and math.isfinite(cutoff_hz) and cutoff_hz > 0):
            raise ParameterError(f"sensors.anti_alias_hz must be > 0 [Hz], got {cutoff_hz!r}")
        self.cutoff_hz, self.dt = float(cutoff_hz), float(dt)
        self.w_c = 2.0 * math.pi * self.cutoff_hz
        self.decay = math.exp(-self.w_c * self.dt)
        self._y = self._yf = None

    def reset(self):
        """Forget the past: the next sample starts the filter at rest on it."""
        self._y = self._yf = None

    def __call__(self, y: np.ndarray) -> np.ndarray:
        """The filtered values at this sample.

        Parameters
        ----------
        y : ndarray
            The unfiltered signals at this sample.

        Returns
        -------
        ndarray
        """
        y = np.array(y, dtype=float)
        if self._y is None:
            self._y, self._yf = y.copy(), y.copy()
            return y
        lag = (y - self._y) / (self.dt * self.w_c)
        self._yf = y - lag + self.decay * (self._yf - self._y + lag)
        self._y = y
        return self._yf.copy()


class MeasurementChain:
    """The rig's sensors on a plant: what a controller reads at each sample.

    Parameters
    ----------
    sensors : Sensors
        The rig's sensors (:class:`~hubbeam_ctrl.plant.rig.Sensors`).
    model : HubBeamModel
        The plant.
    dt : float
        Sample time [s].
    n_samples : int
        Number of samples of the run (noise is drawn for them at once).
    seed : int
        Seed of the noise generator.

    Attributes
    ----------
    names : tuple of str
        The signals, in the order of :meth:`measure`'s vector.
    """

    def __init__(self, sensors: Sensors, model: HubBeamModel, dt: float, n_samples: int, seed: int = 0):
        if not isinstance(sensors, Sensors):
            raise ParameterError(f"sensors must be a Sensors (plant.rig), got {type(sensors).__name__}")
        self.sensors, self.model = sensors, model
        n = model.n_q
        self.n_q = n
        gauges = sensors.strain_gauges
        self.names = signal_names(len(gauges), sensors.tip_accelerometer)
        C = np.zeros((2 + len(gauges), 2 * n))
        C[0, 0], C[1, n] = 1.0, 1.0
        C[2:] = moment_rows(model.params, gauges, model.n_transverse, model.n_axial)
        self.C = C
        self._accel = tip_kinematics_function(model) if sensors.tip_accelerometer else None
        s = sensors
        k = len(gauges)
        self.std = np.array([s.angle_noise, s.rate_noise] + [s.strain_noise] * k
                            + ([s.accel_noise] * 2 if self._accel is not None else []))
        self.bias = np.array([s.angle_bias, s.rate_bias] + [s.strain_bias] * k
                             + ([s.accel_bias] * 2 if self._accel is not None else []))
        self.encoder = s.encoder_step
        rng = np.random.default_rng(seed)
        self._noise = rng.standard_normal((int(n_samples), len(self.names))) * self.std \
            if np.any(self.std > 0) else None
        self._filter = None if s.anti_alias_hz is None else AntiAliasFilter(s.anti_alias_hz, dt)
        # the encoder counts, it is not filtered; an angle sensor without counts is analog
        self._filtered = slice(1, None) if self.encoder else slice(0, None)

    def reset(self):
        """Prepare a new run (the filter starts again at rest)."""
        if self._filter is not None:
            self._filter.reset()

    def exact(self, state) -> np.ndarray:
        """The signals without bias, noise, filter or encoder at an integrator state.

        Parameters
        ----------
        state : ndarray
            ``[q, v]`` or the stepper's ``[q, v, a, ...]`` (accelerations needed for the accelerometer).

        Returns
        -------
        ndarray (len(names),)
        """
        n = self.n_q
        y = self.C @ state[:2 * n]
        if self._accel is not None:
            if len(state) < 3 * n:
                raise ParameterError("the tip accelerometer needs the accelerations: give [q, v, a]")
            acc = np.asarray(self._accel(state[:n], state[n:2 * n], state[2 * n:3 * n])[2]).ravel()
            y = np.concatenate([y, acc])
        return y

    def measure(self, k: int, state) -> np.ndarray:
        """The signals a controller reads at sample ``k``.

        Parameters
        ----------
        k : int
            Sample index (selects the noise draw).
        state : ndarray
            The stepper's state ``[q, v, a, ...]`` at the sample (``[q, v]`` without accelerometer).

        Returns
        -------
        ndarray (len(names),)
        """
        y = self.exact(state) + self.bias
        if self._noise is not None:
            y = y + self._noise[k]
        if self._filter is not None:
            y[self._filtered] = self._filter(y[self._filtered])
        if self.encoder:
            y[0] = self.encoder * round(y[0] / self.encoder)
        return y
