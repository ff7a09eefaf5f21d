"""The open-loop baseline: the paper's Eq. 44 torque, or a reference's feedforward."""

from __future__ import annotations

import math
from dataclasses import dataclass

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_finite

from .base import Controller, DesignModel, Reference, check_positive, saturate, torque_limit

__all__ = ["OpenLoopSettings", "OpenLoop"]


@dataclass(frozen=True)
class OpenLoopSettings:
    """Settings of :class:`OpenLoop`."""

    profile: str = "eq44"
    """``"eq44"``: ``tau_m sin(2 pi t/t_f)`` for ``t <= t_f``, then 0 (the paper's Eq. 44);
    ``"feedforward"``: the reference's rigid-body feedforward torque (clipped at the
    motor's ``Params.tau_max``)."""
    tau_m: float = 200.0
    """Torque amplitude of Eq. 44 [N m], 0 < |tau_m| <= Params.tau_max of the design model
    (negative: the slew turns the other way)."""
    t_f: float = 10.0
    """Maneuver time of Eq. 44 [s], > 0 (one full sine period)."""

    def __post_init__(self):
        if self.profile not in ("eq44", "feedforward"):
            raise ParameterError(f"profile must be 'eq44' or 'feedforward', got {self.profile!r}")
        if check_finite("tau_m", self.tau_m, "N m") == 0.0:
            raise ParameterError("tau_m must be a finite number != 0 [N m], got 0")
        check_positive("tf", self.t_f, "s")


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

    name = "openloop"
    measurement = "state"

    def __init__(self, design: DesignModel, settings: OpenLoopSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or OpenLoopSettings()
        if settings.profile == "feedforward" and reference is None:
            raise ParameterError("profile='feedforward' needs a reference")
        super().__init__(design, settings, reference)
        if settings.profile == "eq44":
            torque_limit(abs(settings.tau_m), design.params, "|tau_m|")     # within the motor's limit
        self._w = 2 * math.pi / settings.t_f

    def __call__(self, t: float, y) -> float:
        s = self.settings
        if s.profile == "eq44":
            return s.tau_m * math.sin(self._w * t) if t <= s.t_f else 0.0
        k = self.reference.index(t)
        return saturate(float(self.reference.window(k, 1)[2][0]), self.tau_max)
