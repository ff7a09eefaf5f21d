"""The values :func:`hubbeam_ctrl.study.compare.compare` takes besides the rig and the task.

``compare(rig, task, controllers, settings)``: the rig (a :class:`~hubbeam_ctrl.plant.rig.Rig`,
a beam alone as :class:`~hubbeam_ctrl.plant.params.Params`, or None for Table 1), the task (a
registered scenario's name or a :class:`~hubbeam_ctrl.study.tasks.Slew` /
:class:`~hubbeam_ctrl.study.tasks.SpinUp`), and one :class:`CompareSettings` that groups the
rest by role (shared/ARCHITECTURE.md, "The rig stage": descriptions are values built once at
the edge and validated there):

* :class:`PlantChoice`: what the controllers are judged on;
* :class:`DesignChoice`: how the controllers are designed and what they track;
* :class:`RunChoice`: the sample time, the simulated time and the integration settings;
* :class:`ScenarioChoice`: the registered scenario's shape, the torque budget, the bands;
* :class:`PayloadChoice`: a payload range to design for, and payload learning.

Each field keeps the name it has always had, so that a refusal names the field as the user
spells it (e.g. ``design_modes must be an integer in 1..20, got 0``).
:func:`compare_arguments` routes a flat dictionary of these names (the command line's, a
sweep's case) into the values, in one place.

Examples
--------
>>> from hubbeam_ctrl.study.compare_values import CompareSettings, PlantChoice, RunChoice
>>> s = CompareSettings(plant=PlantChoice("cfoam", plant_modes=8), run=RunChoice(t_end=5.0))
>>> s.plant.plant, s.run.t_end
('cfoam', 5.0)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from controllers.schedule import MAX_SCHEDULE_POINTS
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.study.scenarios import PLANTS, REFERENCES
from hubbeam_ctrl.study.yardstick import LIMIT_KINDS

__all__ = ["REFERENCE_KINDS", "DEFAULT_T_F", "PlantChoice", "DesignChoice", "RunChoice", "ScenarioChoice",
           "PayloadChoice", "CompareSettings", "compare_arguments", "check_schedule"]

#: The references :func:`~hubbeam_ctrl.study.compare.compare` accepts: the scenario's
#: (:data:`~hubbeam_ctrl.study.scenarios.REFERENCES`) and the nonlinear minimum-vibration slew.
REFERENCE_KINDS = REFERENCES


def _params_or_none(name: str, value) -> None:
    if value is not None and not isinstance(value, Params):
        raise ParameterError(f"{name} must be a Params (hubbeam_ctrl.plant.params) or None, "
                             f"got {type(value).__name__}")


def check_schedule(points) -> int:
    """``points`` if it is a valid number of design spins, else a one-line refusal naming ``schedule``.

    Parameters
    ----------
    points : int
        Spin rates of a design schedule, 1..MAX_SCHEDULE_POINTS.

    Returns
    -------
    int
    """
    if isinstance(points, bool) or not isinstance(points, int) or not 1 <= points <= MAX_SCHEDULE_POINTS:
        shown = (f"{points:.4g}" if isinstance(points, int) and abs(points) >= 10**15     # 1e308 as 1e+308
                 else repr(points) if len(repr(points)) <= 40 else repr(points)[:37] + "...")
        raise ParameterError(f"schedule must be an integer >= 1 and <= {MAX_SCHEDULE_POINTS} (number of spin rates; "
                             f"1 = a single design at the scenario's design spin), got {shown}")
    return points


@dataclass(frozen=True)
class PlantChoice:
    """The nonlinear plant the controllers are judged on.

    Attributes
    ----------
    plant : {"foam", "cfoam", "ancf"}
        Nonlinear plant (:data:`~hubbeam_ctrl.study.scenarios.PLANTS`; default FOAM: it tracks
        an exact beam more closely than CFOAM at large deflection, see docs/physics.md).
    plant_params : Params, optional
        The plant's parameters (SI units) when they differ from the design's (e.g. another
        tip mass); default: the rig's beam.
    plant_modes : int, optional
        Transverse modes of the plant, ``design_modes..20`` (default: every bending mode below
        the sampling frequency and at least three more than the design,
        :func:`~hubbeam_ctrl.sim.evaluation.evaluation_plant`).
    check_plant : {"foam", "cfoam", "ancf"}, optional
        Run every controller also on this plant (same modes, step, sensors and hardware) and
        judge it there (:attr:`Comparison.check_metrics`); a plant other than ``plant``.
    backend : {"auto", "compiled", "vm"}, optional
        How the plant is evaluated (see :class:`~hubbeam_ctrl.sim.stepper.PlantStepper`);
        default ``$HUBBEAM_BACKEND`` or ``"auto"``.
    """

    plant: str = "foam"
    plant_params: Params | None = None
    plant_modes: int | None = None
    check_plant: str | None = None
    backend: str | None = None

    def __post_init__(self):
        _params_or_none("plant_params", self.plant_params)
        if self.check_plant is not None and (self.check_plant not in PLANTS or self.check_plant == self.plant):
            others = ", ".join(p for p in PLANTS if p != self.plant)
            raise ParameterError(f"check_plant must be one of {others} (a plant other than plant = {self.plant!r}), "
                                 f"got {self.check_plant!r}")


@dataclass(frozen=True)
class DesignChoice:
    """How the controllers are designed on SFOAM and what they track.

    Attributes
    ----------
    design_params : Params, optional
        The design model's parameters (SI units) when they differ from the rig's beam.
    design_modes : int, optional
        Transverse modes of the design model, 1..20 (default ``design_params.n_transverse``).
    horizon : int
        MPC horizon [samples] (passed to every controller's ``for_scenario``).
    solver : str
        MPC QP solver (see :data:`controllers.QP_SOLVERS`; passed likewise).
    settings : dict, optional
        Controller name -> settings object, replacing the defaults
        (``SettingsClass.for_scenario(scenario, horizon=..., solver=...)``).
    tolerances : controllers.scaling.Tolerances, optional
        The dimensionless tolerances that scale the default weights, noise levels, settling
        bands, residual window and reference shaping (:mod:`controllers.scaling`).
    integral : bool, optional
        Integral action of LQR, LQG and MPC on a rig (default: on when the rig has friction or
        a DC motor, :func:`hubbeam_ctrl.study.rig_loop.integral_default`).
    limit : {"rigid", "optimal"}
        The yardstick of the settling times (:mod:`hubbeam_ctrl.study.yardstick`).
    reference : {"task", "rigid", "planned", "optimal"}
        The reference and feedforward of the controllers that track one (see
        :func:`~hubbeam_ctrl.study.compare.compare`).
    shaping : {"zv", "zvd", "ei"} or Shaper, optional
        Filter the reference of the controllers that track it through this input shaper,
        designed on the design model's first mode.
    schedule : int
        Spin rates of the design schedule of the controllers with a scheduled version (lqr,
        lqg, mpc), 1..MAX_SCHEDULE_POINTS; 1: a single design at the scenario's design spin.
    """

    design_params: Params | None = None
    design_modes: int | None = None
    horizon: int = 50
    solver: str = "daqp"
    settings: dict | None = None
    tolerances: object = None
    integral: bool | None = None
    limit: str = "rigid"
    reference: str = "task"
    shaping: object = None
    schedule: int = 1

    def __post_init__(self):
        _params_or_none("design_params", self.design_params)
        m = self.design_modes
        if m is not None and (isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= MAX_MODES):
            raise ParameterError(f"design_modes must be an integer in 1..{MAX_MODES}, got {m!r}")
        if self.settings is not None and not isinstance(self.settings, dict):
            raise ParameterError(f"settings must be a dict of controller name -> settings, "
                                 f"got {type(self.settings).__name__}")
        if self.reference not in REFERENCE_KINDS:
            raise ParameterError(f"reference must be one of {', '.join(REFERENCE_KINDS)}, got {self.reference!r}")
        if self.limit not in LIMIT_KINDS:
            raise ParameterError(f"limit must be one of {', '.join(LIMIT_KINDS)}, got {self.limit!r}")
        check_schedule(self.schedule)


@dataclass(frozen=True)
class RunChoice:
    """The sample time, the simulated time and the plant's integration settings.

    Attributes
    ----------
    dt : float, optional
        Controller sample time [s] (default: the rig's, else
        :func:`hubbeam_ctrl.study.yardstick.task_dt`, 10 ms unless the beam's first mode needs less).
    t_end : float, optional
        Simulated time [s] (default: the task's, :func:`hubbeam_ctrl.study.yardstick.task_t_end`).
    sim_settings : ClosedLoopSettings or dict, optional
        Plant integration and sensor settings (its ``dt`` is replaced by ``dt``); a dict gives
        fields of :class:`~hubbeam_ctrl.sim.closedloop.ClosedLoopSettings` that replace those of
        the task's default (the CLI passes ``range_limit`` and its run limits this way).
    side_by_side : bool
        Run the closed loops side by side, part of them in a forked child
        (:mod:`hubbeam_ctrl.study.forked_runs`), when nothing ties them together (no check
        plant, no uncertainty set, no payload learning). The numbers are the same; the
        controllers that ran in the child keep their run's state (step times, counters) there,
        so :attr:`Comparison.controllers` holds them as designed. ``hubbeam compare`` sets it;
        default False (also :data:`hubbeam_ctrl.study.compare.SIDE_BY_SIDE`).
    """

    dt: float | None = None
    t_end: float | None = None
    sim_settings: object = None
    side_by_side: bool = False

    def __post_init__(self):
        s = self.sim_settings
        if isinstance(s, dict):
            unknown = sorted(set(s) - {f.name for f in dataclasses.fields(ClosedLoopSettings)})
            if unknown:
                raise ParameterError(f"sim_settings: unknown field(s) {', '.join(unknown)} of ClosedLoopSettings")
        elif s is not None and not isinstance(s, ClosedLoopSettings):
            raise ParameterError(f"sim_settings must be a ClosedLoopSettings or a dict, got {type(s).__name__}")


#: A registered scenario's maneuver time when none is given [s].
DEFAULT_T_F = 10.0


@dataclass(frozen=True)
class ScenarioChoice:
    """The shape of a registered scenario, the torque budget and the settling bands.

    Attributes
    ----------
    t_f : float, optional
        Maneuver time of a registered scenario [s] (a Slew/SpinUp task gives its own ``duration``).
        None: :data:`DEFAULT_T_F`; on a rig with any hardware (not ideal), a ``slew`` is the rig's default slew
        (:func:`hubbeam_ctrl.study.yardstick.rig_default_slew`, by ``slew_angle`` if given).
    w_f : float
        Spin-up final rate [rad/s] (registered ``spinup`` only).
    slew_angle : float, optional
        Slew angle [rad] (registered ``slew`` only; default: the Eq. 44 angle of ``tau_max`` and ``t_f``).
    tau_max : float, optional
        Torque budget [N m], at most the motor's ``Params.tau_max`` (default: that limit).
    settle_angle, settle_tip : float or str, optional
        The task's own settling bands (a number in rad or m, or ``"2counts"``, ``"0.05deg"``,
        ``"0.5mm"``, ``"1e-3L"``; :func:`hubbeam_ctrl.study.bands.parse_band`).
    """

    t_f: float | None = None
    w_f: float = 3.0
    slew_angle: float | None = None
    tau_max: float | None = None
    settle_angle: object = None
    settle_tip: object = None


@dataclass(frozen=True)
class PayloadChoice:
    """A payload range to design for, and learning the payload during a slew.

    Attributes
    ----------
    payload_range : tuple of float, optional
        ``(m_min, m_max)`` [kg] that LQR, LQG and MPC are designed for
        (:func:`hubbeam_ctrl.study.range_design.range_designs`); must hold the design's ``m_t``.
    payload_learning : controllers.payload_learning.PayloadLearningSettings, optional
        LQR, MPC and LQG learn the payload during a slew and re-plan for it (slew tasks
        without a rig only).
    """

    payload_range: tuple | None = None
    payload_learning: object = None

    def __post_init__(self):
        if self.payload_learning is not None:
            from controllers.payload_learning import PayloadLearningSettings
            if not isinstance(self.payload_learning, PayloadLearningSettings):
                raise ParameterError(f"payload_learning must be a PayloadLearningSettings, "
                                     f"got {type(self.payload_learning).__name__}")


_GROUPS = {"plant": PlantChoice, "design": DesignChoice, "run": RunChoice, "scenario": ScenarioChoice,
           "payload": PayloadChoice}


@dataclass(frozen=True)
class CompareSettings:
    """Everything :func:`~hubbeam_ctrl.study.compare.compare` takes besides the rig, the task
    and the controllers, grouped by role (each group validates its own fields).

    Attributes
    ----------
    plant : PlantChoice
    design : DesignChoice
    run : RunChoice
    scenario : ScenarioChoice
    payload : PayloadChoice
    """

    plant: PlantChoice = field(default_factory=PlantChoice)
    design: DesignChoice = field(default_factory=DesignChoice)
    run: RunChoice = field(default_factory=RunChoice)
    scenario: ScenarioChoice = field(default_factory=ScenarioChoice)
    payload: PayloadChoice = field(default_factory=PayloadChoice)

    def __post_init__(self):
        for name, kind in _GROUPS.items():
            if not isinstance(getattr(self, name), kind):
                raise ParameterError(f"settings.{name} must be a {kind.__name__}, "
                                     f"got {type(getattr(self, name)).__name__}")


#: Field name -> the CompareSettings group that holds it.
FIELD_GROUP = {f.name: group for group, kind in _GROUPS.items() for f in dataclasses.fields(kind)}


def compare_arguments(plant: str = "foam", scenario="slew", controllers=None, *, params=None, rig=None,
                      **fields) -> dict:
    """Route flat option names into ``compare``'s arguments, in one place (the CLI, the ladder,
    the payload study and sweeps build dictionaries of options).

    Parameters
    ----------
    plant : str
        :attr:`PlantChoice.plant`.
    scenario : str or Slew or SpinUp
        The task.
    controllers : str or sequence of str, optional
        The controllers.
    params : Params, optional
        The beam alone (used when ``rig`` is None).
    rig : Rig, optional
        The rig (its beam is the parameters).
    **fields
        Fields of the values above by name (``t_end``, ``design_modes``...), and ``designs``
        and ``progress`` of ``compare``.

    Returns
    -------
    dict
        Keyword arguments of :func:`~hubbeam_ctrl.study.compare.compare`.
    """
    extra = {k: fields.pop(k) for k in ("designs", "progress") if k in fields}
    unknown = sorted(set(fields) - set(FIELD_GROUP))
    if unknown:
        raise ParameterError(f"compare: unknown option(s) {', '.join(unknown)}")
    grouped = {g: {} for g in _GROUPS}
    for k, v in fields.items():
        grouped[FIELD_GROUP[k]][k] = v
    grouped["plant"]["plant"] = plant
    if rig is not None and params is not None:           # the rig's beam replaced by params
        grouped["design"].setdefault("design_params", params)
        grouped["plant"].setdefault("plant_params", params)
    settings = CompareSettings(**{g: _GROUPS[g](**kw) for g, kw in grouped.items()})
    return dict(rig=rig if rig is not None else params, task=scenario, controllers=controllers,
                settings=settings, **extra)


def as_rig(rig) -> tuple:
    """``(rig or None, beam parameters or None)`` of compare's ``rig`` argument.

    Parameters
    ----------
    rig : Rig or Params or None
        A rig, the beam alone (SI units), or None (Table 1).

    Returns
    -------
    tuple
    """
    if rig is None or isinstance(rig, Rig):
        return rig, None
    if isinstance(rig, Params):
        return None, rig
    hint = "; the plant is PlantChoice(plant=...) of CompareSettings" if isinstance(rig, str) else ""
    raise ParameterError(f"rig must be a Rig (hubbeam_ctrl.plant.rig.load_rig), a Params (the beam alone) or None, "
                         f"got {type(rig).__name__}{hint}")
