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
from functools import lru_cache

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.compiled import OPT_HOT, compile_function
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.instruments import _kinematics, moment_rows, signal_names, tip_acceleration
from hubbeam_ctrl.plant.models import HubBeamModel
from hubbeam_ctrl.plant.rig import Sensors

__all__ = ["AntiAliasFilter", "MeasurementChain", "anti_alias_coefficients", "DEFAULT_SIGNALS", "rig_measurement"]


def anti_alias_coefficients(cutoff_hz: float, dt: float) -> tuple:
    """``(decay, b0, b1)`` of the first-order anti-alias filter sampled every ``dt``:
    ``y_f[k] = decay y_f[k-1] + b0 y[k] + b1 y[k-1]`` (:class:`AntiAliasFilter`'s exact update for
    an input that is the straight line through its samples).

    Parameters
    ----------
    cutoff_hz : float
        Cutoff frequency [Hz], > 0.
    dt : float
        Sample time [s], > 0.

    Returns
    -------
    tuple of float
        [-]; ``b0 + b1 = 1 - decay`` (unit gain at rest).

    Examples
    --------
    >>> decay, b0, b1 = anti_alias_coefficients(10.0, 1e-3)
    >>> round(decay + b0 + b1, 12)
    1.0
    """
    w_c = 2.0 * math.pi * float(cutoff_hz)
    decay = math.exp(-w_c * dt)
    c1 = 1.0 / (w_c * dt)
    return decay, 1.0 - c1 * (1.0 - decay), c1 * (1.0 - decay) - decay


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
    >>> out = [float(f(np.array([t]))[0]) for t in (0.0, 1e-3, 2e-3)]      # a ramp from rest
    >>> exact = [t - (1 - np.exp(-f.w_c * t)) / f.w_c for t in (0.0, 1e-3, 2e-3)]
    >>> bool(np.allclose(out, exact, rtol=1e-12, atol=1e-18))
    True
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


@lru_cache(maxsize=32)
def _measure_function(parametric, n_linear: int, accelerometer: bool, filtered: tuple, encoder: bool,
                      pick: tuple) -> ca.Function:
    """One sample of the chain as one CasADi function (the numbers are inputs: compiled once per layout).

    ``(x, C, w, state, coef, p, rL) -> (y, y_read, state_next)`` on the channels the chain
    computes (the linear ones, then the accelerometer's two): ``x = [q, v, a]``, ``C`` the
    linear rows (column-major), ``w`` bias plus noise, ``state = [y_f, y]`` of the previous
    sample, ``coef = [decay, b0, b1, encoder_step, start]``; the encoder counts channel 0.
    """
    n = parametric.n_q
    sym = parametric.sym
    x = sym.sym("x", 3 * n)
    n_ch = n_linear + (2 if accelerometer else 0)
    C = sym.sym("C", n_linear * 2 * n)
    w, state, coef = sym.sym("w", n_ch), sym.sym("state", 2 * n_ch), sym.sym("coef", 5)
    p, rL = sym.sym("p", parametric.n_p), sym.sym("rL")
    y = ca.mtimes(ca.reshape(C, n_linear, 2 * n), x[:2 * n])
    if accelerometer:
        y = ca.vertcat(y, _kinematics(parametric)(x[:n], x[n:2 * n], x[2 * n:], p, rL)[2])
    y = y + w
    decay, b0, b1, step, start = (coef[k] for k in range(5))
    out = []
    for k in range(n_ch):
        yk = y[k]
        if k in filtered:                 # the filter's exact update, or at rest on the first sample
            yk = ca.if_else(start > 0.5, yk, decay * state[k] + b0 * yk + b1 * state[n_ch + k])
        out.append(yk)
    if encoder:
        out[0] = step * ca.floor(out[0] / step + 0.5)
    y_out = ca.vertcat(*out)
    read = ca.vertcat(*[y_out[k] for k in pick])
    return ca.Function("measure", [x, C, w, state, coef, p, rL], [y_out, read, ca.vertcat(y_out, y)],
                       ["x", "C", "w", "state", "coef", "p", "rL"], ["y", "y_read", "state_next"], {"cse": True})


