"""A planar geometrically exact beam on a rigid hub, by Exudyn's ANCF cable elements.

The beam of :class:`~hubbeam_ctrl.plant.params.Params` (length ``L``, ``rho A``, ``E A``,
``E I``) is ``n_elements`` ``ObjectANCFCable2D`` elements (cubic in position, geometrically
exact in stretch and bending), clamped at radius ``r`` to a rigid hub (``ObjectRigidBody2D``
with inertia ``J_h``, its centre held at the origin) by a generic joint that fixes the root's
position and the direction of the beam axis to the hub. The tip mass ``m_t`` is a point mass
joined to the beam at ``l``. The hub torque is a torque load on the hub; the integrator is
Exudyn's generalized-alpha (index 3, spectral radius ``rho_inf``) with a fixed step of
``dt / substeps``, advanced one sample at a time (``MainSolverImplicitSecondOrder.SolveSteps``).

Outputs follow the toolbox's definitions: hub angle and rate; ``v_tip`` and ``u_tip`` the
displacement of the beam's material point at ``l`` in the hub frame (perpendicular to and along
the undeformed axis; ``u_tip`` includes the foreshortening); the root moment is the clamp
joint's reaction moment about the hub axis, signed as ``E I w''(0)`` (the assumed-mode models'
``M_root``). The reaction is the joint's Lagrange multiplier, exact for the discrete model,
whereas the first element's curvature is a cubic's second derivative, which converges one
order slower in the element length and misses the root's share of a moment that varies
along the element. For a controller that reads the state, the hub-frame deflection is
projected onto the clamped-free modes of the assumed-mode plant (mass-weighted least
squares: ``q2 = M2^-1 int rho A f2 w dx``, likewise ``q1`` on the axial modes).
"""

from __future__ import annotations

import importlib.util
import math
import time

import numpy as np

from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.plant.basis import axial_shapes, transverse_shapes
from hubbeam_ctrl.plant.params import Params

__all__ = ["EXUDYN_INSTALL", "MIN_ELEMENTS", "MIN_STEPS_PER_PERIOD", "ExactBeamPlant", "element_rule",
           "exudyn_available", "highest_mode_hz", "min_substeps", "require_exudyn"]

#: One line on how to get the optional dependency.
EXUDYN_INSTALL = "the exact-beam plant needs Exudyn: pip install 'hubbeam-ctrl[exact]' (or pip install exudyn)"
#: Fewest elements the plant accepts, whatever the modes.
MIN_ELEMENTS = 8
#: Elements per resolved bending mode in :func:`element_rule` (its minimum accepted: 2).
ELEMENTS_PER_MODE = 3
#: Fewest integration steps per period of the highest resolved bending mode that the plant accepts
#: (generalized-alpha's frequency error there: -2.2 % at rho_inf = 0.9; the closed loop's rule,
#: ``sim.substep_rule`` at ``ClosedLoopSettings.frequency_tolerance`` = 2 %, takes 12.7 steps per period,
#: the open-loop runs' 0.5 % about 26). Fewer steps do not resolve the mode.
MIN_STEPS_PER_PERIOD = 12
#: Most integration steps per sample (as the assumed-mode stepper's ``MAX_SUBSTEPS``).
MAX_SUBSTEPS = 200


def exudyn_available() -> bool:
    """True when the optional Exudyn package can be imported.

    Returns
    -------
    bool
    """
    return importlib.util.find_spec("exudyn") is not None


def require_exudyn(option: str = "plant='ancf'"):
    """Import Exudyn or raise a one-line :class:`ParameterError` saying how to install it.

    Parameters
    ----------
    option : str
        The option the caller used, named in the message.

    Returns
    -------
    module
        ``exudyn``.
    """
    if not exudyn_available():
        raise ParameterError(f"{option}: {EXUDYN_INSTALL}")
    import exudyn
    return exudyn


