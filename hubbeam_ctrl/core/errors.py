"""Exceptions raised by hubbeam-ctrl."""

__all__ = ["HubbeamError", "ParameterError"]


class HubbeamError(Exception):
    """Base class of the toolbox's own errors."""


class ParameterError(HubbeamError, ValueError):
    """An input is outside its allowed range; the message names it and the range."""
