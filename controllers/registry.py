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
"""

from __future__ import annotations

from dataclasses import dataclass

from hubbeam_ctrl.core.errors import ParameterError

from .base import Controller, ControllerSettings, DesignModel, Reference
from .lqg import LQG, LQGSettings
from .lqr import LQR, LQRSettings
from .mpc import MPC, MPCSettings
from .openloop import OpenLoop, OpenLoopSettings
from .pd import PD, PDSettings

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
    """

    name: str
    controller: type
    settings: type
    color: str | None
    label: str
    target: bool
    default: bool

    @property
    def style(self) -> dict:
        """Plot style ``{"color": ..., "label": ...}``."""
        return {"color": self.color, "label": self.label}


#: Registered controllers by name, in registration order.
CONTROLLERS: dict = {}


def register_controller(name: str, settings, *, controller: type | None = None, color: str | None = None,
                        label: str | None = None, target: bool = False, default: bool = True):
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

    def register(cls):
        if not (isinstance(cls, type) and issubclass(cls, Controller)):
            raise ParameterError(f"controller must be a Controller subclass, got {cls!r}")
        if name in CONTROLLERS and CONTROLLERS[name].controller is not cls:
            raise ParameterError(f"controller {name!r} is already registered "
                                 f"({CONTROLLERS[name].controller.__name__})")
        if "name" not in vars(cls):
            cls.name = name
        CONTROLLERS[name] = ControllerSpec(name, cls, settings, color, label or name, bool(target),
                                           bool(default))
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


def make_controller(name: str, design: DesignModel, settings=None, reference: Reference | None = None):
    """Build a registered controller by name (``openloop``, ``pd``, ``lqr``, ``lqg``, ``mpc``...).

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

    Returns
    -------
    Controller
    """
    spec = _spec(name)
    return spec.controller(design, settings if settings is not None else spec.settings(), reference)


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
register_controller("lqr", LQRSettings, controller=LQR, color="tab:blue", label="LQR", target=True)
register_controller("lqg", LQGSettings, controller=LQG, color="tab:green", label="LQG", target=True)
register_controller("mpc", MPCSettings, controller=MPC, color="tab:red", label="MPC", target=True)
