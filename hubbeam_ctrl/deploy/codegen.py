"""Controllers as portable C99: one header and one source per controller.

:func:`to_c` turns a designed controller into C that does at each sample exactly what the
Python controller's call does, operation by operation: the Kalman filter's prediction and
measurement update, the gain, the reference table (extended beyond its end like
:meth:`controllers.Controller._reference_at`), the feedforward, the saturation. The code
has an instance struct holding all its state, ``<name>_init``, ``<name>_reset`` and
``<name>_step(inst, measurements, reference, command)``; no dynamic memory, no I/O, only
``math.h``; gains and tables are ``static const`` arrays printed with 17 significant
digits (``%.17g``), so double precision reproduces the Python numbers.

Kinds (:data:`CODEGEN_KINDS`):

* ``pd``: :class:`controllers.PD` (reads ``theta``, ``theta_dot``);
* ``lqr``: :class:`controllers.LQR` with its observer (:class:`ObservedLQR`): the
  full-state LQR reads modal coordinates no sensor measures, so the exported LQR is its
  gain on a Kalman filter of its model (reads ``theta``, ``theta_dot``, ``root_moment``);
* ``lqg``: :class:`controllers.LQG` (the same three sensors), and the gain-scheduled
  :class:`controllers.ScheduledLQG` (gains, filter gains and models interpolated on the
  measured spin rate);
* ``mpc``: :class:`controllers.MPC` with its observer (:class:`ObservedMPC`): the condensed
  box-constrained QP solved by a generated primal active-set method (no tip bound);
* ``zv``, ``zvd``, ``ei``, ``openloop`` (profile ``feedforward``): the held torque table
  of an input-shaped or feedforward open loop (reads nothing).

The step's interface is double precision whatever ``precision``; with
``precision="single"`` the arithmetic and the stored data are ``float``.
"""

from __future__ import annotations

import dataclasses
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers import LQG, LQR, MPC, PD, Controller, KalmanNoise, OpenLoop, ScheduledLQG, ShapedOpenLoop
from controllers.drive import VoltageCommand
from controllers.integral import ObservedFeedback
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.fileio import write_folder

from .observed import ObservedLQR, ObservedMPC

#: The drive's numbers a voltage-commanding law carries (controllers.drive.VoltageCommand).
_DRIVE_SCALARS = ("R", "N", "k_t", "k_e", "eta_forward", "eta_backward", "v_eps", "V_max")

__all__ = ["CODEGEN_KINDS", "SENSOR_UNITS", "ControlLaw", "GeneratedCode", "certificate_comment", "control_law",
           "render_c", "to_c", "command_text"]

#: Controller kinds that can be generated, and what each exports.
CODEGEN_KINDS = {
    "pd": "PD on the hub angle and rate, reference table, feedforward, saturation",
    "lqr": "LQR gain on a steady-state Kalman filter of its model (the LQR with its observer)",
    "lqg": "LQG: Kalman filter (with residual modes) and gain, reference table, saturation; the "
           "gain-scheduled LQG with every gain and model interpolated on the spin rate",
    "mpc": "MPC on a Kalman filter of its model: the condensed box-constrained QP solved by a generated "
           "primal active-set method (no tip bound)",
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
_PRECISIONS = {"double": "double", "single": "float"}
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,30}$")


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


def _with_disturbance(K, X, x0) -> tuple:
    """Gain, reference table and initial state on the filter's state with the disturbance ``d``
    (:class:`controllers.integral.OffsetFreeEstimator`): ``u = K (x - x_ref) + d``, ``d_ref = 0``."""
    return (np.append(K, 1.0), np.hstack([X, np.zeros((len(X), 1))]), np.append(x0, 0.0))


