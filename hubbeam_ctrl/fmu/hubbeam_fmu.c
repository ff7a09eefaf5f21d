/*
 * hubbeam-ctrl: the nonlinear hub-beam plant as an FMI 2.0 co-simulation FMU.
 *
 * The model-independent part, written once: the FMI 2.0 functions and the closed loop's
 * fixed-step generalized-alpha sample (hubbeam_ctrl.sim.stepper.PlantStepper) in C:
 * modified Newton with the inverse iteration matrix, refreshed when the iterations converge
 * slowly; a sample whose last Newton correction is not small enough is recomputed by full
 * Newton iterations with the exact Jacobian; with friction, Karnopp sticking of the hub.
 * The equations of the plant are CasADi's generated C (hb_hot.c, hb_cold.c); the sizes,
 * start values and value references are in hubbeam_model.h, generated with them.
 * C99, no I/O besides the FMI logger, memory from the FMI callbacks.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <stdio.h>

#include "fmi2Functions.h"
#include "hb_hot.h"
#include "hb_cold.h"
#include "hubbeam_model.h"

#define N HB_NQ
#define NS (4 * HB_NQ)

/* kinds of value references (VR_KIND in hubbeam_model.h) */
enum { K_U = 0, K_Y, K_Q, K_V, K_P, K_HW, K_X0, K_MISC, K_STUCK, K_CONST, K_ENC };
/* K_MISC entries */
enum { M_STICK_VELOCITY = 0, M_ANGLE_BIAS, M_RATE_BIAS, M_STRAIN_BIAS, M_COUNT };
/* instance modes */
enum { S_INSTANTIATED = 0, S_INIT, S_STEP, S_TERMINATED, S_ERROR };

typedef struct {
    fmi2CallbackFunctions cb;
    char name[128];
    int logging;
    int mode;
    double t;
    double u;                      /* command: torque [N m] or voltage [V] */
    double p[HB_NP > 0 ? HB_NP : 1];
    double hw[HB_NHW];
    double x0[2 * N];
    double misc[M_COUNT];
    int encoder_counts;
    /* integrator */
    int started, J_valid, stuck;
    double s_in[NS], s_out[NS], slip[NS];
    double tau[HB_K], tau0, err, hold;
    double J[N * N], Jinv[N * N], lu[N * N];
    int piv[N];
    long fallbacks, jacobian_updates, stick_events;
    double y[HB_NY];
    int y_valid;
    /* CasADi work arrays */
    const casadi_real *arg[HB_SZ_ARG];
    casadi_real *res[HB_SZ_RES];
    casadi_int iw[HB_SZ_IW];
    casadi_real w[HB_SZ_W];
    /* robust Newton */
    double a[N], r[N], Jr[N * N], da[N], a_try[N], r_try[N];
} Inst;

static void logmsg(Inst *m, fmi2Status status, const char *category, const char *text)
{
    if (m->cb.logger && (m->logging || status != fmi2OK))
        m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", text);
}

/* ---- linear algebra: LU with partial pivoting (the role of numpy.linalg) ---------------- */
static int lu_factor(double *A, int *piv, int n)        /* column-major, in place; 0: singular */
{
    for (int k = 0; k < n; ++k) {
        int p = k;
        double big = fabs(A[k + k * n]);
        for (int i = k + 1; i < n; ++i)
            if (fabs(A[i + k * n]) > big) { big = fabs(A[i + k * n]); p = i; }
        piv[k] = p;
        if (!(big > 0.0)) return 0;
        if (p != k)
            for (int j = 0; j < n; ++j) { double t = A[k + j * n]; A[k + j * n] = A[p + j * n]; A[p + j * n] = t; }
        for (int i = k + 1; i < n; ++i) {
            double f = A[i + k * n] / A[k + k * n];
            A[i + k * n] = f;
            for (int j = k + 1; j < n; ++j) A[i + j * n] -= f * A[k + j * n];
        }
    }
    return 1;
}