class MeasurementChain:
    """The rig's sensors on a plant: what a controller reads at each sample.

    One sample is one call of a CasADi function (compiled like the plant step), so the rig's
    sensors cost a few microseconds per sample.

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
    read : sequence of str, optional
        The signals :meth:`measure` returns, in this order (default all, :attr:`names`).
    backend : {"auto", "compiled", "vm"}, optional
        How the chain is evaluated (:func:`~hubbeam_ctrl.core.compiled.compile_function`).

    Attributes
    ----------
    names : tuple of str
        All the rig's signals (:func:`~hubbeam_ctrl.plant.instruments.signal_names`).
    read : tuple of str
        Those :meth:`measure` returns.
    """

    def __init__(self, sensors: Sensors, model: HubBeamModel, dt: float, n_samples: int, seed: int = 0,
                 read=None, backend=None):
        if not isinstance(sensors, Sensors):
            raise ParameterError(f"sensors must be a Sensors (plant.rig), got {type(sensors).__name__}")
        self.sensors, self.model = sensors, model
        n = model.n_q
        self.n_q = n
        gauges = sensors.strain_gauges
        self.names = signal_names(len(gauges), sensors.tip_accelerometer)
        self.read = self.names if read is None else tuple(read)
        for name in self.read:
            if name not in self.names:
                raise ParameterError(f"signal {name!r} is not among the rig's sensors: {', '.join(self.names)}")
        C = np.zeros((2 + len(gauges), 2 * n))
        C[0, 0], C[1, n] = 1.0, 1.0
        C[2:] = moment_rows(model.params, gauges, model.n_transverse, model.n_axial)
        self.C = C
        accel = sensors.tip_accelerometer
        if accel and model.axial != "dynamic" and any(name.startswith("accel") for name in self.read):
            raise ParameterError("sensors.tip_accelerometer needs a model with dynamic axial coordinates "
                                 f"(axial = 'dynamic'), got axial = {model.axial!r}")
        s = sensors
        k = len(gauges)
        two = 2 if accel else 0
        self.std = np.array([s.angle_noise, s.rate_noise] + [s.strain_noise] * k + [s.accel_noise] * two)
        self.bias = np.array([s.angle_bias, s.rate_bias] + [s.strain_bias] * k + [s.accel_bias] * two)
        self.encoder = s.encoder_step
        rng = np.random.default_rng(seed)            # every signal's noise is drawn, read or not: seeded runs agree
        noise = rng.standard_normal((int(n_samples), len(self.names))) * self.std if np.any(self.std > 0) \
            else np.zeros((int(n_samples), len(self.names)))
        if s.rate_bias_walk > 0:                     # a drifting gyro bias, from its own generator
            walk = np.random.default_rng([int(seed), 1]).standard_normal(int(n_samples))
            noise[:, 1] += np.cumsum(walk) * s.rate_bias_walk * np.sqrt(dt)
        # the chain computes only the channels read (in the order of names): the linear ones, then the
        # accelerometer's two when one of them is read
        lin = [k for k in range(len(C)) if self.names[k] in self.read]
        accel = accel and any(name.startswith("accel") for name in self.read)
        channels = lin + ([len(C), len(C) + 1] if accel else [])
        n_ch = len(channels)
        self._w_all = np.ascontiguousarray((noise + self.bias)[:, channels])
        encoder = bool(self.encoder) and 0 in lin
        # the encoder counts, it is not filtered; an angle sensor without counts is analog
        filtered = () if s.anti_alias_hz is None else tuple(range(1 if encoder else 0, n_ch))
        coef = np.zeros(5)
        if s.anti_alias_hz is not None:
            coef[:3] = anti_alias_coefficients(s.anti_alias_hz, dt)
        coef[3], coef[4] = self.encoder, 1.0
        pick = tuple(channels.index(self.names.index(name)) for name in self.read)
        self._function_pick = pick
        f = _measure_function(model.parametric, len(lin), accel, filtered, encoder, pick)
        self._function = compile_function(f, backend, opt=OPT_HOT)
        self._x, self._C, self._w = np.zeros(3 * n), C[lin].ravel(order="F").copy(), np.zeros(n_ch)
        self._state, self._coef = np.zeros(2 * n_ch), coef
        self._p, self._rL = np.array(model.p, dtype=float), np.array([model.params.r + model.params.L])
        self._y, self._y_read, self._next = np.zeros(n_ch), np.zeros(len(pick)), np.zeros(2 * n_ch)
        buf, self._evaluate = self._function.buffer()
        for i, a in enumerate((self._x, self._C, self._w, self._state, self._coef, self._p, self._rL)):
            buf.set_arg(i, memoryview(a))
        for i, r in enumerate((self._y, self._y_read, self._next)):
            buf.set_res(i, memoryview(r))
        self._buffer = buf                     # keep the buffer alive with its arrays
        self._needs_a = accel
        self._has_accel = sensors.tip_accelerometer
        self._filtering = bool(filtered)

    @property
    def offsets(self):
        """Bias plus noise of each signal read, per sample, as lists of floats, when that is the whole
        chain besides the encoder (no filter, no accelerometer); else None.

        A closed loop that reads only the hub angle and rate adds them itself (faster than a call):
        ``y = exact + offsets[i][k]``, then the angle to its nearest count (:attr:`encoder`).
        """
        if self._filtering or self._needs_a:
            return None
        pick = [self._function_pick[i] for i in range(len(self.read))]
        return [self._w_all[:, c].tolist() for c in pick]

    def reset(self):
        """Prepare a new run (the filter starts again at rest)."""
        self._coef[4] = 1.0

    def exact(self, state) -> np.ndarray:
        """All the signals without bias, noise, filter or encoder at an integrator state.

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
        if self._has_accel:
            if len(state) < 3 * n:
                raise ParameterError("the tip accelerometer needs the accelerations: give [q, v, a]")
            y = np.concatenate([y, tip_acceleration(self.model, state[:n], state[n:2 * n], state[2 * n:3 * n])])
        return y

    def measure(self, k: int, state) -> np.ndarray:
        """The signals :attr:`read` at sample ``k`` (call once per sample, in order: the filter keeps state).

        Parameters
        ----------
        k : int
            Sample index (selects the noise draw).
        state : ndarray
            The stepper's state ``[q, v, a, ...]`` at the sample (``[q, v]`` without accelerometer).

        Returns
        -------
        ndarray (len(read),)
        """
        n = self.n_q
        if self._needs_a:
            self._x[:] = state[:3 * n]
        else:
            self._x[:2 * n] = state[:2 * n]
        self._w[:] = self._w_all[k]
        self._evaluate()
        if self._filtering:
            self._state[:] = self._next
            self._coef[4] = 0.0
        return self._y_read.copy()


#: The signals a controller with ``measurement = "sensors"`` reads from a rig unless it names
#: its own (``signals``): today's hub angle, hub rate and the first strain gauge.
DEFAULT_SIGNALS = ("theta", "theta_dot", "moment_1")

#: The rig key that provides each kind of signal (for refusals).
_RIG_KEYS = {"theta": "sensors.encoder_counts", "moment": "sensors.strain_gauges",
             "accel": "sensors.tip_accelerometer"}


def _rig_key(signal: str) -> str:
    return "sensors.rate" if signal == "theta_dot" else _RIG_KEYS.get(signal.split("_")[0], signal)


def rig_measurement(hardware, controller, kind, model, m, dt, n_samples, seed, backend):
    """``(chain, state_pick)``: the rig's measurement chain reading what the controller reads
    (None: today's sensors) and, for state feedback (None otherwise), where the measured hub
    rate goes in its vector (the angle goes first).

    Parameters
    ----------
    hardware : Hardware or None
        The rig's hardware (its sensors).
    controller : controllers.Controller
        The controller (its ``signals``, if any, and its name for refusals).
    kind : {"state", "sensors"}
        What the controller reads.
    model : HubBeamModel
        The plant.
    m : int
        The plant's bending modes.
    dt : float
        Sample time [s].
    n_samples : int
        Samples of the run.
    seed : int or None
        Noise seed.
    backend : str
        The chain's CasADi backend.

    Returns
    -------
    tuple
        ``(MeasurementChain or None, int or None)``.
    """
    sensors = None if hardware is None else hardware.sensors
    wanted = getattr(controller, "signals", None)
    name = str(getattr(controller, "name", type(controller).__name__))
    if sensors is None:
        if wanted is not None and tuple(wanted) != DEFAULT_SIGNALS[:len(tuple(wanted))]:
            raise ParameterError(f"controller {name!r} reads signals {tuple(wanted)} but the closed loop has no "
                                 "rig sensors: give hardware=Hardware.from_rig(rig)")
        return None, None
    default = sensors.strain_gauges == (0.0,) and not sensors.tip_accelerometer and sensors.rate
    if sensors.is_ideal and default and wanted is None:
        return None, None                          # the beam alone's sensors, bit for bit
    if kind == "state":
        chain = MeasurementChain(sensors, model, dt, n_samples, seed, read=("theta", "theta_dot"),
                                 backend=backend)
        return chain, 1 + m
    names = tuple(DEFAULT_SIGNALS if wanted is None else wanted)
    all_names = signal_names(len(sensors.strain_gauges), sensors.tip_accelerometer)
    if not names:
        raise ParameterError(f"controller {name!r}: signals must name at least one of {', '.join(all_names)}")
    if not sensors.rate:
        all_names = tuple(n for n in all_names if n != "theta_dot")
    for signal in names:
        if signal not in all_names:
            raise ParameterError(f"controller {name!r} reads {signal!r} ({_rig_key(signal)}), "
                                 f"which the rig does not have; its sensors give {', '.join(all_names)}")
    return MeasurementChain(sensors, model, dt, n_samples, seed, read=names, backend=backend), None