def control_law(controller: Controller, noise: KalmanNoise | None = None) -> ControlLaw:
    """The per-sample law of ``controller`` as arrays.

    Parameters
    ----------
    controller : controllers.Controller
        A PD, LQR, LQG, input-shaped open loop or feedforward open loop (or an
        :class:`ObservedLQR`).
    noise : controllers.KalmanNoise, optional
        The observer's noise model for an LQR (default: the simulator's sensors).

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
        law = control_law(controller.inner, noise)
        if law.kind not in ("pd", "observer", "mpc"):
            raise ParameterError(f"controller: a voltage command of {law.controller!r} cannot be generated as C")
        d, f = controller.hardware.drive, controller.hardware.friction
        drive = {"R": d.R, "N": d.N, "k_t": d.k_torque, "k_e": d.k_e, "eta_forward": d.eta_forward,
                 "eta_backward": d.eta_backward, "v_eps": f.v_eps, "V_max": d.V_max}
        arrays = dict(law.arrays)
        if controller._rate_index is None:      # no rate sensor: the estimator's rate where the command acts
            est, fm = controller.inner.estimator, controller.inner.filter_model
            r = fm.action_gain(np.eye(fm.n_x)[fm.n_x // 2][None, :])[0]
            arrays["RATE"] = np.r_[r, np.zeros(est.A.shape[0] - len(r))]
        scalars = {**law.scalars, **{k: float(v) for k, v in drive.items()}}
        law = dataclasses.replace(law, arrays=arrays, scalars=scalars)
        law.check_finite()
        return law
    ctrl = controller
    if type(ctrl) is LQR:                 # not the scheduled subclasses: they interpolate in the spin
        ctrl = ObservedLQR(ctrl, noise)
    elif type(ctrl) is MPC:
        ctrl = ObservedMPC(ctrl, noise)
    if isinstance(ctrl, ObservedFeedback) and type(ctrl.inner) is MPC:
        law = _mpc_law(ctrl)
        law.check_finite()
        return law
    if isinstance(ctrl, ObservedFeedback):
        if type(ctrl.inner) is not LQR:
            raise ParameterError(f"controller: an observer-fed {type(ctrl.inner).__name__} cannot be generated as "
                                 "C (an LQR or an MPC can)")
        inner = ctrl.inner
        X, tff = _reference_table(inner)
        K, x0 = np.asarray(inner.K, float), np.array(X[0])
        x0[ctrl._n_f] -= ctrl.design.spin
        K, X, x0, tff_act = _acting(inner, ctrl.filter_model, K, X, x0, lambda k: inner._reference_at(k)[0])
        tff = tff if tff_act is None else tff_act
        if ctrl.integral:
            K, X, x0 = _with_disturbance(K, X, x0)
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
    elif type(ctrl) is LQG:
        X, tff = _reference_table(ctrl, ctrl._xref_filter, ctrl._E)
        x0 = ctrl._E @ ctrl._reference_at(0)[0]        # LQG.reset
        x0[ctrl._n] -= ctrl.design.spin
        K = ctrl._Ke
        K, X, x0, tff_act = _acting(ctrl, ctrl.filter_model, K, X, x0, ctrl._filter_reference)
        tff = tff if tff_act is None else tff_act
        if ctrl.settings.integral:                      # the estimated disturbance is cancelled
            K, X, x0 = _with_disturbance(K, X, x0)
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


# -- C text ------------------------------------------------------------------------------------
def _number(v: float, single: bool) -> str:
    s = "%.9g" % v if single else "%.17g" % v
    if not any(c in s for c in ".e"):
        s += ".0"
    return s + ("f" if single else "")


def _array(name: str, a, real: str, single: bool, per_line: int = 4) -> str:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        items = [_number(v, single) for v in a]
        lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
        return f"static const {real} {name}[{len(a)}] = {{\n    " + ",\n    ".join(lines) + "\n};\n"
    rows = []
    for r in a:
        items = [_number(v, single) for v in r]
        rows.append("{" + ", ".join(items) + "}")
    return (f"static const {real} {name}[{a.shape[0]}][{a.shape[1]}] = {{\n    "
            + ",\n    ".join(rows) + "\n};\n")


def _array3(name: str, a, real: str, single: bool) -> str:
    """A ``static const`` three-dimensional array."""
    a = np.asarray(a, dtype=float)

    def row(r):
        return "{" + ", ".join(_number(v, single) for v in r) + "}"
    blocks = ["{" + ", ".join(row(r) for r in m) + "}" for m in a]
    return f"static const {real} {name}[{a.shape[0]}][{a.shape[1]}][{a.shape[2]}] = {{\n    " + \
        ",\n    ".join(blocks) + "\n};\n"


def command_text(law: ControlLaw) -> str:
    """What the generated step returns, in which unit and within which limit (the header's words).

    Parameters
    ----------
    law : ControlLaw
        With the drive's scalars (``V_max``...) for a DC motor's voltage command.

    Returns
    -------
    str
        ``"the DC motor's voltage [V] ... within +-10 V ..."`` or ``"the hub torque [N m] ...
        within +-200 N m."``.
    """
    if "V_max" in law.scalars:
        return (f"the DC motor's voltage [V] to hold until the next sample, within +-V_max = "
                f"{law.scalars['V_max']:.12g} V\n *                 (the torque law's hub torque, within "
                f"+-{law.tau_max:.12g} N m, through the drive's static inverse\n *                 at the "
                f"measured hub rate).")
    return f"the hub torque [N m] to hold until the next sample, within +-{law.tau_max:.12g} N m."


def _header(name: str, law: ControlLaw, real: str, struct_body: str, n_meas: int) -> str:
    up = name.upper()
    sensors = "".join(f"\n *                 {i}: {text}" for i, text in enumerate(law.sensor_text())) \
        or " none (open loop)"
    volts = f"#define {up}_V_MAX {law.scalars['V_max']:.17g}  /* [V] */\n" if "V_max" in law.scalars else ""
    return f"""/* {name}.h: {CODEGEN_KINDS[law.controller]}.
 * Generated by hubbeam-ctrl (hubbeam_ctrl.deploy.to_c); C99, no dynamic memory, no I/O.
 *
 * Call {name}_step once per sample, every {law.dt:.17g} s, starting at t = 0 after
 * {name}_init or {name}_reset (the step counts the samples itself).
 *   measurements: {n_meas} value(s):{sensors}
 *   reference:    NULL for the built-in reference table, or {law.n_reference} value(s):
 *                 {law.reference_layout}
 *   command:      {command_text(law)}
 */
#ifndef {up}_H
#define {up}_H

#define {up}_N_MEASUREMENTS {max(n_meas, 1)}
#define {up}_N_REFERENCE {law.n_reference}
#define {up}_DT {law.dt:.17g}
#define {up}_TAU_MAX {law.tau_max:.17g}  /* [N m] */
{volts}
typedef {real} {name}_real;

typedef struct {{
{struct_body}
}} {name}_instance;

void {name}_init({name}_instance *inst);
void {name}_reset({name}_instance *inst);
void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command);
unsigned long {name}_instance_size(void);

#endif
"""


def _measurements(law: ControlLaw, R: str) -> str:
    """C lines that take the measurements in deviation from the steady rotation (``yd``), as
    :meth:`controllers.DesignModel.sensor_deviation`: the angle less ``SPIN t``, the rate less ``SPIN``."""
    lines = ["    /* measurements in deviation from the steady rotation at the design spin */"]
    for i, s in enumerate(law.sensors):
        less = {"theta": " - SPIN * t", "theta_dot": " - SPIN"}.get(s, "")
        lines.append(f"    yd[{i}] = ({R})measurements[{i}]{less};  /* {s} [{sensor_unit(s)}] */")
    return "\n".join(lines) + "\n"


def _innovation(law: ControlLaw) -> str:
    """``L[i][0] * yd[0] + ...``: the filter gain's row ``i`` on the measurements."""
    return " + ".join(f"L[i][{j}] * yd[{j}]" for j in range(len(law.sensors)))


