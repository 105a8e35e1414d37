/*
 * kronsub integrators (see integrators.h): Dormand-Prince 8(5,3) with dense output, the 2-stage
 * Gauss-Legendre method and the classical Runge-Kutta method, for y' = f(t, y; param).
 *
 * C99, libc and libm only; no allocation and no mutable globals, so every function is reentrant.
 */
#include <float.h>
#include <math.h>
#include <string.h>

#include "integrators.h"

/* ------------------------------------------------------------------------------------------ */
/* Shared: evaluating f, recording failures, writing rows                                      */
/* ------------------------------------------------------------------------------------------ */

volatile int ks_interrupt = 0;

const char *ks_status_message(int status)
{
    switch (status) {
    case KS_OK: return "reached the end time";
    case KS_RHS_FAILED:
        return "the right-hand side could not be evaluated (mass matrix singular or not positive definite)";
    case KS_NOT_FINITE: return "the state or its derivative became NaN or infinite";
    case KS_STEP_UNDERFLOW:
        return "the step size fell below round-off, or the implicit stage iteration failed";
    case KS_TOO_MANY_STEPS: return "the maximum number of steps was reached";
    case KS_OUTPUT_FULL: return "the output buffer is full";
    case KS_BAD_ARGUMENT: return "invalid argument";
    case KS_INTERRUPTED: return "interrupted";
    default: return "unknown status";
    }
}

/* One integration's fixed inputs and where its results go. */
typedef struct {
    ks_fn f;
    int dim;
    const double *param;
    double *fail_state;   /* work[0 .. dim-1]: the argument of the call to f that failed */
    double *out;
    long max_rows;
    ks_result *res;
} ks_run;

