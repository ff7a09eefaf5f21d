"""The controller registry: each controller is registered once, everything else reads it.

:func:`make_controller`, the comparison of :mod:`hubbeam_ctrl.study.compare` (default list,
default settings per scenario), the CLI's ``--controllers`` help and the plot colours all
read :data:`CONTROLLERS`. Adding a controller is one new module plus one
:func:`register_controller` entry (for the built-ins: at the end of this module)::

    @dataclass(frozen=True)
    class MySettings(TrackingSettings):
        gain: float = setting(1.0, unit="N m/rad", lo=0.0, doc="Angle gain.")

    class MyController(Controller):
        measurement = "state"
        def __call__(self, t, y): ...

    register_controller("mine", MySettings, controller=MyController, color="tab:purple",
                        label="my controller")

Its settings class's ``for_scenario`` hook (see
:meth:`controllers.base.ControllerSettings.for_scenario`) gives its defaults in a comparison.
Two options of :func:`make_controller` (and of the comparison) act through the registry:
``shaping`` filters the reference of every controller that tracks one (settings derived
from :class:`~controllers.base.TrackingSettings`) through an input shaper, and
``schedule`` builds the controller's gain-scheduled version (its ``scheduled`` entry, e.g.
:class:`~controllers.schedule.ScheduledLQR`) on a :class:`~controllers.schedule.DesignSchedule`.
"""

from __future__ import annotations

from dataclasses import dataclass

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, ControllerSettings, DesignModel, Reference, TrackingSettings
from .hinf import HInf, HInfSettings
from .lqg import LQG, LQGSettings
from .lqr import LQR, LQRSettings
from .mpc import MPC, MPCSettings
from .msmpc import MultiStageMPC, MultiStageMPCSettings
from .nmpc import NMPC, NMPCSettings
from .openloop import OpenLoop, OpenLoopSettings
from .pd import PD, PDSettings
from .schedule import DesignSchedule, ScheduledLQG, ScheduledLQR, ScheduledMPC
from .shaped import EIOpenLoop, ShapedSettings, ZVDOpenLoop, ZVOpenLoop
from .shaping import as_shaper, shape_reference

__all__ = ["ControllerSpec", "CONTROLLERS", "register_controller", "unregister_controller",
           "make_controller", "controller_names", "controller_styles"]


@dataclass(frozen=True)
class ControllerSpec:
    """One registered controller.

    Attributes
    ----------
    name : str
        Registry key (``"lqr"``), also the controller's ``name``.
    controller : type
        The :class:`~controllers.base.Controller` subclass.
    settings : type
        Its settings class (a :class:`~controllers.base.ControllerSettings`).
    color : str or None
        Matplotlib colour of its curves.
    label : str
        Legend label.
    target : bool
        Held to the slew's targets in reports (otherwise only reported).
    default : bool
        Run by a comparison when no list is given.
    scheduled : type or None
        Its gain-scheduled version, built as ``scheduled(schedule, settings, reference)``
        on a :class:`~controllers.schedule.DesignSchedule` (None: no such version).
    """

    name: str
    controller: type
    settings: type
    color: str | None
    label: str
    target: bool
    default: bool
    scheduled: type | None = None

    @property
    def style(self) -> dict:
        """Plot style ``{"color": ..., "label": ...}``."""
        return {"color": self.color, "label": self.label}

    @property
    def tracks_reference(self) -> bool:
        """Whether it follows the reference by feedback (settings a ``TrackingSettings``), so that
        input shaping filters its reference."""
        return issubclass(self.settings, TrackingSettings)


#: Registered controllers by name, in registration order.
CONTROLLERS: dict = {}


