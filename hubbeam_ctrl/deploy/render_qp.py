"""The generated MPC's QP with general rows: a DC motor's voltage limit through back-EMF.

The Python MPC on a DC motor (:attr:`controllers.MPCSettings.emf_torque_limit`) keeps the plan's
torques within ``+-tau_max`` and, at every step of the horizon, ``|u_i + b theta_dot_i| <= g V_max``:
``N`` more rows ``lo <= AV z <= hi`` whose bounds move with the state (``hi = LIM - OFFX x``,
``lo = -LIM - OFFX x``; :func:`hubbeam_ctrl.deploy.laws.control_law` carries them). The C here
solves that QP by a primal active set over the ``2 N`` constraints (the bounds ``e_i`` and the
rows), exact at convergence, from a feasible start, so that when the iteration limit hits the
plan kept is feasible (the failure is counted, as the box template counts its own):

* each iteration solves the equality-constrained QP of the working set ``W`` in range space,
  ``z = -L^-T (w + V nu)``, ``(V'V) nu = -(b_W + V'w)``, with ``H = L L'``, ``w = L^-1 g`` and
  ``V`` the working set's columns of ``CM = L^-1 C'``; ``V'V`` is the working set's block of their
  constant Gram matrix ``GM``, whose Cholesky factor the instance keeps (a constraint added: one
  row; one dropped: the rows after it), valid from one sample to the next since ``GM`` is constant;
* the longest feasible step toward that minimiser adds the first constraint it meets (a step that
  moves it by more than the tolerance: its row is then independent of ``W``'s, whose values the
  step leaves unchanged); at the minimiser the working constraint with the most negative
  multiplier is dropped; none: the plan is optimal;
* the start: the previous working set's minimiser when it is feasible (a slew keeps its active
  set for many samples: one iteration), else the previous plan moved into the feasible set row by
  row (the rows are lower triangular with a positive diagonal: the voltage at step ``i`` depends
  on the torques before it and ``u_i``) with the previous working constraints it holds at their
  bounds. No feasible plan exists when the rate is beyond what the voltage can brake: the plan is
  then kept within the torque limit and the solve counted as failed (the Python MPC falls back to
  its LQR torque there).

The QP is strictly convex, so its minimiser is unique: DAQP, the Python MPC's solver, finds the
same one (to the solvers' tolerances).
"""

from __future__ import annotations

from hubbeam_ctrl.core.errors import ParameterError

from .cfile import _array, _number


