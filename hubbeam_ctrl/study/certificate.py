"""The linear certificate of a verdict: the sampled closed loop on the evaluation plant's
linear model.

A closed-loop run of 30 s cannot see a loop that grows by 0.07 % per second; the sampled
linear loop can. For every controller with a linear form (PD, LQR, LQG, and MPC as its
unconstrained law; a gain-scheduled design at each of its schedule points) this module
closes the controller's feedback (:meth:`controllers.Controller.feedback_matrices`) with
the linear SFOAM of the **evaluation plant** (its physical parameters and all of its
transverse modes, zero-order hold at the controller's sample time) at the spin rates of
the start and of the end of the run, and reports

* the spectral radius of the loop and whether it exceeds ``1 +`` :data:`RADIUS_TOLERANCE`
  (a loop that grows, whatever the run's window shows);
* the frequency of the worst pole as seen in the samples (aliased into ``0..f_s/2``), the
  plant mode it comes from (its true frequency and whether it lies above the Nyquist
  frequency, i.e. folds), or that it is a pole of the controller;
* the growth time constant of a growing loop and the decay time constant of the slowest
  decaying pole (so a report can say whether the run was long enough to see it);
* for a loop that grows only because the plant has no structural damping, the smallest
  modal damping ratio (the same in every mode) that makes it stable, found by bisection on
  the linear loop.

The reference and feedforward are inputs of the loop, not dynamics, and saturation is
ignored: the certificate is about the feedback. The linear plant is SFOAM (hub free): the
axial modes, which a torque at rest does not reach, are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers import CONTROLLERS, Controller
from controllers.drive import VoltageCommand
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.linear.statespace import linear_matrices
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.sampled_loop import AS_DESIGNED, closed_loop_matrix, loop_matrix, loop_parts

__all__ = ["RADIUS_TOLERANCE", "DAMPING_SEARCH_MAX", "LoopCertificate", "Certificate", "linear_points",
           "certify", "loop_matrix", "broken_loop", "hold_gain", "angle_error_tip_gain", "AS_DESIGNED"]

#: A sampled loop whose spectral radius exceeds ``1 + RADIUS_TOLERANCE`` grows [-] (a pole
#: of an undamped mode the controller cannot reach stays within it of the unit circle).
RADIUS_TOLERANCE = 1e-7
#: The damping search stops here: a loop still unstable with this modal damping ratio in
#: every mode is reported as needing more than it [-].
DAMPING_SEARCH_MAX = 0.05


@dataclass(frozen=True)
class LoopCertificate:
    """The sampled closed loop of one linear controller with the plant at one spin rate.

    Attributes
    ----------
    spin : float
        Spin rate of the linearisation [rad/s].
    spectral_radius : float
        Largest ``|z|`` of the loop [-].
    worst_hz : float
        Frequency of the worst pole as seen in the samples, in ``0..1/(2 dt)`` [Hz].
    worst_source : str
        ``"mode N"`` (plant bending mode N, 1-based), ``"rigid"`` or ``"controller"``.
    worst_mode_hz : float or None
        True frequency of that plant mode [Hz] (None for the controller or the rigid body).
    aliased : bool
        The worst pole's plant mode lies above the Nyquist frequency ``1/(2 dt)`` and folds.
    growth_time_s : float or None
        ``dt / ln(rho)`` of a growing loop [s] (None: it does not grow).
    slowest_decay_s : float or None
        ``-dt / ln|z|`` of the slowest decaying pole [s] (None: none decays).
    damping_needed : float or None
        Smallest modal damping ratio in every mode that makes a growing loop stable [-]
        (None: the loop does not grow; ``inf``: more than :data:`DAMPING_SEARCH_MAX`).
    design_modes_radius : float
        Largest ``|z|`` of the loop poles that come from the rigid body and the design
        model's bending modes [-] (how well the modes the design is for are damped).
    """

    spin: float
    spectral_radius: float
    worst_hz: float
    worst_source: str
    worst_mode_hz: float | None
    aliased: bool
    growth_time_s: float | None
    slowest_decay_s: float | None
    damping_needed: float | None
    design_modes_radius: float = float("nan")

    @property
    def grows(self) -> bool:
        """The spectral radius exceeds ``1 + RADIUS_TOLERANCE``."""
        return self.spectral_radius > 1.0 + RADIUS_TOLERANCE


@dataclass(frozen=True)
class Certificate:
    """The linear certificate of one controller on one evaluation plant.

    Attributes
    ----------
    controller : str
        The controller's name.
    plant_modes : int
        Transverse modes of the linear plant.
    damping_ratio : float
        The plant's modal damping ratio [-].
    dt : float
        Sample time [s].
    points : tuple of LoopCertificate
        One per linearisation (start and end of the run, each schedule point).
    note : str
        Why there is no certificate (a controller without a linear form), else "".
    """

    controller: str
    plant_modes: int
    damping_ratio: float
    dt: float
    points: tuple = ()
    note: str = ""

    @property
    def available(self) -> bool:
        """The controller has a linear form and was certified."""
        return bool(self.points)

    @property
    def worst(self) -> LoopCertificate | None:
        """The point of largest spectral radius (None without a certificate)."""
        return max(self.points, key=lambda p: p.spectral_radius) if self.points else None

    @property
    def grows(self) -> bool:
        """Some point's loop grows."""
        return any(p.grows for p in self.points)

    def metrics(self) -> dict:
        """The certificate as flat metrics (the ``loop_*`` entries of
        :data:`hubbeam_ctrl.study.metrics.METRIC_UNITS`)."""
        w = self.worst
        if w is None:
            return {"loop_certificate": self.note or "none"}
        return {"loop_certificate": "grows" if self.grows else "stable",
                "loop_spectral_radius": w.spectral_radius, "loop_worst_hz": w.worst_hz,
                "loop_worst_source": w.worst_source, "loop_worst_mode_hz": w.worst_mode_hz,
                "loop_worst_aliased": w.aliased, "loop_growth_time_s": w.growth_time_s,
                "loop_slowest_decay_s": max((p.slowest_decay_s for p in self.points
                                             if p.slowest_decay_s is not None), default=None),
                "loop_damping_needed": w.damping_needed, "loop_plant_modes": self.plant_modes,
                "loop_design_modes_radius": max(p.design_modes_radius for p in self.points),
                "loop_plant_damping": self.damping_ratio,
                "loop_spins_rad_s": ",".join(f"{p.spin:g}" for p in self.points)}

    def describe(self) -> str:
        """One sentence for reports."""
        w = self.worst
        if w is None:
            return f"no linear certificate ({self.note})"
        where = w.worst_source if w.worst_mode_hz is None else \
            f"{w.worst_source} ({w.worst_mode_hz:.2f} Hz{', folded' if w.aliased else ''})"
        if not self.grows:
            return (f"stable: spectral radius {w.spectral_radius:.7f} on the {self.plant_modes}-mode linear "
                    f"plant (largest pole from {where}, seen at {w.worst_hz:.2f} Hz)")
        damp = ("more than " + f"{DAMPING_SEARCH_MAX:g}" if w.damping_needed == math.inf
                else f"{w.damping_needed:.2g}")
        return (f"GROWS: spectral radius {w.spectral_radius:.7f} (time constant {w.growth_time_s:.3g} s) "
                f"on the {self.plant_modes}-mode linear plant, from {where}, seen at {w.worst_hz:.2f} Hz; "
                f"stable with a modal damping ratio of {damp} in every mode")


