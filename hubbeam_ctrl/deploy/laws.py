"""What a controller does at a sample, as plain arrays: :class:`ControlLaw` and its builders.

:func:`control_law` turns a designed controller into the data of a C template
(:mod:`hubbeam_ctrl.deploy.render`): gains, the steady-state Kalman filter (on whatever sensors
the design reads: :meth:`controllers.DesignModel.on_rig`), reference tables, the MPC's condensed
QP, the scheduled LQG's grids. Every observer-based feedback is
:class:`controllers.integral.ObservedFeedback` (a bare LQR or MPC is wrapped in it,
:mod:`hubbeam_ctrl.deploy.observed`), so the C follows the Python class sample by sample.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from controllers import (
    LQG,
    LQR,
    MPC,
    PD,
    Controller,
    HInf,
    KalmanNoise,
    MultiStageMPC,
    OpenLoop,
    ScheduledLQG,
    ShapedOpenLoop,
)
from controllers.drive import VoltageCommand
from controllers.filter_model import extra_state_gains
from controllers.integral import ObservedFeedback
from hubbeam_ctrl.core.errors import ParameterError

from .observed import ObservedLQR, ObservedMPC

__all__ = ["CODEGEN_KINDS", "SENSOR_UNITS", "ControlLaw", "control_law", "sensor_unit"]

#: Controller kinds that can be generated, and what each exports.
CODEGEN_KINDS = {
    "pd": "PD on the hub angle and rate, reference table, feedforward, saturation",
    "lqr": "LQR gain on a steady-state Kalman filter of its model (the LQR with its observer)",
    "lqg": "LQG: Kalman filter (with residual modes) and gain, reference table, saturation; the "
           "gain-scheduled LQG with every gain and model interpolated on the spin rate",
    "mpc": "MPC on a Kalman filter of its model: the condensed QP (torque bounds; on a DC motor also the "
           "voltage limit through back-EMF) solved by a generated primal active-set method (no tip bound)",
    "msmpc": "multi-stage (scenario-tree) MPC over payload scenarios on a Kalman filter of its nominal model: the "
             "tree's QP (1 + S (N - 1) torques, the first shared; torque bounds only) by the MPC's solver",
    "hinf": "H-infinity LTI law on the hub angle's error (sampled hinfsyn controller), reference table, feedforward, "
            "saturation",
    "zv": "ZV input-shaped open-loop torque table",
    "zvd": "ZVD input-shaped open-loop torque table",
    "ei": "EI input-shaped open-loop torque table",
    "openloop": "feedforward open-loop torque table (profile='feedforward')",
}

#: Units of the sensors a generated controller can read (the closed-loop simulator's order); a
#: rig's strain gauges ``moment_<i>`` read N m (:func:`sensor_unit`).
SENSOR_UNITS = {"theta": "rad", "theta_dot": "rad/s", "root_moment": "N m", "accel_tangential": "m/s^2"}
_SENSORS = ("theta", "theta_dot", "root_moment")


def sensor_unit(name: str) -> str:
    """Unit of a measurement a generated step reads (``moment_<i>``: a strain gauge, N m).

    Parameters
    ----------
    name : str
        A signal name (:data:`SENSOR_UNITS` or ``moment_<i>``).

    Returns
    -------
    str
    """
    return "N m" if name.startswith("moment_") else SENSOR_UNITS[name]



@dataclass(frozen=True, eq=False)
class ControlLaw:
    """What a controller does at a sample, as plain arrays (the input of :func:`render_c`).

    Attributes
    ----------
    kind : {"pd", "observer", "scheduled_lqg", "mpc", "table"}
        Template: PD on the hub sensors, gain on a Kalman filter, the gain-scheduled LQG,
        MPC on a Kalman filter, held torque table.
    controller : str
        The controller's kind (``"lqg"``...).
    dt : float
        Sample time [s].
    tau_max : float
        Torque limit [N m] of the saturation.
    feedforward : float
        1.0 when the reference's feedforward torque is added, else 0.0.
    arrays : dict of str -> ndarray
        The template's data (see :func:`render_c`).
    scalars : dict of str -> float
        The template's scalars (``spin`` [rad/s], ``kp``, ``kd``...).
    sensors : tuple of str
        Measurements the step reads, in order (names of :data:`SENSOR_UNITS`).
    n_reference : int
        Length of the optional external reference vector of the step.
    reference_layout : str
        What that vector holds.
    gauges : tuple of float
        Positions of the strain gauges ``moment_<i>`` reads, from the root [m] (a rig's
        ``sensors.strain_gauges``; empty for the beam alone's root moment).
    """

    kind: str
    controller: str
    dt: float
    tau_max: float
    feedforward: float
    arrays: dict
    scalars: dict = field(default_factory=dict)
    sensors: tuple = ()
    n_reference: int = 0
    reference_layout: str = ""
    gauges: tuple = ()

    def sensor_text(self) -> list:
        """Each measurement as the header names it: ``name [unit]`` (with a gauge's position)."""
        out = []
        for s in self.sensors:
            text = f"{s} [{sensor_unit(s)}]"
            if s.startswith("moment_") and int(s[7:]) <= len(self.gauges):
                text += f" (strain gauge at {self.gauges[int(s[7:]) - 1]:.6g} m from the root)"
            elif s == "accel_tangential":
                text += " (tip accelerometer, tangential)"
            out.append(text)
        return out

    def check_finite(self) -> None:
        """Refuse a non-finite gain, table entry or scalar (one line naming it).

        Raises
        ------
        ParameterError
        """
        for name, value in {**self.arrays, **self.scalars, "dt": self.dt, "tau_max": self.tau_max}.items():
            a = np.asarray(value, dtype=float)
            if not np.all(np.isfinite(a)):
                raise ParameterError(f"controller: {name} has a non-finite entry; C code needs finite gains "
                                     "and tables")


def _reference_table(ctrl: Controller, table=None, embed=None) -> tuple:
    """``(X, tff)`` rows ``k = 0..K-1`` of the controller's reference table as its step reads them."""
    K = len(ctrl._tff)
    rows = []
    for k in range(K):
        xr, _ = ctrl._reference_at(k)
        if table is not None and k < len(table):
            rows.append(np.asarray(table[k], dtype=float))
        else:
            rows.append(np.asarray(xr if embed is None else embed @ xr, dtype=float))
    return np.array(rows), np.asarray(ctrl._tff, dtype=float)


def _filter_arrays(estimator) -> dict:
    """The steady-state filter's data: ``A``, ``B`` (prediction), ``IMLC = I - L C``, ``L``."""
    return {"A": np.asarray(estimator._A, dtype=float), "B": np.asarray(estimator._b, dtype=float),
            "IMLC": np.asarray(estimator._IminusLC, dtype=float), "L": np.asarray(estimator.L, dtype=float)}


def _offset_rows(offset, nz: int) -> np.ndarray:
    """The plan's prediction offsets on the filter's ``nz`` states (none on ``u_prev`` or ``d``)."""
    D = np.zeros((len(offset), nz))
    D[:, :np.shape(offset)[1]] = offset
    return D


def _model_sensors(model) -> tuple:
    """``(sensors, gauges)`` a filter on ``model`` reads (the beam alone's three without a rig layout)."""
    if model is None or model.sensors is None:
        return _SENSORS, ()
    return tuple(model.sensor_labels), tuple(model.sensors.gauges)


def _observer_law(ctrl, controller: str, K, estimator, X, tff, spin: float, ff: float, x0,
                  offset=None, model=None) -> ControlLaw:
    nx = len(estimator._b)
    arrays = {**_filter_arrays(estimator), "K": np.asarray(K, dtype=float),
              "X0": np.asarray(x0, dtype=float), "XREF": X, "TFF": tff}
    if offset is not None and len(offset):   # the filter predicts along the plan (plan_prediction)
        arrays["OFFSET"] = _offset_rows(offset, nx)
    sensors, gauges = _model_sensors(model)
    return ControlLaw(
        kind="observer", controller=controller, dt=float(ctrl.dt), tau_max=float(ctrl.tau_max), feedforward=ff,
        arrays=arrays,
        scalars={"spin": float(spin)}, sensors=sensors, n_reference=nx + 1,
        reference_layout=f"x_ref[0..{nx - 1}] (the filter model's states, absolute hub angle and rate), "
                         f"then tau_ff [N m]", gauges=gauges)


def _acting(ctrl, fm, K, X, x0, reference_at) -> tuple:
    """Gain, reference table and initial state on the filter state ``[x, u_prev]`` of a model that
    carries the previous command (:attr:`controllers.DesignModel.carries_loop`): the law acts on
    the state where the command starts to act (:meth:`controllers.DesignModel.acting_state`),
    ``K (Phi_d x + Gamma_d u_prev - x_ref(k + d))``, written as the template's ``K_z (z - z_ref)``
    with ``z_ref = [Phi_d^-1 (x_ref(k + d) - s(t_k + d dt)) + s(t_k), 0]`` (``s`` the steady
    rotation), so the C template is unchanged. The feedforward is the one where the command acts."""
    if not fm.carries_loop:
        return K, X, x0, None
    d, n, spin, dt = fm.delay, fm.n_x // 2, fm.spin, fm.dt
    Phi, G = fm.action_map()
    K = np.asarray(K, dtype=float)
    Kz = np.append(K @ Phi, K @ G)
    Phi_inv = np.linalg.inv(Phi)
    rows, tff = [], []
    for k in range(len(X)):
        x_act = (1.0 - d) * reference_at(k) + d * reference_at(k + 1)
        steady = lambda t: np.r_[spin * t, np.zeros(n - 1), spin, np.zeros(n - 1)]   # noqa: E731
        z = Phi_inv @ (x_act - steady((k + d) * dt)) + steady(k * dt)
        rows.append(np.append(z, 0.0))
        tff.append(ctrl._reference_acting(k)[1])
    return Kz, np.array(rows), np.append(x0, 0.0), np.array(tff)


def _with_filter_states(K, X, x0, fm, noise, integral: bool, K_act) -> tuple:
    """Gain, reference table and initial state on the filter's whole state ``[x, u_prev, f, b, d]``
    (:func:`controllers.filter_model.filter_matrices`): the anti-alias filter's outputs ``f`` and the
    rate sensor's bias ``b`` are not fed back and the disturbance ``d``
    (:class:`controllers.integral.OffsetFreeEstimator`) is cancelled, ``u = K (x - x_ref) + d``;
    they start at 0 and have reference 0."""
    gains = extra_state_gains(fm, noise, integral, K_act)
    k = len(gains)
    return (np.append(K, gains), np.hstack([X, np.zeros((len(X), k))]), np.append(x0, np.zeros(k)))


def control_law(controller: Controller, noise: KalmanNoise | None = None) -> ControlLaw:
    """The per-sample law of ``controller`` as arrays.

    Parameters
    ----------
    controller : controllers.Controller
        A PD, LQR, MPC, LQG, scheduled LQG, input-shaped open loop or feedforward open loop;
        an LQR or MPC closed through :class:`controllers.integral.ObservedFeedback` (the rig
        path: any sensor set, delay, integral action); any of these behind a DC drive's
        :class:`controllers.drive.VoltageCommand`.
    noise : controllers.KalmanNoise, optional
        The observer's noise model for a bare LQR or MPC (default: the simulator's sensors).

    Returns
    -------
    ControlLaw

    Raises
    ------
    ParameterError
        For a controller kind that cannot be generated (the message lists those that can)
        or a non-finite gain.
    """
    if isinstance(controller, VoltageCommand):      # the torque law, then the drive's static inverse
        if controller.hardware.drive.slew_rate is not None:
            raise ParameterError("controller: a voltage command through an amplifier with a slew-rate limit "
                                 "(motor.slew_rate) cannot be generated as C yet (the filter would need the torque "
                                 "the limited voltage gives)")
        law = control_law(controller.inner, noise)
        if law.kind not in ("pd", "observer", "mpc", "scheduled_lqg"):
            raise ParameterError(f"controller: a voltage command of {law.controller!r} cannot be generated as C")
        d, f = controller.hardware.drive, controller.hardware.friction
        k_e = d.k_e if controller.cancels_back_emf else 0.0       # 0: the design carries the back-EMF
        drive = {"R": d.R, "N": d.N, "k_t": d.k_torque, "k_e": k_e, "eta_forward": d.eta_forward,
                 "eta_backward": d.eta_backward, "v_eps": f.v_eps, "V_max": d.V_max}
        arrays = dict(law.arrays)
        if controller._rate_index is None:      # no rate sensor: the estimator's rate where the command acts
            arrays["RATE"] = controller.rate_row()
        scalars = {**law.scalars, **{k: float(v) for k, v in drive.items()}}
        law = dataclasses.replace(law, arrays=arrays, scalars=scalars)
        law.check_finite()
        return law
    ctrl = controller
    if type(ctrl) is LQR:                 # not the scheduled subclasses: they interpolate in the spin
        ctrl = ObservedLQR(ctrl, noise)
    elif type(ctrl) is MPC:
        ctrl = ObservedMPC(ctrl, noise)
    elif type(ctrl) is MultiStageMPC:     # with its observer, as a bare MPC
        ctrl = ObservedFeedback(ctrl, KalmanNoise() if noise is None else noise)
    if isinstance(ctrl, ObservedFeedback) and type(ctrl.inner) in (MPC, MultiStageMPC):
        law = _mpc_law(ctrl) if type(ctrl.inner) is MPC else _msmpc_law(ctrl)
        law.check_finite()
        return law
    if isinstance(ctrl, ObservedFeedback):
        if type(ctrl.inner) is not LQR:
            raise ParameterError(f"controller: an observer-fed {type(ctrl.inner).__name__} cannot be generated as "
                                 "C (an LQR or an MPC can)")
        inner = ctrl.inner
        X, tff = _reference_table(inner)
        K, x0 = np.asarray(inner.K, float), ctrl.initial_state()[:ctrl.filter_model.n_x]
        K, X, x0, tff_act = _acting(inner, ctrl.filter_model, K, X, x0, lambda k: inner._reference_at(k)[0])
        tff = tff if tff_act is None else tff_act
        K, X, x0 = _with_filter_states(K, X, x0, ctrl.filter_model, ctrl.noise, ctrl.integral, inner.K)
        law = _observer_law(ctrl, "lqr", K, ctrl.estimator, X, tff, ctrl.design.spin, float(inner._ff), x0,
                            ctrl._defect, ctrl.filter_model)
        law.check_finite()
        return law
    if type(ctrl) is PD:
        if ctrl.settings.roll_off_hz is not None:
            raise ParameterError("controller: a PD with a roll_off_hz cannot be generated as C yet (the template is "
                                 "the static PD); use roll_off_hz=None")
        ref = ctrl.reference
        law = ControlLaw(
            kind="pd", controller="pd", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max), feedforward=float(ctrl._ff),
            arrays={"THETA": np.asarray(ref.theta, float), "THETA_DOT": np.asarray(ref.theta_dot, float),
                    "TFF": np.asarray(ref.torque, float)},
            scalars={"kp": float(ctrl.kp), "kd": float(ctrl.kd)}, sensors=_SENSORS[:2], n_reference=3,
            reference_layout="theta_ref [rad], theta_dot_ref [rad/s], tau_ff [N m]")
    elif type(ctrl) is ScheduledLQG:
        law = _scheduled_lqg_law(ctrl)
    elif type(ctrl) is HInf:
        law = _hinf_law(ctrl)
    elif type(ctrl) is LQG:
        X, tff = _reference_table(ctrl, ctrl._xref_filter, ctrl._E)
        x0 = ctrl._E @ ctrl._reference_at(0)[0]        # LQG.reset
        x0[ctrl._n] -= ctrl.design.spin
        K = ctrl._Ke
        K, X, x0, tff_act = _acting(ctrl, ctrl.filter_model, K, X, x0, ctrl._filter_reference)
        tff = tff if tff_act is None else tff_act
        K, X, x0 = _with_filter_states(K, X, x0, ctrl.filter_model, ctrl.settings, ctrl.settings.integral,
                                       ctrl._Ke)
        law = _observer_law(ctrl, "lqg", K, ctrl.estimator, X, tff, ctrl.design.spin, float(ctrl._ff), x0,
                            ctrl._defect, ctrl.filter_model)
    elif isinstance(ctrl, ShapedOpenLoop):
        law = ControlLaw(kind="table", controller=ctrl.kind, dt=float(ctrl.dt), tau_max=float(ctrl.tau_max),
                         feedforward=1.0, arrays={"TORQUE": np.asarray(ctrl.torques, float)},
                         scalars={"tail": float(ctrl._tail)}, n_reference=1,
                         reference_layout="tau [N m] (replaces the table)")
    elif type(ctrl) is OpenLoop and ctrl.settings.profile == "feedforward":
        ref = ctrl.reference
        law = ControlLaw(kind="table", controller="openloop", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max),
                         feedforward=1.0, arrays={"TORQUE": np.array([min(max(float(v), -ctrl.tau_max), ctrl.tau_max)
                                                                      for v in ref.torque])},
                         scalars={"tail": min(max(float(ref.torque[-1]), -ctrl.tau_max), ctrl.tau_max)},
                         n_reference=1, reference_layout="tau [N m] (replaces the table)")
    else:
        kinds = ", ".join(CODEGEN_KINDS)
        raise ParameterError(f"controller: {getattr(controller, 'name', type(controller).__name__)!r} "
                             f"({type(controller).__name__}) cannot be generated as C; kinds: {kinds}")
    law.check_finite()
    return law


