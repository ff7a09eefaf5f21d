"""The C templates with a solver or a schedule: the observed MPC's QP and the gain-scheduled LQG.

Both are built from the helpers of :mod:`hubbeam_ctrl.deploy.cfile` (the filter's fields,
reset and update, the header, ``saturate``, the source file), as the observer template is.
"""

from __future__ import annotations

import numpy as np

from .cfile import (
    PRECISIONS,
    _array,
    _array3,
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
from .render_qp import qp_rows_parts

#: The box-only QP (no voltage rows): the instance's solver members, reset, solver and warm start.
_BOX_FIELDS = """    {R} z[{N}];       /* the plan (the QP's solution) */
    int st[{N}];      /* active set: 0 free, -1 at -tau_max, +1 at +tau_max */
    {R} g[{N}];       /* the QP's linear term */
    {R} M[{N}][{N}];  /* Cholesky factor of the free block of H */
    {R} v[{N}], zs[{N}];
    int fidx[{N}];
    int iterations;   /* active-set iterations of the last solve */
    long failures;    /* solves that hit the iteration limit (plan kept feasible) */"""
_BOX_RESET = """    for (i = 0; i < NZ; ++i) {
        inst->z[i] = 0;
        inst->st[i] = 0;
    }
    inst->iterations = 0;
    inst->failures = 0;
"""
_BOX_WARM = """    /* warm start: the previous active set and plan (kept feasible) */
    for (i = 0; i < NZ; ++i) {
        if (inst->st[i] < 0) inst->z[i] = -TAU_MAX;
        else if (inst->st[i] > 0) inst->z[i] = TAU_MAX;
        else if (inst->z[i] < -TAU_MAX) inst->z[i] = -TAU_MAX;
        else if (inst->z[i] > TAU_MAX) inst->z[i] = TAU_MAX;
    }
"""
_BOX_SOLVER = """/* min 1/2 z'Hz + g'z  s.t. -TAU_MAX <= z <= TAU_MAX: primal active set from a feasible start.
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

"""


def _sizes(law: ControlLaw, name: str, precision: str) -> tuple:
    """``(real, single, R, nx, nh)``: the C type, single precision or not, the real typedef's name,
    the filter's state count and half of it."""
    nx = len(law.arrays["X0"])
    return PRECISIONS[precision], precision == "single", f"{name}_real", nx, nx // 2


def _render_mpc(law: ControlLaw, name: str, precision: str) -> tuple:
    """Body of the MPC template: Kalman filter, then a primal active-set solve of the box QP, or with
    a DC motor's voltage rows (``law.arrays["AV"]``) of the QP with them (:mod:`.render_qp`)."""
    real, single, R, nx, nh = _sizes(law, name, precision)
    N = len(law.arrays["HL"])     # the QP's torques: the horizon, or a scenario tree's 1 + S (N - 1)
    kt = len(law.arrays["REFT"])
    sqrt = "sqrtf" if single else "sqrt"
    fabs = "fabsf" if single else "fabs"
    rows = qp_rows_parts(law, name, R, single) if "AV" in law.arrays else None
    body = _filter_fields(R, nx) + "\n" + (_BOX_FIELDS.format(R=R, N=N) if rows is None else rows["fields"])
    data = _filter_data(law, R, single, ("X0", "P", "GX", "H", "HL", "REFT", "R0", "R1") if rows is None
                        else ("X0", "P", "GX", "HL", "REFT", "R0", "R1"))   # the rows' solver reads H as L L'
    if rows is not None:
        data += rows["data"]
    nu = len(law.arrays["P"])
    kd = len(law.arrays["OFFSET"]) if "OFFSET" in law.arrays else 0
    num = (lambda v: _number(v, single))
    if rows is None:
        reset, solver = _BOX_RESET, _BOX_SOLVER.format(R=R, name=name, sqrt=sqrt, fabs=fabs)
        warm = _BOX_WARM
    else:
        reset, solver, warm = rows["reset"], rows["code"], rows["bounds"]
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
#define MAXIT ({4 if rows is None else 8} * NZ + 10)
static const {R} DT = {num(law.dt)};
static const {R} TAU_MAX = {num(law.tau_max)};
static const {R} SPIN = {num(law.scalars["spin"])};
static const {R} DELAY = {num(law.scalars["delay"])};
static const {R} LAM_TOL = {num(1e-5 if single else 1e-11)};

{_saturate(name)}
void {name}_reset({name}_instance *inst)
{{
    int i;
{_filter_reset()}{reset}}}

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

{solver}{_step_signature(name)}
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
{warm}    inst->iterations = qp_solve(inst);
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
    source = _source(name, precision, data, code, law)
    return header, source


def _render_scheduled_lqg(law: ControlLaw, name: str, precision: str) -> tuple:
    """The gain-scheduled LQG: every gain and model interpolated in the spin rate per sample.

    ``NX`` filter states (the beam alone's model, or on a rig the plain LQG's filter state
    ``[x, u_prev, f, b, d]``), ``NR`` reference states, ``NY`` measurements. On a rig
    (``GREF`` in the law) the law is ``K_z(Omega) z_hat - K(Omega) x_ref``; the measurement rows
    are interpolated too when they change with the spin (``CS``); without a rate sensor the
    measured spin is the prediction's hub rate."""
    real, single, R, nx, _ = _sizes(law, name, precision)
    S = len(law.arrays["SPINS"])
    kt = len(law.arrays["TFF"])
    nr = np.shape(law.arrays["XREF"])[1]
    ny = len(law.sensors)
    rig = "GREF" in law.arrays
    fabs = "fabsf" if single else "fabs"
    body = _filter_fields(R, nx, "absolute coordinates",
                          f"    {R} spin;        /* scheduling variable of the last update [rad/s] */\n")
    names = ("SPINS", "BD") + (() if "CS" in law.arrays else ("C",)) + ("GAINS", "X0", "XREF", "TFF") \
        + (("GREF",) if rig else ())
    data = "".join(_array(k, law.arrays[k], R, single) for k in names)
    data += _array3("AD", np.asarray(law.arrays["AD"]).reshape(S, nx, nx), R, single)
    data += _array3("LK", np.asarray(law.arrays["LK"]).reshape(S, nx, ny), R, single)
    if "CS" in law.arrays:
        data += _array3("CS", np.asarray(law.arrays["CS"]).reshape(S, ny, nx), R, single)
    num = (lambda v: _number(v, single))
    rate = int(law.scalars.get("rate_index", 1))
    measured = f"{fabs}(y[{rate}])" if rate >= 0 else f"{fabs}(inst->x_pred[NRH])"   # no rate sensor: the prediction's
    spin_const = f"static const {R} SPIN = {num(law.scalars['spin'])};\n" if "RATE" in law.arrays else ""
    c_row = ("w == 0 ? CS[s][j][i] : (1 - w) * CS[s][j][i] + w * CS[s + 1][j][i]" if "CS" in law.arrays
             else "C[j][i]")
    if rig:
        gain = """    /* the plain LQG's law where the command acts: K_z(spin) z_hat - K(spin) x_ref */
    u = 0;
    for (i = 0; i < NX; ++i) u += (w == 0 ? GAINS[s][i] : (1 - w) * GAINS[s][i] + w * GAINS[s + 1][i]) * inst->x_hat[i];
    for (i = 0; i < NR; ++i) u -= (w == 0 ? GREF[s][i] : (1 - w) * GREF[s][i] + w * GREF[s + 1][i]) * xr[i];
"""
    else:
        gain = f"""    u = 0;
    for (i = 0; i < NX; ++i) {{
        {R} kk = w == 0 ? GAINS[s][i] : (1 - w) * GAINS[s][i] + w * GAINS[s + 1][i];
        u += kk * (inst->x_hat[i] - xr[i]);
    }}
"""
    code = f"""#define NX {nx}
#define NR {nr}
#define NRH {nr // 2}
#define NY {ny}
#define NS {S}
#define KT {kt}
static const {R} DT = {num(law.dt)};
static const {R} TAU_MAX = {num(law.tau_max)};
static const {R} FF = {num(law.feedforward)};
static const int MEASURED = {int(law.scalars["measured"])};
{spin_const}
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
{_filter_reset()}    inst->spin = 0;
}}

{_step_signature(name)}
{{
    {R} y[NY], innov[NY], xr[NR];
    {R} tff, u, tau, spin, w;
    int i, j, s;
    for (i = 0; i < NY; ++i) y[i] = ({R})measurements[i];
{_reference_row(R, "NR", "NRH")}    /* predict with the model at the last update's spin */
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
    spin = MEASURED ? {measured} : {fabs}(xr[NRH]);
    inst->spin = spin;
    locate(spin, &s, &w);
    for (j = 0; j < NY; ++j) {{
        {R} acc = 0;
        for (i = 0; i < NX; ++i) acc += ({c_row}) * inst->x_pred[i];
        innov[j] = y[j] - acc;
    }}
    for (i = 0; i < NX; ++i) {{
        {R} acc = 0;
        for (j = 0; j < NY; ++j) {{
            {R} l = w == 0 ? LK[s][i][j] : (1 - w) * LK[s][i][j] + w * LK[s + 1][i][j];
            acc += l * innov[j];
        }}
        inst->x_hat[i] = inst->x_pred[i] + acc;
    }}
{gain}    tau = saturate(FF * tff - u);
    inst->tau_prev = tau;
    inst->has_tau = 1;
    inst->k += 1;
    *command = (double)tau;
}}
"""
    header = _header(name, law, real, body, len(law.sensors))
    source = _source(name, precision, data, code, law)
    return header, source