def linear_points(controller: Controller, name: str | None = None) -> list:
    """``(spin, controller)`` pairs of a controller's linear forms.

    A controller with a linear form gives itself at its design spin; a gain-scheduled one
    gives its registered unscheduled class designed at each schedule point.

    Parameters
    ----------
    controller : Controller
    name : str, optional
        Registry name (default ``controller.name``).

    Returns
    -------
    list of tuple
        Empty when the controller has no linear form (the open loop, the shaped profiles).
    """
    schedule = getattr(controller, "schedule", None)
    if schedule is not None:
        spec = CONTROLLERS.get(name or controller.name)
        if spec is None:
            return []
        points = [(float(d.spin), spec.controller(d, controller.settings, controller.reference))
                  for d in schedule.designs]
        if isinstance(controller, VoltageCommand):      # each point commands the DC motor's volts too
            points = [(w, _volts(c, controller)) for w, c in points]
        return points
    try:
        controller.feedback_matrices()
    except HubbeamError:
        return []
    return [(float(controller.design.spin), controller)]


def _volts(point: Controller, scheduled) -> Controller:
    """A schedule point behind the scheduled controller's drive stage, with its rig hardware."""
    out = VoltageCommand(point, scheduled.hardware)
    if getattr(scheduled, "rig_hardware", None) is not None:
        out.rig_hardware = scheduled.rig_hardware
    return out