static void lu_solve(const double *A, const int *piv, int n, double *b)
{
    for (int k = 0; k < n; ++k) { int p = piv[k]; if (p != k) { double t = b[k]; b[k] = b[p]; b[p] = t; } }
    for (int i = 1; i < n; ++i) for (int j = 0; j < i; ++j) b[i] -= A[i + j * n] * b[j];
    for (int i = n - 1; i >= 0; --i) {
        for (int j = i + 1; j < n; ++j) b[i] -= A[i + j * n] * b[j];
        b[i] /= A[i + i * n];
    }
}

static double norm_inf(const double *x, int n)
{
    double m = 0.0;
    for (int i = 0; i < n; ++i) { double a = fabs(x[i]); if (!(a <= m)) m = a; }   /* NaN propagates */
    return m;
}

/* ---- calls of the generated functions ---------------------------------------------------- */
static const double *hw_arg(Inst *m) { return HB_HARDWARE ? m->hw : NULL; }

static int call_jac(Inst *m, const double *s, double tau, double *J)
{
    m->arg[0] = s; m->arg[1] = &tau; m->arg[2] = m->p; m->arg[3] = hw_arg(m);
    m->res[0] = J;
    return hb_jac(m->arg, m->res, m->iw, m->w, 0);
}

static int call_step(Inst *m)
{
    m->arg[0] = m->s_in; m->arg[1] = m->tau; m->arg[2] = m->Jinv; m->arg[3] = m->p; m->arg[4] = hw_arg(m);
    m->res[0] = m->s_out; m->res[1] = &m->err;
    return hb_step(m->arg, m->res, m->iw, m->w, 0);
}

static int call_res(Inst *m, const double *a, const double *s, double tau, double *r, double *J)
{
    m->arg[0] = a; m->arg[1] = s; m->arg[2] = &tau; m->arg[3] = m->p; m->arg[4] = hw_arg(m);
    m->res[0] = r; m->res[1] = J;
    return hb_res(m->arg, m->res, m->iw, m->w, 0);
}

static int call_upd(Inst *m, const double *a, const double *s, double *out)
{
    m->arg[0] = a; m->arg[1] = s;
    m->res[0] = out;
    return hb_upd(m->arg, m->res, m->iw, m->w, 0);
}

static int call_mc(Inst *m, const double *q, const double *v, double *M, double *c)
{
    m->arg[0] = q; m->arg[1] = v; m->arg[2] = m->p;
    m->res[0] = M; m->res[1] = c;
    return hb_mc(m->arg, m->res, m->iw, m->w, 0);
}

static int call_out(Inst *m, const double *x, double *y)
{
    m->arg[0] = x; m->arg[1] = m->p;
    m->res[0] = y;
    return hb_out(m->arg, m->res, m->iw, m->w, 0);
}

#if HB_HARDWARE
static double call_hold(Inst *m, const double *s, double tau)
{
    double hold = NAN;
    m->arg[0] = s; m->arg[1] = &tau; m->arg[2] = m->p; m->arg[3] = m->hw;
    m->res[0] = &hold;
    if (hb_hold(m->arg, m->res, m->iw, m->w, 0)) return NAN;
    return hold;
}

static void call_hub(Inst *m, double u, double thd, double *drive, double *hub)
{
    m->arg[0] = &u; m->arg[1] = &thd; m->arg[2] = m->hw;
    m->res[0] = drive; m->res[1] = hub;
    if (hb_hub(m->arg, m->res, m->iw, m->w, 0)) { *drive = NAN; *hub = NAN; }
}
#endif

/* ---- the plant step (PlantStepper) --------------------------------------------------------- */
static void refresh(Inst *m)
{
    m->tau0 = m->tau[0];
    int ok = call_jac(m, m->s_in, m->tau0, m->J) == 0;
    if (ok) {
        memcpy(m->lu, m->J, sizeof m->J);
        ok = lu_factor(m->lu, m->piv, N);
    }
    if (ok) {
        for (int j = 0; j < N; ++j) {
            double *col = m->Jinv + j * N;
            for (int i = 0; i < N; ++i) col[i] = i == j ? 1.0 : 0.0;
            lu_solve(m->lu, m->piv, N, col);
        }
    } else {                       /* singular: the fast step fails, the full Newton takes over */
        for (int i = 0; i < N * N; ++i) m->Jinv[i] = NAN;
    }
    m->J_valid = 1;
    m->jacobian_updates++;
}

