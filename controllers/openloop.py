"""The open-loop baseline: the paper's Eq. 44 torque, or a reference's feedforward."""

from __future__ import annotations

import math
from dataclasses import dataclass

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, ControllerSettings, DesignModel, Reference, saturate, torque_limit

__all__ = ["OpenLoopSettings", "OpenLoop"]


@dataclass(frozen=True)
class OpenLoopSettings(ControllerSettings):
    """Settings of :class:`OpenLoop`."""

    profile: str = setting("eq44", choices=("eq44", "feedforward"),
                           doc="eq44: tau_m sin(2 pi t/t_f) for t <= t_f, then 0 (the paper's Eq. 44); "
                               "feedforward: the reference's rigid-body feedforward torque (clipped "
                               "at the motor's Params.tau_max).")
    tau_m: float = setting(200.0, unit="N m", doc="Torque amplitude of Eq. 44, not 0 (negative: the "
                                                  "slew turns the other way); abs(tau_m) at most the "
                                                  "motor's Params.tau_max of the design model.")
    t_f: float = setting(10.0, unit="s", lo=0.0, lo_open=True,
                         doc="Maneuver time of Eq. 44 (one full sine period).")

    @classmethod
    def for_scenario(cls, scenario, **options) -> "OpenLoopSettings":
        """The scenario's baseline (``scenario.baseline``) with its amplitude and time.

        Parameters
        ----------
        scenario : object
            Read: ``baseline`` (a profile), ``baseline_tau_m`` (the Eq. 44 amplitude of a
            slew; ``tau_max`` when None), ``t_f``.
        **options
            Ignored.

        Returns
        -------
        OpenLoopSettings
        """
        tau_m = getattr(scenario, "baseline_tau_m", None)
        return cls(profile=scenario.baseline, tau_m=scenario.tau_max if tau_m is None else tau_m,
                   t_f=scenario.t_f)

    def __post_init__(self):
        super().__post_init__()
        if self.tau_m == 0.0:
            raise ParameterError("tau_m must be a finite number != 0 [N m], got 0")


class OpenLoop(Controller):
    """Open-loop torque, sampled and held like any controller's output (no feedback).

    Parameters
    ----------
    design : DesignModel
        Only its ``dt`` is used.
    settings : OpenLoopSettings, optional
    reference : Reference, optional
        Needed for ``profile="feedforward"``.

    Examples
    --------
    >>> from controllers import DesignModel, OpenLoop
    >>> ol = OpenLoop(DesignModel.build(n_modes=1))
    >>> round(ol(2.5, None), 6)           # tau_m sin(pi/2)
    200.0
    """

    measurement = "state"

    def __init__(self, design: DesignModel, settings: OpenLoopSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or OpenLoopSettings()
        if settings.profile == "feedforward" and reference is None:
            raise ParameterError("profile='feedforward' needs a reference")
        super().__init__(design, settings, reference)
        if settings.profile == "eq44":
            torque_limit(abs(settings.tau_m), design.params, "abs(tau_m)")   # within the motor's limit
        self._w = 2 * math.pi / settings.t_f

    def __call__(self, t: float, y) -> float:
        s = self.settings
        if s.profile == "eq44":
            return s.tau_m * math.sin(self._w * t) if t <= s.t_f else 0.0
        k = self.reference.index(t)
        return saturate(float(self.reference.window(k, 1)[2][0]), self.tau_max)