def qp_rows_parts(law, name: str, R: str, single: bool) -> dict:
    """Pieces of the MPC template for a law with voltage rows (``law.arrays["AV"]``).

    Parameters
    ----------
    law : ControlLaw
        An MPC's law with the arrays ``AV``, ``OFFX``, ``LIM``, ``CM``, ``GM``.
    name : str
        The C identifier prefix.
    R : str
        The name of the real typedef.
    single : bool
        Single precision: refused (see Raises).

    Returns
    -------
    dict
        ``fields`` (the instance struct's members), ``data`` (the arrays), ``code`` (the solver,
        C functions), ``reset`` (statements of ``<name>_reset``), ``bounds`` (statements of the step
        that set the rows' bounds from the MPC's state ``xa``).

    Raises
    ------
    ParameterError
        For ``single``: in ``float`` the working set's pivots of nearly parallel constraints (a
        torque bound and its step's voltage row) drown in rounding (measured on a 20-step plan with
        random states: 18 of 400 solves failed, commands up to 2 tau_max off DAQP's).
    """
    if single:
        raise ParameterError("precision: 'single' does not apply to an MPC with a DC motor's voltage limit "
                             "(emf_torque_limit): its QP's active set needs double; use 'double'")
    N = len(law.arrays["LIM"])
    sqrt, fabs = "sqrt", "fabs"
    num = (lambda v: _number(v, False))
    fields = (f"    {R} z[{N}];       /* the plan (the QP's solution) */\n"
              f"    {R} zs[{N}];      /* the working set's minimiser */\n"
              f"    {R} g[{N}];       /* the QP's linear term */\n"
              f"    {R} w[{N}];       /* L^-1 g */\n"
              f"    {R} u[{N}];\n"
              f"    {R} lo[{N}], hi[{N}];  /* bounds of the voltage rows */\n"
              f"    {R} F[{N}][{N}];  /* Cholesky factor of the working set's block of GM */\n"
              f"    {R} nu[{N}], rhs[{N}];\n"
              f"    int wc[{N}];      /* working set: constraint index (0..NZ-1 torque bounds, NZ.. rows) */\n"
              f"    int ws[{N}];      /* and side: -1 lower, +1 upper */\n"
              f"    int inws[{2 * N}];    /* 1 when the constraint is in the working set */\n"
              f"    int nw;           /* size of the working set */\n"
              f"    int iterations;   /* active-set iterations of the last solve */\n"
              f"    long failures;    /* solves that hit the iteration limit or found no feasible plan */")
    data = "".join(_array(k, law.arrays[k], R, False) for k in ("AV", "OFFX", "LIM", "CM", "GM"))
    hmax = max(float(law.arrays["H"][i][i]) for i in range(N))
    code = f"""#define NC (2 * NZ)
static const {R} FEAS_TOL = {num(1e-10)};  /* x TAU_MAX */
static const {R} PIV_TOL = {num(1e-12)};
static const {R} HMAX = {num(hmax)};

/* the value of constraint c at z: z[c] (a torque bound) or AV[c - NZ] z (a voltage row) */
static {R} con_value(int c, const {R} *z)
{{
    {R} s = 0;
    int k;
    if (c < NZ) return z[c];
    c -= NZ;
    for (k = 0; k <= c; ++k) s += AV[c][k] * z[k];
    return s;
}}

static {R} con_lo(const {name}_instance *inst, int c)
{{
    return c < NZ ? -TAU_MAX : inst->lo[c - NZ];
}}

static {R} con_hi(const {name}_instance *inst, int c)
{{
    return c < NZ ? TAU_MAX : inst->hi[c - NZ];
}}

/* the plan moved into the feasible set row by row (AV lower triangular, positive diagonal);
 * -1 when a row admits no torque within the limit (the plan is then kept within the limit) */
static int feasible_start({name}_instance *inst)
{{
    int i, k, ok = 0;
    for (i = 0; i < NZ; ++i) {{
        {R} s = 0, a, b;
        for (k = 0; k < i; ++k) s += AV[i][k] * inst->z[k];
        a = (inst->lo[i] - s) / AV[i][i];
        b = (inst->hi[i] - s) / AV[i][i];
        if (a < -TAU_MAX) a = -TAU_MAX;
        if (b > TAU_MAX) b = TAU_MAX;
        if (a > b) {{
            ok = -1;
            a = -TAU_MAX;
            b = TAU_MAX;
        }}
        if (inst->z[i] < a) inst->z[i] = a;
        else if (inst->z[i] > b) inst->z[i] = b;
    }}
    return ok;
}}

/* row a of F, the Cholesky factor of the working set's block of GM, from the rows before it;
 * -1 when constraint wc[a] is (numerically) dependent on those before it */
static int factor_row({name}_instance *inst, int a)
{{
    int b, c, j = inst->wc[a];
    {R} s;
    for (b = 0; b < a; ++b) {{
        s = GM[j][inst->wc[b]];
        for (c = 0; c < b; ++c) s -= inst->F[a][c] * inst->F[b][c];
        inst->F[a][b] = s / inst->F[b][b];
    }}
    s = GM[j][j];
    for (c = 0; c < a; ++c) s -= inst->F[a][c] * inst->F[a][c];
    if (!(s > PIV_TOL * GM[j][j])) return -1;
    inst->F[a][a] = {sqrt}(s);
    return 0;
}}

/* constraint c at its side (-1 lower, +1 upper) into the working set; -1 (not added) when dependent */
static int ws_add({name}_instance *inst, int c, int side)
{{
    int m = inst->nw;
    if (m == NZ) return -1;
    inst->wc[m] = c;
    inst->ws[m] = side;
    if (factor_row(inst, m) < 0) return -1;
    inst->nw = m + 1;
    inst->inws[c] = 1;
    return 0;
}}

/* entry a out of the working set; the factor's rows after it recomputed (a subset of independent
 * rows stays independent, and its pivots only grow) */
static void ws_drop({name}_instance *inst, int a)
{{
    int b;
    inst->inws[inst->wc[a]] = 0;
    for (b = a; b + 1 < inst->nw; ++b) {{
        inst->wc[b] = inst->wc[b + 1];
        inst->ws[b] = inst->ws[b + 1];
    }}
    inst->nw -= 1;
    for (b = a; b < inst->nw; ++b) (void)factor_row(inst, b);
}}

/* the working set's minimiser zs and multipliers nu (range space, F kept factored) */
static void eqp({name}_instance *inst)
{{
    int a, c, i, m = inst->nw;
    for (a = 0; a < m; ++a) {{
        int j = inst->wc[a];
        {R} s = inst->ws[a] > 0 ? con_hi(inst, j) : con_lo(inst, j);
        for (i = 0; i < NZ; ++i) s += CM[j][i] * inst->w[i];
        inst->rhs[a] = -s;
    }}
    chol_solve((const {R} (*)[NZ])inst->F, m, inst->rhs, inst->nu);
    for (i = 0; i < NZ; ++i) inst->u[i] = inst->w[i];
    for (a = 0; a < m; ++a)
        for (i = 0; i < NZ; ++i) inst->u[i] += inst->nu[a] * CM[inst->wc[a]][i];
    for (a = NZ - 1; a >= 0; --a) {{
        {R} s = -inst->u[a];
        for (c = a + 1; c < NZ; ++c) s -= HL[c][a] * inst->zs[c];
        inst->zs[a] = s / HL[a][a];
    }}
}}

/* the start: the previous working set's minimiser when it is feasible (1), else the previous plan
 * moved into the feasible set with the previous working constraints it holds at their bounds (0);
 * -1 when no plan is feasible (the working set emptied) */
static int warm_start({name}_instance *inst, {R} tol)
{{
    int a, c, m = inst->nw, oc[NZ], os[NZ];
    if (m > 0) {{
        eqp(inst);
        for (c = 0; c < NC; ++c) {{
            {R} v;
            if (inst->inws[c]) continue;
            v = con_value(c, inst->zs);
            if (v > con_hi(inst, c) + tol || v < con_lo(inst, c) - tol) break;
        }}
        if (c == NC) {{
            for (c = 0; c < NZ; ++c) inst->z[c] = inst->zs[c];
            return 1;
        }}
    }}
    for (a = 0; a < m; ++a) {{
        oc[a] = inst->wc[a];
        os[a] = inst->ws[a];
        inst->inws[oc[a]] = 0;
    }}
    inst->nw = 0;
    if (feasible_start(inst) < 0) return -1;
    for (a = 0; a < m; ++a) {{
        {R} bound = os[a] > 0 ? con_hi(inst, oc[a]) : con_lo(inst, oc[a]);
        if ({fabs}(con_value(oc[a], inst->z) - bound) <= tol) (void)ws_add(inst, oc[a], os[a]);
    }}
    return 0;
}}

/* min 1/2 z'Hz + g'z  s.t. -TAU_MAX <= z <= TAU_MAX, lo <= AV z <= hi: primal active set from a
 * feasible start (see hubbeam_ctrl.deploy.render_qp) */
static int qp_solve({name}_instance *inst)
{{
    int it, a, c, i, blk, side, worst_a, have;
    {R} alpha, worst, gmax = 0, tol = FEAS_TOL * TAU_MAX;
    for (a = 0; a < NZ; ++a) {{
        {R} s = inst->g[a];
        for (c = 0; c < a; ++c) s -= HL[a][c] * inst->w[c];
        inst->w[a] = s / HL[a][a];
        if ({fabs}(inst->g[a]) > gmax) gmax = {fabs}(inst->g[a]);
    }}
    have = warm_start(inst, tol);
    if (have < 0) return -1;
    for (it = 0; it < MAXIT; ++it) {{
        if (!have) eqp(inst);
        have = 0;
        /* longest step toward the working set's minimiser that stays feasible */
        alpha = 1;
        blk = -1;
        side = 0;
        for (c = 0; c < NC; ++c) {{
            {R} v, vs, r;
            if (inst->inws[c]) continue;
            v = con_value(c, inst->z);
            vs = con_value(c, inst->zs);
            if (vs > con_hi(inst, c) + tol && vs - v > tol) {{
                r = (con_hi(inst, c) - v) / (vs - v);
                if (r < 0) r = 0;
                if (r < alpha) {{ alpha = r; blk = c; side = 1; }}
            }} else if (vs < con_lo(inst, c) - tol && v - vs > tol) {{
                r = (con_lo(inst, c) - v) / (vs - v);
                if (r < 0) r = 0;
                if (r < alpha) {{ alpha = r; blk = c; side = -1; }}
            }}
        }}
        if (blk >= 0) {{
            for (i = 0; i < NZ; ++i) inst->z[i] += alpha * (inst->zs[i] - inst->z[i]);
            if (blk < NZ) inst->z[blk] = side < 0 ? -TAU_MAX : TAU_MAX;
            if (ws_add(inst, blk, side) < 0) return -1;
            continue;
        }}
        for (i = 0; i < NZ; ++i) inst->z[i] = inst->zs[i];
        /* multipliers of the working set: nu >= 0 at an upper bound, <= 0 at a lower one */
        worst = -LAM_TOL * (gmax + HMAX * TAU_MAX);
        worst_a = -1;
        for (a = 0; a < inst->nw; ++a) {{
            {R} lam = inst->ws[a] * inst->nu[a];
            if (lam < worst) {{
                worst = lam;
                worst_a = a;
            }}
        }}
        if (worst_a < 0) return it + 1;
        ws_drop(inst, worst_a);
    }}
    return -1;
}}
"""
    reset = """    for (i = 0; i < NZ; ++i) inst->z[i] = 0;
    for (i = 0; i < 2 * NZ; ++i) inst->inws[i] = 0;
    inst->nw = 0;
    inst->iterations = 0;
    inst->failures = 0;
"""
    bounds = f"""    /* the voltage rows' bounds at this state: lo = -LIM - OFFX x, hi = LIM - OFFX x */
    for (i = 0; i < NZ; ++i) {{
        {R} s = 0;
        for (j = 0; j < NU; ++j) s += OFFX[i][j] * xa[j];
        inst->lo[i] = -LIM[i] - s;
        inst->hi[i] = LIM[i] - s;
    }}
"""
    return {"fields": fields, "data": data, "code": code, "reset": reset, "bounds": bounds}