/* Newton on each substep with the exact Jacobian (CasADi's rootfinder('newton') in Python:
   abstol 1e-9 on the residual, 1e-13 on the step, 50 iterations, a line search with the hardware) */
static int robust_step(Inst *m)
{
    double s[NS];
    memcpy(s, m->s_in, sizeof s);
    m->fallbacks++;
    for (int k = 0; k < HB_K; ++k) {
        double tau = m->tau[k];
        memcpy(m->a, s + 2 * N, sizeof m->a);
        int converged = 0;
        for (int it = 0; it < 50; ++it) {
            if (call_res(m, m->a, s, tau, m->r, m->Jr)) return 0;
            double rn = norm_inf(m->r, N);
            if (rn <= 1e-9) { converged = 1; break; }
            if (!lu_factor(m->Jr, m->piv, N)) return 0;
            memcpy(m->da, m->r, sizeof m->da);
            lu_solve(m->Jr, m->piv, N, m->da);
            double step = 1.0;
            if (HB_HARDWARE) {     /* backtracking on the residual's norm */
                for (int ls = 0; ls < 30; ++ls) {
                    for (int i = 0; i < N; ++i) m->a_try[i] = m->a[i] - step * m->da[i];
                    if (call_res(m, m->a_try, s, tau, m->r_try, m->Jr)) return 0;
                    if (norm_inf(m->r_try, N) < rn) break;
                    step *= 0.5;
                }
            }
            for (int i = 0; i < N; ++i) m->a[i] -= step * m->da[i];
            if (norm_inf(m->da, N) * step <= 1e-13) { converged = 1; break; }
        }
        if (!converged) return 0;
        double next[NS];
        if (call_upd(m, m->a, s, next)) return 0;
        memcpy(s, next, sizeof s);
    }
    for (int i = 0; i < NS; ++i) if (!isfinite(s[i])) return 0;
    memcpy(m->s_out, s, sizeof s);
    return 1;
}

static int advance_one(Inst *m)      /* one sample into s_out; 0: failed */
{
    const double tol = HB_NEWTON_TOL;
    int fresh = !m->J_valid;
    if (fresh) refresh(m);
    if (call_step(m)) return 0;
    double err = m->err;
    if (!(err <= tol) && !fresh) {
        refresh(m);
        if (call_step(m)) return 0;
        err = m->err;
    }
    if (err <= tol) {
        if (err > 0.1 * tol) m->J_valid = 0;
        return 1;
    }
    return robust_step(m);
}

#if HB_HARDWARE
static void set_stick(Inst *m, int stick)
{
    double v = stick ? 1.0 : 0.0;
    if (m->hw[HB_NHW - 1] != v) {
        m->hw[HB_NHW - 1] = v;
        m->J_valid = 0;
    }
}

static int holds(Inst *m, const double *out)
{
    m->hold = call_hold(m, out, m->tau[HB_K - 1]);
    return fabs(m->hold) <= m->hw[HB_HW_STATIC];
}
#endif

static int advance(Inst *m)
{
#if HB_HARDWARE
    double F_s = m->hw[HB_HW_STATIC], v_stick = m->misc[M_STICK_VELOCITY];
    if (F_s == 0.0) return advance_one(m);
    if (m->stuck) {
        set_stick(m, 1);
        if (!advance_one(m)) return 0;
        if (holds(m, m->s_out)) return 1;
        m->stuck = 0;
    }
    set_stick(m, 0);
    if (!advance_one(m)) return 0;
    double thd0 = m->s_in[N], thd1 = m->s_out[N];
    if ((fabs(thd1) <= v_stick && (fabs(thd1) < fabs(thd0) || thd0 == 0.0)) || thd0 * thd1 < 0) {
        memcpy(m->slip, m->s_out, sizeof m->slip);
        set_stick(m, 1);
        if (!advance_one(m)) return 0;
        if (holds(m, m->s_out)) {
            m->stuck = 1;
            m->stick_events++;
            return 1;
        }
        set_stick(m, 0);
        memcpy(m->s_out, m->slip, sizeof m->slip);
    }
    return 1;
#else
    return advance_one(m);
#endif
}