def _filter_fields(R: str, nx: int) -> str:
    """Instance fields of a steady-state filter's template (prediction, estimate, held command)."""
    return (f"    {R} x_pred[{nx}];  /* prediction of the filter's state (deviation from steady spin) */\n"
            f"    {R} x_hat[{nx}];   /* estimate after the last measurement */\n"
            f"    {R} tau_prev;    /* torque held since the last sample [N m] */\n"
            f"    int has_tau;      /* 0 until the first step after reset */\n"
            f"    long k;           /* sample index */")


def _filter_reset() -> str:
    """C lines of a reset that starts the filter at ``X0`` with no command held."""
    return """    for (i = 0; i < NX; ++i) {
        inst->x_pred[i] = X0[i];
        inst->x_hat[i] = X0[i];
    }
    inst->tau_prev = 0;
    inst->has_tau = 0;
    inst->k = 0;
"""


def _filter_step(law: ControlLaw, R: str) -> str:
    """C lines of one sample of the steady-state filter (:meth:`controllers.KalmanEstimator.update`):
    the prediction with the command held since the last sample (plus the plan's offset when the
    law has one), then ``x_hat = (I - L C) x_pred + L yd``."""
    offset = ("\n            if (inst->k >= 1 && inst->k - 1 < KOFF) s += OFFSET[inst->k - 1][i];  "
              "/* along the plan */") if "OFFSET" in law.arrays else ""
    return f"""    /* predict with the torque held since the last sample */
    if (inst->has_tau) {{
        for (i = 0; i < NX; ++i) {{
            {R} s = 0;
            for (j = 0; j < NX; ++j) s += A[i][j] * inst->x_hat[j];{offset}
            inst->x_pred[i] = s + B[i] * inst->tau_prev;
        }}
    }}
    /* measurement update: x_hat = (I - L C) x_pred + L y */
    for (i = 0; i < NX; ++i) {{
        {R} s = 0;
        for (j = 0; j < NX; ++j) s += IMLC[i][j] * inst->x_pred[j];
        inst->x_hat[i] = s + ({_innovation(law)});
    }}
"""


def _filter_data(law: ControlLaw, R: str, single: bool, names) -> str:
    """``static const`` arrays of the filter (``A B IMLC L``), ``names`` and the plan's ``OFFSET``."""
    data = "".join(_array(k, law.arrays[k], R, single) for k in ("A", "B", "IMLC", "L", *names))
    if "OFFSET" in law.arrays:
        data += _array("OFFSET", law.arrays["OFFSET"], R, single)
    return data


def _source(name: str, precision: str, data: str, code: str) -> str:
    """A generated ``.c`` file: the data, a template's code, ``_init`` and ``_instance_size``."""
    return f"""/* {name}.c: generated by hubbeam-ctrl (hubbeam_ctrl.deploy.to_c). {precision} precision. */
#include <math.h>
#include "{name}.h"

{data}
{code}
void {name}_init({name}_instance *inst)
{{
    {name}_reset(inst);
}}

unsigned long {name}_instance_size(void)
{{
    return (unsigned long)sizeof({name}_instance);
}}
"""


def _saturate(name: str) -> str:
    return f"""static {name}_real saturate({name}_real tau)
{{
    /* as controllers.saturate: NaN passes through */
    return tau > TAU_MAX ? TAU_MAX : (tau < -TAU_MAX ? -TAU_MAX : tau);
}}
"""


def render_c(law: ControlLaw, name: str, precision: str = "double") -> tuple:
    """The header and source text of a control law (with the drive's voltage stage when the law has one).

    Parameters
    ----------
    law : ControlLaw
    name : str
        C identifier prefix and file stem.
    precision : {"double", "single"}
        Type of the stored data and the arithmetic.

    Returns
    -------
    tuple of str
        ``(header, source)``.
    """
    header, source = _render_law(law, name, precision)
    if "V_max" not in law.scalars:
        return header, source
    R = f"{name}_real"
    sc = {k: _number(law.scalars[k], precision == "single") for k in _DRIVE_SCALARS}
    if "theta_dot" in law.sensors:
        rate, estimate = f"({R})measurements[{law.sensors.index('theta_dot')}]", ""
    else:
        rate = "rate_estimate(inst)"
        estimate = (_array("RATE", law.arrays["RATE"], R, precision == "single")
                    + f"""
/* no rate sensor: the filter's hub rate where the command acts (absolute) [rad/s] */
static {R} rate_estimate(const {name}_instance *inst)
{{
    {R} s = 0;
    int i;
    for (i = 0; i < NX; ++i) s += RATE[i] * inst->x_hat[i];
    return s + SPIN;
}}
""")
    stage = estimate + f"""
/* the DC drive's static inverse (controllers.drive.VoltageCommand): the voltage that gives the hub
   torque tau at the measured hub rate thd, through back-EMF and the gear's efficiency, clipped */
static {R} drive_voltage({R} tau, {R} thd)
{{
    {R} x = -thd * (tau >= 0 ? 1 : -1) / {sc["v_eps"]};
    {R} e, th, v;
    x = x < 0 ? 0 : (x > 50 ? 50 : x);
    th = tanh(x);
    e = {sc["eta_forward"]} + (1 / {sc["eta_backward"]} - {sc["eta_forward"]}) * th * th;
    v = {sc["R"]} * tau / ({sc["N"]} * {sc["k_t"]} * e) + {sc["k_e"]} * {sc["N"]} * thd;
    return v > {sc["V_max"]} ? {sc["V_max"]} : (v < -{sc["V_max"]} ? -{sc["V_max"]} : v);
}}
"""
    sat = _saturate(name)
    if sat not in source:
        raise HubbeamError("the voltage stage needs the template's saturate()")
    source = source.replace(sat, sat + stage, 1)
    for old in ("*command = (double)tau;", "*command = (double)saturate(tau);"):
        inner = old[len("*command = (double)"):-1]
        source = source.replace(old, f"*command = (double)drive_voltage({inner}, {rate});")
    return header, source


