"""The loop frozen along a run: the evaluation plant linearised about the bent, spinning beam.

The linear certificate (:mod:`hubbeam_ctrl.study.certificate`) judges the loop about the
straight beam on SFOAM, whose linearisation has no axial coordinates: at rest the axial
modes do not couple with the hub torque or the bending. Bent, they do. On a 2.5 m steel strip
at 1 kHz with one sample of computation delay (a 493 N m torque source, the default slew
bending the tip by 0.6 m), the first axial mode (498 Hz, at the Nyquist frequency) couples
into the loop: the loop frozen at the largest bend has spectral radius 1.11 at 500 Hz, and
the command alternates between +-tau_max for 0.4 s while the straight-beam certificate says
stable (0.99905). Without the delay, or with the axial mode above the Nyquist frequency, the
same slew runs without it.

:func:`frozen_loop` linearises the evaluation model (FOAM or CFOAM, every transverse and axial
coordinate) about a state of a run by CasADi's derivatives of its inverse dynamics
``f(q, v, a) = M(q) a + c(q, v) = B tau``: ``da = M^-1 (B dtau - f_q dq - f_v dv)``. The loop
around it is the certificate's: the rig's drive and viscous friction, the computation delay and
the controller's linear law, the controller's inputs read through the sensor rows of the
straight beam (encoder, tachometer, root gauge; an accelerometer's rows come from the straight
SFOAM). :func:`frozen_scan` freezes the loop at the run's largest bends;
:func:`frozen_cause` names it in the verdict's reason. A frozen loop is a necessary check, not a
proof: the beam passes through the bent states, it does not stay there.
"""

from __future__ import annotations

import math
from functools import lru_cache

import casadi as ca
import numpy as np

from controllers.loop_plant import hardware_plant, sampled_rig_plant
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.models import build_model, jacobian_columns
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.study.sampled_loop import closed_loop_matrix, linear_plant, measurement_rows

__all__ = ["frozen_loop", "frozen_scan", "frozen_cause", "frozen_check", "FROZEN_POINTS", "FROZEN_MODELS"]

#: Samples of the run a scan freezes the loop at (the largest bends over equal spans of the slew).
FROZEN_POINTS = 8
#: A frozen radius past ``1 + FROZEN_MARGIN`` is named in the reason [-]: a growth of 0.1 % a sample
#: (doubling in 700 samples), not the round-off of a neutral mode (an undamped axial mode at rest
#: gives 1 + 1e-13).
FROZEN_MARGIN = 1e-3
#: A frozen radius is named in the reason only when held for one span of the scan (``t_f /``
#: :data:`FROZEN_POINTS`) it would multiply a disturbance by at least this much [-]. Found on a random
#: rig (a 1.14 m steel link with a 0.52 kg payload at 200 Hz, an encoder and a tip accelerometer): a run
#: that did not settle for its counts was also blamed on a frozen radius of 1.0018 at a folded axial
#: mode, a growth of 1.09 over its 50-sample span; the 2.5 m strip's 1.11 is held over a span of hundreds of
#: samples at 1 kHz (tests/test_frozen.py).
FROZEN_GROWTH = 2.0
#: A frozen pole above this share of the Nyquist frequency gets the anti-alias filter's hint.
NYQUIST_SHARE = 0.8
#: The simulators' validated range of the tip deflection [share of L] (ClosedLoopSettings.range_limit).
RANGE_LIMIT = ClosedLoopSettings().range_limit
#: Plant modes within this share of the sampling frequency of a loop pole's are named with it.
NEAR_SHARE = 0.02
#: At most this many of them (the nearest).
NEAR_COUNT = 2
#: Evaluation models with a linearisation about any state (the exact beam has none here).
FROZEN_MODELS = ("foam", "cfoam")


@lru_cache(maxsize=4)
def _derivatives(model_name: str, params: Params):
    """``(model, F)``: ``F(q, v, a) -> (M, f_q, f_v)`` of the inverse dynamics, by CasADi."""
    model = build_model(model_name, params)
    f = model.inverse_dynamics_function
    sym = ca.SX if f.is_a("SXFunction") else ca.MX
    args = [sym.sym(f.name_in(i), f.sparsity_in(i)) for i in range(3)]
    f_q = jacobian_columns(f, args, 0)
    f_v = jacobian_columns(f, args, 1)
    f_a = jacobian_columns(f, args, 2)
    return model, ca.Function("inverse_dynamics_derivatives", args, [f_a, f_q, f_v])