def element_rule(n_modes: int) -> int:
    """ANCF cable elements for a plant that resolves ``n_modes`` bending modes.

    ``3 n_modes`` rounded up to a multiple of 8, at least 16: 32 for the 10-mode evaluation
    plant of Table 1's beam (the exact-beam reference's count; halving the step and doubling
    the elements changes its peak tip deflection by less than 1e-4 m). Cubic elements need
    about two per half wave of a mode shape; three per mode is the margin.

    Parameters
    ----------
    n_modes : int
        Bending modes to resolve, 1..40 [-].

    Returns
    -------
    int
        Number of elements [-].

    Examples
    --------
    >>> element_rule(10)
    32
    """
    n = int(check_in_range("n_modes", n_modes, "", 1, 40))
    return max(16, 8 * math.ceil(ELEMENTS_PER_MODE * n / 8))


def highest_mode_hz(params: Params, n_modes: int, hub: str = "free") -> float:
    """Frequency of the highest bending mode the exact-beam plant resolves [Hz].

    The ``n_modes``-th bending frequency of FOAM with ``n_modes`` transverse modes at rest (a
    Ritz model: its top frequency is slightly above the beam's, so the check errs on the safe
    side); the ANCF elements of :func:`element_rule` resolve at least these modes.

    Parameters
    ----------
    params : Params
        The beam, hub and tip mass.
    n_modes : int
        Bending modes the plant resolves, 1..20 [-].
    hub : {"free", "prescribed"}
        The hub free to turn (torque input) or its angle prescribed (clamped root).

    Returns
    -------
    float
        Frequency [Hz].
    """
    from hubbeam_ctrl.plant.modal import modal_analysis
    from hubbeam_ctrl.plant.models import build_model
    n = int(check_in_range("n_modes", n_modes, "", 1, 20))
    model = build_model("foam", params.replace(n_transverse=n))
    return float(np.max(modal_analysis(model, 0.0, hub).bending_hz))


def min_substeps(dt: float, frequency_hz: float) -> int:
    """Fewest integration steps per sample ``dt`` that resolve a mode of ``frequency_hz``.

    ``ceil(MIN_STEPS_PER_PERIOD dt f)``: at least :data:`MIN_STEPS_PER_PERIOD` steps per period.

    Parameters
    ----------
    dt : float
        Sample period [s], > 0.
    frequency_hz : float
        The highest resolved bending frequency [Hz], > 0.

    Returns
    -------
    int
        Steps per sample [-], at least 1.

    Examples
    --------
    >>> min_substeps(0.01, 113.9)
    14
    """
    return max(1, math.ceil(MIN_STEPS_PER_PERIOD * dt * frequency_hz * (1 - 1e-12)))


def _hermite(xi: np.ndarray, h: float) -> np.ndarray:
    """Cubic Hermite shape functions ``[N0, N0', N1, N1']`` at ``xi`` in [0, 1] of an element of length h."""
    return np.stack([1 - 3 * xi ** 2 + 2 * xi ** 3, h * (xi - 2 * xi ** 2 + xi ** 3),
                     3 * xi ** 2 - 2 * xi ** 3, h * (-xi ** 2 + xi ** 3)], axis=-1)


