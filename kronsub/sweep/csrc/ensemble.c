/*
 * kronsub sweeps: a block of runs of one model in one call (the ensemble of a sweep).
 *
 * Each run r has its own parameters param[r] (nfull = nparam + nstate doubles: the parameters,
 * then the Newton state of a closed loop) and initial state y0[r] = [q; qdot], or [q; u] in the
 * speeds u of a model under velocity constraints (ny doubles). It is
 * integrated exactly as one run of `kronsub simulate` is: the same integrator of integrators.c on
 * the same pieces of the output grid, the derived constants computed once by prepare (pre), the
 * circle state [q; qdot; cos q_c; sin q_c] for dop853 and rk4 when the model has circle
 * coordinates (the piece run again in [q; qdot] when it fails there), the canonical state
 * [q; p = Mbar qdot] for gauss4 when the model has one (canonical; else gauss4 integrates y as
 * the others do). Its summary, nsum = 7 + ny + 2 nq doubles, is
 *     [status, t_last, steps, rejected, evaluations, y_last (ny), min q (nq), max q (nq), E0, E1]
 * with min and max over the rows on the output grid, E = T + V (24) at the start and at the end
 * (NaN unless asked for); given e->rows, the run's rows themselves (a piece's first row, the last
 * of the piece before it, once). No allocation: out holds max_rows * (nz + 1) doubles, work
 * KS_DOP853_WORK(nz), pre npre
 * and start nz doubles, nz = ny + 2 nc.
 */
#include <math.h>
#include <stddef.h>

#include "integrators.h"

typedef void (*ks_prepare_fn)(const double *param, double *pre);
typedef void (*ks_circle_fn)(const double *y, double *z);
typedef void (*ks_momentum_fn)(const double *y, const double *param, double *z);

/* The model's functions and the run's settings, shared by every run of the block. */
typedef struct {
    ks_fn rhs;                 /* on pre: ks_rhs_pre, or ks_rhs_canonical_pre for gauss4 in [q; p] */
    ks_fn rhs_circle;          /* ks_rhs_circle_pre, or NULL without circle coordinates */
    ks_circle_fn circle_state; /* y -> [y; cos q_c; sin q_c], or NULL */
    ks_prepare_fn prepare;     /* param -> pre */
    ks_momentum_fn momentum;   /* y -> [q; Mbar qdot] (gauss4) */
    ks_map_fn velocity;        /* [q; p] -> y (gauss4) */
    ks_energy_fn kinetic;      /* T(y), or NULL: no energies */
    ks_timed_energy_fn potential;
    int method;                /* 0 dop853, 1 gauss4, 2 rk4 */
    int canonical;             /* gauss4 in [q; p]: the model has the canonical form */
    int nq, ny, nc, nfull, npre;
    int n_pieces;
    const double *pieces;      /* [t0, t1] per piece of the output grid */
    double dt, rtol, atol;
    long max_steps;
    long max_rows;
    double *rows;              /* NULL, or each run's rows [t, y] on the output grid: */
    long rows_per_run;         /*   rows_per_run rows of ny + 1 doubles from rows + r rows_per_run (ny + 1) */
    long *rows_written;        /*   and their count per run */
} ks_ensemble;

int ks_ensemble_nsum(int nq, int ny);

/* Set (non-zero) by the client when the sweep is interrupted: no further run of a block starts,
 * and ks_ensemble_run returns the runs it finished (fewer than asked). */
extern volatile int ks_ensemble_stop;
volatile int ks_ensemble_stop = 0;
long ks_ensemble_run(const ks_ensemble *e, long n_runs, const double *param, const double *y0,
                     double *summary, double *out, double *work, double *pre, double *start);

int ks_ensemble_nsum(int nq, int ny) { return 7 + ny + 2 * nq; }

/* One piece from y at t0 to t1; the rows in out, their count in res->n_rows. */
static int piece(const ks_ensemble *e, const double *param, double *pre, double t0, const double *y,
                 double t1, int circle, double *start, double *out, double *work, ks_result *res)
{
    const int ny = e->ny, nz = circle ? ny + 2 * e->nc : ny;
    const int canonical = e->method == 1 && e->canonical;
    const double span = t1 - t0;
    ks_fn f = circle ? e->rhs_circle : e->rhs;
    int i;
    if (canonical)
        e->momentum(y, param, start);
    else if (circle)
        e->circle_state(y, start);
    else
        for (i = 0; i < ny; ++i) start[i] = y[i];
    if (e->method == 0)
        return ks_dop853(f, nz, pre, t0, start, t1, e->dt, e->rtol, e->atol, 0.0, e->max_steps, out,
                         e->max_rows, work, res);
    {
        /* as NativeModel.integrate: h = dt, a row every step, the steps ending on t1 */
        long n_steps = span > 0 ? (long)ceil(span / e->dt * (1 - 2e-7)) : 0;
        long rows = (n_steps < 1 ? 1 : n_steps) + 3;
        if (rows > e->max_rows) rows = e->max_rows;
        if (e->method == 1)
            return ks_gauss4(f, nz, pre, t0, start, t1, e->dt, 1, out, rows, work, res);
        return ks_rk4(f, nz, pre, t0, start, t1, e->dt, 1, out, rows, work, res);
    }
}