def _render_law(law: ControlLaw, name: str, precision: str = "double") -> tuple:
    """The header and source text of a control law's template.

    Parameters
    ----------
    law : ControlLaw
    name : str
        C identifier prefix and file stem.
    precision : {"double", "single"}
        Type of the stored data and the arithmetic.

    Returns
    -------
    tuple of str
        ``(header, source)``.
    """
    if law.kind == "mpc":
        return _render_mpc(law, name, precision)
    if law.kind == "scheduled_lqg":
        return _render_scheduled_lqg(law, name, precision)
    real = _PRECISIONS[precision]
    single = precision == "single"
    R = f"{name}_real"

    def num(v):
        return _number(v, single)

    common = (f"static const {R} DT = {num(law.dt)};\nstatic const {R} TAU_MAX = {num(law.tau_max)};\n"
              f"static const {R} FF = {num(law.feedforward)};\n")
    if law.kind == "observer":
        nx = len(law.arrays["K"])
        nh = nx // 2
        kt = len(law.arrays["TFF"])
        body = _filter_fields(R, nx)
        data = _filter_data(law, R, single, ("K", "X0", "XREF", "TFF"))
        kd = len(law.arrays["OFFSET"]) if "OFFSET" in law.arrays else 0
        code = f"""#define NX {nx}
#define NH {nh}
#define NY {len(law.sensors)}
#define KT {kt}
#define KOFF {kd}
{common}static const {R} SPIN = {num(law.scalars["spin"])};

{_saturate(name)}
void {name}_reset({name}_instance *inst)
{{
    int i;
{_filter_reset()}}}

void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command)
{{
    {R} t = ({R})inst->k * DT;
    {R} yd[NY];
    {R} xr[NX];
    {R} tff, u, tau;
    int i, j;
{_measurements(law, R)}    if (reference) {{
        for (i = 0; i < NX; ++i) xr[i] = ({R})reference[i];
        tff = ({R})reference[NX];
    }} else if (inst->k < KT) {{
        for (i = 0; i < NX; ++i) xr[i] = XREF[inst->k][i];
        tff = TFF[inst->k];
    }} else {{  /* beyond the table: the final rate continues */
        for (i = 0; i < NX; ++i) xr[i] = XREF[KT - 1][i];
        xr[0] = XREF[KT - 1][0] + XREF[KT - 1][NH] * ({R})(inst->k - KT + 1) * DT;
        tff = TFF[KT - 1];
    }}
{_filter_step(law, R)}    /* gain on the tracking error (x_hat is a deviation, x_ref absolute) */
    u = 0;
    for (i = 0; i < NX; ++i) u += K[i] * (inst->x_hat[i] - xr[i]);
    u = u + K[0] * SPIN * t + K[NH] * SPIN;
    tau = saturate(FF * tff - u);
    inst->tau_prev = tau;
    inst->has_tau = 1;
    inst->k += 1;
    *command = (double)tau;
}}
"""
    elif law.kind == "pd":
        kt = len(law.arrays["TFF"])
        body = "    long k;           /* sample index */"
        data = "".join(_array(k, law.arrays[k], R, single) for k in ("THETA", "THETA_DOT", "TFF"))
        code = f"""#define KT {kt}
{common}static const {R} KP = {num(law.scalars["kp"])};
static const {R} KD = {num(law.scalars["kd"])};

{_saturate(name)}
void {name}_reset({name}_instance *inst)
{{
    inst->k = 0;
}}

void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command)
{{
    {R} th, thd, tff, tau;
    if (reference) {{
        th = ({R})reference[0];
        thd = ({R})reference[1];
        tff = ({R})reference[2];
    }} else if (inst->k < KT) {{
        th = THETA[inst->k];
        thd = THETA_DOT[inst->k];
        tff = TFF[inst->k];
    }} else {{  /* beyond the table: the final rate continues */
        th = THETA[KT - 1] + THETA_DOT[KT - 1] * (({R})(inst->k - (KT - 1)) * DT);
        thd = THETA_DOT[KT - 1];
        tff = TFF[KT - 1];
    }}
    tau = FF * tff + KP * (th - ({R})measurements[0]) + KD * (thd - ({R})measurements[1]);
    inst->k += 1;
    *command = (double)saturate(tau);
}}
"""
    elif law.kind == "table":
        kt = len(law.arrays["TORQUE"])
        body = "    long k;           /* sample index */"
        data = _array("TORQUE", law.arrays["TORQUE"], R, single)
        code = f"""#define KT {kt}
static const {R} TAIL = {num(law.scalars["tail"])};

void {name}_reset({name}_instance *inst)
{{
    inst->k = 0;
}}

void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command)
{{
    (void)measurements;
    if (reference) *command = reference[0];
    else *command = (double)(inst->k < KT ? TORQUE[inst->k] : TAIL);
    inst->k += 1;
}}
"""
    else:
        raise HubbeamError(f"unknown control-law template {law.kind!r}")
    n_meas = len(law.sensors)
    header = _header(name, law, real, body, n_meas)
    source = _source(name, precision, data, code)
    return header, source