def _mpc_law(ctrl: ObservedFeedback) -> ControlLaw:
    """An MPC closed through its observer (:class:`controllers.integral.ObservedFeedback`) as
    arrays: the filter (any sensor set, the previous command and the disturbance as states), the
    map ``P`` from the filter's state to the MPC's state where the command acts, the condensed QP
    and its reference terms."""
    mpc = ctrl.inner
    if mpc.settings.tip_bound is not None:
        raise ParameterError("controller: an MPC with a tip_bound cannot be generated as C yet (the generated "
                             "QP solver handles the torque bounds only); use tip_bound=None")
    H = np.asarray(mpc._H.full(), dtype=float)
    kt = len(mpc._ref_term)
    r0 = np.asarray(mpc._reference_term(kt), dtype=float)
    qp = {"GX": np.asarray(mpc._Gx, float), "H": H, "HL": np.linalg.cholesky(H),
          "REFT": np.asarray(mpc._ref_term, dtype=float), "R0": r0,
          "R1": np.asarray(mpc._reference_term(kt + 1), dtype=float) - r0}
    if mpc._emf is not None:
        qp.update(_emf_rows(mpc, qp["HL"]))
    return _observed_qp_law(ctrl, "mpc", qp)


def _observed_qp_law(ctrl: ObservedFeedback, controller: str, qp: dict) -> ControlLaw:
    """The MPC template's law: the observer of ``ctrl`` around the condensed QP ``qp`` (``GX``,
    ``H``, ``HL``, ``REFT``, ``R0``, ``R1`` and the voltage rows' arrays; its size ``len(H)``)."""
    fm, est = ctrl.filter_model, ctrl.estimator
    nz = est.A.shape[0]
    n_z = len(qp["H"])
    Phi, G = fm.action_map()
    act = np.zeros((fm.n_x, nz))                   # the acting state (controllers.DesignModel.acting_state)
    act[:, :fm.n_x] = Phi
    if fm.delay > 0.0:
        act[:, fm.n_x] = G
        if ctrl.integral:                          # the disturbance acts with the previous command
            act[:, nz - 1] = G
    arrays = {**_filter_arrays(est), "X0": ctrl.initial_state(), "P": act[ctrl._pick], **qp}
    if ctrl._defect is not None and len(ctrl._defect):
        arrays["OFFSET"] = _offset_rows(ctrl._defect, nz)
    sensors, gauges = _model_sensors(fm)
    return ControlLaw(
        kind="mpc", controller=controller, dt=float(ctrl.dt), tau_max=float(ctrl.tau_max), feedforward=1.0,
        arrays=arrays,
        scalars={"spin": float(ctrl.design.spin), "horizon": float(ctrl.inner.settings.horizon),
                 "delay": float(fm.delay), "plan_shift": float(np.floor(fm.delay + 0.5)),
                 "integral": 1.0 if ctrl.integral else 0.0},
        sensors=sensors, n_reference=n_z, gauges=gauges,
        reference_layout=f"r[0..{n_z - 1}]: the QP gradient's reference term (g = Gx x - r)")