/* the integrator state from x0 = [q, v] and the command at the start (PlantStepper.initial_state) */
static int initial_state(Inst *m)
{
    double M[N * N], c[N], a[N];
    const double *q = m->x0, *v = m->x0 + N;
    memcpy(m->s_in, m->x0, 2 * N * sizeof(double));
    if (call_mc(m, q, v, M, c)) return 0;
    double force = m->u;
#if HB_HARDWARE
    double F_s = m->hw[HB_HW_STATIC], drive, hub;
    m->stuck = 0;
    if (F_s > 0 && fabs(v[0]) <= m->misc[M_STICK_VELOCITY]) {
        /* the hub clamped: M[1:,1:] a[1:] = -c[1:] */
        double Mr[(N - 1) * (N - 1) + 1];
        int piv[N];
        for (int j = 1; j < N; ++j) for (int i = 1; i < N; ++i) Mr[(i - 1) + (j - 1) * (N - 1)] = M[i + j * N];
        a[0] = 0.0;
        for (int i = 1; i < N; ++i) a[i] = -c[i];
        if (N > 1) {
            if (!lu_factor(Mr, piv, N - 1)) return 0;
            lu_solve(Mr, piv, N - 1, a + 1);
        }
        call_hub(m, m->u, 0.0, &drive, &hub);
        double hold = drive - c[0];
        for (int j = 0; j < N; ++j) hold -= M[j * N] * a[j];
        if (fabs(hold) <= F_s) {
            m->stuck = 1;
            m->hold = hold;
            m->s_in[N] = 0.0;
            memcpy(m->s_in + 2 * N, a, sizeof a);
            memcpy(m->s_in + 3 * N, a, sizeof a);
            return 1;
        }
    }
    call_hub(m, m->u, v[0], &drive, &hub);
    force = hub;
#endif
    for (int i = 0; i < N; ++i) a[i] = -c[i];
    a[0] += force;
    if (!lu_factor(M, m->piv, N)) return 0;
    lu_solve(M, m->piv, N, a);
    memcpy(m->s_in + 2 * N, a, sizeof a);
    memcpy(m->s_in + 3 * N, a, sizeof a);
    for (int i = 0; i < NS; ++i) if (!isfinite(m->s_in[i])) return 0;
    return 1;
}

/* ---- outputs --------------------------------------------------------------------------------- */
static const double *state_x(Inst *m) { return m->started ? m->s_in : m->x0; }

static int update_outputs(Inst *m)
{
    if (m->y_valid) return 1;
    if (call_out(m, state_x(m), m->y)) return 0;
    /* sensors: bias, then the encoder's nearest count */
    m->y[HB_Y_THETA] += m->misc[M_ANGLE_BIAS];
    if (m->encoder_counts > 0) {
        double step = 2.0 * 3.14159265358979323846 / m->encoder_counts;
        m->y[HB_Y_THETA] = step * floor(m->y[HB_Y_THETA] / step + 0.5);
    }
    m->y[HB_Y_THETA_DOT] += m->misc[M_RATE_BIAS];
    for (int k = HB_Y_MOMENT0; k < HB_Y_MOMENT0 + HB_N_MOMENTS; ++k) m->y[k] += m->misc[M_STRAIN_BIAS];
    m->y_valid = 1;
    return 1;
}

static void set_defaults(Inst *m)
{
    for (int i = 0; i < HB_NP; ++i) m->p[i] = HB_P_START[i];
    for (int i = 0; i < HB_NHW; ++i) m->hw[i] = HB_HW_START[i];
    for (int i = 0; i < 2 * N; ++i) m->x0[i] = 0.0;
    for (int i = 0; i < M_COUNT; ++i) m->misc[i] = HB_MISC_START[i];
    m->encoder_counts = HB_ENCODER_COUNTS;
    m->u = 0.0;
    m->t = 0.0;
    m->started = 0;
    m->J_valid = 0;
    m->stuck = 0;
    m->hold = 0.0;
    m->fallbacks = m->jacobian_updates = m->stick_events = 0;
    m->y_valid = 0;
    m->mode = S_INSTANTIATED;
}