def _measured_rows(controller, params: Params, n_axial: int, hardware, command: str):
    """The rows of the controller's inputs on the model's ``[q, v]`` (and the drive's states after
    them), with the feedthrough of the command, from the straight beam's SFOAM rows."""
    inputs = list(controller.feedback_matrices()[5])
    A0, A1, B0, C0 = linear_plant(params, 0.0)
    A_s, B_s, _ = hardware_plant(A0, B0, hardware, command)
    design = getattr(controller, "design", None)
    layout = getattr(design, "sensors", None)
    rig_signals = layout is not None and inputs == list(layout.signals)
    if rig_signals:
        C_s, D_s = layout.rows(A_s, B_s, params, 0.0)
    else:
        C_s = measurement_rows(controller, inputs, C0, A_s.shape[0])
        D_s = np.zeros((C_s.shape[0], 1))
    n_s = 1 + params.n_transverse                      # SFOAM coordinates: theta, q2
    n_q = n_s + n_axial
    C = np.zeros((C_s.shape[0], A_s.shape[0] - 2 * n_s + 2 * n_q))
    C[:, 0], C[:, 1 + n_axial:n_q] = C_s[:, 0], C_s[:, 1:n_s]
    C[:, n_q], C[:, n_q + 1 + n_axial:2 * n_q] = C_s[:, n_s], C_s[:, n_s + 1:2 * n_s]
    C[:, 2 * n_q:] = C_s[:, 2 * n_s:]
    return C, D_s, layout if rig_signals else None


def frozen_loop(controller, model_name: str, params: Params, q, v, tau: float) -> dict:
    """The sampled loop of ``controller`` on the evaluation model linearised about ``(q, v, tau)``.

    Parameters
    ----------
    controller : Controller
        With a linear form (:meth:`~controllers.Controller.feedback_matrices`), as it runs on
        the rig (its ``rig_hardware``, the design's delay and sensors).
    model_name : {"foam", "cfoam"}
        The evaluation model.
    params : Params
        Its parameters (``n_transverse``, ``n_axial``: every coordinate of the run).
    q, v : array_like (n_q,)
        Coordinates and velocities of the run [rad, m, rad/s, m/s].
    tau : float
        Hub torque at that sample [N m].

    Returns
    -------
    dict
        ``radius`` (the largest modulus of the frozen loop's eigenvalues; inf when the
        linearisation is not finite) [-], ``hz`` (its frequency) [Hz] and
        ``mode``: the frozen plant's modes nearest it in the sampled frequency (folded into
        ``[0, 1 / (2 dt)]``; the :data:`NEAR_COUNT` nearest within :data:`NEAR_SHARE` of the sampling frequency):
        ``"axial mode 1 (498.2 Hz) and axial mode 2 (1501 Hz, folded to 499 Hz)"``; ``poles``, every
        eigenvalue of the frozen loop [-].
    """
    model, derivatives = _derivatives(model_name, params)
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    for name, x in (("q", q), ("v", v)):
        if x.shape != (model.n_q,):
            raise ParameterError(f"{name} must hold the model's {model.n_q} coordinates (theta, {model.n_axial} "
                                 f"axial, {model.n_transverse} transverse), got shape {x.shape}")
    a = model.accelerations(q, v, tau)
    M, f_q, f_v = (np.asarray(x, dtype=float) for x in derivatives(q, v, a))
    n = len(q)
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ f_q, -Minv @ f_v]])
    B = np.concatenate([np.zeros(n), Minv[:, 0]])[:, None]
    hw = getattr(controller, "rig_hardware", None)
    command = getattr(controller, "command", "torque")
    C, D, layout = _measured_rows(controller, params, model.n_axial, hw, command)
    delay = float(getattr(getattr(controller, "design", None), "delay", 0.0))    # without hardware
    dt, inputs = float(controller.dt), list(controller.feedback_matrices()[5])
    Ad, Bd, Cm, _ = sampled_rig_plant(A, B, dt, inputs, None, hardware=hw, command=command, delay=delay,
                                      layout=layout, rows=(C, D))
    laws = tuple(np.atleast_2d(np.asarray(x, dtype=float)) for x in controller.feedback_matrices()[:4])
    loop = closed_loop_matrix(Ad, Bd, Cm, laws)
    if not np.all(np.isfinite(loop)):          # the sampled plant overflows: a state far past the model's range
        return {"radius": math.inf, "hz": math.nan, "mode": "not finite", "poles": np.full(len(loop), np.nan)}
    z = np.linalg.eigvals(loop)
    k = int(np.argmax(np.abs(z)))
    return {"radius": float(abs(z[k])), "hz": float(abs(np.angle(z[k])) / (2 * math.pi * dt)),
            "mode": _mode_of(z[k], A, n, model.n_axial, dt), "poles": z}


