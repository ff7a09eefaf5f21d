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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.poles import continuous_poles, poles_hz
from hubbeam_ctrl.plant.linearization import first_order_matrices, second_order_linearization
from hubbeam_ctrl.plant.models import MODEL_NAMES, HubBeamModel, build_model
from hubbeam_ctrl.plant.params import Params, check_spin
from hubbeam_ctrl.plant.sensors import SENSOR_NAMES, sensor_matrix

# python-control is imported where a system is built: the matrices alone (linear_matrices) do not
# need it, and a command that needs only them (hubbeam compare) does not pay for its import
if TYPE_CHECKING:
    import control

#: Allowed sample times of :func:`~hubbeam_ctrl.linear.transforms.discretize` [s].
DT_RANGE = (1e-6, 10.0)

__all__ = ["LinearModel", "OUTPUTS", "DEFAULT_OUTPUTS", "linearize", "linear_matrices"]

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


def state_unit(name: str) -> str:
    """Unit of a state named ``name`` (``-`` for the balanced coordinates).

    Parameters
    ----------
    name : str
        ``theta``, ``q2_1``, ``q1_dot_2``...

    Returns
    -------
    str
    """
    if name in _STATE_UNITS:
        return _STATE_UNITS[name]
    if name.startswith(("q1_dot_", "q2_dot_")):
        return "m/s"
    if name.startswith(("q1_", "q2_")):
        return "m"
    return "-"


class SystemViews:
    """Read-only views of a named python-control system held as ``sys``: its matrices, sample
    time and signal names (shared by :class:`LinearModel` and
    :class:`~controllers.export.ControllerModel`)."""

    sys: control.StateSpace

    A = property(lambda self: np.asarray(self.sys.A, dtype=float), doc="State matrix (n, n).")
    B = property(lambda self: np.asarray(self.sys.B, dtype=float), doc="Input matrix (n, inputs).")
    C = property(lambda self: np.asarray(self.sys.C, dtype=float), doc="Output matrix (outputs, n).")
    D = property(lambda self: np.asarray(self.sys.D, dtype=float),
                 doc="Feedthrough (outputs, inputs); zero for the plant models built here.")
    name = property(lambda self: self.sys.name, doc="python-control system name.")
    state_names = property(lambda self: list(self.sys.state_labels), doc="Names of the states.")
    input_names = property(lambda self: list(self.sys.input_labels), doc="Names of the inputs.")
    output_names = property(lambda self: list(self.sys.output_labels), doc="Names of the outputs.")
    n_states = property(lambda self: int(self.sys.nstates), doc="Number of states.")

    @property
    def dt(self) -> float:
        """Sample time [s]; 0 for a continuous-time system."""
        return 0.0 if not self.sys.dt else float(self.sys.dt)

    @property
    def is_discrete(self) -> bool:
        """True for a sampled system."""
        return self.dt > 0


@dataclass(frozen=True, eq=False)
class LinearModel(SystemViews):
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

    state_units = property(lambda self: [state_unit(s) for s in self.state_names],
                           doc="Unit of each state (``-`` for the balanced coordinates).")
    output_units = property(lambda self: [OUTPUTS[o][0] if o in OUTPUTS else "-" for o in self.output_names],
                            doc="Unit of each output (:data:`OUTPUTS`).")

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


def named_ss(A, B, C, D, dt, states, outputs, name) -> control.StateSpace:
    """A python-control system with the input ``tau`` [N m] and named states and outputs.

    Parameters
    ----------
    A, B, C, D : array_like
        State-space matrices.
    dt : float
        Sample time [s], 0 for continuous time.
    states, outputs : list of str
        Names of the states and outputs.
    name : str
        System name.
    """
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
    sys = named_ss(A, B, C, D, 0, states, outputs, name)
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