def _emf_rows(mpc: MPC, HL: np.ndarray) -> dict:
    """The voltage limit's rows of an MPC on a DC motor (:attr:`controllers.MPCSettings.emf_torque_limit`)
    as the template's data: ``lo <= AV z <= hi`` with ``hi = LIM - OFFX x``, ``lo = -LIM - OFFX x``
    (rows scaled as the Python MPC scales them), and ``CM``: ``L^-1 c`` for every constraint ``c``
    (the ``N`` torque bounds ``e_i``, then the ``N`` rows; ``H = L L'``) with their Gram matrix
    ``GM = CM CM'``, so the active-set solve factors only the working set's block."""
    N = mpc.settings.horizon
    off_x, limit = mpc._emf
    AV = np.asarray(mpc._A.full(), dtype=float)[-N:, :N]
    if np.any(np.triu(AV, 1) != 0.0) or not np.all(np.diag(AV) > 0.0):
        raise ParameterError("controller: the MPC's voltage rows are not lower triangular with a positive "
                             "diagonal; the generated solver's feasible start needs them so")
    C = np.vstack([np.eye(N), AV])
    CM = np.linalg.solve(HL, C.T).T               # row j: L^-1 c_j
    return {"AV": AV, "OFFX": np.asarray(off_x, dtype=float), "LIM": np.asarray(limit, dtype=float),
            "CM": CM, "GM": CM @ CM.T}