def broken_loop(controller: Controller, params: Params, spin: float, damping_ratio: float = 0.0,
                hardware=AS_DESIGNED) -> tuple:
    """The loop of :func:`loop_matrix` broken at the plant input, for its margins.

    Parameters
    ----------
    controller, params, spin, damping_ratio, hardware
        As :func:`loop_matrix`.

    Returns
    -------
    tuple of ndarray
        ``(A, B, C, D)`` of the return ratio ``L`` with the loop ``u = -L u``
        (:func:`controllers.analysis.margins_of_loop` takes them).
    """
    Ad, Bd, Cm, (Ak, Bk, Ck, Dk), _ = loop_parts(controller, params, spin, damping_ratio, hardware)
    n, nk = Ad.shape[0], (Ak.shape[0] if Ak.size else 0)
    A = np.block([[Ad, np.zeros((n, nk))], [Bk @ Cm, Ak]]) if nk else Ad
    B = np.vstack([Bd, np.zeros((nk, Bd.shape[1]))])
    C = -np.hstack([Dk @ Cm, Ck]) if nk else -(Dk @ Cm)
    return A, B, C, np.zeros((1, 1))


def hold_gain(controller: Controller, params: Params, spin: float = 0.0, hardware=AS_DESIGNED) -> float:
    """The closed loop's steady hub-angle offset per newton-metre of constant torque at the hub.

    At rest a constant torque ``w`` at the hub (Coulomb friction holding the hub, a gravity load)
    moves the sampled loop of :func:`loop_matrix` to ``x = (I - A_loop)^-1 [B_d; 0] w / g`` (a
    constant passes the hold and the delay unchanged; ``g`` the drive's torque per unit command:
    1 on a torque source). Its hub-angle entry per N m is the loop's compliance: 0 with integral
    action, ``1 / K_theta`` for a state feedback of angle stiffness ``K_theta``.

    Parameters
    ----------
    controller : Controller
        With a linear form whose loop is stable.
    params : Params
        The plant.
    spin : float
        Spin rate of the linearisation [rad/s].
    hardware : Hardware or None, optional
        As :func:`loop_matrix`.

    Returns
    -------
    float
        [rad / (N m)], >= 0; inf when the loop is not stable.
    """
    Ad, Bd, Cm, laws, _ = loop_parts(controller, params, spin, 0.0, hardware)
    A_loop = closed_loop_matrix(Ad, Bd, Cm, laws)
    if np.max(np.abs(np.linalg.eigvals(A_loop))) >= 1.0:
        return math.inf
    hw = getattr(controller, "rig_hardware", None) if hardware is AS_DESIGNED else hardware
    voltage = hw is not None and getattr(controller, "command", "torque") == "voltage" and hw.command == "voltage"
    g = hw.torque_per_volt() if voltage else 1.0
    b = np.zeros(A_loop.shape[0])
    b[:Bd.shape[0]] = Bd[:, 0] / g
    x = np.linalg.solve(np.eye(A_loop.shape[0]) - A_loop, b)
    return abs(float(x[0]))