class ExactBeamPlant:
    """The hub-beam as a geometrically exact ANCF beam (Exudyn), stepped one sample at a time.

    It has the methods of :class:`~hubbeam_ctrl.sim.stepper.PlantStepper` that the closed loop
    uses: :meth:`initial_state` and :meth:`step` return the plant's state projected onto the
    assumed modes, ``[theta, q1, q2, theta_dot, q1_dot, q2_dot]`` (``n_axial`` and ``n_modes``
    of them), and :attr:`outputs` holds the exact outputs of the last sample.

    Parameters
    ----------
    params : Params
        The physical beam, hub and tip mass (Table 1 by default). Damping: ``damping_ratio``
        (or the first of ``damping_ratios``) is matched at the first bending mode by
        stiffness-proportional (Rayleigh ``beta``) damping of bending and stretch.
    n_elements : int
        ANCF cable elements, at least ``max(8, 2 n_modes)`` (:func:`element_rule`).
    dt : float
        Sample period [s]: one :meth:`step` advances the plant by ``dt``.
    substeps : int
        Integration steps per sample, 1..200 (the step is ``dt / substeps``); at least
        :func:`min_substeps` of the highest resolved mode (:data:`MIN_STEPS_PER_PERIOD` steps per
        period of bending mode ``n_modes``, :func:`highest_mode_hz`), else refused naming the least.
    n_modes : int
        Transverse modes of the projected state (that a state-feedback controller reads), 1..20.
    n_axial : int
        Axial modes of the projected state, 1..20.
    rho_inf : float
        Spectral radius at infinity of generalized-alpha [-], 0..1.
    hardware : object, optional
        The rig's drive and friction: an object with ``hub_torque(command, theta_dot)`` and, for
        sticking, ``friction.static`` and ``friction.stick_velocity`` (as
        :class:`~hubbeam_ctrl.sim.hardware.Hardware`, whose ``hub_torque_scalar`` is used when
        present); the input of :meth:`step` is then the command (one value, or one per
        integration step: a computation delay), turned into the hub torque inside every
        integration step at the hub rate of the current Newton iterate (its derivative in the
        Jacobian). With friction the hub sticks (Karnopp) inside the step: a sliding hub that
        slowed into ``stick_velocity`` or reversed within an integration step repeats the step
        held (a velocity constraint, Exudyn's discontinuous iteration from the start of the step)
        and stays held while the holding torque (:attr:`hold_torque`, the constraint's reaction)
        is within the breakaway torque; :attr:`stuck` says whether it is held. (The assumed-mode
        stepper decides the same per sample.)
    prescribed : callable, optional
        ``theta(t)`` [rad]: the hub angle is prescribed (a constraint) and the torque input is
        ignored; the hub torque it takes is in :attr:`outputs`.
    torque_function : callable, optional
        ``tau(t)`` [N m] added to the held input at every integration step (an open-loop torque
        without the zero-order hold).
    substeps_option, dt_option : str
        How the caller spells ``substeps`` and ``dt`` (named in the refusal of a step too long).

    Examples
    --------
    >>> plant = ExactBeamPlant(Params(), n_elements=16, dt=0.01, substeps=20)  # doctest: +SKIP
    >>> x = plant.step(plant.initial_state(), 100.0)                           # doctest: +SKIP
    """

    def __init__(self, params: Params | None = None, *, n_elements: int = 32, dt: float = 0.01,
                 substeps: int = 20, n_modes: int = 10, n_axial: int = 5, rho_inf: float = 0.9,
                 hardware=None, prescribed=None, torque_function=None, substeps_option: str = "substeps",
                 dt_option: str = "dt"):
        exu = require_exudyn()
        from exudyn import itemInterface as ii

        self.params = p = Params() if params is None else params
        if not isinstance(p, Params):
            raise ParameterError(f"params must be a Params, got {type(p).__name__}")
        self.n_modes = int(check_in_range("n_modes", n_modes, "", 1, 20))
        self.n_axial = int(check_in_range("n_axial", n_axial, "", 1, 20))
        lo = max(MIN_ELEMENTS, 2 * self.n_modes)
        if isinstance(n_elements, bool) or not isinstance(n_elements, (int, np.integer)) or \
                not lo <= n_elements <= 512:
            raise ParameterError(f"n_elements must be an integer in [{lo}, 512] (two per resolved bending "
                                 f"mode, at least {MIN_ELEMENTS}) for {self.n_modes} modes, got {n_elements!r}")
        self.n_elements = ne = int(n_elements)
        self.dt = check_in_range("dt", dt, "s", 1e-5, 1.0)
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or not 1 <= substeps <= 200:
            raise ParameterError(f"substeps must be an integer in [1, 200], got {substeps!r}")
        self.substeps = int(substeps)
        #: The highest resolved bending mode's frequency [Hz] and the fewest steps per sample it needs.
        self.highest_mode_hz = highest_mode_hz(p, self.n_modes, "free" if prescribed is None else "prescribed")
        self.min_substeps = min_substeps(self.dt, self.highest_mode_hz)
        if self.substeps < self.min_substeps:
            need = f"bending mode {self.n_modes} of the exact beam at {self.highest_mode_hz:.4g} Hz needs " \
                   f"{MIN_STEPS_PER_PERIOD} steps per period"
            if self.min_substeps > MAX_SUBSTEPS:
                dt_max = MAX_SUBSTEPS / (MIN_STEPS_PER_PERIOD * self.highest_mode_hz)
                raise ParameterError(f"{dt_option} must be at most {dt_max:.4g} s ({need}; at most {MAX_SUBSTEPS} "
                                     f"steps per sample), got {self.dt:g} s")
            raise ParameterError(f"{substeps_option} must be at least {self.min_substeps} for {dt_option} = "
                                 f"{self.dt:g} s ({need}), got {self.substeps}")
        self.rho_inf = check_in_range("rho_inf", rho_inf, "", 0.0, 1.0)
        self.hardware = hardware if hardware is not None and not getattr(hardware, "is_ideal", False) else None
        if self.hardware is not None:      # plain floats when the hardware offers them (sim.Hardware)
            self._hub_torque = getattr(self.hardware, "hub_torque_scalar",
                                       lambda u, thd: float(self.hardware.hub_torque(u, thd)))
        self.prescribed = prescribed
        self.torque_function = torque_function
        # PlantStepper's statistics, for the closed loop's result
        self.fallbacks = 0
        self.jacobian_updates = 0
        self.stick_events = 0
        self.backend = "exudyn"
        self.wall_s = 0.0

        L, r = p.L, p.r
        l_tip = p.l if p.l is not None else L
        h = L / ne
        self.h = h
        zeta = p.damping_ratios[0] if p.damping_ratios else p.damping_ratio
        w1 = 2 * math.pi * self._first_frequency_hz()
        beta = 2 * zeta / w1
        self.rayleigh_beta = beta

        SC = exu.SystemContainer()
        mbs = SC.AddSystem()
        self._SC, self.mbs, self._exu = SC, mbs, exu
        mbs.AddObject(ii.ObjectGround())
        n_hub = mbs.AddNode(ii.NodeRigidBody2D(referenceCoordinates=[0, 0, 0]))
        hub = mbs.AddObject(ii.ObjectRigidBody2D(mass=1.0, inertia=p.J_h, nodeNumber=n_hub))
        m_ground = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=mbs.AddNode(ii.NodePointGround()),
                                                         coordinate=0))
        for c in (0, 1):               # the hub's centre held at the origin
            mc = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=n_hub, coordinate=c))
            mbs.AddObject(ii.ObjectConnectorCoordinate(markerNumbers=[m_ground, mc]))
        if prescribed is not None:
            m_phi = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=n_hub, coordinate=2))
            self._drive = mbs.AddObject(ii.ObjectConnectorCoordinate(
                markerNumbers=[m_ground, m_phi],
                offsetUserFunction=lambda mbs_, t, item, offset: float(prescribed(t))))
        self._lock = None
        self.stuck, self.hold_torque = False, 0.0
        self._step_end, self._tried_held, self._stuck_at_start = -1.0, False, False
        friction = getattr(self.hardware, "friction", None)       # None: no sticking (hub_torque only)
        self._F_s = float(getattr(friction, "static", 0.0))
        self._v_stick = float(getattr(friction, "stick_velocity", 0.0))
        if self._F_s > 0 and prescribed is None:      # Karnopp: the hub held at rest (its rate zero)
            m_phi = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=n_hub, coordinate=2))
            self._lock = mbs.AddObject(ii.ObjectConnectorCoordinate(markerNumbers=[m_ground, m_phi],
                                                                    velocityLevel=True, activeConnector=False))
        nodes = [mbs.AddNode(ii.NodePoint2DSlope1(referenceCoordinates=[r + i * h, 0.0, 1.0, 0.0]))
                 for i in range(ne + 1)]
        EI, EA, rhoA = p.E * p.I, p.E * p.A, p.rho * p.A
        self.EI = EI
        elements = [mbs.AddObject(ii.ObjectANCFCable2D(
            length=h, massPerLength=rhoA, bendingStiffness=EI, axialStiffness=EA,
            bendingDamping=beta * EI, axialDamping=beta * EA, nodeNumbers=[nodes[i], nodes[i + 1]]))
            for i in range(ne)]
        m_hub_root = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=hub, localPosition=[r, 0, 0]))
        m_beam_root = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=elements[0], localPosition=[0, 0, 0]))
        self._clamp = mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m_hub_root, m_beam_root],
                                                          constrainedAxes=[1, 1, 0, 0, 0, 1]))
        k_tip = min(int(l_tip / h), ne - 1)
        self._tip_element, self._tip_xi = k_tip, (l_tip - k_tip * h) / h
        if p.m_t > 0:
            n_tip = mbs.AddNode(ii.NodePoint2D(referenceCoordinates=[r + l_tip, 0.0]))
            mbs.AddObject(ii.ObjectMassPoint2D(mass=p.m_t, nodeNumber=n_tip))
            m_on_beam = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=elements[k_tip],
                                                            localPosition=[l_tip - k_tip * h, 0, 0]))
            mbs.AddObject(ii.ObjectJointRevolute2D(markerNumbers=[m_on_beam,
                                                                  mbs.AddMarker(ii.MarkerNodePosition(nodeNumber=n_tip))]))
        m_hub = mbs.AddMarker(ii.MarkerNodeRigid(nodeNumber=n_hub))
        self._tau = 0.0
        self._u_sub = np.zeros(self.substeps)       # the command in each step of the sample (hardware)
        self._h_step = self.dt / self.substeps
        if self.hardware is not None:
            self._load = mbs.AddLoad(ii.LoadTorqueVector(markerNumber=m_hub, loadVector=[0, 0, 0],
                                                         loadVectorUserFunction=self._hardware_torque))
        elif torque_function is not None:
            self._load = mbs.AddLoad(ii.LoadTorqueVector(
                markerNumber=m_hub, loadVector=[0, 0, 0],
                loadVectorUserFunction=lambda mbs_, t, load: [0.0, 0.0, self._tau + float(torque_function(t))]))
        else:
            self._load = mbs.AddLoad(ii.LoadTorqueVector(markerNumber=m_hub, loadVector=[0, 0, 0]))
        mbs.Assemble()

        sd = mbs.systemData
        self._i_hub = int(sd.GetObjectLTGODE2(hub)[2])
        idx = [list(sd.GetObjectLTGODE2(e)) for e in elements]
        self._i_nodes = np.array([i[:4] for i in idx] + [idx[-1][4:]], dtype=int)    # (ne+1, 4)
        self._elements = elements
        self._q_ref = np.asarray(sd.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))
        self._setup_projection()

        ss = exu.SimulationSettings()
        ti = ss.timeIntegration
        ti.numberOfSteps = self.substeps
        ti.endTime = self.dt
        ti.generalizedAlpha.spectralRadius = self.rho_inf
        ti.verboseMode = 0
        ti.newton.useModifiedNewton = True
        # measured on 32 elements, 2 s of a sine torque: Exudyn's defaults (relative 1e-8, absolute 1e-10)
        # stall the modified Newton iterations at a small torque (2 N m: 4 samples in 20 s, 61000
        # Jacobians) since the stiff axial terms' round-off exceeds 1e-10; absolute 1e-6, relative 1e-7:
        # 0.7-1.0 s, one Jacobian per sample, the tip to 1e-13 m of a tighter run at 200 N m
        ti.newton.relativeTolerance = 1e-7
        ti.newton.absoluteTolerance = 1e-6
        ss.solution.file.write = False
        ss.solution.sensors.writePeriod = 1e9
        ss.show.statistics = False
        ss.show.computationTime = False
        ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        self._settings = ss
        self._solver = exu.MainSolverImplicitSecondOrder()
        if self.hardware is not None:        # the hub torque's dependence on the hub rate in the Jacobian
            ti.computeLoadsJacobian = 2
            sd.AddODE2LoadDependencies(self._load, [self._i_hub])
        if self._lock is not None:
            ti.discontinuous.maxIterations = 4          # slide, held, and back (one switch each way)
            ti.discontinuous.ignoreMaxIterations = False
            mbs.SetPostNewtonUserFunction(self._post_newton)
        self._t = 0.0
        self._initialized = False
        #: Exact outputs of the last sample: ``v_tip``, ``u_tip`` [m], ``root_moment``,
        #: ``hub_torque`` [N m].
        self.outputs = {}

    # -- set-up ----------------------------------------------------------------
    def _first_frequency_hz(self) -> float:
        """First clamped bending frequency of the non-rotating beam (tip mass ignored) [Hz]."""
        p = self.params
        return 1.8751040687 ** 2 / (2 * math.pi * p.L ** 2) * math.sqrt(p.E * p.I / (p.rho * p.A))

    def _setup_projection(self):
        """Matrices from nodal hub-frame values ``[w_i, w_i']`` (and ``u``) to modal coordinates."""
        p, ne, h = self.params, self.n_elements, self.h
        g, wg = np.polynomial.legendre.leggauss(6)
        xi = 0.5 * (g + 1)
        H = _hermite(xi, h)                                         # (6, 4)
        x = (np.arange(ne)[:, None] + xi[None, :]).ravel() * h      # (ne*6,)
        wq = np.tile(0.5 * wg * h, ne)
        f2 = transverse_shapes(x, self.n_modes, p.L).reshape(len(x), -1)
        f1 = axial_shapes(x, self.n_axial, p.L).reshape(len(x), -1)
        # interpolation of a nodal field (ne+1 values and slopes) at the quadrature points
        N = np.zeros((len(x), 2 * (ne + 1)))
        for e in range(ne):
            rows = slice(6 * e, 6 * e + 6)
            N[rows, 2 * e:2 * e + 4] = H
        P2 = np.linalg.solve((f2 * wq[:, None]).T @ f2, (f2 * wq[:, None]).T @ N)
        P1 = np.linalg.solve((f1 * wq[:, None]).T @ f1, (f1 * wq[:, None]).T @ N)
        self._P1, self._P2 = P1, P2
        self._x_nodes = p.r + h * np.arange(ne + 1)
        self._H_tip = _hermite(np.array([self._tip_xi]), h)[0]

    # -- the PlantStepper interface ----------------------------------------------
    @property
    def n_q(self) -> int:
        """Projected coordinates ``1 + n_axial + n_modes`` [-]."""
        return 1 + self.n_axial + self.n_modes

    def initial_state(self, x0=None, tau: float = 0.0) -> np.ndarray:
        """The projected state at rest (the exact plant starts at rest, undeformed).

        Parameters
        ----------
        x0 : array_like, optional
            Must be None or zeros (a deformed start is not supported).
        tau : float
            Hub torque or command at t = 0 [N m].

        Returns
        -------
        ndarray (2 n_q,)
        """
        if x0 is not None and np.any(np.asarray(x0, dtype=float) != 0):
            raise ParameterError("x0: the exact-beam plant starts at rest, undeformed (give x0=None)")
        if not self._initialized:
            self._settings.timeIntegration.endTime = self.dt
            self._solver.InitializeSolver(self.mbs, self._settings)
            self._initialized = True
        return self._projected_state()

    def step(self, state, tau) -> np.ndarray:
        """Advance the plant by one sample with the torque (or command) ``tau`` held.

        Parameters
        ----------
        state : ndarray
            The previous projected state (unused: the plant keeps its own exact state).
        tau : float
            Hub torque [N m], or the drive's command with ``hardware``.

        Returns
        -------
        ndarray (2 n_q,)
            The projected state at the end of the sample.

        Raises
        ------
        HubbeamError
            If Exudyn's Newton iterations fail.
        """
        if not self._initialized:
            self.initial_state()
        if self.hardware is not None:          # drive and friction inside every step (_hardware_torque)
            self._u_sub[:] = np.asarray(tau, dtype=float).ravel() if np.size(tau) == self.substeps \
                else float(np.asarray(tau, dtype=float).ravel()[-1])
        else:
            u = float(np.asarray(tau, dtype=float).ravel()[-1])
            self._tau = u
            if self.torque_function is None:
                self.mbs.SetLoadParameter(self._load, "loadVector", [0.0, 0.0, u])
        start = time.perf_counter()
        it = self._solver.it
        it.startTime, it.endTime = self._t, self._t + self.dt
        ok = self._solver.SolveSteps(self.mbs, self._settings)
        self.wall_s += time.perf_counter() - start
        if not ok:
            raise HubbeamError(f"Exudyn's generalized-alpha failed on the exact beam at t = {self._t:.4f} s")
        self._t += self.dt
        return self._projected_state()

    def _post_newton(self, mbs, t) -> list:
        """Karnopp inside the step (Exudyn's discontinuous iteration, called after each step's Newton
        iterations; a return above 1 repeats the step from its start with the switched constraint):
        a sliding hub that slowed into ``stick_velocity`` or reversed within the step is tried held
        (the velocity constraint on): kept if the holding torque (the constraint's reaction) is within
        breakaway, else the step is repeated sliding; a held hub whose holding torque exceeds
        breakaway is released and the step repeated sliding. As the assumed-mode stepper, per
        integration step instead of per sample."""
        if t != self._step_end:                        # a new step (its end time): its first solution
            self._step_end, self._tried_held = t, False
            self._stuck_at_start = self.stuck
        sd = mbs.systemData
        if self.stuck:
            out = mbs.GetObjectOutput(self._lock, self._exu.OutputVariableType.Force)
            hold = -float(np.ravel(out)[0])
            if abs(hold) <= self._F_s:
                self.hold_torque = hold
                if not self._stuck_at_start:
                    self.stick_events += 1
                    self._stuck_at_start = True
                return [0.0, -1.0]
            self.stuck = False                           # breakaway: the step again, sliding
            self._tried_held = True
            mbs.SetObjectParameter(self._lock, "activeConnector", False)
            return [2.0, -1.0]
        if self._tried_held:
            return [0.0, -1.0]
        thd1 = float(sd.GetODE2Coordinates_t()[self._i_hub])
        thd0 = float(sd.GetODE2Coordinates_t(configuration=self._exu.ConfigurationType.StartOfStep)[self._i_hub])
        if abs(thd1) <= self._v_stick and (abs(thd1) < abs(thd0) or thd0 == 0.0) or thd0 * thd1 < 0:
            self.stuck = True                            # the step again, held
            self._tried_held = True
            mbs.SetObjectParameter(self._lock, "activeConnector", True)
            return [2.0, -1.0]
        return [0.0, -1.0]

    def _hardware_torque(self, mbs, t, load):
        """The hub torque of the rig's drive and sliding friction at time ``t`` of the sample, at the
        hub rate of the current iterate: the command of the step that holds ``t`` (a computation delay
        gives the steps before it the previous command)."""
        j = min(max(math.ceil((t - self._t) / self._h_step - 1e-6) - 1, 0), self.substeps - 1)
        thd = mbs.systemData.GetODE2Coordinates_t()[self._i_hub]
        tau = self._hub_torque(float(self._u_sub[j]), float(thd))
        if self.torque_function is not None:
            tau += float(self.torque_function(t))
        self._tau = tau
        return [0.0, 0.0, tau]

    # -- outputs ---------------------------------------------------------------
    def _hub_frame(self):
        """Nodal hub-frame displacements (u, w), their slopes and rates."""
        sd = self.mbs.systemData
        q = np.asarray(sd.GetODE2Coordinates()) + self._q_ref    # Exudyn stores displacements
        v = np.asarray(sd.GetODE2Coordinates_t())
        th, thd = q[self._i_hub], v[self._i_hub]
        c, s = math.cos(th), math.sin(th)
        nq, nv = q[self._i_nodes], v[self._i_nodes]              # (ne+1, 4): x, y, x', y'
        xh = c * nq[:, 0] + s * nq[:, 1]
        yh = -s * nq[:, 0] + c * nq[:, 1]
        sxh = c * nq[:, 2] + s * nq[:, 3]
        syh = -s * nq[:, 2] + c * nq[:, 3]
        # d/dt (R^T p) = R^T p_dot + theta_dot [y_h, -x_h]
        vxh = c * nv[:, 0] + s * nv[:, 1] + thd * yh
        vyh = -s * nv[:, 0] + c * nv[:, 1] - thd * xh
        vsxh = c * nv[:, 2] + s * nv[:, 3] + thd * syh
        vsyh = -s * nv[:, 2] + c * nv[:, 3] - thd * sxh
        u, w = xh - self._x_nodes, yh
        su = sxh - 1.0
        return th, thd, u, w, su, syh, vxh, vyh, vsxh, vsyh

    def _projected_state(self) -> np.ndarray:
        th, thd, u, w, su, sw, du, dw, dsu, dsw = self._hub_frame()
        inter = lambda a, b: np.column_stack([a, b]).ravel()      # noqa: E731  [a0, b0, a1, b1, ...]
        W, U = inter(w, sw), inter(u, su)
        Wd, Ud = inter(dw, dsw), inter(du, dsu)
        k = self._tip_element
        self.outputs = {"theta": th, "theta_dot": thd,
                        "v_tip": float(self._H_tip @ W[2 * k:2 * k + 4]),
                        "u_tip": float(self._H_tip @ U[2 * k:2 * k + 4]),
                        "root_moment": self.root_moment(), "hub_torque": self.drive_torque()}
        return np.concatenate([[th], self._P1 @ U, self._P2 @ W, [thd], self._P1 @ Ud, self._P2 @ Wd])

    def drive_torque(self) -> float:
        """Hub torque that the prescribed motion takes [N m] (the drive constraint's reaction;
        0 when the hub is free: the applied torque is the input).

        Returns
        -------
        float
        """
        if self.prescribed is None:
            return self._tau
        out = self.mbs.GetObjectOutput(self._drive, self._exu.OutputVariableType.Force)
        return -float(np.ravel(out)[0])     # the constraint acts on the hub with the opposite sign

    def root_moment(self) -> float:
        """Bending moment at the root [N m]: the clamp's reaction moment, signed as ``E I w''(0)``."""
        out = self.mbs.GetObjectOutput(self._clamp, self._exu.OutputVariableType.TorqueLocal)
        return float(-out[2])

    def root_moment_from_curvature(self) -> float:
        """Bending moment at the root from the first element's curvature ``E I w''(0)`` [N m] (the
        cross-check of :meth:`root_moment`; converges more slowly in the element length)."""
        th, thd, u, w, su, sw, *_ = self._hub_frame()
        h = self.h
        wpp = (6 * (w[1] - w[0]) / h - 4 * sw[0] - 2 * sw[1]) / h
        return float(self.EI * wpp)