def _msmpc_law(ctrl: ObservedFeedback) -> ControlLaw:
    """A multi-stage MPC (:class:`controllers.MultiStageMPC`) closed through its observer, as the MPC
    template's law with the tree's QP: ``z`` the ``1 + S (N - 1)`` torques (the shared first one at
    index 0), the tree's Hessian and state gradient, and the reference term ``r_k``: each scenario's
    plain-MPC term weighted and placed at its variables (:meth:`controllers.MultiStageMPC.qp_at`)."""
    ms = ctrl.inner
    if ms._soft:
        raise ParameterError("controller: a multi-stage MPC with a tip_bound cannot be generated as C yet (the "
                             "generated QP solver handles the torque bounds only); use tip_bound=None")
    if ms._A.shape[0]:
        raise ParameterError("controller: a multi-stage MPC with the DC motor's voltage rows (emf_torque_limit) "
                             "cannot be generated as C yet (the generated solver's feasible start needs one "
                             "lower-triangular row per torque; the tree has one per scenario and step); use "
                             "emf_torque_limit=None or a torque-source drive")
    n_u = ms._n_u

    def term(k: int) -> np.ndarray:
        r = np.zeros(n_u)
        for st, w, idx in zip(ms.stages, ms.weights, ms._index):
            r[idx] += w * np.asarray(st._reference_term(k), dtype=float)
        return r

    kt = min(len(st._ref_term) for st in ms.stages)
    table = np.zeros((kt, n_u))
    for st, w, idx in zip(ms.stages, ms.weights, ms._index):
        table[:, idx] += w * np.asarray(st._ref_term[:kt], dtype=float)
    r0 = term(kt)
    H = np.asarray(ms._Hu, dtype=float)
    qp = {"GX": np.asarray(ms._Gx, float), "H": H, "HL": np.asarray(ms._chol, dtype=float), "REFT": table,
          "R0": r0, "R1": term(kt + 1) - r0}
    return _observed_qp_law(ctrl, "msmpc", qp)