def angle_error_tip_gain(controller: Controller, params: Params, spin: float = 0.0,
                         max_samples: int = 400_000) -> float:
    """The loop's peak-to-peak gain from an error in the hub-angle reading to the tip deflection.

    An error ``n_k`` added to the angle the controller reads (an encoder's rounding, within half a
    count) moves the tip of the sampled loop of :func:`loop_matrix` by
    ``v_k = sum_j h_j n_(k-j)``, so ``max |v| <= (sum_j |h_j|) max |n|``: the l1 norm of the
    impulse response ``h`` is the least bound that holds for every error sequence of that size
    (Dahleh and Diaz-Bobillo 1995, "Control of Uncertain Systems: A Linear Programming Approach",
    chapter 3). The plant is the certificate's (its hardware, the design's delay, no damping
    beyond ``params``' own).

    Parameters
    ----------
    controller : Controller
        With a linear form that reads ``theta``.
    params : Params
        The plant.
    spin : float
        Spin rate of the linearisation [rad/s].
    max_samples : int
        Length of the impulse response summed at most.

    Returns
    -------
    float
        [m / rad], >= 0; inf when the loop is not stable or its response has not decayed to
        1e-9 of its start within ``max_samples``; 0 when the controller does not read ``theta``.
    """
    inputs = list(controller.feedback_matrices()[5])
    if "theta" not in inputs:
        return 0.0
    Ad, Bd, Cm, laws, A = loop_parts(controller, params, spin, 0.0, AS_DESIGNED)
    A_loop = closed_loop_matrix(Ad, Bd, Cm, laws)
    if np.max(np.abs(np.linalg.eigvals(A_loop))) >= 1.0:
        return math.inf
    Ak, Bk, _, Dk = laws
    j = inputs.index("theta")
    b = Bd @ Dk[:, j]
    if Ak.size:
        b = np.concatenate([b, Bk[:, j]])
    tip = np.asarray(linear_matrices("sfoam", float(spin), params, ("tip_deflection",))[2], dtype=float)[0]
    c = np.zeros(A_loop.shape[0])
    c[:tip.size] = tip
    block = 64                           # the response in blocks: X holds A^(64 i + 0..63) b
    X = np.empty((b.size, block))
    X[:, 0] = b
    for k in range(1, block):
        X[:, k] = A_loop @ X[:, k - 1]
    step = np.linalg.matrix_power(A_loop, block)
    start, total = float(np.linalg.norm(b)), 0.0
    for _ in range(max(1, max_samples // block)):
        total += float(np.sum(np.abs(c @ X)))
        X = step @ X
        if float(np.linalg.norm(X[:, 0])) <= 1e-9 * start:
            return total
    return math.inf


def _source(z: complex, plant_poles_s: np.ndarray, dt: float, n_plant: int, n_loop: int):
    """The plant mode (or the controller) a loop pole comes from: the nearest open-loop pole."""
    images = np.exp(plant_poles_s * dt)
    i = int(np.argmin(np.abs(images - z)))
    nearest_plant = float(np.abs(images[i] - z))
    if n_loop > n_plant and nearest_plant > 0.05:
        return "controller", None, False
    f = abs(plant_poles_s[i].imag) / (2 * np.pi)
    if f < 1e-9:
        return "rigid", None, False
    freqs = np.unique(np.round(np.abs(plant_poles_s.imag[plant_poles_s.imag > 1e-9]) / (2 * np.pi), 9))
    mode = int(np.argmin(np.abs(freqs - f))) + 1
    return f"mode {mode}", float(f), bool(f > 0.5 / dt)


def _point(controller: Controller, params: Params, spin: float, damping_ratio: float) -> LoopCertificate:
    dt = float(controller.dt)
    A_loop, poles_s = loop_matrix(controller, params, spin, damping_ratio)
    z = np.linalg.eigvals(A_loop)
    mags = np.abs(z)
    k = int(np.argmax(mags))
    rho = float(mags[k])
    source, mode_hz, aliased = _source(z[k], poles_s, dt, poles_s.size, z.size)
    decaying = mags[mags < 1.0 - RADIUS_TOLERANCE]
    slowest = float(-dt / np.log(np.max(decaying))) if decaying.size and np.max(decaying) > 0 else None
    grows = rho > 1.0 + RADIUS_TOLERANCE
    needed = _damping_needed(controller, params, spin, damping_ratio) if grows else None
    design_radius = _design_modes_radius(A_loop, poles_s.size, int(controller.n_modes))
    return LoopCertificate(spin=float(spin), spectral_radius=rho,
                           worst_hz=float(abs(np.angle(z[k])) / (2 * np.pi * dt)), worst_source=source,
                           worst_mode_hz=mode_hz, aliased=aliased,
                           growth_time_s=float(dt / np.log(rho)) if grows else None,
                           slowest_decay_s=slowest, damping_needed=needed,
                           design_modes_radius=design_radius)


def _design_modes_radius(A_loop: np.ndarray, n_plant: int, n_design: int) -> float:
    """Largest ``|z|`` of the loop poles whose eigenvector's plant part lies mostly (> 50 %) in the
    coordinates of the rigid body and the design modes (``theta``, ``q2_1..q2_m`` and rates)."""
    z, V = np.linalg.eig(A_loop)
    m = n_plant // 2
    design = np.zeros(n_plant, dtype=bool)
    design[:1 + n_design] = True
    design[m:m + 1 + n_design] = True
    w = np.abs(V[:n_plant]) ** 2
    share = w[design].sum(axis=0) / np.maximum(w.sum(axis=0), np.finfo(float).tiny)
    mags = np.abs(z)[share > 0.5]
    return float(np.max(mags)) if mags.size else float("nan")


def _radius(controller, params, spin, zeta) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(loop_matrix(controller, params, spin, zeta)[0]))))