/* ---- FMI 2.0 ----------------------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    ((Inst *)c)->logging = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation; (void)visible;
    if (!functions || !functions->allocateMemory) return NULL;
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "error",
                              "this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, HB_GUID) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "error",
                              "GUID %s does not match this FMU's %s", fmuGUID ? fmuGUID : "(null)", HB_GUID);
        return NULL;
    }
    Inst *m = (Inst *)functions->allocateMemory(1, sizeof(Inst));
    if (!m) return NULL;
    memset(m, 0, sizeof *m);
    m->cb = *functions;
    snprintf(m->name, sizeof m->name, "%s", instanceName ? instanceName : "hubbeam");
    m->logging = loggingOn;
    set_defaults(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c)
{
    Inst *m = (Inst *)c;
    if (m) m->cb.freeMemory(m);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Inst *)c)->t = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    ((Inst *)c)->mode = S_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Inst *m = (Inst *)c;
    for (int i = 0; i < 2 * N; ++i)
        if (!isfinite(m->x0[i])) { logmsg(m, fmi2Error, "error", "the initial state must be finite"); return fmi2Error; }
    m->mode = S_STEP;
    m->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { ((Inst *)c)->mode = S_TERMINATED; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) { set_defaults((Inst *)c); return fmi2OK; }

static int settable(Inst *m, int kind)
{
    if (kind == K_U) return 1;
    if (kind == K_P || kind == K_HW || kind == K_X0 || kind == K_MISC || kind == K_ENC)
        return m->mode == S_INSTANTIATED || m->mode == S_INIT;
    return 0;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Inst *m = (Inst *)c;
    for (size_t k = 0; k < nvr; ++k) {
        if (vr[k] >= HB_NVR) { logmsg(m, fmi2Error, "error", "unknown value reference"); return fmi2Error; }
        int idx = HB_VR_INDEX[vr[k]];
        switch (HB_VR_KIND[vr[k]]) {
        case K_U: value[k] = m->u; break;
        case K_Y:
            if (!update_outputs(m)) { logmsg(m, fmi2Error, "error", "outputs could not be evaluated"); return fmi2Error; }
            value[k] = m->y[idx];
            break;
        case K_Q: value[k] = state_x(m)[idx]; break;
        case K_V: value[k] = state_x(m)[N + idx]; break;
        case K_P: value[k] = m->p[idx]; break;
        case K_HW: value[k] = m->hw[idx]; break;
        case K_X0: value[k] = m->x0[idx]; break;
        case K_MISC: value[k] = m->misc[idx]; break;
        case K_STUCK: value[k] = m->stuck ? 1.0 : 0.0; break;
        case K_CONST: value[k] = HB_CONST[idx]; break;
        default: logmsg(m, fmi2Error, "error", "not a Real variable"); return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Inst *m = (Inst *)c;
    for (size_t k = 0; k < nvr; ++k) {
        if (vr[k] >= HB_NVR) { logmsg(m, fmi2Error, "error", "unknown value reference"); return fmi2Error; }
        int kind = HB_VR_KIND[vr[k]], idx = HB_VR_INDEX[vr[k]];
        if (kind == K_ENC || !settable(m, kind)) {
            logmsg(m, fmi2Error, "error", "variable cannot be set now (fixed parameters only before initialization)");
            return fmi2Error;
        }
        switch (kind) {
        case K_U: m->u = value[k]; break;
        case K_P: m->p[idx] = value[k]; break;
        case K_HW: m->hw[idx] = value[k]; break;
        case K_X0: m->x0[idx] = value[k]; break;
        case K_MISC: m->misc[idx] = value[k]; break;
        default: break;
        }
    }
    m->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Inst *m = (Inst *)c;
    for (size_t k = 0; k < nvr; ++k) {
        if (vr[k] >= HB_NVR || HB_VR_KIND[vr[k]] != K_ENC) { logmsg(m, fmi2Error, "error", "not an Integer variable"); return fmi2Error; }
        value[k] = m->encoder_counts;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Inst *m = (Inst *)c;
    for (size_t k = 0; k < nvr; ++k) {
        if (vr[k] >= HB_NVR || HB_VR_KIND[vr[k]] != K_ENC || !settable(m, K_ENC)) {
            logmsg(m, fmi2Error, "error", "not a settable Integer variable"); return fmi2Error;
        }
        if (value[k] < 0) { logmsg(m, fmi2Error, "error", "sensors.encoder_counts must be >= 0"); return fmi2Error; }
        m->encoder_counts = value[k];
    }
    m->y_valid = 0;
    return fmi2OK;
}

/* The FMU has only Real variables: a get or set of nvr > 0 Boolean or String variables is an error. */
static fmi2Status no_variables(fmi2Component c, size_t nvr, const char *type)
{
    char text[64];
    if (nvr == 0) return fmi2OK;
    snprintf(text, sizeof text, "this FMU has no %s variables", type);
    logmsg((Inst *)c, fmi2Error, "error", text);
    return fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)vr; (void)value;
    return no_variables(c, nvr, "Boolean");
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    return fmi2GetBoolean(c, vr, nvr, (fmi2Boolean *)value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)vr; (void)value;
    return no_variables(c, nvr, "String");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    return fmi2GetString(c, vr, nvr, (fmi2String *)value);
}

