"""The robust certificate: the sampled loop as it runs, over everything the user does not know.

A :class:`~hubbeam_ctrl.plant.uncertainty.Uncertainty` is a box of physical parameters
(payload, its position, E, J_h, the damping floor, friction, the drive's constants, the
delay). :func:`certify_set` closes a controller, as it runs on the rig (zero-order hold,
delay, drive in volts with its back-EMF, the estimator: :func:`~hubbeam_ctrl.study.certificate.loop_matrix`),
with the linear plant of each parameter point it visits, and reports:

* **searched** (:attr:`WorstCase.radius`, :attr:`WorstCase.worst`): the largest spectral radius
  found over the box and the plant where it was found. The search evaluates a regular grid
  (``grid`` points per parameter, the corners included), then climbs from the worst grid
  points by a bounded Nelder-Mead on the radius (:data:`LOCAL_STARTS` starts). A found worst
  case is exact at that plant; that no worse plant exists is not proven by a search.
* **bounded** (:attr:`WorstCase.bound`): a first-order bound over the grid's cells. For a grid
  point ``p0`` with loop matrix ``A0 = V diag(z) V^-1`` every eigenvalue of the loop at a
  plant ``p`` of its cell lies within ``cond(V) ||A(p) - A0||_2`` of an eigenvalue of ``A0``
  (Bauer-Fike), and ``||A(p) - A0||`` is bounded by half the differences to the neighbouring
  grid points (exact when ``A`` is linear in the parameters across a cell; first order
  otherwise). A bound below 1 proves the set stable under that linearity; a lightly damped
  flexible loop has ``cond(V)`` of 1e2-1e6, so the bound is usually far above the searched
  radius: the certificate says which of the two its verdict rests on.
* the smallest **disk margin** (as it runs) at the grid's corners, the nominal and the worst
  plant, and the **worst-case settling** time constant ``-dt / ln(radius)`` of the worst plant.

A design is **certified** when the searched worst radius is at most ``1 -``
:data:`RADIUS_MARGIN` (a decay of at least 1e-6 per sample everywhere found). Coulomb
friction is not linear: it varies only in nonlinear runs (:func:`check_worst`), and the
certificate lists it as not covered.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from controllers.analysis import margins_of_loop
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.plant.uncertainty import NONLINEAR_ONLY, Uncertainty
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.study.certificate import _source, broken_loop, linear_points, loop_matrix

__all__ = ["RADIUS_MARGIN", "LOCAL_STARTS", "WorstCase", "certify_set", "SetPoint"]

#: A loop is certified when its worst spectral radius is at most ``1 - RADIUS_MARGIN`` [-].
RADIUS_MARGIN = 1e-6
#: Local searches started from the worst grid points.
LOCAL_STARTS = 3
#: Radius evaluations of one local search, per varying parameter.
LOCAL_EVALUATIONS = 40
#: Frequency points of each disk-margin evaluation.
MARGIN_POINTS = 800


@dataclass(frozen=True)
class SetPoint:
    """One plant of the set as the certificate evaluated it.

    A :class:`WorstCase` holds two: the nominal plant (:attr:`WorstCase.nominal`) and the worst one
    found (:attr:`WorstCase.worst`).

    Attributes
    ----------
    values : dict
        Uncertain parameter -> value (SI units).
    radius : float
        Spectral radius of the loop there (largest over the linearisation spins) [-].
    spin : float
        The spin of that radius [rad/s].
    """

    values: dict
    radius: float
    spin: float


@dataclass(frozen=True)
class WorstCase:
    """The robust certificate of one controller over one uncertainty set (module docstring).

    Attributes
    ----------
    controller : str
    uncertainty : Uncertainty
    dt : float
        Sample time [s].
    plant_modes : int
        Bending modes of the linear plant.
    nominal : SetPoint
        The rig as given.
    worst : SetPoint
        The largest radius found (searched).
    grid_radius : float
        The largest radius on the grid alone [-].
    bound : float
        The first-order Bauer-Fike bound over the grid's cells [-] (inf when not computable).
    evaluations : int
        Loops evaluated.
    worst_source : str
        The plant mode (or the controller) the worst pole comes from, and whether it folds.
    undamped_radius : float or None
        The worst plant's radius with no structural damping (None: damping is not in the set
        and the rig has none).
    disk_margin : float or None
        The smallest disk margin found [-] (at the corners, the nominal and the worst plant).
    disk_margin_at : dict
        Where it was found.
    not_covered : tuple of str
        Uncertain parameters a linear loop does not see (Coulomb friction).
    wall_s : float
        Wall time of the certificate [s].
    """

    controller: str
    uncertainty: Uncertainty
    dt: float
    plant_modes: int
    nominal: SetPoint
    worst: SetPoint
    grid_radius: float
    bound: float
    evaluations: int
    worst_source: str = ""
    undamped_radius: float | None = None
    disk_margin: float | None = None
    disk_margin_at: dict = field(default_factory=dict)
    not_covered: tuple = ()
    wall_s: float = 0.0

    @property
    def certified(self) -> bool:
        """The searched worst radius is at most ``1 - RADIUS_MARGIN``."""
        return self.worst.radius <= 1.0 - RADIUS_MARGIN

    @property
    def proven(self) -> bool:
        """The first-order bound is below 1 (stable on the whole box, under the bound's linearity)."""
        return self.bound < 1.0

    @property
    def settling_time_constant_s(self) -> float:
        """``-dt / ln(radius)`` of the worst plant [s] (inf: it does not decay)."""
        r = self.worst.radius
        return float(-self.dt / math.log(r)) if 0.0 < r < 1.0 else math.inf

    def verdict(self) -> str:
        """``"certified"``, ``"not certified"`` (a plant of the set found with radius above ``1 - margin``)."""
        return "certified" if self.certified else "not certified"

    def describe(self) -> str:
        """A few sentences for reports and the CLI: what is searched, what is bounded."""
        w = self.worst
        where = ", ".join(f"{k} = {v:.4g}" for k, v in w.values.items())
        # the rig's own values, clipped into the set (a set that leaves the rig's value out says where it is)
        nominal = ", ".join(f"{k} = {v:.4g}" for k, v in self.nominal.values.items()) or "the rig's values"
        text = (f"{self.controller}: {self.verdict().upper()} over {self.uncertainty.describe()}: "
                f"worst spectral radius found {w.radius:.8f} at {where} (spin {w.spin:g} rad/s, "
                f"{self.worst_source}; searched, {self.evaluations} loops of {self.plant_modes} bending modes); "
                f"nominal {self.nominal.radius:.8f} (at {nominal}).")
        if self.undamped_radius is not None:
            text += f" Without structural damping the worst plant's radius is {self.undamped_radius:.8f}."
        text += (f" First-order bound over the grid's cells: {self.bound:.4g}"
                 + (" (below 1: the set is stable under the bound's linearity)." if self.proven
                    else " (not below 1: the verdict rests on the search)."))
        if self.disk_margin is not None:
            at = ", ".join(f"{k} = {v:.4g}" for k, v in self.disk_margin_at.items())
            text += f" Smallest disk margin found {self.disk_margin:.3g} (at {at})."
        if self.certified:
            text += f" Worst-case settling time constant {self.settling_time_constant_s:.3g} s."
        if self.not_covered:
            text += f" Not in the linear loop: {', '.join(self.not_covered)} (nonlinear runs only)."
        return text

    def metrics(self) -> dict:
        """Flat entries for reports and JSON (``robust_*``)."""
        return {"robust_verdict": self.verdict(), "robust_radius": self.worst.radius,
                "robust_worst": dict(self.worst.values), "robust_worst_spin_rad_s": self.worst.spin,
                "robust_worst_source": self.worst_source, "robust_nominal_radius": self.nominal.radius,
                "robust_grid_radius": self.grid_radius, "robust_bound": self.bound,
                "robust_evaluations": self.evaluations, "robust_undamped_radius": self.undamped_radius,
                "robust_disk_margin": self.disk_margin, "robust_disk_margin_at": dict(self.disk_margin_at),
                "robust_settling_time_constant_s": self.settling_time_constant_s,
                "robust_set": self.uncertainty.to_table(), "robust_not_covered": list(self.not_covered),
                "robust_plant_modes": self.plant_modes, "robust_wall_s": self.wall_s}


class _Loop:
    """The loop at a point of the set: parameters -> (matrix per spin), cached by point."""

    def __init__(self, forms, rig: Rig, uncertainty: Uncertainty, plant_modes: int, spins):
        self.forms, self.rig, self.set, self.modes = forms, rig, uncertainty, int(plant_modes)
        self.spins = spins
        self.count = 0
        self._cache = {}

    def plant(self, values: dict):
        r = self.set.apply(self.rig, values)
        params = r.plant_params.replace(n_transverse=self.modes)
        zeta = 0.0
        if "damping" in values:      # every mode alike: the certificate's damping term
            zeta = float(values["damping"])
            params = params.replace(damping_ratios=(), damping_ratio=0.0)
        hw = None if r.is_ideal else Hardware.from_rig(r)
        return params, zeta, hw

    def matrices(self, values: dict) -> list:
        key = tuple(sorted((k, round(float(v), 15)) for k, v in values.items()))
        if key not in self._cache:
            params, zeta, hw = self.plant(values)
            out = []
            for spin, form in self._pairs():
                A, poles = loop_matrix(form, params, spin, zeta, hardware=hw)
                out.append((spin, form, A, poles))
            self.count += 1
            self._cache[key] = out
        return self._cache[key]

    def _pairs(self):
        pairs = list(self.forms)
        if len(self.forms) == 1:
            s0, form = self.forms[0]
            pairs += [(s, form) for s in self.spins if abs(s - s0) > 1e-9]
        return pairs

    def radius(self, values: dict) -> tuple:
        best = (-1.0, 0.0)
        for spin, _, A, _ in self.matrices(values):
            r = float(np.max(np.abs(np.linalg.eigvals(A))))
            if not math.isfinite(r):
                r = math.inf
            best = max(best, (r, spin))
        return best


def _grid(n_dims: int, grid: int):
    axis = np.linspace(0.0, 1.0, grid)
    return [np.array(u) for u in itertools.product(axis, repeat=n_dims)]


def _bauer_fike(loop: _Loop, uncertainty: Uncertainty, grid_pts, radii, grid: int) -> float:
    """The first-order Bauer-Fike bound over the grid's cells (module docstring)."""
    vary = uncertainty.varying
    if not vary:
        return max(radii)
    h = 1.0 / (grid - 1)
    index = {tuple(np.round(u / h).astype(int)): k for k, u in enumerate(grid_pts)}
    bound = 0.0
    for k, u in enumerate(grid_pts):
        mats = loop.matrices(uncertainty.values_at(u))
        ijk = np.round(u / h).astype(int)
        for m, (spin, _, A0, _) in enumerate(mats):
            delta = 0.0
            for d in range(len(vary)):
                diffs = []
                for step in (-1, 1):
                    nb = ijk.copy()
                    nb[d] += step
                    j = index.get(tuple(nb))
                    if j is None:
                        continue
                    A1 = loop.matrices(uncertainty.values_at(grid_pts[j]))[m][2]
                    if A1.shape != A0.shape:
                        return math.inf
                    diffs.append(np.linalg.norm(A1 - A0, 2))
                delta += 0.5 * max(diffs, default=0.0)
            z, V = np.linalg.eig(A0)
            kappa = np.linalg.cond(V)
            if not math.isfinite(kappa):
                return math.inf
            bound = max(bound, float(np.max(np.abs(z))) + kappa * delta)
    return float(bound)


def _local_search(loop: _Loop, uncertainty: Uncertainty, u0: np.ndarray, evaluations: int):
    """Bounded Nelder-Mead on ``-radius`` from ``u0``; returns ``(radius, spin, u)``."""
    best = [loop.radius(uncertainty.values_at(u0)) + (u0,)]

    def f(u):
        u = np.clip(u, 0.0, 1.0)
        r, s = loop.radius(uncertainty.values_at(u))
        if r > best[0][0]:
            best[0] = (r, s, u.copy())
        return -r

    n = u0.size
    simplex = [u0] + [np.clip(u0 + np.where(np.arange(n) == i, 0.25 if u0[i] < 0.5 else -0.25, 0.0), 0, 1)
                      for i in range(n)]
    import scipy.optimize  # here: SciPy's optimize package costs 0.2 s of every command's start
    scipy.optimize.minimize(f, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * n,
                            options={"maxfev": evaluations, "initial_simplex": np.array(simplex),
                                     "xatol": 1e-4, "fatol": 1e-10})
    return best[0]


def _disk(loop: _Loop, form, values: dict, spin: float) -> float | None:
    params, zeta, hw = loop.plant(values)
    try:
        A, B, C, D = broken_loop(form, params, spin, zeta, hardware=hw)
        m = margins_of_loop(A, B, C, D, float(form.dt), "", MARGIN_POINTS)
    except (HubbeamError, np.linalg.LinAlgError, ValueError):
        return None
    return float(m.disk_margin)


def certify_set(controller, rig: Rig, uncertainty: Uncertainty | None = None, *, plant_modes: int,
                spins=(), name: str | None = None, grid: int = 3, local_starts: int = LOCAL_STARTS,
                margins: bool = True, progress: bool = False) -> WorstCase:
    """The robust certificate of ``controller`` on ``rig`` over ``uncertainty`` (module docstring).

    Parameters
    ----------
    controller : Controller
        As it runs on the rig (``rig_hardware``, sensors, delay), with a linear form.
    rig : Rig
        The nominal rig.
    uncertainty : Uncertainty, optional
        The set (default the rig's own ``[uncertainty]``).
    plant_modes : int
        Bending modes of the linear plant (the evaluation plant's, at least the controller's).
    spins : sequence of float
        Spin rates [rad/s] besides the design spin (e.g. the start and end of a run).
    name : str, optional
        The controller's registry name.
    grid : int
        Grid points per varying parameter, >= 2 (the corners; 3 adds the middles).
    local_starts : int
        Local searches from the worst grid points, >= 0.
    margins : bool
        Also the smallest disk margin at the corners, the nominal and the worst plant.
    progress : bool
        A progress bar (stderr, on a terminal).

    Returns
    -------
    WorstCase

    Examples
    --------
    >>> from controllers import DesignModel, LQR
    >>> from hubbeam_ctrl import Params
    >>> from hubbeam_ctrl.plant.rig import Rig
    >>> u = Uncertainty.from_table({"m_t": (0.0, 0.5)})
    >>> wc = certify_set(LQR(DesignModel.build(Params(), 0.0, 0.01, 2)), Rig(), u, plant_modes=2, margins=False)
    >>> wc.certified, sorted(wc.worst.values)
    (True, ['m_t'])
    """
    start = time.perf_counter()
    uncertainty = rig.uncertainty if uncertainty is None else uncertainty
    if not isinstance(uncertainty, Uncertainty) or not uncertainty.is_set:
        raise ParameterError("uncertainty must name at least one uncertain parameter ([uncertainty] in the rig "
                             "file, or --uncertainty NAME=LO:HI)")
    if isinstance(grid, bool) or not isinstance(grid, int) or not 2 <= grid <= 9:
        raise ParameterError(f"grid must be an integer in [2, 9], got {grid!r}")
    if isinstance(local_starts, bool) or not isinstance(local_starts, int) or not 0 <= local_starts <= 20:
        raise ParameterError(f"local_starts must be an integer in [0, 20], got {local_starts!r}")
    uncertainty.check(rig.replace(uncertainty=Uncertainty()))
    label = name or getattr(controller, "name", type(controller).__name__)
    forms = linear_points(controller, name)
    if not forms:
        raise ParameterError(f"controller {label!r} has no linear feedback law to certify")
    loop = _Loop(forms, rig.replace(uncertainty=Uncertainty()), uncertainty, plant_modes,
                 sorted({round(float(s), 12) for s in spins}))
    vary = uncertainty.varying
    nominal_values = {r.name: _nominal(rig, r.name, r) for r in uncertainty.ranges}
    pts = _grid(len(vary), grid) if vary else [np.zeros(0)]
    total = len(pts) + local_starts * LOCAL_EVALUATIONS * max(1, len(vary))
    radii, spins_at = [], []
    with progress_bar(total, f"certify {label}", enabled=progress) as bar:
        for u in pts:
            r, s = loop.radius(uncertainty.values_at(u))
            radii.append(r)
            spins_at.append(s)
            bar.update(1)
        order = np.argsort(radii)[::-1]
        best = (radii[order[0]], spins_at[order[0]], pts[order[0]])
        if vary:
            for k in order[:local_starts]:
                before = loop.count
                found = _local_search(loop, uncertainty, pts[k], LOCAL_EVALUATIONS * len(vary))
                bar.update(loop.count - before)
                if found[0] > best[0]:
                    best = found
        nominal_r, nominal_s = loop.radius(nominal_values)
        grid_radius = float(max(radii))
        bound = _bauer_fike(loop, uncertainty, pts, radii, grid) if vary else grid_radius
    worst_values = uncertainty.values_at(best[2]) if vary else dict(nominal_values)
    worst = SetPoint(worst_values, float(best[0]), float(best[1]))
    source = _worst_source(loop, worst)
    undamped = None
    if "damping" in worst_values or rig.damping.is_set or rig.beam.damping_ratio > 0:
        undamped = loop.radius({**worst_values, "damping": 0.0})[0]
    disk, disk_at = None, {}
    if margins:
        corners = [np.array(c, dtype=float) for c in itertools.product((0.0, 1.0), repeat=len(vary))]
        candidates = [uncertainty.values_at(c) for c in corners] + [nominal_values, worst_values]
        form_for = {s: f for s, f in loop._pairs()}
        for values in candidates:
            spin = worst.spin if worst.spin in form_for else forms[0][0]
            d = _disk(loop, form_for.get(spin, forms[0][1]), values, spin)
            if d is not None and (disk is None or d < disk):
                disk, disk_at = d, dict(values)
    return WorstCase(label, uncertainty, float(forms[0][1].dt), int(plant_modes),
                     SetPoint(nominal_values, float(nominal_r), float(nominal_s)), worst, grid_radius,
                     float(bound), loop.count, source, undamped, disk, disk_at,
                     tuple(n for n in uncertainty.names if n in NONLINEAR_ONLY),
                     time.perf_counter() - start)


def _nominal(rig: Rig, name: str, r) -> float:
    """The rig's own value of an uncertain parameter, clipped into its range."""
    return float(min(max(Uncertainty.rig_value(rig, name), r.lo), r.hi))


def _worst_source(loop: _Loop, worst: SetPoint) -> str:
    for spin, form, A, poles in loop.matrices(worst.values):
        if spin != worst.spin:
            continue
        z = np.linalg.eigvals(A)
        k = int(np.argmax(np.abs(z)))
        src, hz, folded = _source(z[k], poles, float(form.dt), poles.size, z.size)
        return src if hz is None else f"{src} ({hz:.2f} Hz{', folded' if folded else ''})"
    return ""