def register_controller(name: str, settings, *, controller: type | None = None, color: str | None = None,
                        label: str | None = None, target: bool = False, default: bool = True,
                        scheduled: type | None = None):
    """Register a controller class under ``name`` (a decorator, or a call with ``controller``).

    Parameters
    ----------
    name : str
        Registry key: lower case, no comma (it appears in ``--controllers`` lists).
    settings : type
        Settings class, a subclass of :class:`~controllers.base.ControllerSettings`.
    controller : type, optional
        The :class:`~controllers.base.Controller` subclass; without it a decorator is returned.
    color : str, optional
        Matplotlib colour (default: the colour cycle).
    label : str, optional
        Legend label (default ``name``).
    target : bool
        Held to the slew's targets in reports.
    default : bool
        Part of a comparison's default list.
    scheduled : type, optional
        Its gain-scheduled version (a ``controller`` subclass taking a
        :class:`~controllers.schedule.DesignSchedule` instead of the design model).

    Returns
    -------
    type or callable
        ``controller`` (its ``name`` set to ``name`` unless it defines its own), or a decorator.

    Examples
    --------
    >>> from controllers import TrackingSettings
    >>> @register_controller("zero", TrackingSettings, default=False)
    ... class Zero(Controller):
    ...     def __call__(self, t, y):
    ...         return 0.0
    >>> Zero.name, CONTROLLERS["zero"].label
    ('zero', 'zero')
    >>> unregister_controller("zero")
    """
    if not isinstance(name, str) or not name or name != name.strip().lower() or "," in name:
        raise ParameterError(f"name must be a non-empty lower-case string without commas, got {name!r}")
    if not (isinstance(settings, type) and issubclass(settings, ControllerSettings)):
        raise ParameterError(f"settings must be a ControllerSettings subclass, got {settings!r}")
    if scheduled is not None and not (isinstance(scheduled, type) and issubclass(scheduled, Controller)):
        raise ParameterError(f"scheduled must be a Controller subclass, got {scheduled!r}")

    def register(cls):
        if not (isinstance(cls, type) and issubclass(cls, Controller)):
            raise ParameterError(f"controller must be a Controller subclass, got {cls!r}")
        if name in CONTROLLERS and CONTROLLERS[name].controller is not cls:
            raise ParameterError(f"controller {name!r} is already registered "
                                 f"({CONTROLLERS[name].controller.__name__})")
        for c in (cls, scheduled):
            if c is not None and "name" not in vars(c):
                c.name = name
        CONTROLLERS[name] = ControllerSpec(name, cls, settings, color, label or name, bool(target),
                                           bool(default), scheduled)
        return cls

    return register if controller is None else register(controller)


def unregister_controller(name: str) -> None:
    """Remove a registered controller (e.g. one a test added).

    Parameters
    ----------
    name : str
        Registry key.
    """
    if CONTROLLERS.pop(name, None) is None:
        raise ParameterError(f"controller {name!r} is not registered")


def _spec(name: str) -> ControllerSpec:
    if name not in CONTROLLERS:
        raise ParameterError(f"controllers: unknown controller {name!r}; allowed: {', '.join(CONTROLLERS)}")
    return CONTROLLERS[name]


def make_controller(name: str, design: DesignModel, settings=None, reference: Reference | None = None, *,
                    shaping=None, schedule: DesignSchedule | None = None):
    """Build a registered controller by name (``openloop``, ``pd``, ``lqr``, ``lqg``, ``mpc``, ``zv``...).

    Parameters
    ----------
    name : str
        Registry key.
    design : DesignModel
        Sampled design model.
    settings : ControllerSettings, optional
        The controller's settings (default: its settings class's defaults).
    reference : Reference, optional
        Hub trajectory and feedforward torque.
    shaping : {"zv", "zvd", "ei"} or Shaper, optional
        Filter the reference (and its feedforward) through this input shaper first (a kind:
        designed on the first mode of ``design``, see :func:`controllers.shaping.as_shaper`).
        Only for controllers that track the reference (:attr:`ControllerSpec.tracks_reference`).
    schedule : DesignSchedule, optional
        Build the controller's gain-scheduled version on it (:attr:`ControllerSpec.scheduled`);
        ``design`` then gives the shaper, and its rig's sensors and delay, which every design of
        the grid takes (:meth:`DesignSchedule.on_rig`: a scheduled LQG reads the rig's own sensors).

    Returns
    -------
    Controller

    Examples
    --------
    >>> from controllers import DesignModel
    >>> from hubbeam_ctrl import Params
    >>> ctrl = make_controller("lqr", DesignModel.build(Params(n_axial=1, n_transverse=2)), shaping="zvd")
    >>> ctrl.reference.description
    'rest, shaped by zvd (2.175 s)'
    """
    spec = _spec(name)
    settings = settings if settings is not None else spec.settings()
    if shaping is not None:
        if not spec.tracks_reference:
            raise ParameterError(f"shaping: {name!r} does not track a reference (only the controllers "
                                 f"with TrackingSettings do: {', '.join(_tracking_names())})")
        reference = shape_reference(reference if reference is not None else Reference.rest(design.dt),
                                    as_shaper(design, shaping))
    if schedule is None:
        return spec.controller(design, settings, reference)
    if spec.scheduled is None:
        raise ParameterError(f"schedule: no scheduled version of {name!r}; allowed: "
                             f"{', '.join(n for n, s in CONTROLLERS.items() if s.scheduled)}")
    # the grid's designs read what the design reads (a rig's sensors and delay: DesignModel.on_rig)
    return spec.scheduled(schedule.on_rig(design.sensors, design.delay, design.hub_damping), settings, reference)