def _hinf_law(ctrl) -> ControlLaw:
    """An H-infinity controller (:class:`controllers.HInf`, the sampled LTI law on the hub angle's error)
    as the observer template's law, in absolute coordinates (``spin`` 0).

    The filter's state is ``[theta, x_k (split at NH by a zero entry)]``: the measurement update puts
    the measured hub angle in entry 0 (``I - L C`` keeps ``x_k``), the gain ``K = [D_k, -C_k]`` on
    ``x_hat - x_ref`` with ``x_ref = [theta_ref, 0...]`` gives ``tau = tau_ff + C_k x_k + D_k (theta_ref -
    theta)``, and the prediction ``x_k+ = A_k x_k + B_k (theta_ref - theta)`` reads the previous sample's
    reference angle through ``BREF``. The zero entry at ``NH`` holds the reference's rate (the template
    extends the angle past the table with it, as :meth:`controllers.Reference.window`); its gain is 0."""
    Ak, Bk, Ck, Dk = ctrl._Ak, ctrl._Bk[:, 0], ctrl._Ck[0], float(ctrl._Dk[0, 0])
    n = len(Ak)
    nx = n + 2
    nh = nx // 2
    pos = np.r_[1:nh, nh + 1:nx]                      # where x_k sits
    sensors = _SENSORS if ctrl.signals is None else tuple(ctrl.signals)
    A, IMLC, L = np.zeros((nx, nx)), np.zeros((nx, nx)), np.zeros((nx, len(sensors)))
    A[np.ix_(pos, pos)] = Ak
    A[pos, 0] = -Bk
    IMLC[pos, pos] = 1.0
    L[0, sensors.index("theta")] = 1.0
    bref, K = np.zeros(nx), np.zeros(nx)
    bref[pos] = Bk
    K[0], K[pos] = Dk, -Ck
    ref = ctrl.reference
    X = np.zeros((len(ref.theta), nx))
    X[:, 0], X[:, nh] = ref.theta, ref.theta_dot
    return ControlLaw(
        kind="observer", controller="hinf", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max),
        feedforward=float(ctrl._ff),
        arrays={"A": A, "B": np.zeros(nx), "IMLC": IMLC, "L": L, "K": K, "X0": np.zeros(nx), "XREF": X,
                "TFF": np.asarray(ref.torque, dtype=float), "BREF": bref},
        scalars={"spin": 0.0}, sensors=sensors, n_reference=nx + 1,
        reference_layout=f"x_ref[0] the hub angle's reference [rad], x_ref[{nh}] its rate [rad/s] (used past the "
                         f"table only), the other entries to {nx - 1} zero, then tau_ff [N m]")