@dataclass(frozen=True, eq=False)
class GeneratedCode:
    """C sources of one controller, as written by :func:`to_c`.

    Attributes
    ----------
    name : str
        C prefix and file stem (``<name>.h``, ``<name>.c``).
    folder : pathlib.Path or None
        Where the files were written (None: in memory only).
    header, source : str
        The files' text.
    precision : {"double", "single"}
    law : ControlLaw
        What the code computes.
    certificate : dict or None
        The robust certificate the code was exported with (``robust_*`` entries of
        :meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`), also in the header's first
        comment and the metadata.
    """

    name: str
    folder: Path | None
    header: str
    source: str
    precision: str
    law: ControlLaw
    certificate: dict | None = None

    @property
    def header_path(self) -> Path:
        """``<folder>/<name>.h``."""
        return Path(self.folder) / f"{self.name}.h"

    @property
    def source_path(self) -> Path:
        """``<folder>/<name>.c``."""
        return Path(self.folder) / f"{self.name}.c"

    @property
    def data_bytes(self) -> int:
        """Bytes of the ``static const`` data (gains and tables) [B]."""
        size = 4 if self.precision == "single" else 8
        return int(sum(np.asarray(a).size for a in self.law.arrays.values()) * size)

    def metadata(self) -> dict:
        """What the controller expects and gives: sensors with units, sample time, limits."""
        law = self.law
        return {"name": self.name, "controller": law.controller, "precision": self.precision,
                "dt_s": law.dt, "tau_max_nm": law.tau_max,
                "measurements": [{"name": s, "unit": sensor_unit(s)} for s in law.sensors],
                "reference": law.reference_layout, "n_reference": law.n_reference,
                "command": ({"name": "V", "unit": "V", "V_max": law.scalars["V_max"]} if "V_max" in law.scalars
                            else {"name": "tau", "unit": "N m"}), "data_bytes": self.data_bytes,
                **({"robust_certificate": self.certificate} if self.certificate is not None else {})}


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not _IDENT.match(name):
        raise ParameterError(f"name must be a C identifier of at most 31 characters, got {name!r}")
    return name


def _check_out(out_dir, force: bool) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"out: {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise ParameterError(f"out: folder {out} exists and is not empty (use --force / force=True to "
                             "write into it)")
    if not out.parent.is_dir():
        raise ParameterError(f"out: folder {out.parent} does not exist")
    return out


def to_c(controller: Controller, out_dir=None, precision: str = "double", *, name: str | None = None,
         force: bool = False, noise: KalmanNoise | None = None, check=None,
         certificate: dict | None = None) -> GeneratedCode:
    """Write ``controller`` as portable C99 (``<name>.h``, ``<name>.c``, ``<name>.json``).

    Parameters
    ----------
    controller : controllers.Controller
        One of :data:`CODEGEN_KINDS` (an LQR is exported with its observer,
        :class:`~hubbeam_ctrl.deploy.observed.ObservedLQR`).
    out_dir : str or Path, optional
        Output folder, written atomically (built beside it, then renamed; a failed build
        leaves nothing). None: return the text without writing.
    precision : {"double", "single"}
        ``double`` (default) reproduces the Python controller to rounding; ``single``
        stores and computes in ``float`` (see docs/deploy.md for its measured error).
    name : str, optional
        C prefix and file stem (default: the controller's kind, e.g. ``"lqg"``).
    force : bool
        Write into an existing, non-empty folder.
    noise : controllers.KalmanNoise, optional
        Noise model of the LQR's observer (default: the simulator's sensors).
    check : callable, optional
        ``check(folder, name)`` run on the written files before they are moved into place
        (e.g. a compile, :func:`hubbeam_ctrl.deploy.sil.compile_c`); if it raises, nothing
        is left.
    certificate : dict, optional
        The robust certificate of the controller over its rig's uncertainty set
        (:meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`): its verdict, worst radius
        and worst plant open the header, and the metadata carries it whole.

    Returns
    -------
    GeneratedCode

    Raises
    ------
    ParameterError
        Unknown precision, a controller kind that cannot be generated, a non-finite gain, a
        bad name, or an output folder that is not empty without ``force``.
    """
    if precision not in _PRECISIONS:
        raise ParameterError(f"precision must be one of {', '.join(_PRECISIONS)}, got {precision!r}")
    law = control_law(controller, noise)
    name = _check_name(law.controller if name is None else name)
    header, source = render_c(law, name, precision)
    if certificate is not None:
        header = certificate_comment(certificate) + header
    code = GeneratedCode(name, None, header, source, precision, law, certificate)
    if out_dir is None:
        return code
    out = _check_out(out_dir, force)
    meta = json.dumps(code.metadata(), indent=1) + "\n"

    def write(folder: Path) -> None:
        (folder / f"{name}.h").write_text(header)
        (folder / f"{name}.c").write_text(source)
        (folder / f"{name}.json").write_text(meta)
        if check is not None:
            check(folder, name)

    write_folder(out, write, "out")
    return GeneratedCode(name, out, header, source, precision, law, certificate)


def certificate_comment(certificate: dict) -> str:
    """The C comment that opens a certified controller's header.

    Parameters
    ----------
    certificate : dict
        ``robust_*`` entries (:meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`).

    Returns
    -------
    str
    """
    worst = ", ".join(f"{k} = {v:.6g}" for k, v in (certificate.get("robust_worst") or {}).items())
    box = ", ".join(f"{k} [{lo:.6g}, {hi:.6g}]" for k, (lo, hi) in (certificate.get("robust_set") or {}).items())
    text = (f"/* Robust certificate: {str(certificate.get('robust_verdict', '?')).upper()} over {box}.\n"
            f"   Worst spectral radius of the sampled loop found {certificate.get('robust_radius', float('nan')):.8f} "
            f"at {worst} (searched, {certificate.get('robust_evaluations')} loops of "
            f"{certificate.get('robust_plant_modes')} bending modes; hubbeam_ctrl.study.worst_case). */\n")
    return text + "\n"


