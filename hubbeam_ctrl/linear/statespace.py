"""Linear state-space models about steady spin, for control design and export.

:func:`linearize` turns any of the four nonlinear models (SFOAM by default) into a
python-control :class:`~control.StateSpace` with named states, input and outputs,
wrapped in a :class:`LinearModel` that also keeps the model name, the spin rate and the
:class:`~hubbeam_ctrl.plant.params.Params` it was made from. The linearisation itself is
:func:`hubbeam_ctrl.plant.linearization.second_order_linearization` (CasADi automatic differentiation
about ``theta_dot = spin``, ``q1 = q1*(spin)`` (the steady axial stretch), ``q2 = 0``,
``tau = 0``), so FOAM's and CFOAM's stretch and gyroscopic coupling are included.

State vector (deviations from steady rotation)
----------------------------------------------
``x = [theta, q1_1..q1_n1, q2_1..q2_n2, theta_dot, q1_dot_1.., q2_dot_1..]``

* ``theta`` [rad]: hub angle minus the steadily turning reference ``spin * t``;
  ``theta_dot`` [rad/s]: hub rate minus ``spin``.
* ``q1_i`` [m]: axial modal coordinates minus the steady stretch ``q1*(spin)`` (FOAM,
  CFOAM, TLAM only; SFOAM has none). Shape ``f1_i(x) = sin((2i-1) pi x / 2L)``, so
  ``f1_i(L) = +-1`` and ``q1_i`` is that mode's axial tip displacement.
* ``q2_i`` [m]: transverse modal coordinates, ``w2(x) = sum f2_i(x) q2_i`` in the hub
  frame. ``f2_i`` are the clamped-free beam eigenfunctions normalised to
  ``int_0^L f2_i^2 dx = L``, hence ``|f2_i(L)| = 2``: ``q2_i`` is half of mode i's tip
  deflection.

Outputs (:data:`OUTPUTS`): ``theta`` [rad], ``theta_dot`` [rad/s], ``tip_deflection``
``v_tip = w2(L)`` [m], ``tip_rate`` [m/s], ``root_moment`` ``E I w2''(0)`` [N m] (what a
strain gauge at the root reads). The input is the hub torque ``tau`` [N m]. ``D = 0``.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_in_range, check_integer
from hubbeam_ctrl.plant.linearization import first_order_matrices, second_order_linearization, velocity_name
from hubbeam_ctrl.plant.models import MODEL_NAMES, HubBeamModel, build_model
from hubbeam_ctrl.plant.params import Params, check_spin
from hubbeam_ctrl.plant.sensors import SENSOR_NAMES, sensor_matrix

# python-control is imported where a system is built: the matrices alone (linear_matrices) do not
# need it, and a command that needs only them (hubbeam compare) does not pay for its import
if TYPE_CHECKING:
    import control

#: Allowed sample times of :func:`discretize` [s].
DT_RANGE = (1e-6, 10.0)

__all__ = ["LinearModel", "OUTPUTS", "DEFAULT_OUTPUTS", "linearize", "linear_matrices", "discretize", "reduce",
           "poles", "continuous_poles", "poles_hz", "compare_poles", "PoleComparison"]

#: Available outputs: name -> (unit, description).
OUTPUTS = {
    "theta": ("rad", "hub angle relative to the steady rotation"),
    "theta_dot": ("rad/s", "hub rate relative to the steady spin"),
    "tip_deflection": ("m", "transverse tip deflection v_tip = w2(L) in the hub frame"),
    "tip_rate": ("m/s", "rate of the transverse tip deflection"),
    "root_moment": ("N m", "root bending moment E I w2''(0) (root strain gauge)"),
}

#: Outputs of :func:`linearize` unless told otherwise.
DEFAULT_OUTPUTS = ("theta", "tip_deflection")

_STATE_UNITS = {"theta": "rad", "theta_dot": "rad/s", "rigid": "rad", "rigid_dot": "rad/s"}


def _state_unit(name: str) -> str:
    if name in _STATE_UNITS:
        return _STATE_UNITS[name]
    if name.startswith(("q1_dot_", "q2_dot_")):
        return "m/s"
    if name.startswith(("q1_", "q2_")):
        return "m"
    return "-"


@dataclass(frozen=True, eq=False)
class LinearModel:
    """A named python-control state-space model plus what it was made from.

    Attributes
    ----------
    sys : control.StateSpace
        The model (named states, input ``tau``, named outputs). Use it with any
        python-control function (``control.step_response(lm.sys)``, ``control.lqr``...).
    model : str
        Source model: ``"sfoam"``, ``"foam"``, ``"cfoam"`` or ``"tlam"``.
    spin : float
        Steady spin rate it is linearised about [rad/s].
    params : Params
        System parameters (tip mass, number of modes, damping ratio...).
    reduction : str
        ``"none"``, ``"modal:K"`` or ``"balanced:K"`` (K flexible modes kept).

    Equality (``==``) is exact: same matrices bit for bit, names, sample time and metadata.

    Examples
    --------
    >>> lm = linearize("sfoam", spin=0.0, params=Params(n_transverse=2))
    >>> lm.state_names
    ['theta', 'q2_1', 'q2_2', 'theta_dot', 'q2_dot_1', 'q2_dot_2']
    >>> lm.output_names, lm.input_names
    (['theta', 'tip_deflection'], ['tau'])
    """

    sys: control.StateSpace
    model: str
    spin: float
    params: Params
    reduction: str = "none"

    # -- views --------------------------------------------------------------
    @property
    def A(self) -> np.ndarray:
        """State matrix (n, n)."""
        return np.asarray(self.sys.A)

    @property
    def B(self) -> np.ndarray:
        """Input matrix (n, 1) [per N m]."""
        return np.asarray(self.sys.B)

    @property
    def C(self) -> np.ndarray:
        """Output matrix (p, n)."""
        return np.asarray(self.sys.C)

    @property
    def D(self) -> np.ndarray:
        """Feedthrough (p, 1), zero for the models built here."""
        return np.asarray(self.sys.D)

    @property
    def dt(self) -> float:
        """Sample time [s]; 0 for a continuous-time model."""
        return 0.0 if not self.sys.dt else float(self.sys.dt)

    @property
    def is_discrete(self) -> bool:
        """True for a sampled model."""
        return self.dt > 0

    @property
    def name(self) -> str:
        """python-control system name."""
        return self.sys.name

    @property
    def state_names(self) -> list:
        return list(self.sys.state_labels)

    @property
    def input_names(self) -> list:
        return list(self.sys.input_labels)

    @property
    def output_names(self) -> list:
        return list(self.sys.output_labels)

    @property
    def n_states(self) -> int:
        return int(self.sys.nstates)

    @property
    def state_units(self) -> list:
        """Unit of each state (``-`` for the balanced coordinates)."""
        return [_state_unit(s) for s in self.state_names]

    @property
    def output_units(self) -> list:
        return [OUTPUTS[o][0] if o in OUTPUTS else "-" for o in self.output_names]

    # -- analysis ----------------------------------------------------------
    def poles(self) -> np.ndarray:
        """Poles of the model (z-plane for a sampled model), :meth:`control.StateSpace.poles`."""
        return self.sys.poles()

    def poles_hz(self) -> np.ndarray:
        """Undamped natural frequencies of the oscillatory poles [Hz], ascending.

        See :func:`poles_hz`.
        """
        return poles_hz(self)

    @property
    def unstable(self) -> bool:
        """True when a mode grows (a pole with positive real part, or ``|z| > 1`` sampled),
        e.g. TLAM above its critical speed. The rigid-body poles at 0 (``z = 1``) do not count."""
        if self.is_discrete:          # in the z-plane: log(z) of a huge pole loses the small ones
            z = self.poles()
            return bool(not np.all(np.isfinite(z)) or np.any(np.abs(z) > 1.0 + 1e-6))
        lam = continuous_poles(self)
        return bool(np.any(lam.real > 1e-9 * np.maximum(1.0, np.abs(lam)) + 1e-11 * np.abs(lam).max()))

    def metadata(self) -> dict:
        """Everything but the matrices, as plain JSON-able values."""
        return {
            "model": self.model, "spin_rad_s": self.spin, "dt": self.dt, "name": self.name,
            "reduction": self.reduction, "hub": "free", "unstable": self.unstable,
            "state_names": self.state_names, "input_names": self.input_names,
            "output_names": self.output_names, "state_units": self.state_units,
            "input_units": ["N m"], "output_units": self.output_units,
            "params": dataclasses.asdict(self.params), "param_units": Params.units(),
        }

    def __eq__(self, other):
        if not isinstance(other, LinearModel):
            return NotImplemented
        same = all(a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()
                   for a, b in zip((self.A, self.B, self.C, self.D),
                                   (other.A, other.B, other.C, other.D)))
        return same and self.metadata() == other.metadata() and self.params == other.params

    __hash__ = None

    def __repr__(self):
        kind = f"dt={self.dt:g} s" if self.is_discrete else "continuous"
        return (f"LinearModel({self.model!r}, spin={self.spin:g} rad/s, {self.n_states} states, "
                f"outputs={self.output_names}, {kind}, reduction={self.reduction!r})")


def _make_ss(A, B, C, D, dt, states, outputs, name) -> control.StateSpace:
    import control
    return control.ss(A, B, C, D, dt, states=list(states), inputs=["tau"],
                      outputs=list(outputs), name=name)


def _parse_outputs(outputs) -> list:
    if isinstance(outputs, str):
        outputs = [o.strip() for o in outputs.split(",") if o.strip()]
    outputs = list(outputs)
    allowed = ", ".join(OUTPUTS)
    if not outputs:
        raise ParameterError(f"outputs must name at least one of {allowed}, got none")
    for o in outputs:
        if o not in OUTPUTS:
            raise ParameterError(f"outputs must be among {allowed}, got {o!r}")
    if len(set(outputs)) != len(outputs):
        raise ParameterError(f"outputs must not repeat a name, got {','.join(outputs)}")
    return outputs


def linearize(model="sfoam", spin: float = 0.0, params: Params | None = None,
              outputs=DEFAULT_OUTPUTS, *, n_modes: int | None = None,
              tip_mass: float | None = None, tip_position: float | None = None,
              damping: float | None = None, name: str | None = None) -> LinearModel:
    """Linearise a hub-beam model about steady spin with the hub free.

    Parameters
    ----------
    model : {"sfoam", "foam", "cfoam", "tlam"} or HubBeamModel
        Source model (default SFOAM, the paper's design model).
    spin : float
        Steady hub rate Omega [rad/s] (default 0, the slew design point), a number with
        ``|spin| <= params.max_spin``.
    params : Params, optional
        System parameters (default: the paper's Table 1). Ignored for a HubBeamModel.
    outputs : sequence of str or comma-separated str
        Any of :data:`OUTPUTS`, in the order wanted (default ``theta, tip_deflection``).
    n_modes : int, optional
        Number of transverse modes n2 (1..20), overriding ``params.n_transverse``.
    tip_mass : float, optional
        Tip mass m_t [kg] (>= 0), overriding ``params.m_t``.
    tip_position : float, optional
        Tip-mass position l [m] (0..L), overriding ``params.l``.
    damping : float, optional
        Modal damping ratio zeta of the clamped modes (0 <= zeta < 1), overriding
        ``params.damping_ratio``.
    name : str, optional
        System name without '.' (default ``"<model>_spin<spin>"``, '.' written 'p').

    Returns
    -------
    LinearModel
        ``.sys`` is the named :class:`control.StateSpace`; states as in the module
        docstring, input ``tau`` [N m].

    Examples
    --------
    >>> lm = linearize(outputs="theta,root_moment", n_modes=3)
    >>> lm.n_states, lm.sys.output_labels
    (8, ['theta', 'root_moment'])
    """
    hub_model, spin, outputs, A, B, C, D, states = _linearized(
        model, spin, params, outputs, n_modes=n_modes, tip_mass=tip_mass, tip_position=tip_position,
        damping=damping)
    if name is None:
        name = f"{hub_model.name}_spin{spin:g}".replace(".", "p")
    if not isinstance(name, str) or not name or "." in name:
        raise ParameterError(f"name must be a non-empty string without '.', got {name!r}")
    sys = _make_ss(A, B, C, D, 0, states, outputs, name)
    return LinearModel(sys=sys, model=hub_model.name, spin=spin, params=hub_model.params)


def linear_matrices(model="sfoam", spin: float = 0.0, params: Params | None = None,
                    outputs=DEFAULT_OUTPUTS, *, n_modes: int | None = None, tip_mass: float | None = None,
                    tip_position: float | None = None, damping: float | None = None,
                    state_names: bool = False) -> tuple:
    """The matrices of :func:`linearize` without building a python-control system.

    The same numbers as ``linearize(...).A`` etc., for callers that need only the matrices
    (the study layer's linear certificate): python-control is not imported, which keeps a
    command such as ``hubbeam compare`` from loading it and SciPy's signal package.

    Parameters
    ----------
    model, spin, params, outputs, n_modes, tip_mass, tip_position, damping
        As for :func:`linearize` (``spin`` [rad/s], ``tip_mass`` [kg], ``tip_position`` [m],
        ``damping`` [-]).
    state_names : bool
        Also return the names of the states (as ``linearize(...).state_names``).

    Returns
    -------
    tuple
        ``(A, B, C, D)``: (n, n) [1/s], (n, 1) [per N m], (p, n) and (p, 1) in the outputs' units;
        with ``state_names``, ``(A, B, C, D, names)``.

    Examples
    --------
    >>> A, B, C, D = linear_matrices(outputs="theta,root_moment", n_modes=3)
    >>> A.shape, C.shape
    ((8, 8), (2, 8))
    """
    _, _, _, A, B, C, D, states = _linearized(model, spin, params, outputs, n_modes=n_modes, tip_mass=tip_mass,
                                              tip_position=tip_position, damping=damping)
    return (A, B, C, D, list(states)) if state_names else (A, B, C, D)


def _linearized(model, spin, params, outputs, *, n_modes, tip_mass, tip_position, damping) -> tuple:
    """``(hub_model, spin, outputs, A, B, C, D, states)`` of :func:`linearize`, checked."""
    if isinstance(model, HubBeamModel):
        hub_model = model
        overrides = any(v is not None for v in (n_modes, tip_mass, tip_position, damping))
        if overrides:
            raise ParameterError("model: pass a model name (not a HubBeamModel) to override "
                                 "n_modes, tip_mass, tip_position or damping")
    else:
        if not isinstance(model, str) or model.lower() not in MODEL_NAMES:
            raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {model!r}")
        p = params if params is not None else Params()
        if not isinstance(p, Params):
            raise ParameterError(f"params must be a Params, got {type(p).__name__}")
        changes = {}
        if n_modes is not None:
            changes["n_transverse"] = n_modes
        if tip_mass is not None:
            changes["m_t"] = tip_mass
        if tip_position is not None:
            changes["l"] = tip_position
        if damping is not None:
            changes["damping_ratio"] = damping
        if changes:
            p = p.replace(**changes)
        check_spin("spin", spin, p)            # before the (costly) model build
        hub_model = build_model(model.lower(), p)
    spin = check_spin("spin", spin, hub_model.params)
    outputs = _parse_outputs(outputs)

    lin = second_order_linearization(hub_model, spin, "free")
    A, B, states = first_order_matrices(lin)
    n = hub_model.n_q
    b, pr = hub_model.basis, hub_model.params
    q2 = hub_model.transverse_slice
    sensors = sensor_matrix(pr, hub_model.n_transverse, hub_model.n_axial)   # the simulator's rows
    rows = []
    for o in outputs:
        c = np.zeros(2 * n)
        if o in SENSOR_NAMES:
            c = sensors[SENSOR_NAMES.index(o)]
        elif o == "tip_deflection":
            c[q2] = b.f2_tip
        elif o == "tip_rate":
            c[n + q2.start:n + q2.stop] = b.f2_tip
        rows.append(c)
    C = np.array(rows)
    D = np.zeros((len(outputs), 1))
    return hub_model, spin, outputs, A, B, C, D, states


# -- poles ------------------------------------------------------------------------
def poles(lm) -> np.ndarray:
    """Poles of a :class:`LinearModel` or :class:`control.StateSpace` (z-plane if sampled).

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
        The model.
    """
    sys = lm.sys if isinstance(lm, LinearModel) else lm
    return sys.poles()


def continuous_poles(lm) -> np.ndarray:
    """Poles in the s-plane [rad/s]; a sampled model's ``z`` are mapped by ``log(z)/dt``.

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
        The model (continuous or sampled).
    """
    sys = lm.sys if isinstance(lm, LinearModel) else lm
    lam = poles(sys).astype(complex)
    if sys.dt:
        dt = float(sys.dt)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.log(lam) / dt
    return lam


def _split_rigid(lam: np.ndarray, n_rigid: int):
    """Indices of the ``n_rigid`` poles nearest zero, and of the rest."""
    order = np.argsort(np.abs(lam), kind="stable")
    return order[:n_rigid], order[n_rigid:]


def poles_hz(lm, n_rigid: int | None = None) -> np.ndarray:
    """Undamped natural frequencies of the oscillatory poles [Hz], ascending.

    Each complex-conjugate pair counts once (``|s| / 2 pi``); the rigid-body double pole
    at ``s = 0`` and real poles (a mode that has lost its stiffness) are left out.

    Parameters
    ----------
    lm : LinearModel or control.StateSpace
    n_rigid : int, optional
        Number of rigid-body poles to drop (the ones nearest zero). Default: 2 for a
        :class:`LinearModel` (free hub), else those with ``|s| < 1e-9 max|s|``.

    Returns
    -------
    ndarray
    """
    lam = continuous_poles(lm)
    if n_rigid is None and isinstance(lm, LinearModel):
        n_rigid = 2
    if n_rigid is None:
        keep = np.abs(lam) > 1e-9 * max(np.abs(lam).max(), 1.0)
    else:
        keep = np.zeros(len(lam), bool)
        keep[_split_rigid(lam, n_rigid)[1]] = True
    lam = lam[keep]
    osc = lam[(lam.imag > 0) & (np.abs(lam.imag) > 1e-9 * np.abs(lam))]
    return np.sort(np.abs(osc)) / (2 * np.pi)


# -- discretisation ---------------------------------------------------------------
def discretize(lm: LinearModel, dt: float, method: str = "zoh") -> LinearModel:
    """Sample a continuous model (zero-order hold by default).

    Parameters
    ----------
    lm : LinearModel
        Continuous-time model.
    dt : float
        Sample time [s], in [1e-6, 10]; refused when a growing mode overflows the sampled
        matrices.
    method : {"zoh", "foh", "impulse", "tustin", "bilinear", "euler", "backward_diff"}
        Passed to :meth:`control.StateSpace.sample` (default zero-order hold).

    Returns
    -------
    LinearModel
        Same state, input and output names; ``sys.dt == dt``; name ``<name>_d``.
    """
    if not isinstance(lm, LinearModel):
        raise ParameterError(f"model must be a LinearModel, got {type(lm).__name__}")
    dt = check_in_range("dt", dt, "s", DT_RANGE[0], DT_RANGE[1])
    if lm.is_discrete:
        raise ParameterError(f"model must be continuous-time to discretize, it has dt = {lm.dt}")
    methods = ("zoh", "foh", "impulse", "tustin", "bilinear", "euler", "backward_diff")
    if method not in methods:
        raise ParameterError(f"method must be one of {', '.join(methods)}, got {method!r}")
    with np.errstate(all="ignore"), warnings.catch_warnings():   # overflow is checked below
        warnings.simplefilter("ignore", RuntimeWarning)
        sysd = lm.sys.sample(dt, method=method, name=f"{lm.name}_d", copy_names=True)
    if not all(np.all(np.isfinite(np.asarray(M))) for M in (sysd.A, sysd.B, sysd.C, sysd.D)):
        growth = float(np.max(continuous_poles(lm).real))
        raise ParameterError(f"dt = {dt:g} s is too long for this model: its fastest-growing mode "
                             f"(real part {growth:.4g} 1/s) overflows the sampled matrices")
    sysd = _make_ss(sysd.A, sysd.B, sysd.C, sysd.D, dt, lm.state_names, lm.output_names, sysd.name)
    return dataclasses.replace(lm, sys=sysd)


# -- reduction ------------------------------------------------------------------
def _modal_basis(A: np.ndarray):
    """Real modal coordinates of a free-hub model.

    Returns ``P`` (columns: rigid angle, rigid rate, then per mode ``eta``, ``eta_dot``) and
    the s-plane eigenvalue pairs of the modes, sorted by undamped natural frequency.
    ``x = P xi`` with ``xi = [rigid, rigid_dot, eta_1, eta_dot_1, ...]``.
    """
    n2 = A.shape[0]
    n = n2 // 2
    # rigid rotation: A r1 = 0 (r1 = unit hub angle), A r2 = r1 (Jordan chain)
    r1 = np.zeros(n2)
    r1[0] = 1.0
    scale = max(np.abs(A).max(), 1.0)
    if np.abs(A @ r1).max() > 1e-10 * scale:
        raise ParameterError("model: the hub angle is not a rigid-body coordinate (hub not free)")
    r2 = np.linalg.lstsq(A, r1, rcond=None)[0]
    r2 -= r2[0] * r1
    if np.abs(A @ r2 - r1).max() > 1e-8:
        raise ParameterError("model: no rigid-body double integrator found (hub not free)")
    lam, V = np.linalg.eig(A)
    rigid, rest = _split_rigid(lam, 2)
    lam, V = lam[rest], V[:, rest]
    # pair the eigenvalues: conjugate pairs, and real ones (lost stiffness) by shape
    used = np.zeros(len(lam), bool)
    pairs = []
    disp = V[:n]
    for i in np.argsort(np.abs(lam), kind="stable"):
        if used[i]:
            continue
        used[i] = True
        cand = np.nonzero(~used)[0]
        if abs(lam[i].imag) > 1e-9 * abs(lam[i]):
            j = cand[np.argmin(np.abs(lam[cand] - np.conj(lam[i])))]
        else:
            cand = cand[np.abs(lam[cand].imag) <= 1e-9 * np.abs(lam[cand])]
            if not len(cand):
                raise ParameterError("model: an unpaired real pole prevents modal reduction")
            a = disp[:, i] / np.linalg.norm(disp[:, i])
            cos = [abs(np.vdot(a, disp[:, c])) / np.linalg.norm(disp[:, c]) for c in cand]
            j = cand[int(np.argmax(cos))]
        used[j] = True
        if lam[i].imag < 0:
            i, j = j, i
        pairs.append((i, j))
    cols, mode_lams = [r1, r2], []
    for i, j in pairs:
        la, lb = lam[i], lam[j]
        va, vb = V[:, i].copy(), V[:, j].copy()
        # normalise: displacement part's largest elastic component = 1 (eta in metres)
        k = 1 + np.argmax(np.abs(va[1:n]))
        va /= va[k]
        vb /= vb[k]
        Pk = np.column_stack([va, vb]) @ np.linalg.inv(np.array([[1, 1], [la, lb]]))
        cols += [Pk[:, 0].real, Pk[:, 1].real]
        mode_lams.append((la, lb))
    return np.column_stack(cols), mode_lams


def reduce(lm: LinearModel, n_modes: int, method: str = "modal") -> LinearModel:
    """Reduced-order model keeping the rigid rotation and ``n_modes`` flexible modes.

    Parameters
    ----------
    lm : LinearModel
        Continuous-time, free-hub model (from :func:`linearize`).
    n_modes : int
        Flexible modes to keep, 1..(number of modes of ``lm``).
    method : {"modal", "balanced"}
        ``modal``: modal truncation keeping the ``n_modes`` lowest-frequency modes of the
        coupled system exactly (their poles and residues are those of ``lm``). States
        ``[rigid, mode_1..mode_k, rigid_dot, mode_dot_1..mode_dot_k]``: ``rigid`` [rad] is
        the rigid-body hub angle, ``mode_i`` [m] the amplitude of mode i with its
        displacement shape scaled so that its largest elastic coordinate (q1 or q2) is 1;
        each mode obeys ``mode_i'' + 2 zeta_i w_i mode_i' + w_i^2 mode_i = b_i tau``.
        ``balanced``: the rigid block is kept exactly and the flexible part is reduced
        by balanced truncation to ``2 n_modes`` states (``control.balred`` when slycot is
        installed, else a square-root algorithm on SciPy). States ``rigid``,
        ``rigid_dot``, ``xb_1..``. Needs ``damping_ratio > 0`` (undamped modes have no
        finite Gramians).

    Returns
    -------
    LinearModel
        ``reduction`` is ``"modal:K"`` or ``"balanced:K"``.
    """
    if not isinstance(lm, LinearModel):
        raise ParameterError(f"model must be a LinearModel, got {type(lm).__name__}")
    if lm.is_discrete:
        raise ParameterError("model must be continuous-time to reduce (reduce, then discretize)")
    if lm.reduction != "none":
        raise ParameterError(f"model is already reduced ({lm.reduction}); reduce the full model")
    if method not in ("modal", "balanced"):
        raise ParameterError(f"method must be 'modal' or 'balanced', got {method!r}")
    A, B, C, D = lm.A, lm.B, lm.C, lm.D
    n_flex = A.shape[0] // 2 - 1
    n_modes = check_integer("n_modes", n_modes, 1, n_flex)
    P, mode_lams = _modal_basis(A)
    T = np.linalg.inv(P)
    Bm, Cm = T @ B, C @ P
    if method == "modal":
        k = n_modes
        Ar = np.zeros((2 * k + 2, 2 * k + 2))
        # reorder xi = [rigid, rigid_dot, eta_1, eta_dot_1, ...] to positions then rates
        pos = [0] + [2 + 2 * i for i in range(k)]
        vel = [1] + [3 + 2 * i for i in range(k)]
        idx = pos + vel
        m = k + 1
        Ar[0, m] = 1.0
        for i, (la, lb) in enumerate(mode_lams[:k], start=1):
            Ar[i, m + i] = 1.0
            Ar[m + i, i] = -(la * lb).real
            Ar[m + i, m + i] = (la + lb).real
        Br, Cr = Bm[idx], Cm[:, idx]
        states = ["rigid"] + [f"mode_{i}" for i in range(1, k + 1)]
        states = states + [velocity_name(s) for s in states]
    else:
        zeta = lm.params.damping_ratio
        if zeta <= 0:
            raise ParameterError("damping_ratio must be > 0 for balanced reduction (undamped "
                                 "modes have no finite Gramians), got 0")
        Af = T[2:] @ A @ P[:, 2:]
        if np.linalg.eigvals(Af).real.max() >= 0:
            raise ParameterError("model: balanced reduction needs stable flexible modes "
                                 "(this one has lost its stiffness)")
        Ab, Bb, Cb = _balanced_truncation(Af, Bm[2:], Cm[:, 2:], 2 * n_modes)
        r = Ab.shape[0]
        Ar = np.zeros((r + 2, r + 2))
        Ar[0, 1] = 1.0
        Ar[2:, 2:] = Ab
        Br = np.vstack([Bm[:2], Bb])
        Cr = np.hstack([Cm[:, :2], Cb])
        states = ["rigid", "rigid_dot"] + [f"xb_{i}" for i in range(1, r + 1)]
    sysr = _make_ss(Ar, Br, Cr, D, 0, states, lm.output_names,
                    f"{lm.name}_{method}{n_modes}")
    return dataclasses.replace(lm, sys=sysr, reduction=f"{method}:{n_modes}")


def _balanced_truncation(A, B, C, order):
    """Balanced truncation of a stable system to ``order`` states."""
    import control
    try:
        red = control.balred(control.ss(A, B, C, np.zeros((C.shape[0], B.shape[1]))), order)
        return np.asarray(red.A), np.asarray(red.B), np.asarray(red.C)
    except (ImportError, control.exception.ControlSlycot):
        pass
    import scipy.linalg as sla
    Wc = sla.solve_continuous_lyapunov(A, -B @ B.T)
    Wo = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    Lc = _psd_factor(Wc)
    Lo = _psd_factor(Wo)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    S = np.diag(s[:order] ** -0.5)
    Tl = S @ U[:, :order].T @ Lo.T          # reduced = Tl x
    Tr = Lc @ Vt[:order].T @ S              # x ~ Tr reduced
    return Tl @ A @ Tr, Tl @ B, C @ Tr


def _psd_factor(W):
    """``L`` with ``W = L L'`` for a symmetric positive semidefinite ``W``."""
    w, V = np.linalg.eigh(0.5 * (W + W.T))
    return V * np.sqrt(np.clip(w, 0, None))


# -- comparison -------------------------------------------------------------------
@dataclass(frozen=True)
class PoleComparison:
    """Poles of two models at the same spin, side by side (from :func:`compare_poles`).

    Attributes
    ----------
    model_a, model_b : str
    spin : float
        [rad/s]
    bending_a_hz, bending_b_hz : ndarray
        Bending natural frequencies [Hz], ascending, both of the same length; NaN for
        the lowest modes of a model that has lost their stiffness (real poles).
    axial_a_hz, axial_b_hz : ndarray
        Axial natural frequencies [Hz] (empty for SFOAM).
    zeta_a, zeta_b : ndarray
        Damping ratios of the bending modes.
    unstable_a, unstable_b : bool
        A mode has lost its stiffness (TLAM above its critical speed).
    """

    model_a: str
    model_b: str
    spin: float
    bending_a_hz: np.ndarray
    bending_b_hz: np.ndarray
    axial_a_hz: np.ndarray
    axial_b_hz: np.ndarray
    zeta_a: np.ndarray
    zeta_b: np.ndarray
    unstable_a: bool
    unstable_b: bool

    @property
    def bending_rel_diff(self) -> np.ndarray:
        """``(f_b - f_a) / f_a`` per bending mode [-] (NaN where a mode is lost)."""
        return (self.bending_b_hz - self.bending_a_hz) / self.bending_a_hz

    def rows(self) -> list:
        """One dict per mode: ``kind``, ``index``, ``a_hz``, ``b_hz``, ``rel_diff``.

        ``None`` marks a mode a model does not have (SFOAM's axial modes) or has lost.
        """
        out = []
        for kind, fa, fb in (("bending", self.bending_a_hz, self.bending_b_hz),
                             ("axial", self.axial_a_hz, self.axial_b_hz)):
            for i in range(max(len(fa), len(fb))):
                a = float(fa[i]) if i < len(fa) and np.isfinite(fa[i]) else None
                b = float(fb[i]) if i < len(fb) and np.isfinite(fb[i]) else None
                rel = (b - a) / a if a is not None and b is not None else None
                out.append({"kind": kind, "index": i + 1, "a_hz": a, "b_hz": b, "rel_diff": rel})
        return out

    def table(self) -> str:
        """The comparison as a text table."""
        a, b = self.model_a.upper(), self.model_b.upper()
        lines = [f"poles at spin {self.spin:g} rad/s (hub free): {a} vs {b}",
                 f"{'mode':<12}{a + ' [Hz]':>16}{b + ' [Hz]':>16}{'(b-a)/a':>14}"]
        for r in self.rows():
            cells = []
            for v in (r["a_hz"], r["b_hz"]):
                gone = "(lost)" if r["kind"] == "bending" else "(absent)"
                cells.append(f"{v:16.6f}" if v is not None else f"{gone:>16}")
            rel = f"{r['rel_diff']:14.3e}" if r["rel_diff"] is not None else f"{'':>14}"
            lines.append(f"{r['kind'] + ' ' + str(r['index']):<12}{cells[0]}{cells[1]}{rel}")
        for m, u in ((a, self.unstable_a), (b, self.unstable_b)):
            if u:
                lines.append(f"{m}: a mode has lost its stiffness (real pole > 0), not listed")
        return "\n".join(lines)

    def __str__(self):
        return self.table()


def compare_poles(model_a="sfoam", model_b="foam", spin: float = 0.0,
                  params: Params | None = None) -> PoleComparison:
    """Set the poles of two models linearised about the same spin side by side.

    Shows what one model leaves out (e.g. SFOAM's missing axial modes and axial coupling
    against FOAM). Modes are classified as bending or axial by where their kinetic energy
    lies (:func:`hubbeam_ctrl.plant.modal.modal_analysis`, hub free).

    Parameters
    ----------
    model_a, model_b : str or LinearModel
        Model names, or models from :func:`linearize` (their model, spin and params are
        used; ``spin`` and ``params`` are then ignored).
    spin : float
        Spin rate [rad/s].
    params : Params, optional

    Returns
    -------
    PoleComparison
        ``print(cmp)`` gives a table.

    Examples
    --------
    >>> c = compare_poles("sfoam", "foam", spin=2.0)
    >>> len(c.axial_a_hz), len(c.axial_b_hz)
    (0, 5)
    """
    from hubbeam_ctrl.plant.modal import modal_analysis

    def analyse(m):
        if isinstance(m, LinearModel):
            return modal_analysis(m.model, m.spin, "free", m.params), m.spin
        if not isinstance(m, str) or m.lower() not in MODEL_NAMES:
            raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {m!r}")
        return modal_analysis(m.lower(), float(spin), "free",
                              params if params is not None else Params()), float(spin)

    ra, sa = analyse(model_a)
    rb, sb = analyse(model_b)
    if sa != sb:
        raise ParameterError(f"spin must be the same for both models, got {sa} and {sb}")
    n = max(len(ra.bending_hz), len(rb.bending_hz))

    def pad(values):   # modes that lost their stiffness are the lowest: pad in front
        return np.concatenate([np.full(n - len(values), np.nan), values])

    return PoleComparison(model_a=ra.model, model_b=rb.model, spin=sa,
                          bending_a_hz=pad(ra.bending_hz), bending_b_hz=pad(rb.bending_hz),
                          axial_a_hz=ra.axial_hz, axial_b_hz=rb.axial_hz,
                          zeta_a=pad(ra.damping_ratios), zeta_b=pad(rb.damping_ratios),
                          unstable_a=ra.unstable, unstable_b=rb.unstable)