def _scheduled_lqg_law(ctrl) -> ControlLaw:
    """A :class:`controllers.ScheduledLQG` as arrays: gains, filter gains and models per spin.

    On a rig's own sensors (:meth:`controllers.DesignSchedule.on_rig`) the same tables on the
    filter's whole state ``[x, u_prev, f, b, d]`` (the plain LQG's filter at each spin), the
    measurement rows per spin when they change (``CS``), the LQR gain on the reference
    (``GREF``) and the reference table where the command acts (the rig's delay)."""
    est = ctrl.estimator
    E = ctrl._E
    K = len(ctrl._tff)
    models = np.asarray(est.models, dtype=float)
    S, nz = models.shape[0], models.shape[1]
    ny = np.shape(est._C)[0]
    rig = bool(ctrl._on_rig)
    rows = [ctrl._reference_acting(k) if rig else ctrl._reference_at(k) for k in range(K)]
    X = np.array([E @ xr for xr, _ in rows])
    nx = X.shape[1]
    x0 = np.zeros(nz)
    x0[:nx] = X[0] if not rig else E @ ctrl._reference_at(0)[0]
    arrays = {"SPINS": np.asarray(est.schedule._grid, dtype=float),
              "AD": models[:, :, :nz].reshape(S * nz, nz), "BD": models[:, :, nz],
              "LK": np.asarray(est.L, dtype=float).reshape(S * nz, ny), "C": np.asarray(est._C, dtype=float),
              "GAINS": np.asarray(ctrl.gains, dtype=float), "X0": x0, "XREF": X,
              "TFF": np.array([t for _, t in rows], dtype=float) if rig else np.asarray(ctrl._tff, dtype=float)}
    if est.Cs is not None:
        arrays["CS"] = np.asarray(est.Cs, dtype=float).reshape(S * ny, nz)
    if rig:
        arrays["GREF"] = np.asarray(ctrl.reference_gains, dtype=float)
    rate = ctrl._rate_index if rig else 1
    sensors, gauges = _model_sensors(ctrl.filter_model)
    return ControlLaw(
        kind="scheduled_lqg", controller="lqg", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max),
        feedforward=float(ctrl._ff), arrays=arrays,
        scalars={"measured": 1.0 if ctrl.variable == "measured" else 0.0,
                 "rate_index": -1.0 if rate is None else float(rate), "spin": float(ctrl.filter_model.spin)},
        sensors=sensors, gauges=gauges, n_reference=nx + 1,
        reference_layout=f"x_ref[0..{nx - 1}] (the filter model's states, absolute hub angle and rate"
                         f"{', where the command acts' if rig else ''}), then tau_ff [N m]")