def _tracking_names() -> list:
    return [n for n, s in CONTROLLERS.items() if s.tracks_reference]


def controller_names(default: bool | None = None, target: bool | None = None) -> tuple:
    """Registered names in registration order, optionally filtered.

    Parameters
    ----------
    default : bool, optional
        Keep only those with (or without) the ``default`` flag.
    target : bool, optional
        Keep only those with (or without) the ``target`` flag.

    Returns
    -------
    tuple of str
    """
    return tuple(n for n, s in CONTROLLERS.items()
                 if (default is None or s.default == default) and (target is None or s.target == target))


def controller_styles(names=None) -> dict:
    """Plot styles ``name -> {"color", "label"}`` of registered controllers.

    Parameters
    ----------
    names : iterable of str, optional
        Default: every registered controller. Unregistered names are left out.

    Returns
    -------
    dict
    """
    names = CONTROLLERS if names is None else names
    return {n: CONTROLLERS[n].style for n in names if n in CONTROLLERS}


# -- the built-in controllers (one entry each, in the order comparisons show them) ---------------
register_controller("openloop", OpenLoopSettings, controller=OpenLoop, color="0.45", label="open loop")
register_controller("pd", PDSettings, controller=PD, color="tab:orange", label="PD")
register_controller("lqr", LQRSettings, controller=LQR, color="tab:blue", label="LQR", target=True,
                    scheduled=ScheduledLQR)
register_controller("lqg", LQGSettings, controller=LQG, color="tab:green", label="LQG", target=True,
                    scheduled=ScheduledLQG)
register_controller("mpc", MPCSettings, controller=MPC, color="tab:red", label="MPC", target=True,
                    scheduled=ScheduledMPC)
# multi-stage MPC over payload scenarios (controllers.msmpc), run when asked for
register_controller("msmpc", MultiStageMPCSettings, controller=MultiStageMPC, color="tab:pink",
                    label="MSMPC", default=False)
# mixed-sensitivity H-infinity on the hub angle (controllers.hinf, needs slycot), run when asked for
register_controller("hinf", HInfSettings, controller=HInf, color="tab:gray", label="H-infinity", default=False)
# nonlinear MPC on the beam's own model by real-time iteration (controllers.nmpc), run when asked for
register_controller("nmpc", NMPCSettings, controller=NMPC, color="tab:brown", label="NMPC", default=False)
# open-loop input-shaped slews (controllers.shaped), run only when asked for
register_controller("zv", ShapedSettings, controller=ZVOpenLoop, color="tab:purple", label="ZV shaped",
                    default=False)
register_controller("zvd", ShapedSettings, controller=ZVDOpenLoop, color="tab:cyan", label="ZVD shaped",
                    default=False)
register_controller("ei", ShapedSettings, controller=EIOpenLoop, color="tab:olive", label="EI shaped",
                    default=False)