def _mpc_law(ctrl: ObservedFeedback) -> ControlLaw:
    """An MPC closed through its observer (:class:`controllers.integral.ObservedFeedback`) as
    arrays: the filter (any sensor set, the previous command and the disturbance as states), the
    map ``P`` from the filter's state to the MPC's state where the command acts, the condensed QP
    and its reference terms."""
    mpc, fm, est = ctrl.inner, ctrl.filter_model, ctrl.estimator
    s = mpc.settings
    if s.tip_bound is not None:
        raise ParameterError("controller: an MPC with a tip_bound cannot be generated as C yet (the generated "
                             "QP solver handles the torque bounds only); use tip_bound=None")
    if s.emf_torque_limit is not None:
        raise ParameterError("controller: an MPC with an emf_torque_limit (a DC motor's voltage limit) cannot be "
                             "generated as C yet; use emf_torque_limit=None")
    N = s.horizon
    nz = est.A.shape[0]
    Phi, G = fm.action_map()
    act = np.zeros((fm.n_x, nz))                   # the acting state (controllers.DesignModel.acting_state)
    act[:, :fm.n_x] = Phi
    if fm.delay > 0.0:
        act[:, fm.n_x] = G
    H = np.asarray(mpc._H.full(), dtype=float)
    table = np.asarray(mpc._ref_term, dtype=float)
    kt = len(table)
    r0 = np.asarray(mpc._reference_term(kt), dtype=float)
    r1 = np.asarray(mpc._reference_term(kt + 1), dtype=float) - r0
    arrays = {**_filter_arrays(est), "X0": ctrl.initial_state(), "P": act[ctrl._pick],
              "GX": np.asarray(mpc._Gx, float), "H": H, "HL": np.linalg.cholesky(H), "REFT": table, "R0": r0, "R1": r1}
    if ctrl._defect is not None and len(ctrl._defect):
        arrays["OFFSET"] = _offset_rows(ctrl._defect, nz)
    sensors, gauges = _model_sensors(fm)
    return ControlLaw(
        kind="mpc", controller="mpc", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max), feedforward=1.0,
        arrays=arrays,
        scalars={"spin": float(ctrl.design.spin), "horizon": float(N), "delay": float(fm.delay),
                 "plan_shift": float(np.floor(fm.delay + 0.5)), "integral": 1.0 if ctrl.integral else 0.0},
        sensors=sensors, n_reference=N, gauges=gauges,
        reference_layout=f"r[0..{N - 1}]: the QP gradient's reference term (g = Gx x - r)")


