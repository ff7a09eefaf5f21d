"""One description of the physical rig: the beam, the drive, friction, damping, sensors, timing.

A :class:`Rig` is a frozen, validated value that says everything about a setup: the beam
(:class:`~hubbeam_ctrl.plant.params.Params`, as everywhere in the toolbox) and the hardware
around it: :class:`Drive` (an ideal torque source, the default, or a geared DC motor),
:class:`Friction` at the hub, :class:`Damping` of the beam's modes, :class:`Sensors` and
:class:`Timing`. Every field has a unit, a range and a description (``docs/ranges.md``);
a value out of range gives one line naming the key as it is written in a rig file
(``motor.R must be > 0 [ohm], got -1``).

One TOML file holds a rig, one table per part::

    [beam]        # Params fields (L, rho, A, E, I, J_h, r, m_t, ...)
    [motor]       # Drive fields (kind = "dc_motor", R, k_t, k_e, N, ...)
    [friction]    # Friction fields (viscous, coulomb, ...)
    [damping]     # Damping fields (ratios, alpha, beta)
    [sensors]     # Sensors fields (encoder_counts, strain_gauges, ...)
    [timing]      # Timing fields (dt, delay)

A missing table means ideal hardware for that part; today's flat parameter file (the
:class:`Params` fields at top level or in ``[params]``) loads as the beam alone with ideal
hardware. :func:`load_rig` also takes the name of a preset that ships with the toolbox
(:data:`PRESETS`: ``servo_link``, a Quanser-class rotary flexible link on an SRV02-class
servo, and ``paper``, Table 1 of Bai et al. with ideal hardware).

Examples
--------
>>> rig = load_rig("servo_link")
>>> rig.drive.kind, rig.drive.N, rig.sensors.encoder_counts
('dc_motor', 70.0, 4096)
>>> Rig().is_ideal
True
>>> Drive(kind="dc_motor", R=-1)
Traceback (most recent call last):
...
hubbeam_ctrl.core.errors.ParameterError: motor.R must be in (0, 10000] [ohm], got -1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text, path_exists, read_toml
from hubbeam_ctrl.core.settings import Settings, setting
from hubbeam_ctrl.plant.params import MAX_MODES, MAX_PARAMS_FILE_BYTES, Params, _read_toml

__all__ = ["Drive", "Friction", "Damping", "Sensors", "Timing", "Rig", "load_rig", "save_rig", "PRESETS",
           "RIG_TABLES", "RIG_RELATIONS", "rig_from_dict", "rig_to_toml"]

#: The presets that ship with the toolbox (``hubbeam_ctrl/data/rigs/<name>.toml``).
PRESETS = ("servo_link", "paper")


@dataclass(frozen=True)
class Drive(Settings):
    """The hub drive: an ideal torque source (default) or a DC motor with a gearbox.

    The DC motor (``kind = "dc_motor"``) takes a voltage ``V`` clipped to ``+-V_max``; its
    armature current ``i = (V - k_e N thd) / R`` (with inductance ``L > 0``: the state of
    ``L di/dt = V - R i - k_e N thd``) is clipped to ``+-I_max`` by the amplifier, and the
    torque at the hub is ``eta_forward N k_t i`` while the motor drives the load (``i thd >=
    0``) and ``N k_t i / eta_backward`` while the load drives the gear (``i thd < 0``: braking,
    the power flows back through the gear). The rotor inertia ``J_r`` adds ``N^2 J_r`` to the
    hub inertia (:attr:`Rig.plant_params`). With ``kind = "torque"`` the motor fields are not used.
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

    @property
    def is_ideal(self) -> bool:
        """True for the ideal torque source."""
        return self.kind == "torque"

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the hub ``N^2 J_r`` [kg m^2] (0 for the torque drive)."""
        return 0.0 if self.is_ideal else self.N ** 2 * self.J_r

    @property
    def stall_torque(self) -> float:
        """Largest hub torque at rest ``eta_forward N k_t min(I_max, V_max / R)`` [N m] (inf: torque drive)."""
        if self.is_ideal:
            return math.inf
        return self.eta_forward * self.N * self.k_t * min(self.I_max, self.V_max / self.R)


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
    angle_noise: float = setting(0.0, unit="rad", lo=0.0, hi=1.0, doc="Hub-angle noise, standard deviation.")
    angle_bias: float = setting(0.0, unit="rad", lo=-1.0, hi=1.0, doc="Hub-angle bias.")
    rate_noise: float = setting(0.0, unit="rad/s", lo=0.0, hi=10.0, doc="Hub-rate noise, standard deviation.")
    rate_bias: float = setting(0.0, unit="rad/s", lo=-10.0, hi=10.0, doc="Hub-rate bias.")
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


#: Bounds of rig fields that depend on other fields: ``(class name, field) -> text`` (``docs/ranges.md``).
RIG_RELATIONS = {
    ("Drive", "I_max"): "eta_forward N k_t I_max >= friction breakaway (the motor holds the hub at rest)",
    ("Friction", "breakaway"): ">= coulomb",
    ("Damping", "ratios"): "each in [0, 1)",
    ("Sensors", "strain_gauges"): "each in [0, beam.L]",
    ("Rig", "beam"): "damping_ratio = 0 when [damping] is given",
}

#: The tables of a rig file and the class each holds, in file order.
RIG_TABLES = {"beam": Params, "motor": Drive, "friction": Friction, "damping": Damping, "sensors": Sensors,
              "timing": Timing}

_ATTR = {"beam": "beam", "motor": "drive", "friction": "friction", "damping": "damping", "sensors": "sensors",
         "timing": "timing"}


@dataclass(frozen=True)
class Rig(Settings):
    """The physical rig: the beam and the hardware around it (see the module docstring).

    Beyond each part's own ranges, a rig is refused when its DC motor cannot hold the hub
    at rest against friction (``eta_forward N k_t I_max`` below the breakaway torque), a
    strain gauge lies beyond the beam, or the beam's ``damping_ratio`` and the rig's
    ``[damping]`` are both given.
    """

    beam: Params = setting(factory=Params, doc="The beam, hub and tip mass (Params).")
    drive: Drive = setting(factory=Drive, doc="The hub drive ([motor] in a rig file).")
    friction: Friction = setting(factory=Friction, doc="Friction at the hub.")
    damping: Damping = setting(factory=Damping, doc="Damping of the beam's modes.")
    sensors: Sensors = setting(factory=Sensors, doc="The sensors.")
    timing: Timing = setting(factory=Timing, doc="Sample time and computation delay.")

    def __post_init__(self):
        super().__post_init__()
        d, f = self.drive, self.friction
        if not d.is_ideal and d.eta_forward * d.N * d.k_t * d.I_max < f.static:
            need = f.static / (d.eta_forward * d.N * d.k_t)
            raise ParameterError(f"motor.I_max must be >= {need:.4g} [A] (eta_forward N k_t I_max must hold "
                                 f"the hub against the breakaway friction {f.static:g} N m), got {d.I_max:g}")
        for k, x in enumerate(self.sensors.strain_gauges):
            if x > self.beam.L:
                raise ParameterError(f"sensors.strain_gauges[{k}] must be in [0, L] = [0, {self.beam.L:g}] [m] "
                                     f"(on the beam), got {x:g}")
        if self.damping.is_set and self.beam.damping_ratio > 0:
            raise ParameterError(f"beam.damping_ratio must be 0 when [damping] is given (one source of "
                                 f"damping), got {self.beam.damping_ratio:g}")

    @property
    def is_ideal(self) -> bool:
        """True when the hardware is ideal: torque drive, no friction, no extra damping, ideal
        sensors, no delay (the rig is then the beam alone)."""
        return (self.drive.is_ideal and self.friction.is_ideal and not self.damping.is_set
                and self.sensors.is_ideal and self.timing.is_ideal)

    @property
    def plant_params(self) -> Params:
        """The beam's :class:`Params` as the plant sees them: ``J_h`` plus the reflected rotor
        inertia ``N^2 J_r``, and the rig's damping as per-mode ratios of the transverse clamped
        modes (``damping_ratios``, all :data:`~hubbeam_ctrl.plant.params.MAX_MODES` of them, Rayleigh
        terms at each mode's frequency); the beam itself when there is neither."""
        changes = {}
        if self.drive.reflected_inertia:
            changes["J_h"] = self.beam.J_h + self.drive.reflected_inertia
        if self.damping.is_set:
            changes["damping_ratios"] = self.mode_damping()
        return self.beam.replace(**changes) if changes else self.beam

    def mode_damping(self, n: int = MAX_MODES) -> tuple:
        """Damping ratios of transverse clamped modes 1..n by :meth:`Damping.ratio` [-].

        Parameters
        ----------
        n : int
            Number of modes (default all the toolbox models, 20).

        Returns
        -------
        tuple of float
        """
        from hubbeam_ctrl.plant.basis import modal_basis
        b = modal_basis(self.beam.replace(n_transverse=n, damping_ratios=()))
        omega = np.sqrt(np.diag(b.K2)[:n] / np.diag(b.beam.M2)[:n])
        out = tuple(min(self.damping.ratio(i + 1, float(w)), 0.999) for i, w in enumerate(omega))
        return out

    def to_tables(self) -> dict:
        """The rig as the tables of a rig file: ``{"beam": {...}, "motor": {...}, ...}``."""
        out = {}
        for table in RIG_TABLES:
            part = getattr(self, _ATTR[table])
            out[table] = {f.name: getattr(part, f.name) for f in fields(part)}
        return out


def _part(table: str, data, path, what: str = "rig file") -> Settings:
    cls = RIG_TABLES[table]
    where = f"{what} {path}: " if path is not None else ""
    if not isinstance(data, dict):
        raise ParameterError(f"{where}[{table}] must be a table of keys, got {type(data).__name__}")
    if cls is Params:
        try:
            return Params.from_dict(data)
        except ParameterError as exc:
            raise ParameterError(f"{where}beam.{exc}" if str(exc).split(" ")[0] in data
                                 else f"{where}[beam]: {exc}") from None
    known = [f.name for f in fields(cls)]
    for key in data:
        if key not in known:
            raise ParameterError(f"{where}unknown key {table}.{str(key)[:40]}; allowed in [{table}]: "
                                 f"{', '.join(known)}")
    try:
        return cls(**data)
    except ParameterError as exc:
        raise ParameterError(f"{where}{exc}") from None
    except TypeError as exc:
        raise ParameterError(f"{where}[{table}]: {exc}") from None


def rig_from_dict(data: dict, path=None, what: str = "rig file") -> Rig:
    """A :class:`Rig` from the tables of a rig file (or a flat :class:`Params` mapping).

    Parameters
    ----------
    data : dict
        ``{"beam": {...}, "motor": {...}, ...}`` (:data:`RIG_TABLES`); a mapping without
        tables (or with ``[params]`` only) is a flat parameter set: the beam alone, ideal hardware.
    path : str or Path, optional
        The file it came from (named in error messages).
    what : str
        What the file is, as error messages start (``"rig file"``; ``"params file"`` for a
        parameter file read as a rig).

    Returns
    -------
    Rig
    """
    where = f"{what} {path}: " if path is not None else ""
    if not isinstance(data, dict):
        raise ParameterError(f"{where}a rig must be a mapping of tables, got {type(data).__name__}")
    if set(data) == {"params"} and isinstance(data["params"], dict):
        data = data["params"]
    if not any(isinstance(v, dict) for v in data.values()):      # today's flat Params file
        try:
            return Rig(beam=Params.from_dict(data))
        except ParameterError as exc:
            raise ParameterError(f"{where}{exc}") from None
    for key, value in data.items():
        if key not in RIG_TABLES:
            kind = "table" if isinstance(value, dict) else "key"
            shown = f"[{str(key)[:40]}]" if kind == "table" else str(key)[:40]
            raise ParameterError(f"{where}unknown {kind} {shown}; allowed tables: "
                                 f"{', '.join(f'[{t}]' for t in RIG_TABLES)}")
    parts = {_ATTR[t]: _part(t, data[t], path, what) for t in RIG_TABLES if t in data}
    try:
        return Rig(**parts)
    except ParameterError as exc:
        raise ParameterError(f"{where}{exc}") from None


def _preset_path(name: str):
    return resources.files("hubbeam_ctrl").joinpath("data", "rigs", f"{name}.toml")


def load_rig(source, what: str = "rig") -> Rig:
    """Load a rig from a TOML file or a preset name.

    Parameters
    ----------
    source : str or Path
        A rig file (tables ``[beam]``, ``[motor]``, ``[friction]``, ``[damping]``,
        ``[sensors]``, ``[timing]``; or a flat parameter file: the beam alone), or the name
        of a preset (:data:`PRESETS`). An existing file wins over a preset of the same name.
    what : str
        The input's name as error messages start (``"rig"``: ``rig file x.toml does not
        exist``; the command line puts its option in front, ``--rig file ...``).

    Returns
    -------
    Rig

    Raises
    ------
    ParameterError
        One line naming the file and the table or key at fault.
    """
    if isinstance(source, Rig):
        return source
    if source is None or str(source).strip() == "":
        raise ParameterError(f"{what} must name a file or a preset ({', '.join(PRESETS)}), got {source!r}")
    path = Path(source)
    exists = path_exists(path)
    if not exists and str(source) in PRESETS:
        with resources.as_file(_preset_path(str(source))) as preset:
            return rig_from_dict(_read_toml(preset), path=f"(preset {source})")
    if not exists and path.suffix == "" and "/" not in str(source):
        raise ParameterError(f"{what} {str(source)[:80]!r} is neither a file nor a preset "
                             f"({', '.join(PRESETS)})")
    data = read_toml(path, f"{what} file", MAX_PARAMS_FILE_BYTES)
    return rig_from_dict(data, path=path, what=f"{what} file")


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def rig_to_toml(rig: Rig) -> str:
    """The TOML text of a rig file (units as comments; unset optional keys as comments).

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    str
    """
    lines = ["# hubbeam-ctrl rig, SI units"]
    for table, values in rig.to_tables().items():
        units = RIG_TABLES[table].units()
        lines += ["", f"[{table}]"]
        for key, value in values.items():
            unit = units[key]
            if value is None:
                lines.append(f"# {key} unset")
                continue
            lines.append(f"{key} = {_toml_value(value)}" + ("" if unit in ("", "-") else f"  # [{unit}]"))
    return "\n".join(lines) + "\n"


def save_rig(rig: Rig, path) -> None:
    """Write a rig to a TOML file atomically (:func:`load_rig` reads it back equal).

    Parameters
    ----------
    rig : Rig
    path : str or Path
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    atomic_write_text(path, rig_to_toml(rig))
