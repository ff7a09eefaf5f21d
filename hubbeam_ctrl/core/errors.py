"""Exceptions raised by hubbeam-ctrl."""

import errno as _errno

__all__ = ["HubbeamError", "ParameterError", "UserFunctionError", "ResourceError", "RESOURCE_ERRNOS",
           "write_error"]

#: OS errors that say the system ran out of something (space, quota, the device), not that
#: the caller asked for something wrong.
RESOURCE_ERRNOS = frozenset(getattr(_errno, n) for n in ("ENOSPC", "EDQUOT", "EIO", "EFBIG", "ENOMEM")
                            if hasattr(_errno, n))


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


class ResourceError(HubbeamError, OSError):
    """The system could not do what was asked (disk full, quota, I/O error): not bad input.

    The command line reports it in one line with exit status 1 (2 is kept for bad input).
    """


def write_error(exc: OSError, what: str) -> HubbeamError:
    """The one-line error of a failed write: :class:`ResourceError` when the system ran out of
    something (:data:`RESOURCE_ERRNOS`), else :class:`ParameterError` (a path the caller chose
    that cannot be written).

    Parameters
    ----------
    exc : OSError
        What the system raised.
    what : str
        The start of the message (``"out: cannot write results.csv"``).
    """
    reason = exc.strerror or getattr(exc, "reason", None) or exc      # a nested write_error: its reason alone
    resource = exc.errno in RESOURCE_ERRNOS or isinstance(exc, ResourceError)
    err = (ResourceError if resource else ParameterError)(f"{what}: {reason}")
    err.reason = str(reason)
    return err