def _render_mpc(law: ControlLaw, name: str, precision: str) -> tuple:
    """Body of the MPC template: Kalman filter, then a primal active-set solve of the box QP."""
    real = _PRECISIONS[precision]
    single = precision == "single"
    R = f"{name}_real"
    nx = len(law.arrays["X0"])
    nh = nx // 2
    N = int(law.scalars["horizon"])
    kt = len(law.arrays["REFT"])
    sqrt = "sqrtf" if single else "sqrt"
    fabs = "fabsf" if single else "fabs"
    body = (_filter_fields(R, nx) + "\n"
            f"    {R} z[{N}];       /* the plan (the QP's solution) */\n"
            f"    int st[{N}];      /* active set: 0 free, -1 at -tau_max, +1 at +tau_max */\n"
            f"    {R} g[{N}];       /* the QP's linear term */\n"
            f"    {R} M[{N}][{N}];  /* Cholesky factor of the free block of H */\n"
            f"    {R} v[{N}], zs[{N}];\n"
            f"    int fidx[{N}];\n"
            f"    int iterations;   /* active-set iterations of the last solve */\n"
            f"    long failures;    /* solves that hit the iteration limit (plan kept feasible) */")
    data = _filter_data(law, R, single, ("X0", "P", "GX", "H", "HL", "REFT", "R0", "R1"))
    nu = len(law.arrays["P"])
    kd = len(law.arrays["OFFSET"]) if "OFFSET" in law.arrays else 0
    num = (lambda v: _number(v, single))
    code = f"""#define NX {nx}
#define NH {nh}
#define NY {len(law.sensors)}
#define NU {nu}
#define NUH {nu // 2}
#define NZ {N}
#define KT {kt}
#define KOFF {kd}
#define PLAN_SHIFT {int(law.scalars["plan_shift"])}
#define INTEGRAL {int(law.scalars["integral"])}
#define MAXIT (4 * NZ + 10)
static const {R} DT = {num(law.dt)};
static const {R} TAU_MAX = {num(law.tau_max)};
static const {R} SPIN = {num(law.scalars["spin"])};
static const {R} DELAY = {num(law.scalars["delay"])};
static const {R} LAM_TOL = {num(1e-5 if single else 1e-11)};

{_saturate(name)}
void {name}_reset({name}_instance *inst)
{{
    int i;
{_filter_reset()}    for (i = 0; i < NZ; ++i) {{
        inst->z[i] = 0;
        inst->st[i] = 0;
    }}
    inst->iterations = 0;
    inst->failures = 0;
}}

/* solve L L' x = v in place (L lower triangular, n x n, row stride NZ) */
static void chol_solve(const {R} (*F)[NZ], int n, const {R} *v, {R} *x)
{{
    int a, c;
    for (a = 0; a < n; ++a) {{
        {R} s = v[a];
        for (c = 0; c < a; ++c) s -= F[a][c] * x[c];
        x[a] = s / F[a][a];
    }}
    for (a = n - 1; a >= 0; --a) {{
        {R} s = x[a];
        for (c = a + 1; c < n; ++c) s -= F[c][a] * x[c];
        x[a] = s / F[a][a];
    }}
}}

/* min 1/2 z'Hz + g'z  s.t. -TAU_MAX <= z <= TAU_MAX: primal active set from a feasible start.
 * The QP is strictly convex, so its minimiser is unique: the Python MPC's solver finds the same. */
static int qp_solve({name}_instance *inst)
{{
    int it, i, j, a, b, c, nf, blk, side, worst_i;
    {R} alpha, worst;
    for (it = 0; it < MAXIT; ++it) {{
        nf = 0;
        for (i = 0; i < NZ; ++i)
            if (inst->st[i] == 0) inst->fidx[nf++] = i;
        for (a = 0; a < nf; ++a) {{
            {R} s;
            i = inst->fidx[a];
            s = inst->g[i];
            for (j = 0; j < NZ; ++j)
                if (inst->st[j] != 0) s += H[i][j] * inst->z[j];
            inst->v[a] = -s;
        }}
        if (nf == NZ) {{
            chol_solve(HL, nf, inst->v, inst->zs);
        }} else if (nf > 0) {{
            for (a = 0; a < nf; ++a) {{
                for (b = 0; b <= a; ++b) {{
                    {R} s = H[inst->fidx[a]][inst->fidx[b]];
                    for (c = 0; c < b; ++c) s -= inst->M[a][c] * inst->M[b][c];
                    if (a == b) {{
                        if (!(s > 0)) return -1;
                        inst->M[a][a] = {sqrt}(s);
                    }} else {{
                        inst->M[a][b] = s / inst->M[b][b];
                    }}
                }}
            }}
            chol_solve((const {R} (*)[NZ])inst->M, nf, inst->v, inst->zs);
        }}
        /* longest step toward the subproblem's minimiser that stays feasible */
        alpha = 1;
        blk = -1;
        side = 0;
        for (a = 0; a < nf; ++a) {{
            {R} d, r;
            i = inst->fidx[a];
            d = inst->zs[a] - inst->z[i];
            if (inst->zs[a] < -TAU_MAX) {{
                r = (-TAU_MAX - inst->z[i]) / d;
                if (r < alpha) {{ alpha = r; blk = i; side = -1; }}
            }} else if (inst->zs[a] > TAU_MAX) {{
                r = (TAU_MAX - inst->z[i]) / d;
                if (r < alpha) {{ alpha = r; blk = i; side = 1; }}
            }}
        }}
        if (blk >= 0) {{
            for (a = 0; a < nf; ++a) {{
                i = inst->fidx[a];
                inst->z[i] += alpha * (inst->zs[a] - inst->z[i]);
            }}
            inst->z[blk] = side < 0 ? -TAU_MAX : TAU_MAX;
            inst->st[blk] = side;
            continue;
        }}
        for (a = 0; a < nf; ++a) inst->z[inst->fidx[a]] = inst->zs[a];
        /* multipliers of the bounds in the working set */
        worst = 0;
        worst_i = -1;
        for (i = 0; i < NZ; ++i) {{
            {R} gr, lam;
            if (inst->st[i] == 0) continue;
            gr = inst->g[i];
            for (j = 0; j < NZ; ++j) gr += H[i][j] * inst->z[j];
            lam = inst->st[i] < 0 ? gr : -gr;
            if (lam < worst && lam < -LAM_TOL * ({fabs}(inst->g[i]) + H[i][i] * TAU_MAX)) {{
                worst = lam;
                worst_i = i;
            }}
        }}
        if (worst_i < 0) return it + 1;
        inst->st[worst_i] = 0;
    }}
    return -1;
}}

void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command)
{{
    {R} t = ({R})inst->k * DT;
    {R} yd[NY];
    {R} xa[NU];
    {R} tau;
    long kr = inst->k + PLAN_SHIFT;  /* the plan's reference sample where the command acts */
    int i, j;
{_measurements(law, R)}{_filter_step(law, R)}    /* the MPC's state where the command acts (absolute) */
    for (i = 0; i < NU; ++i) {{
        {R} s = 0;
        for (j = 0; j < NX; ++j) s += P[i][j] * inst->x_hat[j];
        xa[i] = s;
    }}
    xa[0] = xa[0] + SPIN * (t + DELAY * DT);
    xa[NUH] = xa[NUH] + SPIN;
    /* the QP's linear term g = Gx x - r_k */
    for (i = 0; i < NZ; ++i) {{
        {R} s = 0, r;
        for (j = 0; j < NU; ++j) s += GX[i][j] * xa[j];
        if (reference) r = ({R})reference[i];
        else if (kr < KT) r = REFT[kr][i];
        else r = R0[i] + ({R})(kr - KT) * R1[i];
        inst->g[i] = s - r;
    }}
    /* warm start: the previous active set and plan (kept feasible) */
    for (i = 0; i < NZ; ++i) {{
        if (inst->st[i] < 0) inst->z[i] = -TAU_MAX;
        else if (inst->st[i] > 0) inst->z[i] = TAU_MAX;
        else if (inst->z[i] < -TAU_MAX) inst->z[i] = -TAU_MAX;
        else if (inst->z[i] > TAU_MAX) inst->z[i] = TAU_MAX;
    }}
    inst->iterations = qp_solve(inst);
    if (inst->iterations < 0) inst->failures += 1;
    tau = saturate(inst->z[0]);
    if (INTEGRAL) tau = saturate(tau - inst->x_hat[NX - 1]);  /* the estimated disturbance */
    inst->tau_prev = tau;
    inst->has_tau = 1;
    inst->k += 1;
    *command = (double)tau;
}}
"""
    header = _header(name, law, real, body, len(law.sensors))
    source = _source(name, precision, data, code)
    return header, source


def _scheduled_lqg_law(ctrl) -> ControlLaw:
    """A :class:`controllers.ScheduledLQG` as arrays: gains, filter gains and models per spin."""
    est = ctrl.estimator
    E = ctrl._E
    K = len(ctrl._tff)
    X = np.array([E @ ctrl._reference_at(k)[0] for k in range(K)])
    models = np.asarray(est.models, dtype=float)
    S, nx = models.shape[0], models.shape[1]
    return ControlLaw(
        kind="scheduled_lqg", controller="lqg", dt=float(ctrl.dt), tau_max=float(ctrl.tau_max),
        feedforward=float(ctrl._ff),
        arrays={"SPINS": np.asarray(est.schedule._grid, dtype=float),
                "AD": models[:, :, :nx].reshape(S * nx, nx), "BD": models[:, :, nx],
                "LK": np.asarray(est.L, dtype=float).reshape(S * nx, 3), "C": np.asarray(est._C, dtype=float),
                "GAINS": np.asarray(ctrl.gains, dtype=float), "X0": X[0].copy(), "XREF": X,
                "TFF": np.asarray(ctrl._tff, dtype=float)},
        scalars={"measured": 1.0 if ctrl.variable == "measured" else 0.0}, sensors=_SENSORS,
        n_reference=nx + 1,
        reference_layout=f"x_ref[0..{nx - 1}] (the filter model's states, absolute hub angle and rate), "
                         f"then tau_ff [N m]")