def _damping_needed(controller, params, spin, zeta0: float, iterations: int = 30) -> float:
    """Bisection on the modal damping ratio (every mode alike) for a spectral radius <= 1 + tol."""
    if _radius(controller, params, spin, DAMPING_SEARCH_MAX) > 1.0 + RADIUS_TOLERANCE:
        return math.inf
    lo, hi = zeta0, DAMPING_SEARCH_MAX
    for _ in range(iterations):
        mid = 0.5 * (lo + hi) if lo > 0 else math.sqrt(max(lo, 1e-7) * hi)
        if _radius(controller, params, spin, mid) > 1.0 + RADIUS_TOLERANCE:
            lo = mid
        else:
            hi = mid
        if hi - lo < 0.02 * hi:
            break
    return float(hi)


def certify(controller: Controller, plant_params: Params, *, spins=(), name: str | None = None,
            damping_ratio: float | None = None) -> Certificate:
    """The linear certificate of ``controller`` on the plant ``plant_params``.

    Parameters
    ----------
    controller : Controller
        Any registered controller; one without a linear form gets an empty certificate
        that says so.
    plant_params : Params
        The evaluation plant's parameters (``n_transverse``: all of its modes, at least the
        controller's design modes).
    spins : sequence of float
        Spin rates [rad/s] at which to linearise besides the design spin(s), e.g. the hub
        rates at the start and at the end of the run (default none).
    name : str, optional
        Registry name (default ``controller.name``).
    damping_ratio : float, optional
        Modal damping ratio of the plant [-] (default ``plant_params.damping_ratio``).

    Returns
    -------
    Certificate
        One loop certificate per linearisation (the design spins and ``spins``).

    Examples
    --------
    >>> from controllers import DesignModel, LQR
    >>> from hubbeam_ctrl import Params
    >>> c = certify(LQR(DesignModel.build(Params(), 0.0, 0.01, 5)), Params(n_transverse=5))
    >>> c.grows, c.worst.worst_source            # on its own design modes the LQR is stable
    (False, 'rigid')
    """
    zeta = plant_params.damping_ratio if damping_ratio is None else float(damping_ratio)
    if not (math.isfinite(zeta) and 0.0 <= zeta < 1.0):
        raise ParameterError(f"damping_ratio must be in [0, 1), got {damping_ratio!r}")
    label = name or getattr(controller, "name", type(controller).__name__)
    dt = float(getattr(controller, "dt", 0.0) or 0.0)
    forms = linear_points(controller, name)
    if not forms:
        return Certificate(label, plant_params.n_transverse, zeta, dt,
                           note="the controller has no linear feedback law")
    points = []
    extra = sorted({round(float(s), 12) for s in spins})
    for spin, form in forms:
        points.append(_point(form, plant_params, spin, zeta))
    if len(forms) == 1:
        design_spin = forms[0][0]
        for spin in extra:
            if abs(spin - design_spin) > 1e-9:
                points.append(_point(forms[0][1], plant_params, spin, zeta))
    return Certificate(label, plant_params.n_transverse, zeta, dt, tuple(points))
