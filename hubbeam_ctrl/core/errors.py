"""Exceptions raised by hubbeam-ctrl."""

__all__ = ["HubbeamError", "ParameterError", "UserFunctionError"]


class HubbeamError(Exception):
    """Base class of the toolbox's own errors."""


class ParameterError(HubbeamError, ValueError):
    """An input is outside its allowed range; the message names it and the range."""


class UserFunctionError(HubbeamError):
    """A function given by the caller (a torque or maneuver of time) raised or returned a bad value.

    The message names the function and the time; ``t`` holds that time [s] (``None`` when
    it is not known) and ``__cause__`` the caller's own exception, if there was one.

    Parameters
    ----------
    message : str
        One line naming the function and the time.
    t : float, optional
        Time where it failed [s].
    """

    def __init__(self, message: str, t: float | None = None):
        super().__init__(message)
        self.t = t