long ks_ensemble_run(const ks_ensemble *e, long n_runs, const double *param, const double *y0,
                     double *summary, double *out, double *work, double *pre, double *start)
{
    const int nq = e->nq, ny = e->ny, nsum = ks_ensemble_nsum(nq, ny);
    const int canonical = e->method == 1 && e->canonical;
    const int with_circle = e->method != 1 && e->nc > 0 && e->rhs_circle != NULL && e->circle_state != NULL;
    long r;
    for (r = 0; r < n_runs; ++r) {
        const double *p = param + r * e->nfull;
        double *s = summary + r * nsum;
        double *y = s + 5, *lo = s + 5 + ny, *hi = s + 5 + ny + nq;
        int k, i, status = 0;
        long steps = 0, rejected = 0, evals = 0;
        double t_last = 0.0;
        ks_result res;
        if (ks_ensemble_stop)
            return r;
        for (i = 0; i < ny; ++i) y[i] = y0[r * ny + i];
        for (i = 0; i < nq; ++i) lo[i] = hi[i] = y[i];
        e->prepare(p, pre);
        s[5 + ny + 2 * nq] = s[6 + ny + 2 * nq] = NAN;
        if (e->kinetic != NULL)
            s[5 + ny + 2 * nq] = e->kinetic(y, p) + e->potential(e->pieces[0], y, p);
        t_last = e->pieces[0];
        if (e->rows != NULL)
            e->rows_written[r] = 0;
        for (k = 0; k < e->n_pieces && status == 0; ++k) {
            const double t0 = e->pieces[2 * k], t1 = e->pieces[2 * k + 1];
            int circle = with_circle, width;
            long row;
            double *last;
            status = piece(e, p, pre, t0, y, t1, circle, start, out, work, &res);
            if (circle && status != 0 && status != KS_OUTPUT_FULL) {
                circle = 0;  /* as a run of simulate: the failed attempt's cost is not counted */
                status = piece(e, p, pre, t0, y, t1, 0, start, out, work, &res);
            }
            steps += res.n_steps;
            rejected += res.n_rejected;
            evals += res.n_evals;
            width = (circle ? ny + 2 * e->nc : ny) + 1;
            for (row = 0; row < res.n_rows; ++row)
                for (i = 0; i < nq; ++i) {
                    const double v = out[row * width + 1 + i];
                    if (v < lo[i]) lo[i] = v;
                    if (v > hi[i]) hi[i] = v;
                }
            if (e->rows != NULL) {
                double *to = e->rows + r * e->rows_per_run * (ny + 1);
                for (row = k > 0 ? 1 : 0; row < res.n_rows && e->rows_written[r] < e->rows_per_run; ++row) {
                    double *dst = to + e->rows_written[r] * (ny + 1);
                    const double *src = out + row * width;
                    dst[0] = src[0];
                    if (canonical) {
                        if (e->velocity(src + 1, pre, dst + 1))
                            for (i = nq; i < ny; ++i) dst[1 + i] = NAN;
                        for (i = 0; i < nq; ++i) dst[1 + i] = src[1 + i];
                    } else
                        for (i = 0; i < ny; ++i) dst[1 + i] = src[1 + i];
                    ++e->rows_written[r];
                }
            }
            if (res.n_rows > 0) {
                last = out + (res.n_rows - 1) * width;
                t_last = last[0];
                if (canonical) {
                    if (e->velocity(last + 1, pre, y)) {  /* [q; p] -> [q; qdot] */
                        for (i = nq; i < ny; ++i) y[i] = NAN;
                        if (status == 0) status = KS_RHS_FAILED;
                    }
                    for (i = 0; i < nq; ++i) y[i] = last[1 + i];
                } else
                    for (i = 0; i < ny; ++i) y[i] = last[1 + i];
            }
            if (status != 0)
                t_last = res.t_fail;
        }
        if (status == 0 && e->kinetic != NULL)
            s[6 + ny + 2 * nq] = e->kinetic(y, p) + e->potential(t_last, y, p);
        s[0] = status;
        s[1] = t_last;
        s[2] = (double)steps;
        s[3] = (double)rejected;
        s[4] = (double)evals;
    }
    return n_runs;
}
