"""The parts of a rig: drive, friction, damping, sensors and timing (:class:`~hubbeam_ctrl.plant.rig.Rig`
puts them around the beam).

Each part is a frozen :class:`~hubbeam_ctrl.core.settings.Settings` value whose fields have a unit,
a range and a description (``docs/ranges.md``); a value out of range gives one line naming the key
as it is written in a rig file (``motor.R must be > 0 [ohm], got -1``). The defaults are ideal
hardware.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, setting

__all__ = ["Drive", "Friction", "Damping", "Sensors", "Timing"]


@dataclass(frozen=True)
class Drive(Settings):
    """The hub drive: an ideal torque source (default) or a DC motor with a gearbox.

    The DC motor (``kind = "dc_motor"``) takes a voltage ``V`` clipped to ``+-V_max``; its
    armature current ``i = (V - k_e N thd) / R`` (with inductance ``L > 0``: the state of
    ``L di/dt = V - R i - k_e N thd``) is clipped to ``+-I_max`` by the amplifier, and the
    torque at the hub is ``eta_forward N k_t i`` while the motor drives the load (``i thd >=
    0``) and ``N k_t i / eta_backward`` while the load drives the gear (``i thd < 0``: braking,
    the power flows back through the gear). The motor's own efficiency ``eta_motor`` (apart
    from the gear's) multiplies the torque constant's torque: the motor gives ``eta_motor k_t
    i`` at its shaft (:attr:`k_torque`). The rotor inertia ``J_r`` adds ``N^2 J_r`` to the
    hub inertia (:attr:`Rig.plant_params`). With ``kind = "torque"`` the motor fields are not
    used but ``tau_max``, the torque source's own limit.

    The drive's hub-torque limit (:attr:`torque_limit`) is the beam's ``tau_max``: a DC
    motor's stall torque ``eta_forward N eta_motor k_t min(V_max / R, I_max)``, or a torque
    source's ``tau_max`` (:class:`Rig` checks ``beam.tau_max`` against it).
    """

    _setting_prefix = "motor."

    kind: str = setting("torque", choices=("torque", "dc_motor"),
                        doc='Drive model: "torque" (an ideal torque source, the paper\'s) or "dc_motor" '
                            "(voltage input through a geared DC motor).")
    R: float = setting(2.6, unit="ohm", lo=0.0, lo_open=True, hi=1e4, doc="Armature resistance.")
    L: float = setting(0.0, unit="H", lo=0.0, hi=10.0,
                       doc="Armature inductance; > 0: the current is a state of the plant step (L di/dt = "
                           "V - R i - k_e N thd, backward Euler per substep); 0: neglected, i = (V - k_e N "
                           "thd) / R.")
    k_t: float = setting(7.68e-3, unit="N m/A", lo=0.0, lo_open=True, hi=1e3, doc="Motor torque constant.")
    k_e: float = setting(7.68e-3, unit="V s/rad", lo=0.0, lo_open=True, hi=1e3,
                         doc="Back-EMF constant (equals k_t in SI units for an ideal machine).")
    N: float = setting(1.0, lo=0.0, lo_open=True, hi=1e4,
                       doc="Gear ratio, motor turns per hub turn (1: direct drive).")
    eta_forward: float = setting(1.0, lo=0.0, lo_open=True, hi=1.0,
                                 doc="Gear efficiency when the motor drives the load (power from motor "
                                     "to hub).")
    eta_backward: float = setting(1.0, lo=0.0, lo_open=True, hi=1.0,
                                  doc="Gear efficiency when the load drives the gear (power from hub to "
                                      "motor, e.g. braking).")
    J_r: float = setting(0.0, unit="kg m^2", lo=0.0, hi=1e6,
                         doc="Rotor inertia at the motor shaft; N^2 J_r is added to the hub inertia J_h.")
    V_max: float = setting(10.0, unit="V", lo=0.0, lo_open=True, hi=1e5, doc="Amplifier voltage limit.")
    I_max: float = setting(4.0, unit="A", lo=0.0, lo_open=True, hi=1e5, doc="Amplifier current limit.")
    eta_motor: float = setting(1.0, lo=0.0, lo_open=True, hi=1.0,
                               doc="Motor efficiency apart from the gear's: the motor's shaft torque is "
                                   "eta_motor k_t i.")
    slew_rate: float | None = setting(None, unit="V/s or N m/s", lo=0.0, lo_open=True, hi=1e12, kind=float,
                                      doc="The amplifier's slew-rate limit: the command changes by at most this "
                                          "times the sample time from one sample to the next (volts on a DC "
                                          "motor, newton-metres on a torque source); None: none.")
    tau_max: float | None = setting(None, unit="N m", lo=0.0, lo_open=True, hi=1e9, kind=float,
                                    doc='The torque source\'s limit at the hub (kind = "torque"); None: '
                                        "beam.tau_max. A DC motor's follows from its voltage and current "
                                        "limits (its stall torque) and takes none.")

    def __post_init__(self):
        super().__post_init__()
        if not self.is_ideal and self.tau_max is not None:
            raise ParameterError(f'motor.tau_max is the limit of a torque source (kind = "torque"); a DC '
                                 f"motor's is its stall torque eta_forward N eta_motor k_t min(V_max / R, "
                                 f"I_max) = {self.stall_torque:.4g} N m: remove motor.tau_max, got "
                                 f"{self.tau_max:g}")

    @property
    def is_ideal(self) -> bool:
        """True for the ideal torque source."""
        return self.kind == "torque"

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the hub ``N^2 J_r`` [kg m^2] (0 for the torque drive)."""
        return 0.0 if self.is_ideal else self.N ** 2 * self.J_r

    @property
    def k_torque(self) -> float:
        """Shaft torque per ampere ``eta_motor k_t`` [N m/A] (the motor's efficiency applied)."""
        return self.eta_motor * self.k_t

    @property
    def stall_torque(self) -> float:
        """Largest hub torque at rest ``eta_forward N eta_motor k_t min(I_max, V_max / R)`` [N m]
        (inf: torque drive)."""
        if self.is_ideal:
            return math.inf
        return self.eta_forward * self.N * self.k_torque * min(self.I_max, self.V_max / self.R)

    @property
    def torque_limit(self) -> float | None:
        """The drive's hub-torque limit [N m]: the DC motor's :attr:`stall_torque`, the torque
        source's ``tau_max`` (None: not given, the beam's ``tau_max`` holds)."""
        return self.tau_max if self.is_ideal else self.stall_torque

    @property
    def peak_hub_torque(self) -> float | None:
        """Largest hub torque the drive can give in any state [N m]: on a DC motor the
        back-driven torque at the current limit ``N eta_motor k_t I_max / eta_backward`` (braking
        passes more torque than motoring, ``eta_forward <= 1 <= 1 / eta_backward``); on a torque
        source :attr:`torque_limit`."""
        if self.is_ideal:
            return self.tau_max
        return self.N * self.k_torque * self.I_max / self.eta_backward


