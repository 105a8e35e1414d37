/*
 * kronsub sweeps: a block of runs of the Taylor integrator generated for a model
 * (kronsub/simulation/csrc/taylor.c.in), each run one call of its ks_taylor_io exactly as one run
 * of `kronsub simulate --method taylor` makes it (the output grid's times in one call), with the
 * summary of ensemble.c: [status, t_last, steps, rejected (0), evaluations (0), y_last (ny),
 * min q (nq), max q (nq), E0, E1], E = T + V (24) from the model's own library (kinetic and
 * potential NULL: NaN). io holds 8 + npar + 2 ny + m + m ny doubles, npar = max(1, nparam);
 * rows (NULL, or m (ny + 1) doubles per run) receives each run's rows [t, q, qdot]. Without rows,
 * the rows inside a step are asked for their coordinates only (all min and max read; the
 * numbers those of whole rows): a run that stops is run again with whole rows for its last one.
 */
#include <math.h>
#include <stddef.h>

int ks_taylor_io(double *io);

typedef double (*ks_kinetic_fn)(const double *y, const double *param);
typedef double (*ks_potential_fn)(double t, const double *y, const double *param);

long ks_taylor_ensemble(long n_runs, int nq, int nparam, double tol, double max_steps, long m, const double *times,
                        const double *param, const double *y0, double *summary, double *io, ks_kinetic_fn kinetic,
                        ks_potential_fn potential, double *rows, long *rows_written);

/* Set (non-zero) by the client when the sweep is interrupted: no further run of a block starts,
 * and ks_taylor_ensemble returns the runs it finished (fewer than asked). */
extern volatile int ks_ensemble_stop;
volatile int ks_ensemble_stop = 0;

long ks_taylor_ensemble(long n_runs, int nq, int nparam, double tol, double max_steps, long m, const double *times,
                        const double *param, const double *y0, double *summary, double *io, ks_kinetic_fn kinetic,
                        ks_potential_fn potential, double *rows, long *rows_written)
{
    const int ny = 2 * nq, npar = nparam > 0 ? nparam : 1, nsum = 7 + 2 * ny;
    const long at = 8 + npar + 2 * ny;
    long r, k;
    int i;
    for (r = 0; r < n_runs; ++r) {
        const double *p = param + r * nparam, *y = y0 + r * ny;
        double *s = summary + r * nsum, *out = io + at + m, *last;
        double *lo = s + 5 + ny, *hi = s + 5 + ny + nq;
        long written;
        int status;
        if (ks_ensemble_stop)
            return r;
        io[0] = times[0];
        io[1] = tol;
        io[2] = max_steps;
        io[3] = (double)m;
        io[4] = rows == NULL ? 2 : 0;  /* without rows asked for, the coordinates inside the steps only */
        io[5] = io[6] = 0;
        io[7] = times[0];
        for (i = 0; i < nparam; ++i) io[8 + i] = p[i];
        for (i = 0; i < ny; ++i) io[8 + npar + i] = y[i];
        for (k = 0; k < m; ++k) io[at + k] = times[k];
        status = ks_taylor_io(io);
        if (status != 0 && io[4] != 0) {  /* stopped: its last row may lie inside a step; again, whole rows */
            io[4] = io[5] = io[6] = 0;
            io[7] = times[0];
            status = ks_taylor_io(io);
        }
        written = (long)io[6];
        for (i = 0; i < nq; ++i) lo[i] = hi[i] = y[i];
        for (k = 0; k < written; ++k)
            for (i = 0; i < nq; ++i) {
                const double v = out[k * ny + i];
                if (v < lo[i]) lo[i] = v;
                if (v > hi[i]) hi[i] = v;
            }
        last = written > 0 ? out + (written - 1) * ny : (double *)y;
        for (i = 0; i < ny; ++i) s[5 + i] = last[i];
        s[0] = status;
        s[1] = status == 0 ? times[m - 1] : io[7];
        s[2] = io[5];
        s[3] = s[4] = 0;
        s[5 + ny + 2 * nq] = s[6 + ny + 2 * nq] = NAN;
        if (kinetic != NULL) {
            s[5 + ny + 2 * nq] = kinetic(y, p) + potential(times[0], y, p);
            if (status == 0) s[6 + ny + 2 * nq] = kinetic(last, p) + potential(times[m - 1], last, p);
        }
        if (rows != NULL) {
            double *to = rows + r * m * (ny + 1);
            rows_written[r] = written;
            for (k = 0; k < written; ++k) {
                to[k * (ny + 1)] = times[k];
                for (i = 0; i < ny; ++i) to[k * (ny + 1) + 1 + i] = out[k * ny + i];
            }
        }
    }
    return n_runs;
}
