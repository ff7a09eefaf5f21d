"""The design grid of gain scheduling: design models at a grid of spin rates.

A :class:`DesignSchedule` holds the sampled design models (:class:`~controllers.base.DesignModel`)
at a grid of spin rates, strictly ascending; the scheduled controllers of
:mod:`controllers.schedule` interpolate what they need from it (see there for the measured
effect of the grid's size).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params

from .base import DesignModel, Reference, check_positive

__all__ = ["DesignSchedule", "DEFAULT_SCHEDULE_POINTS", "MAX_SCHEDULE_POINTS", "VARIABLES"]

#: Spin rates of the default grid (0 to the top rate, evenly spaced).
DEFAULT_SCHEDULE_POINTS = 9
#: Most spin rates of a schedule (each is a design; a few suffice, 1000 is far past use).
MAX_SCHEDULE_POINTS = 1000
#: Scheduling variables.
VARIABLES = ("measured", "reference")


def _check_spins(spins) -> np.ndarray:
    try:
        s = np.asarray(spins, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ParameterError(f"spins must be numbers [rad/s], got {spins!r}") from None
    if s.size < 2:
        raise ParameterError(f"spins must hold at least 2 spin rates [rad/s], got {s.size}")
    if not np.all(np.isfinite(s)):
        raise ParameterError("spins must be finite numbers [rad/s] (got NaN or inf)")
    if np.any(s < 0):
        raise ParameterError(f"spins must be >= 0 [rad/s], got {s.min():g}")
    if np.any(np.diff(s) <= 0):
        raise ParameterError("spins must be strictly ascending [rad/s]")
    return s


@dataclass(frozen=True, eq=False)
class DesignSchedule:
    """Design models (:class:`DesignModel`) at a grid of spin rates.

    Build it with :meth:`build`.

    Attributes
    ----------
    spins : ndarray (S,)
        Spin rates of the grid [rad/s], strictly ascending, >= 0.
    designs : tuple of DesignModel
        One per spin rate, all with the same parameters, modes and sample time.
    """

    spins: np.ndarray
    designs: tuple

    @classmethod
    def build(cls, params: Params = Params(), spins=None, dt: float = 0.01, n_modes: int | None = None,
              top: float = 3.0, points: int = DEFAULT_SCHEDULE_POINTS) -> "DesignSchedule":
        """Linearise SFOAM at every spin rate of a grid and sample it.

        Parameters
        ----------
        params : Params
        spins : array_like, optional
            Spin rates [rad/s]: at least 2, strictly ascending, >= 0. Default:
            ``points`` evenly spaced from 0 to ``top``.
        dt : float
            Sample time [s], > 0.
        n_modes : int, optional
            Transverse modes of the design models (default ``params.n_transverse``).
        top : float
            Top of the default grid [rad/s], > 0.
        points : int
            Size of the default grid, >= 2.

        Returns
        -------
        DesignSchedule

        Examples
        --------
        >>> s = DesignSchedule.build(Params(n_axial=1, n_transverse=2), top=3.0, points=4)
        >>> s.spins.tolist(), len(s.designs)
        ([0.0, 1.0, 2.0, 3.0], 4)
        """
        if spins is None:
            top = check_positive("top", top, "rad/s")
            if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
                raise ParameterError(f"points must be an integer >= 2, got {points!r}")
            spins = np.linspace(0.0, top, int(points))
        s = _check_spins(spins)
        return cls(s, tuple(DesignModel.build(params, float(w), dt, n_modes) for w in s))

    @classmethod
    def for_scenario(cls, scenario, points: int = DEFAULT_SCHEDULE_POINTS,
                     n_modes: int | None = None) -> "DesignSchedule":
        """The schedule of a closed-loop scenario: ``points`` spins from 0 to its reference's top rate.

        Parameters
        ----------
        scenario : object
            A :class:`hubbeam_ctrl.study.scenarios.Scenario` (read: ``params``, ``dt``,
            ``reference``).
        points : int
            Number of spin rates, >= 2.
        n_modes : int, optional
            Transverse modes of the design models (default: the scenario's).

        Returns
        -------
        DesignSchedule
        """
        top = float(np.max(np.abs(scenario.reference.theta_dot)))
        if not top > 0:
            raise ParameterError("schedule: the scenario's reference never turns (top rate 0 rad/s); "
                                 "use a single design (schedule=1)")
        return cls.build(scenario.params, dt=scenario.dt, n_modes=n_modes, top=top, points=points)

    def __post_init__(self):
        s = _check_spins(self.spins)
        if len(self.designs) != s.size or not all(isinstance(d, DesignModel) for d in self.designs):
            raise ParameterError("designs must hold one DesignModel per spin rate")
        object.__setattr__(self, "spins", s)
        object.__setattr__(self, "_grid", s.tolist())

    @property
    def dt(self) -> float:
        """Sample time [s]."""
        return self.designs[0].dt

    @property
    def n_x(self) -> int:
        """Number of states."""
        return self.designs[0].n_x

    @property
    def n_modes(self) -> int:
        """Transverse modes of the design models."""
        return self.designs[0].n_modes

    def on_rig(self, sensors=None, delay: float = 0.0, hub_damping: float = 0.0) -> "DesignSchedule":
        """Every design of the grid reading the rig's sensors with its computation delay and hub
        damping (:meth:`DesignModel.on_rig`).

        Parameters
        ----------
        sensors : controllers.sensing.SensorLayout, optional
            The signals the estimators read (default: the beam alone's three).
        delay : float
            Computation delay as a fraction of the sample [-], in [0, 1].
        hub_damping : float
            Linear damping of the hub [N m s/rad], >= 0.

        Returns
        -------
        DesignSchedule
            ``self`` when no design changes (the beam alone's grid, bit for bit).
        """
        designs = tuple(d.on_rig(sensors, delay, hub_damping) for d in self.designs)
        if all(a is b for a, b in zip(designs, self.designs)):
            return self
        return DesignSchedule(self.spins, designs)

    def locate(self, spin: float) -> tuple:
        """``(i, w)`` with ``value(spin) = (1 - w) table[i] + w table[i + 1]`` (clamped to the grid).

        Parameters
        ----------
        spin : float
            Spin rate [rad/s].
        """
        g = self._grid
        if not spin > g[0]:                 # also NaN -> the first point
            return 0, 0.0
        if spin >= g[-1]:
            return len(g) - 2, 1.0
        i = bisect.bisect_right(g, spin) - 1
        return i, (spin - g[i]) / (g[i + 1] - g[i])

    def interpolate(self, table: np.ndarray, spin: float) -> np.ndarray:
        """Linear interpolation of ``table`` (first axis: the spins) at ``spin`` [rad/s].

        Parameters
        ----------
        table : ndarray
            Values per design spin (first axis).
        spin : float
            Spin rate [rad/s].
        """
        i, w = self.locate(float(spin))
        return table[i] if w == 0.0 else (1.0 - w) * table[i] + w * table[i + 1]

    def stack(self, f) -> np.ndarray:
        """``np.array([f(d) for d in designs])``.

        Parameters
        ----------
        f : callable
            ``f(design) -> array`` for one :class:`DesignModel`.
        """
        return np.array([f(d) for d in self.designs])

    def reference_states(self, reference: Reference, elastic: bool = True) -> np.ndarray:
        """Reference states as :meth:`DesignModel.reference_states`, with the quasi-static gain
        of the model at each sample's reference rate.

        Parameters
        ----------
        reference : Reference
            Hub reference of the task.
        elastic : bool
            Include the quasi-static elastic states (else rigid only).
        """
        X = self.designs[0].reference_states(reference, elastic=False)
        if elastic and len(reference.theta) > 1:
            n = self.n_x // 2
            g = self.stack(lambda d: d.quasi_static_gain)
            G = np.array([np.interp(np.abs(reference.theta_dot), self.spins, g[:, j]) for j in range(n - 1)]).T
            q = G * reference.theta_ddot[:, None]
            X[:, 1:n] = q
            X[:, n + 1:] = np.gradient(q, reference.dt, axis=0)
        return X
