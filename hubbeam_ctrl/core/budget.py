"""Budgets: the memory and wall time a run will take, estimated before it starts.

A run whose estimate exceeds its limits is refused with one line that names the quantity
that makes it large, the estimate, the limit and how to raise the limit, before any work is
done. The estimates are deliberately low (costs measured on a 2-core machine, divided by
about three), so a run that is refused would certainly have exceeded its limit; runs that
pass may still reach their wall-time limit, which the simulators then enforce while running
(:class:`WallClock`, checked at least once per second of wall time).

Examples
--------
>>> check_budget("t_end = 10 s", memory_bytes=1e6, seconds=2.0, max_memory_mb=2048, max_wall_s=600)
>>> check_budget("t_end = 1e+06 s", memory_bytes=95e9, seconds=1e4, max_memory_mb=2048,
...              max_wall_s=600)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
hubbeam_ctrl.core.errors.ParameterError: t_end = 1e+06 s needs about 95 GB of memory, above ...
"""

from __future__ import annotations

import time

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["T_END_MAX", "check_budget", "format_bytes", "format_seconds", "WallClock", "SECONDS_PER_SAMPLE",
           "simulation_bytes_per_sample", "mpc_bytes", "mpc_seconds", "model_build_seconds"]

#: Longest simulated time any simulator accepts [s] (the budgets usually bind long before).
T_END_MAX = 1e9

#: Lower bounds of the wall time per output sample of :func:`~hubbeam_ctrl.sim.simulate.simulate`
#: with 5 + 5 modes [s] (measured 82, 100, 271, 819 us; divided by about 4). They scale with
#: the square of the number of coordinates.
SECONDS_PER_SAMPLE = {"sfoam": 20e-6, "tlam": 25e-6, "foam": 60e-6, "cfoam": 200e-6}

#: Lower bound of the plant stepper's and a state-feedback controller's time per closed-loop
#: sample [s] (measured 60-100 us with 5 + 5 modes).
CLOSED_LOOP_SECONDS_PER_SAMPLE = 20e-6


def simulation_bytes_per_sample(n_q: int) -> int:
    """Memory per output sample of an open-loop run [bytes].

    ``q``, ``v``, ``a`` and eight series of float64, about three times over (integrator
    chunks, their concatenation and the result).

    Parameters
    ----------
    n_q : int
        Number of generalised coordinates.
    """
    return 8 * 3 * (3 * n_q + 8)


def model_build_seconds(model: str, n_transverse: int) -> float:
    """Lower bound of the time to build a model's equations [s] (CFOAM grows as n2^3.5).

    Parameters
    ----------
    model : str
    n_transverse : int
    """
    base = 0.1 if model == "cfoam" else 0.01
    return base * (n_transverse / 5.0) ** 3.5


def mpc_bytes(horizon: int, n_x: int) -> float:
    """Memory of the condensed MPC's matrices [bytes]: the block-diagonal state weight
    ``(N n_x)^2`` (twice: ``np.kron`` builds it through a temporary) and the prediction and
    constraint matrices ``3 N^2 n_x`` (float64). Horizon 1000 on 5 modes: 2.6 GB.

    Parameters
    ----------
    horizon : int
        Prediction horizon N [samples].
    n_x : int
        States of the design model.
    """
    N = float(horizon)
    return 8.0 * (2.0 * (N * n_x) ** 2 + 3.0 * N * N * n_x)


def mpc_seconds(horizon: int, n_x: int, steps: int) -> float:
    """Lower bound of an MPC run's time [s]: building ``Gamma' Qb Gamma`` (``N^3 n_x^2``
    flops at 10 GFlop/s) and one dense QP per step (0.1 ms at N = 50, growing as ``N^2``).

    Parameters
    ----------
    horizon : int
    n_x : int
    steps : int
        Closed-loop samples.
    """
    N = float(horizon)
    return N ** 3 * n_x ** 2 / 1e10 + steps * 1e-4 * (N / 50.0) ** 2


def format_bytes(n: float) -> str:
    """``n`` bytes as ``"12 MB"``, ``"3.4 GB"`` (powers of 1000).

    Parameters
    ----------
    n : float
        A size [bytes].
    """
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.2g} {unit}" if n / size < 10 else f"{n / size:.0f} {unit}"
    return f"{n:.0f} B"


def format_seconds(s: float) -> str:
    """``s`` seconds as ``"40 s"``, ``"12 min"``, ``"3.1 h"``, ``"2.0 days"``.

    Parameters
    ----------
    s : float
        A duration [s].
    """
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    if s < 172800:
        return f"{s / 3600:.1f} h"
    return f"{s / 86400:.1f} days"


def check_budget(what: str, *, memory_bytes: float, seconds: float, max_memory_mb: float,
                 max_wall_s: float) -> None:
    """Refuse a run whose estimated memory or time exceeds its limits.

    Parameters
    ----------
    what : str
        What makes the run large, as the caller spelled it (``"t_end = 1e+06 s"``,
        ``"horizon = 100000"``); starts the message.
    memory_bytes : float
        Estimated memory [bytes].
    seconds : float
        Estimated wall time (a lower bound) [s].
    max_memory_mb : float
        Memory limit [MB] (``settings.max_memory_mb``; ``--allow-large`` lifts it).
    max_wall_s : float
        Wall-time limit [s] (``settings.max_wall_s``; ``--max-wall``).

    Raises
    ------
    ParameterError
        One line: the estimate, the limit and how to raise it.
    """
    if memory_bytes > max_memory_mb * 1e6:
        raise ParameterError(f"{what} needs about {format_bytes(memory_bytes)} of memory, above "
                             f"max_memory_mb = {max_memory_mb:g} MB (raise max_memory_mb; command "
                             f"line: --allow-large)")
    if seconds > max_wall_s:
        raise ParameterError(f"{what} would take at least {format_seconds(seconds)}, above "
                             f"max_wall_s = {max_wall_s:g} s (raise max_wall_s; command line: "
                             f"--max-wall SECONDS)")


class WallClock:
    """A wall-time limit, checked cheaply and often.

    Parameters
    ----------
    max_wall_s : float
        Limit [s].

    Examples
    --------
    >>> clock = WallClock(600.0)
    >>> clock.expired()
    False
    """

    def __init__(self, max_wall_s: float):
        self.max_wall_s = float(max_wall_s)
        self.start = time.perf_counter()

    def elapsed(self) -> float:
        """Seconds since the start."""
        return time.perf_counter() - self.start

    def expired(self, now: float | None = None) -> bool:
        """True once the limit has passed (``now``: a ``time.perf_counter()`` reading to reuse).

        Parameters
        ----------
        now : float, optional
            A ``time.perf_counter()`` reading [s] to reuse.
        """
        return ((time.perf_counter() if now is None else now) - self.start) > self.max_wall_s

    def message(self, t: float) -> str:
        """``"stopped after max_wall_s = ... s at t = ... s"`` for a run stopped at sim time ``t``.

        Parameters
        ----------
        t : float
            Simulated time where the run stopped [s].
        """
        return f"stopped after max_wall_s = {self.max_wall_s:g} s at t = {t:.3f} s"