@dataclass(frozen=True)
class Friction(Settings):
    """Friction at the hub (output side of the gear): viscous, Coulomb and optionally Stribeck.

    While the hub slips, the friction torque is ``viscous thd + (coulomb + (breakaway -
    coulomb) exp(-(thd / stribeck_velocity)^2)) tanh(thd / v_eps)``: the sign function of
    Coulomb friction regularised by ``tanh`` over ``v_eps``. A hub slower than
    ``stick_velocity`` whose holding torque is within ``breakaway`` sticks (Karnopp's model):
    it is held at rest, exactly, until the torque needed to hold it exceeds ``breakaway``.
    """

    _setting_prefix = "friction."

    viscous: float = setting(0.0, unit="N m s/rad", lo=0.0, hi=1e9, doc="Viscous friction coefficient b.")
    coulomb: float = setting(0.0, unit="N m", lo=0.0, hi=1e9, doc="Coulomb (sliding) friction torque F_c.")
    breakaway: float | None = setting(None, unit="N m", lo=0.0, hi=1e9, kind=float,
                                      doc="Static (breakaway) friction torque F_s >= coulomb; None: equal to "
                                          "coulomb (no Stribeck effect).")
    stribeck_velocity: float = setting(0.1, unit="rad/s", lo=0.0, lo_open=True, hi=1e3,
                                       doc="Stribeck velocity: friction falls from breakaway to coulomb over "
                                           "about this hub rate.")
    v_eps: float = setting(1e-3, unit="rad/s", lo=1e-9, hi=1.0,
                           doc="Regularisation velocity of the sliding friction: sign(thd) is replaced "
                               "by tanh(thd / v_eps).")
    stick_velocity: float = setting(1e-3, unit="rad/s", lo=1e-9, hi=1.0,
                                    doc="Karnopp dead band: a hub slower than this (or reversing within a "
                                        "sample) is tried at rest and held while the holding torque is "
                                        "within breakaway.")

    def __post_init__(self):
        super().__post_init__()
        if self.breakaway is not None and self.breakaway < self.coulomb:
            raise ParameterError(f"friction.breakaway must be >= friction.coulomb = {self.coulomb:g} [N m], "
                                 f"got {self.breakaway:g}")

    @property
    def static(self) -> float:
        """Breakaway torque F_s [N m] (``coulomb`` when ``breakaway`` is None)."""
        return self.coulomb if self.breakaway is None else self.breakaway

    @property
    def is_ideal(self) -> bool:
        """True without any friction."""
        return self.viscous == 0.0 and self.coulomb == 0.0 and self.static == 0.0