def _mode_of(z: complex, A: np.ndarray, n: int, n_axial: int, dt: float) -> str:
    """The frozen plant's oscillatory mode whose frequency, folded into ``[0, 1 / (2 dt)]`` by the
    sampling, is nearest a loop pole's, named by the coordinates it moves most."""
    s, vec = np.linalg.eig(A)
    f_s = 1.0 / dt
    hz = abs(np.angle(z)) / (2 * math.pi * dt)
    modes = [j for j in range(len(s)) if s[j].imag > 1e-9]
    if not modes:
        return "rigid"
    folded = np.array([abs((s[j].imag / (2 * math.pi) + f_s / 2) % f_s - f_s / 2) for j in modes])
    gap = np.abs(folded - hz)
    near = [modes[k] for k in np.argsort(gap)[:NEAR_COUNT] if gap[k] <= max(NEAR_SHARE * f_s, float(np.min(gap)))]

    def axial(j):
        shape = np.abs(vec[:n, j]) ** 2
        return float(np.sum(shape[1:1 + n_axial])) > float(np.sum(shape[1 + n_axial:]))

    names = []
    for i in sorted(near, key=lambda j: s[j].imag):
        rank = 1 + sum(1 for j in modes if axial(j) == axial(i) and s[j].imag < s[i].imag - 1e-6)
        f = s[i].imag / (2 * math.pi)
        fold = "" if f <= f_s / 2 else f", folded to {abs((f + f_s / 2) % f_s - f_s / 2):.4g} Hz"
        names.append(f"{'axial' if axial(i) else 'bending'} mode {rank} ({f:.4g} Hz{fold})")
    return " and ".join(names)


def frozen_scan(result, controller, model_name: str, params: Params, t_f: float,
                points: int = FROZEN_POINTS, range_limit: float = RANGE_LIMIT) -> dict | None:
    """The loop frozen at a run's largest bends: the largest tip deflection in each of ``points``
    equal spans of ``[0, t_f]`` (the slew).

    Parameters
    ----------
    result : SimResult
        The closed-loop run (``t``, ``q``, ``v``, ``tau``, ``v_tip``).
    controller : Controller
        With a linear form, as it ran.
    model_name : str
        The evaluation model (:data:`FROZEN_MODELS`; None is returned for others).
    params : Params
        The evaluation plant's parameters.
    t_f : float
        The manoeuvre time [s].
    points : int
        Spans of the slew, >= 1.
    range_limit : float
        States with ``|v_tip| > range_limit L`` are past the models' validated range and are
        not frozen [-] (default the simulators' ``range_limit``).

    Returns
    -------
    dict or None
        :func:`frozen_loop`'s entries at the worst point, with ``t_s`` [s], ``tip_m`` [m],
        ``nyquist_hz`` [Hz] and ``span_samples`` (one span's length in samples) (None: no state to
        freeze).
    """
    if model_name not in FROZEN_MODELS or not hasattr(controller, "feedback_matrices"):
        return None
    t, v_tip = np.asarray(result.t), np.abs(np.asarray(result.v_tip))
    # the models hold within range_limit L (the run says when it left it): no bend past it is frozen
    v_tip = np.where(v_tip <= range_limit * params.L, v_tip, -1.0)
    q, v, tau = np.asarray(result.q), np.asarray(result.v), np.asarray(result.tau)
    edges = np.searchsorted(t, np.linspace(0.0, min(t_f, float(t[-1])), points + 1))
    worst = None
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi <= lo:
            continue
        i = int(lo + np.argmax(v_tip[lo:hi]))
        if v_tip[i] < 0.0:
            continue
        try:       # a diagnostic: a state the linearisation cannot take is left out, the run stands
            out = frozen_loop(controller, model_name, params, q[i], v[i], float(tau[min(i, len(tau) - 1)]))
        except (np.linalg.LinAlgError, ValueError):
            continue
        out.update(t_s=float(t[i]), tip_m=float(v_tip[i]), nyquist_hz=0.5 / float(controller.dt),
                   span_samples=min(t_f, float(t[-1])) / points / float(controller.dt))
        if worst is None or out["radius"] > worst["radius"]:
            worst = out
    return worst


