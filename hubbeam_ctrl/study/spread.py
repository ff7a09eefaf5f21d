"""The plant spread of a study: its factors, the ``[grid]`` table and the ``[random]`` samples.

A factor is a :class:`~hubbeam_ctrl.plant.params.Params` field, the spin-up rate ``w_f`` or
the sensor-noise ``seed``; :class:`Distribution` is one ``[random]`` factor. The
:class:`~hubbeam_ctrl.study.spec.StudySpec` (:mod:`hubbeam_ctrl.study.spec`) reads its
tables with these and crosses the grid with the samples; the names are importable from
:mod:`hubbeam_ctrl.study.spec` too.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params

__all__ = ["Distribution", "FACTORS_EXTRA", "DISTRIBUTIONS", "SAMPLERS"]

#: Most cases one sweep runs (grid points times random samples).
MAX_CASES = 100_000

#: Factors beyond the Params fields: the spin-up rate [rad/s] and the sensor-noise seed.
FACTORS_EXTRA = {"w_f": "rad/s", "seed": "-"}
#: Distributions of ``[random]`` factors and their keys.
DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("median", "sigma")}
#: Samplers of ``[random]``: Latin hypercube (default), scrambled Sobol and Halton, plain Monte Carlo.
SAMPLERS = ("lhs", "sobol", "halton", "random")
_INTEGER_FACTORS = ("n_axial", "n_transverse", "seed")


def _factor_names() -> tuple:
    return tuple(f.name for f in dataclasses.fields(Params)) + tuple(FACTORS_EXTRA)


def _check_factor(name: str, where: str, scenario: str) -> None:
    if name not in _factor_names():
        raise ParameterError(f"{where}: unknown factor {name!r}; allowed: Params fields "
                             f"({', '.join(f.name for f in dataclasses.fields(Params))}) and "
                             f"{', '.join(FACTORS_EXTRA)}")
    if name == "w_f" and scenario != "spinup":
        raise ParameterError(f"{where}.w_f: the spin rate varies only in a spinup study, "
                             f"this one is {scenario!r}")


def _number(where: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ParameterError(f"{where} must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Distribution:
    """One ``[random]`` factor: ``uniform(low, high)``, ``normal(mean, std)`` or
    ``lognormal(median, sigma)`` (``sigma`` the standard deviation of its log), optionally
    truncated to ``[low, high]`` (normal, lognormal).

    Attributes
    ----------
    dist : {"uniform", "normal", "lognormal"}
        The distribution.
    a : float
        ``low`` (uniform), ``mean`` (normal) or ``median`` (lognormal), in the factor's unit.
    b : float
        ``high`` (uniform), ``std`` (normal) or the log-space ``sigma`` (lognormal).
    low : float, optional
        Truncation below (normal, lognormal).
    high : float, optional
        Truncation above.
    """

    dist: str
    a: float
    b: float
    low: float | None = None
    high: float | None = None

    @classmethod
    def from_dict(cls, where: str, table) -> "Distribution":
        """Validate one factor's table (``where`` names it in errors).

        Parameters
        ----------
        where : str
            The factor's name in the spec (``random.m_t``), for messages.
        table : dict
            The factor's TOML table (``dist`` and its parameters).
        """
        if not isinstance(table, dict) or table.get("dist") not in DISTRIBUTIONS:
            raise ParameterError(f"{where} must be a table with dist = one of "
                                 f"{', '.join(DISTRIBUTIONS)}, got {table!r}")
        dist = table["dist"]
        keys = DISTRIBUTIONS[dist]
        allowed = {"dist", *keys} | ({"low", "high"} if dist != "uniform" else set())
        extra = sorted(set(table) - allowed)
        if extra or any(k not in table for k in keys):
            raise ParameterError(f"{where}: a {dist} distribution takes {', '.join(sorted(allowed - {'dist'}))}"
                                 f"{' (low/high optional)' if dist != 'uniform' else ''}, got "
                                 f"{', '.join(sorted(set(table) - {'dist'})) or 'nothing'}")
        a, b = (_number(f"{where}.{k}", table[k]) for k in keys)
        low = _number(f"{where}.low", table["low"]) if "low" in table and dist != "uniform" else None
        high = _number(f"{where}.high", table["high"]) if "high" in table and dist != "uniform" else None
        out = cls(dist, a, b, low, high)
        out._check(where)
        return out

    def _check(self, where: str) -> None:
        if self.dist == "uniform" and not self.a < self.b:
            raise ParameterError(f"{where}: uniform needs low < high, got low = {self.a:g}, high = {self.b:g}")
        if self.dist == "normal" and not self.b > 0:
            raise ParameterError(f"{where}: normal needs std > 0, got {self.b:g}")
        if self.dist == "lognormal" and not (self.a > 0 and self.b > 0):
            raise ParameterError(f"{where}: lognormal needs median > 0 and sigma > 0, got "
                                 f"median = {self.a:g}, sigma = {self.b:g}")
        if self.low is not None and self.high is not None and not self.low < self.high:
            raise ParameterError(f"{where}: needs low < high, got low = {self.low:g}, high = {self.high:g}")
        lo, hi = self._u_range()
        if not hi > lo:
            raise ParameterError(f"{where}: the truncation [low, high] holds no probability")

    def _cdf(self, x: float) -> float:
        from scipy.stats import norm
        if self.dist == "normal":
            return float(norm.cdf((x - self.a) / self.b))
        return float(norm.cdf(math.log(x / self.a) / self.b)) if x > 0 else 0.0

    def _u_range(self) -> tuple:
        if self.dist == "uniform":
            return 0.0, 1.0
        lo = self._cdf(self.low) if self.low is not None else 0.0
        hi = self._cdf(self.high) if self.high is not None else 1.0
        return lo, hi

    def ppf(self, u: np.ndarray) -> np.ndarray:
        """Map uniform samples ``u`` in [0, 1) to this distribution (inverse CDF).

        Parameters
        ----------
        u : ndarray
            Uniform samples in [0, 1).
        """
        from scipy.stats import norm
        if self.dist == "uniform":
            return self.a + u * (self.b - self.a)
        lo, hi = self._u_range()
        z = norm.ppf(lo + u * (hi - lo))
        x = self.a + self.b * z if self.dist == "normal" else self.a * np.exp(self.b * z)
        return np.clip(x, self.low if self.low is not None else -np.inf,
                       self.high if self.high is not None else np.inf)

    def to_dict(self) -> dict:
        """The TOML table of this distribution."""
        out = {"dist": self.dist, **dict(zip(DISTRIBUTIONS[self.dist], (self.a, self.b)))}
        out.update({k: v for k, v in (("low", self.low), ("high", self.high)) if v is not None})
        return out


def _unit_samples(method: str, d: int, n: int, seed: int) -> np.ndarray:
    from scipy.stats import qmc
    if method == "random":
        return np.random.default_rng(seed).random((n, d))
    if method == "lhs":
        return qmc.LatinHypercube(d=d, rng=np.random.default_rng(seed)).random(n)
    engine = qmc.Sobol if method == "sobol" else qmc.Halton
    return engine(d=d, scramble=True, rng=np.random.default_rng(seed)).random(n)


def _grid(where: str, table: dict, scenario: str) -> dict:
    if not isinstance(table, dict):
        raise ParameterError(f"{where} must be a table of factor = [values], got {table!r}")
    out = {}
    for name, values in table.items():
        _check_factor(name, where, scenario)
        if not isinstance(values, list) or not values:
            raise ParameterError(f"{where}.{name} must be a non-empty list of values, got {values!r}")
        if name == "l":
            vals = [None if v == "L" else _number(f"{where}.l", v) for v in values]
        else:
            vals = [_number(f"{where}.{name}", v) for v in values]
        if name in _INTEGER_FACTORS:
            if any(v != int(v) for v in vals):
                raise ParameterError(f"{where}.{name} must hold integers, got {values!r}")
            vals = [int(v) for v in vals]
        if len(set(vals)) != len(vals):
            raise ParameterError(f"{where}.{name} repeats a value: {values!r}"[:300])
        out[name] = vals
    return out


def _random(where: str, table: dict, scenario: str, grid: dict) -> tuple:
    if not isinstance(table, dict):
        raise ParameterError(f"{where} must be a table, got {table!r}")
    n = table.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_CASES:
        raise ParameterError(f"{where}.n must be an integer in 1..{MAX_CASES} (number of samples), got {n!r}")
    seed = table.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ParameterError(f"{where}.seed must be an integer >= 0, got {seed!r}")
    method = table.get("method", "lhs")
    if method not in SAMPLERS:
        raise ParameterError(f"{where}.method must be one of {', '.join(SAMPLERS)}, got {method!r}")
    dists = {}
    for name, sub in table.items():
        if name in ("n", "seed", "method"):
            continue
        _check_factor(name, where, scenario)
        if name in _INTEGER_FACTORS:
            raise ParameterError(f"{where}.{name}: integer factors vary only in [grid]")
        if name in grid:
            raise ParameterError(f"{where}.{name}: already a [grid] factor; vary it in one place")
        dists[name] = Distribution.from_dict(f"{where}.{name}", sub)
    if not dists:
        raise ParameterError(f"{where} names no factor (give e.g. m_t = {{dist = \"uniform\", low = 0, high = 0.5}})")
    return n, seed, method, dists
