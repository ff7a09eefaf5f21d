"""The C templates of the PD, the observer law (LQR, LQG) and the torque table; :func:`render_c`.

The MPC and the gain-scheduled LQG are in :mod:`hubbeam_ctrl.deploy.render_mpc`; all share the
helpers of :mod:`hubbeam_ctrl.deploy.cfile`. A law with a DC drive's scalars gets the drive's
static inverse as a last stage (:class:`controllers.drive.VoltageCommand`).
"""

from __future__ import annotations

from hubbeam_ctrl.core.errors import HubbeamError

from .cfile import (
    PRECISIONS,
    _array,
    _filter_data,
    _filter_fields,
    _filter_reset,
    _filter_step,
    _header,
    _measurements,
    _number,
    _reference_row,
    _saturate,
    _source,
    _step_signature,
)
from .laws import ControlLaw
from .render_mpc import _render_mpc, _render_scheduled_lqg

__all__ = ["render_c"]

#: The drive's numbers a voltage-commanding law carries (controllers.drive.VoltageCommand).
_DRIVE_SCALARS = ("R", "N", "k_t", "k_e", "eta_forward", "eta_backward", "v_eps", "V_max")


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
    if law.scalars["k_e"]:
        inverse_doc = ("/* the DC drive's static inverse (controllers.drive.VoltageCommand): the voltage that gives "
                       "the hub\n   torque tau at the measured hub rate thd, through back-EMF and the gear's "
                       "efficiency, clipped */")
        emf_term = f' + {sc["k_e"]} * {sc["N"]} * thd'
    else:       # the design model carries the back-EMF (DesignModel.hub_damping): no compensation
        inverse_doc = ("/* the DC drive's voltage for the torque at rest tau (controllers.drive.VoltageCommand; the "
                       "design\n   model carries the back-EMF as hub damping), through the gear's efficiency, "
                       "clipped */")
        emf_term = ""
    stage = estimate + f"""
/* the gear's efficiency for the hub torque tau at the hub rate thd: eta_forward driving, 1 / eta_backward
   back-driven, switched smoothly over the friction's v_eps (sim.hardware) */
static {R} drive_efficiency({R} tau, {R} thd)
{{
    {R} x = -thd * (tau >= 0 ? 1 : -1) / {sc["v_eps"]};
    {R} th;
    x = x < 0 ? 0 : (x > 50 ? 50 : x);
    th = tanh(x);
    return {sc["eta_forward"]} + (1 / {sc["eta_backward"]} - {sc["eta_forward"]}) * th * th;
}}

{inverse_doc}
static {R} drive_voltage({R} tau, {R} thd)
{{
    {R} v = {sc["R"]} * tau / ({sc["N"]} * {sc["k_t"]} * drive_efficiency(tau, thd)){emf_term};
    return v > {sc["V_max"]} ? {sc["V_max"]} : (v < -{sc["V_max"]} ? -{sc["V_max"]} : v);
}}
"""
    if "inst->tau_prev" in source:
        stage += f"""
/* Hardware.clipped_torque: past +-V_max the filter predicts with the torque +-V_max gives (the law's
   tau needs more than the back-EMF leaves) */
static void clipped_torque({name}_instance *inst, {R} tau, {R} thd)
{{
    {R} e = drive_efficiency(tau, thd);
    {R} v = {sc["R"]} * tau / ({sc["N"]} * {sc["k_t"]} * e) + {sc["k_e"]} * {sc["N"]} * thd;
    if (v > {sc["V_max"]})
        inst->tau_prev = ({sc["V_max"]} - {sc["k_e"]} * {sc["N"]} * thd) * {sc["N"]} * {sc["k_t"]} * e / {sc["R"]};
    else if (v < -{sc["V_max"]})
        inst->tau_prev = (-{sc["V_max"]} - {sc["k_e"]} * {sc["N"]} * thd) * {sc["N"]} * {sc["k_t"]} * e / {sc["R"]};
}}
"""
    sat = _saturate(name)
    if sat not in source:
        raise HubbeamError("the voltage stage needs the template's saturate()")
    source = source.replace(sat, sat + stage, 1)
    filtered = "inst->tau_prev" in source
    for old in ("*command = (double)tau;", "*command = (double)saturate(tau);"):
        inner = old[len("*command = (double)"):-1]
        if not filtered:
            source = source.replace(old, f"*command = (double)drive_voltage({inner}, {rate});")
            continue
        # clipped at V_max: the filter predicts with the torque V_max gives at that rate (VoltageCommand)
        source = source.replace(old, f"""{{
        {R} thd = {rate};
        clipped_torque(inst, {inner}, thd);
        *command = (double)drive_voltage({inner}, thd);
    }}""")
    return header, source


def _render_law(law: ControlLaw, name: str, precision: str = "double") -> tuple:
    """``(header, source)`` of the law's own template, before any drive stage (see :func:`render_c`)."""
    if law.kind == "mpc":
        return _render_mpc(law, name, precision)
    if law.kind == "scheduled_lqg":
        return _render_scheduled_lqg(law, name, precision)
    real = PRECISIONS[precision]
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
        bref = "BREF" in law.arrays      # the prediction reads the reference angle (an LTI law on the error)
        body = _filter_fields(R, nx, extra=f"    {R} r_prev;      /* reference angle of the last sample [rad] */\n"
                              if bref else "")
        data = _filter_data(law, R, single, ("K", "X0", "XREF", "TFF", *(("BREF",) if bref else ())))
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
{_filter_reset()}{"    inst->r_prev = 0;" + chr(10) if bref else ""}}}

{_step_signature(name)}
{{
    {R} t = ({R})inst->k * DT;
    {R} yd[NY];
    {R} xr[NX];
    {R} tff, u, tau;
    int i, j;
{_measurements(law, R)}{_reference_row(R)}{_filter_step(law, R)}\
    /* gain on the tracking error (x_hat is a deviation, x_ref absolute) */
    u = 0;
    for (i = 0; i < NX; ++i) u += K[i] * (inst->x_hat[i] - xr[i]);
    u = u + K[0] * SPIN * t + K[NH] * SPIN;
    tau = saturate(FF * tff - u);
{"    inst->r_prev = xr[0];" + chr(10) if bref else ""}    inst->tau_prev = tau;
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

{_step_signature(name)}
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

{_step_signature(name)}
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
    source = _source(name, precision, data, code, law)
    return header, source
