"""Connecting a sweep to a Dask cluster: :func:`connect` parses the scheduler's address and
probes its port before making the client, so a wrong or unreachable address is a one-line
error. :func:`hubbeam_ctrl.study.sweep.sweep` runs its batches on the client
(:class:`~hubbeam_ctrl.study.sweep.Engine`); the name is importable from
:mod:`hubbeam_ctrl.study.sweep` too.
"""

from __future__ import annotations

import socket
import sys

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["connect"]


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".strip()


def connect(address: str, timeout: float = 10.0):
    """A ``dask.distributed.Client`` of the scheduler at ``address``.

    The address is parsed and the scheduler's port probed (one TCP connection, at most
    ``timeout`` seconds) before the client is made, so a wrong or unreachable address is one
    :class:`ParameterError`, not a half-made client.

    Parameters
    ----------
    address : str
        E.g. ``tcp://10.0.0.5:8786`` (``tcp://`` or ``tls://``; the port defaults to 8786).
    timeout : float
        Seconds to wait for the scheduler, > 0.

    Returns
    -------
    distributed.Client

    Raises
    ------
    ParameterError
        If the address is not ``tcp://HOST:PORT`` or no scheduler answers within ``timeout``.
    """
    host, port = _scheduler_host_port(address)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout < 1e6:
        raise ParameterError(f"timeout must be a number of seconds in (0, 1e6), got {timeout!r}")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except (OSError, ValueError) as exc:
        raise ParameterError(f"scheduler: no Dask scheduler answered at {address!r} within {timeout:g} s "
                             f"({_one_line(exc)})") from None
    failure = _make_client(address, timeout)
    if not isinstance(failure, str):
        return failure
    raise ParameterError(f"scheduler: {address!r} did not answer as a Dask scheduler within {timeout:g} s ({failure})")


def _scheduler_host_port(address) -> tuple:
    """``(host, port)`` of a scheduler address, or ParameterError naming ``--scheduler``."""
    from distributed.comm.addressing import parse_address, parse_host_port
    bad = ParameterError(f"scheduler must be an address tcp://HOST:PORT (port 1..65535), got {str(address)[:80]!r}")
    if not isinstance(address, str) or not address.strip() or any(c.isspace() for c in address):
        raise bad
    try:
        scheme, loc = parse_address(address)
        host, port = parse_host_port(loc, 8786)
    except (ValueError, TypeError):
        raise bad from None
    if scheme not in ("tcp", "tls") or not host or not 1 <= int(port) <= 65535:
        raise bad
    return host, int(port)


def _make_client(address: str, timeout: float):
    """The client, or the one-line reason it could not be made (its half-made client is
    collected here, quietly: ``Client.__del__`` would print a traceback later)."""
    import gc

    from distributed import Client
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a garbled answer can be a MemoryError, an OSError, ...
        failure = _one_line(exc)
        exc.__traceback__ = None
        del exc
    hook, sys.unraisablehook = sys.unraisablehook, lambda _u: None
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook
    return failure