static fmi2Status unsupported(fmi2Component c, const char *what)
{
    char text[160];
    snprintf(text, sizeof text, "%s is not supported by this FMU", what);
    logmsg((Inst *)c, fmi2Error, "error", text);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return unsupported(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2FreeFMUstate"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{ (void)s; (void)n; return unsupported(c, "fmi2SerializedFMUstateSize"); }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{ (void)s; (void)b; (void)n; return unsupported(c, "fmi2SerializeFMUstate"); }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{ (void)s; (void)b; (void)n; return unsupported(c, "fmi2DeSerializeFMUstate"); }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real du[], fmi2Real dz[])
{ (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz; return unsupported(c, "fmi2GetDirectionalDerivative"); }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{ (void)vr; (void)nvr; (void)order; (void)value; return unsupported(c, "fmi2SetRealInputDerivatives"); }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{ (void)vr; (void)nvr; (void)order; (void)value; return unsupported(c, "fmi2GetRealOutputDerivatives"); }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    Inst *m = (Inst *)c;
    char text[200];
    if (m->mode != S_STEP) { logmsg(m, fmi2Error, "error", "fmi2DoStep before initialization or after an error"); return fmi2Error; }
    double samples = h / HB_DT;
    long n = lround(samples);
    if (n < 1 || fabs(samples - n) > 1e-6) {
        snprintf(text, sizeof text, "communicationStepSize must be a whole number of samples of %g s, got %.17g",
                 HB_DT, h);
        logmsg(m, fmi2Error, "error", text);
        return fmi2Error;
    }
    if (!isfinite(m->u)) { logmsg(m, fmi2Error, "error", "the input is not finite"); m->mode = S_ERROR; return fmi2Error; }
    if (!m->started) {
        if (!initial_state(m)) { logmsg(m, fmi2Error, "error", "the initial accelerations could not be computed"); m->mode = S_ERROR; return fmi2Error; }
        m->started = 1;
    }
    for (int k = 0; k < HB_K; ++k) m->tau[k] = m->u;          /* zero-order hold over the sample */
    for (long i = 0; i < n; ++i) {
        if (!advance(m)) {
            snprintf(text, sizeof text, "the implicit step did not converge at t = %.6g s", m->t);
            logmsg(m, fmi2Error, "error", text);
            m->mode = S_ERROR;
            return fmi2Error;
        }
        memcpy(m->s_in, m->s_out, sizeof m->s_in);
        m->t = t + (i + 1) * HB_DT;
    }
    m->t = t + h;
    m->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{ (void)s; (void)value; return unsupported(c, "fmi2GetStatus"); }

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    if (s == fmi2LastSuccessfulTime) { *value = ((Inst *)c)->t; return fmi2OK; }
    return unsupported(c, "fmi2GetRealStatus");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{ (void)s; (void)value; return unsupported(c, "fmi2GetIntegerStatus"); }

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{ (void)s; (void)value; return unsupported(c, "fmi2GetBooleanStatus"); }

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{ (void)s; (void)value; return unsupported(c, "fmi2GetStringStatus"); }