def _render_scheduled_lqg(law: ControlLaw, name: str, precision: str) -> tuple:
    """The gain-scheduled LQG: every gain and model interpolated in the spin rate per sample."""
    real = _PRECISIONS[precision]
    single = precision == "single"
    R = f"{name}_real"
    nx = len(law.arrays["X0"])
    nh = nx // 2
    S = len(law.arrays["SPINS"])
    kt = len(law.arrays["TFF"])
    fabs = "fabsf" if single else "fabs"
    body = (f"    {R} x_pred[{nx}];  /* prediction of the state (absolute coordinates) */\n"
            f"    {R} x_hat[{nx}];   /* estimate after the last measurement */\n"
            f"    {R} tau_prev;    /* torque held since the last sample [N m] */\n"
            f"    {R} spin;        /* scheduling variable of the last update [rad/s] */\n"
            f"    int has_tau;      /* 0 until the first step after reset */\n"
            f"    long k;           /* sample index */")
    arrays = dict(law.arrays)
    arrays["AD"] = np.asarray(arrays["AD"]).reshape(S, nx, nx)
    data = "".join(_array(k, law.arrays[k], R, single) for k in ("SPINS", "BD", "C", "GAINS", "X0", "XREF", "TFF"))
    data += _array3("AD", arrays["AD"], R, single)
    data += _array3("LK", np.asarray(law.arrays["LK"]).reshape(S, nx, 3), R, single)
    num = (lambda v: _number(v, single))
    code = f"""#define NX {nx}
#define NH {nh}
#define NS {S}
#define KT {kt}
static const {R} DT = {num(law.dt)};
static const {R} TAU_MAX = {num(law.tau_max)};
static const {R} FF = {num(law.feedforward)};
static const int MEASURED = {int(law.scalars["measured"])};

{_saturate(name)}
/* as DesignSchedule.locate: value = (1 - w) table[i] + w table[i + 1], clamped to the grid */
static void locate({R} spin, int *i, {R} *w)
{{
    int j;
    if (!(spin > SPINS[0])) {{ *i = 0; *w = 0; return; }}
    if (spin >= SPINS[NS - 1]) {{ *i = NS - 2; *w = 1; return; }}
    j = 0;
    while (SPINS[j + 1] <= spin) ++j;
    *i = j;
    *w = (spin - SPINS[j]) / (SPINS[j + 1] - SPINS[j]);
}}

void {name}_reset({name}_instance *inst)
{{
    int i;
    for (i = 0; i < NX; ++i) {{
        inst->x_pred[i] = X0[i];
        inst->x_hat[i] = X0[i];
    }}
    inst->tau_prev = 0;
    inst->spin = 0;
    inst->has_tau = 0;
    inst->k = 0;
}}

void {name}_step({name}_instance *inst, const double *measurements, const double *reference,
{' ' * (len(name) + 10)}double *command)
{{
    {R} y[3], innov[3], xr[NX];
    {R} tff, u, spin, w;
    int i, j, s;
    for (i = 0; i < 3; ++i) y[i] = ({R})measurements[i];
    if (reference) {{
        for (i = 0; i < NX; ++i) xr[i] = ({R})reference[i];
        tff = ({R})reference[NX];
    }} else if (inst->k < KT) {{
        for (i = 0; i < NX; ++i) xr[i] = XREF[inst->k][i];
        tff = TFF[inst->k];
    }} else {{  /* beyond the table: the final rate continues */
        for (i = 0; i < NX; ++i) xr[i] = XREF[KT - 1][i];
        xr[0] = XREF[KT - 1][0] + XREF[KT - 1][NH] * ({R})(inst->k - KT + 1) * DT;
        tff = TFF[KT - 1];
    }}
    spin = MEASURED ? {fabs}(y[1]) : {fabs}(xr[NH]);
    /* predict with the model at the last update's spin */
    if (inst->has_tau) {{
        locate(inst->spin, &s, &w);
        for (i = 0; i < NX; ++i) {{
            {R} acc = 0;
            for (j = 0; j < NX; ++j) {{
                {R} a = w == 0 ? AD[s][i][j] : (1 - w) * AD[s][i][j] + w * AD[s + 1][i][j];
                acc += a * inst->x_hat[j];
            }}
            inst->x_pred[i] = acc + (w == 0 ? BD[s][i] : (1 - w) * BD[s][i] + w * BD[s + 1][i]) * inst->tau_prev;
        }}
    }}
    inst->spin = spin;
    locate(spin, &s, &w);
    for (j = 0; j < 3; ++j) {{
        {R} acc = 0;
        for (i = 0; i < NX; ++i) acc += C[j][i] * inst->x_pred[i];
        innov[j] = y[j] - acc;
    }}
    for (i = 0; i < NX; ++i) {{
        {R} acc = 0;
        for (j = 0; j < 3; ++j) {{
            {R} l = w == 0 ? LK[s][i][j] : (1 - w) * LK[s][i][j] + w * LK[s + 1][i][j];
            acc += l * innov[j];
        }}
        inst->x_hat[i] = inst->x_pred[i] + acc;
    }}
    u = 0;
    for (i = 0; i < NX; ++i) {{
        {R} kk = w == 0 ? GAINS[s][i] : (1 - w) * GAINS[s][i] + w * GAINS[s + 1][i];
        u += kk * (inst->x_hat[i] - xr[i]);
    }}
    inst->tau_prev = saturate(FF * tff - u);
    inst->has_tau = 1;
    inst->k += 1;
    *command = (double)inst->tau_prev;
}}
"""
    header = _header(name, law, real, body, len(law.sensors))
    source = _source(name, precision, data, code)
    return header, source