def frozen_cause(metrics: dict, scan: dict | None) -> None:
    """Add the frozen loop's radius to a run's metrics and, when it is past ``1 +``
    :data:`FROZEN_MARGIN` and held over one span of the scan would grow by :data:`FROZEN_GROWTH` at
    least (``frozen_growth``), name it in the verdict's reason (in place).

    Parameters
    ----------
    metrics : dict
        One run's metrics; gets ``frozen_radius`` [-], ``frozen_at_s`` [s], ``frozen_tip_m``
        [m], ``frozen_hz`` [Hz] and ``frozen_mode``.
    scan : dict or None
        :func:`frozen_scan` of the run.
    """
    if not scan:
        return
    radius = scan["radius"]
    growth = radius ** scan["span_samples"] if radius > 1.0 and math.isfinite(radius) else None
    metrics.update(frozen_radius=radius, frozen_at_s=scan["t_s"], frozen_tip_m=scan["tip_m"],
                   frozen_hz=scan["hz"], frozen_mode=scan["mode"], frozen_growth=growth)
    if not radius > 1.0 + FROZEN_MARGIN or not math.isfinite(radius) or growth < FROZEN_GROWTH:
        return    # decaying, neutral (undamped axial modes: 1 + 1e-13), no finite linearisation or too brief
    what = (f"the loop frozen at the bent beam of t = {scan['t_s']:.3g} s (tip {scan['tip_m']:.3g} m) has spectral "
            f"radius {scan['radius']:.4g} at {scan['hz']:.4g} Hz, next to the bent beam's {scan['mode']}: bent, the "
            "beam couples into the loop what the straight-beam certificate does not see")
    if scan["hz"] >= NYQUIST_SHARE * scan.get("nyquist_hz", math.inf):
        what += ("; an anti-alias filter on the analog signals, which the design models ([sensors] anti_alias_hz, "
                 "e.g. a tenth of the sampling frequency), lowers the loop's gain there")
    if metrics.get("verdict") == "settled":       # settled, but banging at the limit on the way
        what = f"the command at its limit {metrics.get('time_at_limit_slew_s') or 0.0:.3g} s of the slew: {what}"
    else:
        what = f"cause: {what}"
    metrics["verdict_reason"] = f"{metrics.get('verdict_reason', '')}; {what}".lstrip("; ")


def frozen_check(metrics: dict, result, controller, model_name: str, params: Params, t_f: float) -> None:
    """:func:`frozen_cause` of :func:`frozen_scan` for a run whose command sat at its limit during
    the slew (``time_at_limit_slew_s`` > 0) or that did not settle; nothing for the others (in place).

    Parameters
    ----------
    metrics : dict
        The run's metrics (:func:`~hubbeam_ctrl.study.judge.judge`).
    result : SimResult
        The run.
    controller : Controller
        As it ran.
    model_name : str
        The evaluation model.
    params : Params
        Its parameters.
    t_f : float
        The manoeuvre time [s].
    """
    if (metrics.get("time_at_limit_slew_s") or 0.0) > 0.0 or metrics.get("verdict") != "settled":
        frozen_cause(metrics, frozen_scan(result, controller, model_name, params, t_f))