def _float_tuple(name: str, value, lo: float, hi: float, unit: str, hi_open: bool = False) -> tuple:
    """``value`` (a sequence of numbers) as a tuple of floats in [lo, hi], or one line naming it."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise ParameterError(f"{name} must be a list of numbers [{unit}], got {str(value)[:40]!r}")
    out = []
    for k, x in enumerate(value):
        ok = isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
        if not ok or x < lo or (x >= hi if hi_open else x > hi):
            rng = f"[{lo:g}, {hi:g}{')' if hi_open else ']'}"
            raise ParameterError(f"{name}[{k}] must be in {rng} [{unit}], got {str(x)[:40]}")
        out.append(float(x))
    return tuple(out)


@dataclass(frozen=True)
class Damping(Settings):
    """Damping of the beam's clamped modes: per-mode ratios and/or Rayleigh coefficients.

    Transverse mode ``i`` (1-based, natural frequency ``w_i`` of the clamped beam) gets the
    ratio ``zeta_i = ratios[i-1] + alpha / (2 w_i) + beta w_i / 2``; modes beyond the list
    take its last value (so ``ratios = [0.034]`` damps every mode at 0.034). Empty ratios and
    zero Rayleigh coefficients (the default) leave the beam's own ``damping_ratio``.
    """

    _setting_prefix = "damping."

    ratios: tuple = setting((), kind=tuple,
                            doc="Modal damping ratios of transverse modes 1, 2, ... in [0, 1); the last "
                                "applies to the modes beyond the list.")
    alpha: float = setting(0.0, unit="1/s", lo=0.0, hi=1e6, doc="Rayleigh mass-proportional coefficient.")
    beta: float = setting(0.0, unit="s", lo=0.0, hi=1.0, doc="Rayleigh stiffness-proportional coefficient.")

    def __post_init__(self):
        if isinstance(self.ratios, list):
            object.__setattr__(self, "ratios", tuple(self.ratios))
        super().__post_init__()
        object.__setattr__(self, "ratios", _float_tuple("damping.ratios", self.ratios, 0.0, 1.0, "-", True))

    @property
    def is_set(self) -> bool:
        """True when the rig gives its own damping (ratios or Rayleigh coefficients)."""
        return bool(self.ratios) or self.alpha > 0 or self.beta > 0

    def ratio(self, mode: int, omega: float) -> float:
        """Damping ratio of a mode [-].

        Parameters
        ----------
        mode : int
            1-based mode number.
        omega : float
            Its natural frequency [rad/s], > 0.

        Returns
        -------
        float
        """
        base = self.ratios[min(mode, len(self.ratios)) - 1] if self.ratios else 0.0
        return base + self.alpha / (2.0 * omega) + 0.5 * self.beta * omega


@dataclass(frozen=True)
class Sensors(Settings):
    """The rig's sensors: hub encoder, strain gauges along the beam, tip accelerometer.

    Noise is zero-mean Gaussian white noise of the given standard deviation, drawn at each
    sample; the bias is a constant offset. All zero (the default): ideal sensors. The closed
    loop measures them through :class:`~hubbeam_ctrl.sim.measurement.MeasurementChain`
    (sensor, bias, noise, anti-alias filter, encoder); a controller reads the signals it names
    (``theta``, ``theta_dot``, ``moment_<i>`` of gauge ``i``, ``accel_radial``,
    ``accel_tangential``; :func:`~hubbeam_ctrl.plant.instruments.signal_names`).
    """

    _setting_prefix = "sensors."

    encoder_counts: int = setting(0, lo=0, hi=10 ** 9, unit="counts/rev",
                                  doc="Hub encoder resolution; the angle is quantised to 2 pi / counts "
                                      "(0: ideal, not quantised).")
    strain_gauges: tuple = setting((0.0,), kind=tuple, unit="m",
                                   doc="Positions of the strain gauges along the beam from its root, each "
                                       "in [0, L]; gauge i reads the bending moment E I w2''(x) there "
                                       "(signal moment_i).")
    tip_accelerometer: bool = setting(False, doc="A two-axis accelerometer at the tip: the in-plane inertial "
                                                 "acceleration in hub axes (accel_radial, accel_tangential), "
                                                 "centripetal and Coriolis terms included.")
    rate: bool = setting(True, doc="A hub-rate sensor (tachometer or gyro) gives theta_dot; false: none, the "
                                   "estimators derive the rate from the other signals.")
    angle_noise: float = setting(0.0, unit="rad", lo=0.0, hi=1.0,
                                 doc="Hub-angle noise, standard deviation (an absolute angle sensor's, e.g. a "
                                     "star tracker).")
    angle_bias: float = setting(0.0, unit="rad", lo=-1.0, hi=1.0, doc="Hub-angle bias.")
    rate_noise: float = setting(0.0, unit="rad/s", lo=0.0, hi=10.0, doc="Hub-rate noise, standard deviation.")
    rate_bias: float = setting(0.0, unit="rad/s", lo=-10.0, hi=10.0, doc="Hub-rate bias (its initial value).")
    rate_bias_walk: float = setting(0.0, unit="rad/s/sqrt(s)", lo=0.0, hi=1.0,
                                    doc="Random walk of the hub-rate bias (a gyro's drift): the bias changes by "
                                        "this times sqrt(dt) standard deviation per sample.")
    strain_noise: float = setting(0.0, unit="N m", lo=0.0, hi=1e6,
                                  doc="Strain-gauge (bending moment) noise, standard deviation (each gauge).")
    strain_bias: float = setting(0.0, unit="N m", lo=-1e6, hi=1e6, doc="Strain-gauge (bending moment) bias.")
    accel_noise: float = setting(0.0, unit="m/s^2", lo=0.0, hi=1e4,
                                 doc="Tip-accelerometer noise, standard deviation (each axis).")
    accel_bias: float = setting(0.0, unit="m/s^2", lo=-1e4, hi=1e4, doc="Tip-accelerometer bias.")
    anti_alias_hz: float | None = setting(None, unit="Hz", lo=0.0, lo_open=True, hi=1e6, kind=float,
                                          doc="Cutoff of a first-order anti-alias filter on every analog "
                                              "signal (not an encoder's count), exact per sample; None: no "
                                              "filter.")

    def __post_init__(self):
        if isinstance(self.strain_gauges, list):
            object.__setattr__(self, "strain_gauges", tuple(self.strain_gauges))
        super().__post_init__()
        object.__setattr__(self, "strain_gauges",
                           _float_tuple("sensors.strain_gauges", self.strain_gauges, 0.0, math.inf, "m"))

    @property
    def is_ideal(self) -> bool:
        """True for exact, noise-free, unfiltered sensors (the strain gauges' places aside)."""
        return (self.encoder_counts == 0 and self.anti_alias_hz is None
                and not any(getattr(self, n) for n in ("angle_noise", "angle_bias", "rate_noise", "rate_bias",
                                                       "rate_bias_walk",
                                                       "strain_noise", "strain_bias", "accel_noise",
                                                       "accel_bias")))

    @property
    def encoder_step(self) -> float:
        """Angle quantum ``2 pi / encoder_counts`` [rad] (0: ideal encoder)."""
        return 0.0 if self.encoder_counts == 0 else 2.0 * math.pi / self.encoder_counts

    def sensor_settings(self, seed: int = 0):
        """The closed loop's :class:`~hubbeam_ctrl.plant.sensors.SensorSettings` of these sensors.

        Noise standard deviations of angle, rate and the first strain gauge, and the encoder:
        the closed loop's own sensors. The whole chain (biases, every gauge, the accelerometer,
        the filter) is measured when the closed loop gets the rig's sensors
        (``hardware=Hardware.from_rig(rig)``).

        Parameters
        ----------
        seed : int
            Seed of the noise generator.

        Returns
        -------
        SensorSettings
        """
        from hubbeam_ctrl.plant.sensors import SensorSettings
        return SensorSettings(angle_noise_rad=self.angle_noise, rate_noise_rad_s=self.rate_noise,
                              moment_noise_nm=self.strain_noise, seed=seed, encoder_counts=self.encoder_counts)


@dataclass(frozen=True)
class Timing(Settings):
    """Sampling and computation delay of the controller."""

    _setting_prefix = "timing."

    dt: float | None = setting(None, unit="s", lo=1e-6, hi=10.0, kind=float,
                               doc="Sample time of the controller; None: the task's.")
    delay: float = setting(0.0, lo=0.0, hi=1.0,
                           doc="Computation delay as a fraction of the sample (0: the command acts at the "
                               "sample instant, 1: one sample later); rounded to the plant's integration "
                               "substep in the closed loop.")

    @property
    def is_ideal(self) -> bool:
        """True without computation delay."""
        return self.delay == 0.0