static int all_finite(const double *v, int n)
{
    int i;
    for (i = 0; i < n; ++i)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* Stop with `status` at time t; y (may be NULL) is kept in fail_state. Returns status. */
static int stop(ks_run *run, int status, double t, const double *y)
{
    run->res->status = status;
    run->res->t_fail = t;
    if (y != NULL && y != run->fail_state)
        memmove(run->fail_state, y, (size_t)run->dim * sizeof(double));
    return status;
}

/* ydot = f(t, y); 0, or the failure status (1: f failed, 2: non-finite ydot). */
static int eval(ks_run *run, double t, const double *y, double *ydot)
{
    run->res->n_evals++;
    if (run->f(t, y, run->param, ydot) != 0) return stop(run, KS_RHS_FAILED, t, y);
    if (!all_finite(ydot, run->dim)) return stop(run, KS_NOT_FINITE, t, y);
    return 0;
}

/* Append the row [t, y]; 0, or KS_OUTPUT_FULL. */
static int write_row(ks_run *run, double t, const double *y)
{
    double *row;
    if (run->res->n_rows >= run->max_rows) return stop(run, KS_OUTPUT_FULL, t, NULL);
    row = run->out + run->res->n_rows * (long)(run->dim + 1);
    row[0] = t;
    memcpy(row + 1, y, (size_t)run->dim * sizeof(double));
    run->res->n_rows++;
    return 0;
}

/* Clear res and check the arguments common to all integrators; 0 or KS_BAD_ARGUMENT. */
static int start(ks_run *run, ks_fn f, int dim, const double *param, double t0, const double *y0,
                 double t_end, double *out, long max_rows, double *work, ks_result *res)
{
    if (res == NULL) return KS_BAD_ARGUMENT;
    memset(res, 0, sizeof *res);
    run->f = f;
    run->dim = dim;
    run->param = param;
    run->fail_state = work;
    run->out = out;
    run->max_rows = max_rows;
    run->res = res;
    if (f == NULL || dim < 1 || y0 == NULL || out == NULL || work == NULL || max_rows < 1
        || !isfinite(t0) || !isfinite(t_end) || !(t_end >= t0)) {
        res->status = KS_BAD_ARGUMENT;
        res->t_fail = t0;
        return KS_BAD_ARGUMENT;
    }
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* Dormand-Prince 8(5,3)                                                                       */
/* ------------------------------------------------------------------------------------------ */

/*
 * The published coefficients of DOP853 (Hairer, Norsett & Wanner; as distributed with Hairer's
 * Fortran code and scipy.integrate): nodes DP_C, stage coefficients DP_A (row 12 holds the
 * weights b of the 8th-order solution, rows 13-15 the extra stages of the dense output), the
 * 5th-order error weights DP_E5, the 3rd-order comparison weights DP_BHH (at stages 0, 8, 11) and
 * the dense-output coefficients DP_D (the 5th-8th coefficients of the continuous extension).
 */
static const double DP_C[16] = {
    0.0, 0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01, 0.118350341907227396726757197510,
    0.281649658092772603273242802490, 0.333333333333333333333333333333,
    0.25, 0.307692307692307692307692307692,
    0.651282051282051282051282051282, 0.6,
    0.857142857142857142857142857142, 1.0,
    1.0, 0.1,
    0.2, 0.777777777777777777777777777778,
};
static const double DP_A[16][16] = {
    {0.0},
    { /* stage 1 */
        5.26001519587677318785587544488e-2,
    },
    { /* stage 2 */
        1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2,
    },
    { /* stage 3 */
        2.95875854768068491816892993775e-2, 0.0,
        8.87627564304205475450678981324e-2,
    },
    { /* stage 4 */
        2.41365134159266685502369798665e-1, 0.0,
        -8.84549479328286085344864962717e-1, 9.24834003261792003115737966543e-1,
    },
    { /* stage 5 */
        3.7037037037037037037037037037e-2, 0.0,
        0.0, 1.70828608729473871279604482173e-1,
        1.25467687566822425016691814123e-1,
    },
    { /* stage 6 */
        3.7109375e-2, 0.0,
        0.0, 1.70252211019544039314978060272e-1,
        6.02165389804559606850219397283e-2, -1.7578125e-2,
    },
    { /* stage 7 */
        3.70920001185047927108779319836e-2, 0.0,
        0.0, 1.70383925712239993810214054705e-1,
        1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
        8.27378916381402288758473766002e-3,
    },
    { /* stage 8 */
        6.24110958716075717114429577812e-1, 0.0,
        0.0, -3.36089262944694129406857109825,
        -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
        2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1,
    },
    { /* stage 9 */
        4.77662536438264365890433908527e-1, 0.0,
        0.0, -2.48811461997166764192642586468,
        -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
        1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
        -2.03312017085086261358222928593e-2,
    },
    { /* stage 10 */
        -9.3714243008598732571704021658e-1, 0.0,
        0.0, 5.18637242884406370830023853209,
        1.09143734899672957818500254654, -8.14978701074692612513997267357,
        -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1,
        2.49360555267965238987089396762, -3.0467644718982195003823669022,
    },
    { /* stage 11 */
        2.27331014751653820792359768449, 0.0,
        0.0, -1.05344954667372501984066689879e1,
        -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
        2.79488845294199600508499808837e1, -2.85899827713502369474065508674,
        -8.87285693353062954433549289258, 1.23605671757943030647266201528e1,
        6.43392746015763530355970484046e-1,
    },
    { /* stage 12 */
        5.42937341165687622380535766363e-2, 0.0,
        0.0, 0.0,
        0.0, 4.45031289275240888144113950566,
        1.89151789931450038304281599044, -5.8012039600105847814672114227,
        3.1116436695781989440891606237e-1, -1.52160949662516078556178806805e-1,
        2.01365400804030348374776537501e-1, 4.47106157277725905176885569043e-2,
    },
    { /* stage 13 */
        5.61675022830479523392909219681e-2, 0.0,
        0.0, 0.0,
        0.0, 0.0,
        2.53500210216624811088794765333e-1, -2.46239037470802489917441475441e-1,
        -1.24191423263816360469010140626e-1, 1.5329179827876569731206322685e-1,
        8.20105229563468988491666602057e-3, 7.56789766054569976138603589584e-3,
        -8.298e-3,
    },
    { /* stage 14 */
        3.18346481635021405060768473261e-2, 0.0,
        0.0, 0.0,
        0.0, 2.83009096723667755288322961402e-2,
        5.35419883074385676223797384372e-2, -5.49237485713909884646569340306e-2,
        0.0, 0.0,
        -1.08347328697249322858509316994e-4, 3.82571090835658412954920192323e-4,
        -3.40465008687404560802977114492e-4, 1.41312443674632500278074618366e-1,
    },
    { /* stage 15 */
        -4.28896301583791923408573538692e-1, 0.0,
        0.0, 0.0,
        0.0, -4.69762141536116384314449447206,
        7.68342119606259904184240953878, 4.06898981839711007970213554331,
        3.56727187455281109270669543021e-1, 0.0,
        0.0, 0.0,
        -1.39902416515901462129418009734e-3, 2.9475147891527723389556272149,
        -9.15095847217987001081870187138,
    },
};
static const double DP_E5[12] = {
    0.1312004499419488073250102996e-1, 0.0,
    0.0, 0.0,
    0.0, -0.1225156446376204440720569753e+1,
    -0.4957589496572501915214079952, 0.1664377182454986536961530415e+1,
    -0.3503288487499736816886487290, 0.3341791187130174790297318841,
    0.8192320648511571246570742613e-1, -0.2235530786388629525884427845e-1,
};
static const double DP_D[4][16] = {
    {
        -0.84289382761090128651353491142e+1, 0.0,
        0.0, 0.0,
        0.0, 0.56671495351937776962531783590,
        -0.30689499459498916912797304727e+1, 0.23846676565120698287728149680e+1,
        0.21170345824450282767155149946e+1, -0.87139158377797299206789907490,
        0.22404374302607882758541771650e+1, 0.63157877876946881815570249290,
        -0.88990336451333310820698117400e-1, 0.18148505520854727256656404962e+2,
        -0.91946323924783554000451984436e+1, -0.44360363875948939664310572000e+1,
    },
    {
        0.10427508642579134603413151009e+2, 0.0,
        0.0, 0.0,
        0.0, 0.24228349177525818288430175319e+3,
        0.16520045171727028198505394887e+3, -0.37454675472269020279518312152e+3,
        -0.22113666853125306036270938578e+2, 0.77334326684722638389603898808e+1,
        -0.30674084731089398182061213626e+2, -0.93321305264302278729567221706e+1,
        0.15697238121770843886131091075e+2, -0.31139403219565177677282850411e+2,
        -0.93529243588444783865713862664e+1, 0.35816841486394083752465898540e+2,
    },
    {
        0.19985053242002433820987653617e+2, 0.0,
        0.0, 0.0,
        0.0, -0.38703730874935176555105901742e+3,
        -0.18917813819516756882830838328e+3, 0.52780815920542364900561016686e+3,
        -0.11573902539959630126141871134e+2, 0.68812326946963000169666922661e+1,
        -0.10006050966910838403183860980e+1, 0.77771377980534432092869265740,
        -0.27782057523535084065932004339e+1, -0.60196695231264120758267380846e+2,
        0.84320405506677161018159903784e+2, 0.11992291136182789328035130030e+2,
    },
    {
        -0.25693933462703749003312586129e+2, 0.0,
        0.0, 0.0,
        0.0, -0.15418974869023643374053993627e+3,
        -0.23152937917604549567536039109e+3, 0.35763911791061412378285349910e+3,
        0.93405324183624310003907691704e+2, -0.37458323136451633156875139351e+2,
        0.10409964950896230045147246184e+3, 0.29840293426660503123344363579e+2,
        -0.43533456590011143754432175058e+2, 0.96324553959188282948394950600e+2,
        -0.39177261675615439165231486172e+2, -0.14972683625798562581422125276e+3,
    },
};
static const double DP_BHH[3] = {
    0.244094488188976377952755905512, 0.733846688281611857341361741547,
    0.220588235294117647058823529412e-1,
};

#define DP_B (DP_A[12])
#define DP_SAFE 0.9
/* h_new = h / fac with fac = err^(1/8) / safe kept in [DP_FAC_LO, DP_FAC_HI]: 0.333 h .. 6 h */
#define DP_FAC_LO (1.0 / 6.0)
#define DP_FAC_HI (1.0 / 0.333)

/* ytmp = y + h sum_{j < s} a_sj K_j */
static void dp_stage_state(int dim, const double *y, double h, const double *K, int s, double *ytmp)
{
    int i, j;
    for (i = 0; i < dim; ++i) ytmp[i] = 0.0;
    for (j = 0; j < s; ++j) {
        const double a = DP_A[s][j];
        const double *Kj = K + (long)j * dim;
        if (a == 0.0) continue;
        for (i = 0; i < dim; ++i) ytmp[i] += a * Kj[i];
    }
    for (i = 0; i < dim; ++i) ytmp[i] = y[i] + h * ytmp[i];
}

/*
 * The first step, as Hairer's HINIT: h = 0.01 |y|/|f| (scaled norms), then from one Euler step
 * the second-derivative estimate, and h = min(100 h, (0.01 / max(|f'|, |f|))^(1/8), hmax).
 * Uses K[dim .. 2 dim) and ytmp as scratch; returns 0 or the failure status.
 */
static int dp_initial_step(ks_run *run, double t, const double *y, const double *f0, double rtol,
                           double atol, double hmax, double *K1, double *ytmp, double *h_out)
{
    const int dim = run->dim;
    double dnf = 0.0, dny = 0.0, der2 = 0.0, der12, h, h1;
    int i, status;
    for (i = 0; i < dim; ++i) {
        const double sk = atol + rtol * fabs(y[i]);
        dnf += (f0[i] / sk) * (f0[i] / sk);
        dny += (y[i] / sk) * (y[i] / sk);
    }
    h = (dnf <= 1e-10 || dny <= 1e-10) ? 1e-6 : 0.01 * sqrt(dny / dnf);
    h = fmin(h, hmax);
    for (i = 0; i < dim; ++i) ytmp[i] = y[i] + h * f0[i];
    status = eval(run, t + h, ytmp, K1);
    if (status) return status;
    for (i = 0; i < dim; ++i) {
        const double sk = atol + rtol * fabs(y[i]);
        der2 += ((K1[i] - f0[i]) / sk) * ((K1[i] - f0[i]) / sk);
    }
    der2 = sqrt(der2) / h;
    der12 = fmax(fabs(der2), sqrt(dnf));
    h1 = der12 <= 1e-15 ? fmax(1e-6, 1e-3 * h) : pow(0.01 / der12, 1.0 / 8.0);
    *h_out = fmin(fmin(100.0 * h, h1), hmax);
    return 0;
}

/*
 * The continuous extension on [t, t + h] (Hairer's CONTD8), from the 16 stages:
 *   y(t + s h) = c0 + s (c1 + s1 (c2 + s (c3 + s1 (c4 + s (c5 + s1 (c6 + s c7)))))),  s1 = 1 - s,
 * c0 = y, c1 = ynew - y, c2 = h K0 - c1, c3 = c1 - h K12 - c2, c_{4+r} = h sum_j d_rj K_j.
 */
static void dp_dense_coefficients(int dim, const double *y, const double *ynew, double h,
                                  const double *K, double *cont)
{
    int i, j, r;
    const double *K0 = K, *K12 = K + 12L * dim;
    for (i = 0; i < dim; ++i) {
        const double dy = ynew[i] - y[i];
        const double bspl = h * K0[i] - dy;
        cont[i] = y[i];
        cont[dim + i] = dy;
        cont[2L * dim + i] = bspl;
        cont[3L * dim + i] = dy - h * K12[i] - bspl;
    }
    for (r = 0; r < 4; ++r) {
        double *c = cont + (4L + r) * dim;
        for (i = 0; i < dim; ++i) c[i] = 0.0;
        for (j = 0; j < 16; ++j) {
            const double d = DP_D[r][j];
            const double *Kj = K + (long)j * dim;
            if (d == 0.0) continue;
            for (i = 0; i < dim; ++i) c[i] += d * Kj[i];
        }
        for (i = 0; i < dim; ++i) c[i] *= h;
    }
}

static void dp_dense_eval(int dim, const double *cont, double s, double *yout)
{
    const double s1 = 1.0 - s;
    int i;
    for (i = 0; i < dim; ++i) {
        const double *c = cont + i;
        const long n = dim;
        const double tail = c[4 * n] + s * (c[5 * n] + s1 * (c[6 * n] + s * c[7 * n]));
        yout[i] = c[0] + s * (c[n] + s1 * (c[2 * n] + s * (c[3 * n] + s1 * tail)));
    }
}

/* The k-th output time t0 + k dt_out, or t_end (is_final) once within 1e-7 dt_out of it. */
static double output_time(double t0, double dt_out, double t_end, long k, int *is_final)
{
    const double tk = t0 + (double)k * dt_out;
    *is_final = tk >= t_end - 1e-7 * dt_out;
    return *is_final ? t_end : tk;
}

/*
 * Hairer's stiffness test of DOP853 (Solving ODEs II, Sec. IV.2): with the last stage taken at
 * c = 1, |h| ||f(ynew) - f(y_12)|| / ||ynew - y_12|| estimates |h lambda| of the dominant
 * eigenvalue; beyond 6.1 (the boundary of the method's stability region) in 15 tests with no 6
 * quiet ones between, the step size is set by stability rather than accuracy: the problem is
 * stiff there, and res->t_stiff records when this was first seen.
 */
#define DP_NSTIFF 100
static void dp_stiffness_test(int dim, double h, const double *ynew, const double *y12,
                              const double *f_new, const double *f12, int *stiff_count,
                              int *nonstiff_count, double t, ks_result *res)
{
    double num = 0.0, den = 0.0;
    int i;
    for (i = 0; i < dim; ++i) {
        num += (f_new[i] - f12[i]) * (f_new[i] - f12[i]);
        den += (ynew[i] - y12[i]) * (ynew[i] - y12[i]);
    }
    if (!(den > 0.0)) return;
    if (fabs(h) * sqrt(num / den) > 6.1) {
        *nonstiff_count = 0;
        if (++*stiff_count >= 15) {
            if (res->n_stiff == 0) res->t_stiff = t;
            res->n_stiff++;
        }
    } else if (++*nonstiff_count == 6) {
        *stiff_count = 0;
    }
}

int ks_dop853(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
              double dt_out, double rtol, double atol, double h0, long max_steps,
              double *out, long max_rows, double *work, ks_result *res)
{
    ks_run run;
    double *ytmp, *y, *ynew, *K, *cont, *K0, *K12;
    double t = t0, h, hmax = t_end - t0;
    long attempts = 0, k_out = 1;
    int status, reject = 0, last = 0, final_written = 0, i, j, s;
    int stiff_count = 0, nonstiff_count = 0;

    status = start(&run, f, dim, param, t0, y0, t_end, out, max_rows, work, res);
    if (status) return status;
    if (!(rtol >= 0.0) || !(atol >= 0.0) || (rtol == 0.0 && atol == 0.0) || isnan(dt_out)
        || isnan(h0))
        return stop(&run, KS_BAD_ARGUMENT, t0, NULL);
    ytmp = work;
    y = work + dim;
    ynew = work + 2L * dim;
    K = work + 3L * dim;          /* 16 stages */
    cont = work + 19L * dim;      /* 8 dense-output coefficients */
    K0 = K;
    K12 = K + 12L * dim;
    memcpy(y, y0, (size_t)dim * sizeof(double));
    if (!all_finite(y, dim)) return stop(&run, KS_NOT_FINITE, t0, y);
    if (write_row(&run, t0, y)) return res->status;
    if (t_end == t0) return KS_OK;
    if (eval(&run, t, y, K0)) return res->status;
    if (h0 > 0.0) {
        h = fmin(h0, hmax);
    } else if (dp_initial_step(&run, t, y, K0, rtol, atol, hmax, K + dim, ytmp, &h)) {
        return res->status;
    }

    for (;;) {
        double err5 = 0.0, err3 = 0.0, deno, err, fac11, fac, h_new;
        if (max_steps > 0 && attempts >= max_steps) return stop(&run, KS_TOO_MANY_STEPS, t, NULL);
        if (ks_interrupt) return stop(&run, KS_INTERRUPTED, t, NULL);
        if (0.1 * fabs(h) <= DBL_EPSILON * fmax(fabs(t), fabs(t_end)))
            return stop(&run, KS_STEP_UNDERFLOW, t, NULL);
        if (t + 1.01 * h - t_end > 0.0) {
            h = t_end - t;
            last = 1;
        }
        attempts++;

        /* stages 1..11, then the 8th-order solution ynew = y + h sum b_j K_j */
        for (s = 1; s < 12; ++s) {
            dp_stage_state(dim, y, h, K, s, ytmp);
            if (eval(&run, t + DP_C[s] * h, ytmp, K + (long)s * dim)) return res->status;
        }
        dp_stage_state(dim, y, h, K, 12, ynew);

        /* error: E5 and E3 are squared scaled norms of the 5th- and 3rd-order differences */
        for (i = 0; i < dim; ++i) {
            double bsum = 0.0, e5 = 0.0, e3, sk;
            for (j = 0; j < 12; ++j) {
                const double kj = K[(long)j * dim + i];
                bsum += DP_B[j] * kj;
                e5 += DP_E5[j] * kj;
            }
            e3 = bsum - DP_BHH[0] * K[i] - DP_BHH[1] * K[8L * dim + i]
                 - DP_BHH[2] * K[11L * dim + i];
            sk = atol + rtol * fmax(fabs(y[i]), fabs(ynew[i]));
            err5 += (e5 / sk) * (e5 / sk);
            err3 += (e3 / sk) * (e3 / sk);
        }
        deno = err5 + 0.01 * err3;
        if (deno <= 0.0) deno = 1.0;
        err = fabs(h) * err5 * sqrt(1.0 / ((double)dim * deno));
        if (!all_finite(ynew, dim)) err = HUGE_VAL;   /* overflow in a too-long step: reject */

        /* step-size control (Hairer's DOP853 with beta = 0): h_new = h / clamp(err^(1/8) / safe) */
        fac11 = pow(err, 1.0 / 8.0);
        fac = fmax(DP_FAC_LO, fmin(DP_FAC_HI, fac11 / DP_SAFE));
        h_new = h / fac;

        if (!(err <= 1.0)) {
            h = h / fmin(DP_FAC_HI, fac11 / DP_SAFE);
            reject = 1;
            last = 0;
            res->n_rejected++;
            continue;
        }

        /* accepted */
        {
            const double t_new = last ? t_end : t + h;
            res->n_steps++;
            if (eval(&run, t_new, ynew, K12)) return res->status;
            if (res->n_steps % DP_NSTIFF == 0 || stiff_count > 0)
                dp_stiffness_test(dim, h, ynew, ytmp, K12, K + 11L * dim, &stiff_count,
                                  &nonstiff_count, t_new, res);

            if (dt_out > 0.0) {
                int is_final, dense_ready = 0;
                while (!final_written) {
                    const double tk = output_time(t0, dt_out, t_end, k_out, &is_final);
                    if (is_final) {
                        if (!last) break;
                        if (write_row(&run, t_end, ynew)) return res->status;
                        final_written = 1;
                    } else if (tk > t_new) {
                        break;
                    } else if (tk == t_new) {
                        if (write_row(&run, tk, ynew)) return res->status;
                    } else {
                        if (!dense_ready) {
                            for (s = 13; s < 16; ++s) {
                                dp_stage_state(dim, y, h, K, s, ytmp);
                                if (eval(&run, t + DP_C[s] * h, ytmp, K + (long)s * dim))
                                    return res->status;
                            }
                            dp_dense_coefficients(dim, y, ynew, h, K, cont);
                            dense_ready = 1;
                        }
                        dp_dense_eval(dim, cont, (tk - t) / h, ytmp);
                        if (write_row(&run, tk, ytmp)) return res->status;
                    }
                    k_out++;
                }
            } else if (write_row(&run, t_new, ynew)) {
                return res->status;
            }

            memcpy(K0, K12, (size_t)dim * sizeof(double));
            {
                double *swap = y;
                y = ynew;
                ynew = swap;
            }
            t = t_new;
            if (last) return KS_OK;
            if (fabs(h_new) > hmax) h_new = hmax;
            if (reject) h_new = fmin(h_new, h);
            reject = 0;
            h = h_new;
        }
    }
}

/* ------------------------------------------------------------------------------------------ */
/* Fixed-step methods                                                                          */
/* ------------------------------------------------------------------------------------------ */

/* n = ceil((t_end - t0) / h) steps of (t_end - t0) / n, a span up to 2e-7 h over whole steps
 * taking none more (a t_end within 1e-7 dt_out of a row is that row, as in output_time);
 * 0 or KS_BAD_ARGUMENT. */
static int fixed_steps(double t0, double t_end, double h, long *n, double *step)
{
    double r;
    if (!(h > 0.0) || !isfinite(h)) return KS_BAD_ARGUMENT;
    r = (t_end - t0) / h;
    if (!(r < 9.0e15)) return KS_BAD_ARGUMENT;
    *n = (long)ceil(r * (1.0 - 2e-7));
    if (*n < 1) *n = 1;
    *step = (t_end - t0) / (double)*n;
    return 0;
}

/* After step k of n, at t: the row if k is a multiple of out_every, or the last. */
#define KS_CONTINUE (-1)

/* The common start of the fixed-step methods: y = y0, the first row, n steps of `step`.
   Returns KS_CONTINUE, or the status to return (KS_OK when t_end == t0). */
static int fixed_begin(ks_run *run, double *y, const double *y0, double t0, double t_end, double h,
                       long *n, double *step)
{
    memcpy(y, y0, (size_t)run->dim * sizeof(double));
    if (!all_finite(y, run->dim)) return stop(run, KS_NOT_FINITE, t0, y);
    if (write_row(run, t0, y)) return run->res->status;
    if (t_end == t0) return KS_OK;
    if (fixed_steps(t0, t_end, h, n, step)) return stop(run, KS_BAD_ARGUMENT, t0, NULL);
    return KS_CONTINUE;
}

static int fixed_row(ks_run *run, long k, long n, long out_every, double t, const double *y)
{
    if (k == n || (out_every > 0 && k % out_every == 0)) return write_row(run, t, y);
    return 0;
}

/* y += inc with compensated (Kahan) summation: comp carries the low-order bits lost so far. */
static void add_compensated(int dim, double *y, double *comp, const double *inc_a,
                            const double *inc_b, double scale)
{
    int i;
    for (i = 0; i < dim; ++i) {
        const double delta = scale * (inc_a[i] + inc_b[i]) + comp[i];
        const double y_new = y[i] + delta;
        comp[i] = delta - (y_new - y[i]);
        y[i] = y_new;
    }
}

/* The scales of the two halves of the state, [q; p]: s = max_i max(|y_i|, |h K_1i|, |h K_2i|)
   over each half (the whole state when its dimension is odd). */
static void gauss_block_scales(int dim, const double *y, const double *K1, const double *K2,
                               double h, double *scale)
{
    int i;
    scale[0] = scale[1] = 0.0;
    for (i = 0; i < dim; ++i) {
        const double s = fmax(fabs(y[i]), h * fmax(fabs(K1[i]), fabs(K2[i])));
        const int b = (dim % 2 == 0 && 2 * i >= dim) ? 1 : 0;
        scale[b] = fmax(scale[b], s);
    }
    if (dim % 2) scale[1] = scale[0];
}

/*
 * 2-stage Gauss-Legendre (Hairer, Lubich & Wanner, Geometric Numerical Integration, II.1.3):
 *   c = 1/2 -+ sqrt(3)/6,  A = [[1/4, 1/4 - sqrt(3)/6], [1/4 + sqrt(3)/6, 1/4]],  b = [1/2, 1/2].
 * The stage derivatives start from the previous step's collocation polynomial, extrapolated:
 * K_i = K_1 + (1 + c_i - c_1) / (c_2 - c_1) (K_2 - K_1).
 */
int ks_gauss4(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
              double h, long out_every, double *out, long max_rows, double *work, ks_result *res)
{
    const double r3 = 1.7320508075688772935274463415059;   /* sqrt(3) */
    const double c1 = 0.5 - r3 / 6.0, c2 = 0.5 + r3 / 6.0;
    const double a11 = 0.25, a12 = 0.25 - r3 / 6.0, a21 = 0.25 + r3 / 6.0, a22 = 0.25;
    const double tol = 1e-15;
    const int max_iter = 50;
    ks_run run;
    double *ytmp, *y, *comp, *K1, *K2, *F1, *F2, step;
    long n, k;
    int i, status;

    status = start(&run, f, dim, param, t0, y0, t_end, out, max_rows, work, res);
    if (status) return status;
    ytmp = work;
    y = work + dim;
    comp = work + 2L * dim;
    K1 = work + 3L * dim;
    K2 = work + 4L * dim;
    F1 = work + 5L * dim;
    F2 = work + 6L * dim;
    status = fixed_begin(&run, y, y0, t0, t_end, h, &n, &step);
    if (status != KS_CONTINUE) return status;
    for (i = 0; i < dim; ++i) comp[i] = 0.0;
    if (eval(&run, t0, y, K1)) return res->status;
    memcpy(K2, K1, (size_t)dim * sizeof(double));

    for (k = 0; k < n; ++k) {
        const double t = t0 + (double)k * step;
        const double t_new = k + 1 == n ? t_end : t0 + (double)(k + 1) * step;
        double d_prev = HUGE_VAL, block_scale[2];
        int it, converged = 0;
        if (k > 0) {
            const double e1 = (1.0 + c1 - c1) / (c2 - c1), e2 = (1.0 + c2 - c1) / (c2 - c1);
            for (i = 0; i < dim; ++i) {
                const double dk = K2[i] - K1[i];
                K2[i] = K1[i] + e2 * dk;
                K1[i] = K1[i] + e1 * dk;
            }
        }
        for (it = 0; it < max_iter && !converged; ++it) {
            double d = 0.0;
            for (i = 0; i < dim; ++i) ytmp[i] = y[i] + step * (a11 * K1[i] + a12 * K2[i]);
            if (eval(&run, t + c1 * step, ytmp, F1)) return res->status;
            for (i = 0; i < dim; ++i) ytmp[i] = y[i] + step * (a21 * K1[i] + a22 * K2[i]);
            if (eval(&run, t + c2 * step, ytmp, F2)) return res->status;
            /* d = max_i |h (F - K)_i| / s_B(i): relative to the norm of the block B(i) the
               component belongs to (the coordinates, or the momenta), so a momentum passing
               through zero is not measured against its own round-off. */
            gauss_block_scales(dim, y, K1, K2, step, block_scale);
            for (i = 0; i < dim; ++i) {
                const double scale = block_scale[2 * i < dim ? 0 : 1];
                const double diff = step * fmax(fabs(F1[i] - K1[i]), fabs(F2[i] - K2[i]));
                if (diff > 0.0) d = fmax(d, scale > 0.0 ? diff / scale : HUGE_VAL);
            }
            memcpy(K1, F1, (size_t)dim * sizeof(double));
            memcpy(K2, F2, (size_t)dim * sizeof(double));
            /* converged at the tolerance, or stalled at round-off */
            converged = d <= tol || (it >= 2 && d >= d_prev && d <= 1e-12);
            d_prev = d;
        }
        if (!converged) return stop(&run, KS_STEP_UNDERFLOW, t, y);
        add_compensated(dim, y, comp, K1, K2, 0.5 * step);
        if (!all_finite(y, dim)) return stop(&run, KS_NOT_FINITE, t_new, y);
        res->n_steps++;
        if (fixed_row(&run, k + 1, n, out_every, t_new, y)) return res->status;
    }
    return KS_OK;
}

/*
 * The classical Runge-Kutta method: k1 = f(t, y), k2 = f(t + h/2, y + h/2 k1),
 * k3 = f(t + h/2, y + h/2 k2), k4 = f(t + h, y + h k3), y += h/6 (k1 + 2 k2 + 2 k3 + k4).
 */
int ks_rk4(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
           double h, long out_every, double *out, long max_rows, double *work, ks_result *res)
{
    ks_run run;
    double *ytmp, *y, *k1, *k2, *k3, *k4, step;
    long n, k;
    int i, status;

    status = start(&run, f, dim, param, t0, y0, t_end, out, max_rows, work, res);
    if (status) return status;
    ytmp = work;
    y = work + dim;
    k1 = work + 2L * dim;
    k2 = work + 3L * dim;
    k3 = work + 4L * dim;
    k4 = work + 5L * dim;
    status = fixed_begin(&run, y, y0, t0, t_end, h, &n, &step);
    if (status != KS_CONTINUE) return status;

    for (k = 0; k < n; ++k) {
        const double t = t0 + (double)k * step;
        const double t_new = k + 1 == n ? t_end : t0 + (double)(k + 1) * step;
        if (eval(&run, t, y, k1)) return res->status;
        for (i = 0; i < dim; ++i) ytmp[i] = y[i] + 0.5 * step * k1[i];
        if (eval(&run, t + 0.5 * step, ytmp, k2)) return res->status;
        for (i = 0; i < dim; ++i) ytmp[i] = y[i] + 0.5 * step * k2[i];
        if (eval(&run, t + 0.5 * step, ytmp, k3)) return res->status;
        for (i = 0; i < dim; ++i) ytmp[i] = y[i] + step * k3[i];
        if (eval(&run, t + step, ytmp, k4)) return res->status;
        for (i = 0; i < dim; ++i)
            y[i] += step / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        if (!all_finite(y, dim)) return stop(&run, KS_NOT_FINITE, t_new, y);
        res->n_steps++;
        if (fixed_row(&run, k + 1, n, out_every, t_new, y)) return res->status;
    }
    return KS_OK;
}

/* ------------------------------------------------------------------------------------------ */
/* Row helpers                                                                                 */
/* ------------------------------------------------------------------------------------------ */

long ks_map_rows(ks_map_fn g, int dim, const double *param, double *rows, long n_rows,
                 double *work)
{
    long r;
    for (r = 0; r < n_rows; ++r) {
        double *x = rows + r * (long)(dim + 1) + 1;
        if (g(x, param, work) != 0) return r;
        memcpy(x, work, (size_t)dim * sizeof(double));
    }
    return -1;
}

void ks_energy_rows(ks_energy_fn kinetic, ks_timed_energy_fn potential, int dim,
                    const double *param, const double *rows, long n_rows, double *T_out,
                    double *V_out)
{
    long r;
    for (r = 0; r < n_rows; ++r) {
        const double *row = rows + r * (long)(dim + 1);
        T_out[r] = kinetic(row + 1, param);
        V_out[r] = potential(row[0], row + 1, param);
    }
}
