/*
 * kronsub integrators: self-contained ODE integrators for y' = f(t, y), in C99 with libc and libm.
 *
 * The right-hand side has the signature of a kronsub model's ks_rhs / ks_rhs_canonical:
 *     int f(double t, const double *y, const double *param, double *ydot)
 * returning 0 on success and non-zero when it cannot be evaluated (for a kronsub model: the mass
 * matrix Mbar is not positive definite at y).
 *
 * Every integrator writes rows [t, y_0 .. y_{dim-1}] (dim + 1 doubles each, row-major) to `out`,
 * never allocates (the caller passes `work`, of the size given by the KS_*_WORK macros), keeps no
 * state between calls, and so is reentrant. On failure it stops, keeps the rows written so far,
 * fills `res` (status and t_fail) and, for statuses 1 and 2, leaves in work[0 .. dim-1] the state
 * argument of the call to f that failed. The return value is res->status.
 */
#ifndef KS_INTEGRATORS_H
#define KS_INTEGRATORS_H

/* The right-hand side y' = f(t, y; param). Returns 0, or non-zero when it cannot be evaluated. */
typedef int (*ks_fn)(double t, const double *y, const double *param, double *ydot);

/* Status codes of ks_result. */
#define KS_OK 0              /* reached t_end */
#define KS_RHS_FAILED 1      /* f returned non-zero (for a model: singular mass matrix) */
#define KS_NOT_FINITE 2      /* f returned NaN or Inf, or the state became non-finite */
#define KS_STEP_UNDERFLOW 3  /* dop853: step below round-off; gauss4: stage iteration failed */
#define KS_TOO_MANY_STEPS 4  /* max_steps step attempts used before t_end */
#define KS_OUTPUT_FULL 5     /* out has no room for the next row (max_rows) */
#define KS_BAD_ARGUMENT 6    /* dim < 1, t_end < t0, bad step or tolerance, or a NULL array */
#define KS_INTERRUPTED 7     /* dop853: ks_interrupt was set (by another thread) before a step */

/* Set non-zero by another thread to stop a run of ks_dop853 before its next step (KS_INTERRUPTED):
 * a caller waiting on an interrupt stops a long call within a step. */
extern volatile int ks_interrupt;

/* What one integration did. */
typedef struct {
    int status;        /* one of the KS_* codes above */
    double t_fail;     /* when status != 0: the time it stopped (of the failed call to f) */
    long n_steps;      /* accepted steps */
    long n_rejected;   /* rejected steps (dop853 only) */
    long n_evals;      /* calls to f */
    long n_rows;       /* rows written to out */
    long n_stiff;      /* dop853: stiffness tests that found |h lambda| at the stability limit */
    double t_stiff;    /* dop853: when the problem was first found stiff (0 when never) */
} ks_result;

/* A one-line English description of a status code. */
const char *ks_status_message(int status);

/* Scratch sizes, in doubles. */
#define KS_DOP853_WORK(dim) (27L * (long)(dim))
#define KS_GAUSS4_WORK(dim) (7L * (long)(dim))
#define KS_RK4_WORK(dim) (6L * (long)(dim))

/*
 * Dormand-Prince 8(5,3) (Hairer, Norsett & Wanner, Solving ODEs I, 2nd ed., Sec. II.5 and II.10;
 * the step and error control of Hairer's DOP853): an explicit 12-stage Runge-Kutta method of
 * order 8 with the error estimate err = |h| E5 / sqrt(dim (E5 + 0.01 E3)), E5 and E3 the squared
 * scaled norms of a 5th- and a 3rd-order embedded difference, sc_i = atol + rtol max(|y_i|,
 * |ynew_i|); a step is accepted when err <= 1, and the next step is
 * h_new = h / clamp(err^(1/8) / 0.9, 1/6, 1/0.333).
 * Rows are written at t0, t0 + dt_out, t0 + 2 dt_out, ... and exactly at t_end, with the
 * 7th-order dense output (3 extra evaluations on steps that contain an output time); if
 * dt_out <= 0, a row at t0 and at every accepted step. h0 <= 0 chooses the first step
 * automatically (Hairer's HINIT). max_steps bounds the step attempts (accepted + rejected);
 * <= 0 means no bound.
 * work: KS_DOP853_WORK(dim) doubles; out: max_rows * (dim + 1) doubles.
 */
int ks_dop853(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
              double dt_out, double rtol, double atol, double h0, long max_steps,
              double *out, long max_rows, double *work, ks_result *res);

/*
 * The 2-stage Gauss-Legendre collocation method (order 4, symmetric, and symplectic when f is a
 * canonical Hamiltonian system z = [q; p]) with a constant step: the number of steps is
 * n = ceil((t_end - t0) / h) and the step used is (t_end - t0) / n, so the last lands on t_end.
 * The stage equations K_i = f(t + c_i h, y + h sum_j a_ij K_j) are solved by fixed-point
 * iteration until the change is below 1e-15 relative (or stalls at round-off), at most 50
 * iterations; else status 3. The new state y + h (K_1 + K_2) / 2 is accumulated with compensated
 * summation. Rows at t0, after every out_every steps, and at t_end (out_every < 1: only those two).
 * work: KS_GAUSS4_WORK(dim) doubles; out: max_rows * (dim + 1) doubles.
 */
int ks_gauss4(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
              double h, long out_every, double *out, long max_rows, double *work, ks_result *res);

/*
 * The classical 4-stage Runge-Kutta method with a constant step (steps and rows as for
 * ks_gauss4): the cheap baseline, 4 evaluations per step, no error control.
 * work: KS_RK4_WORK(dim) doubles; out: max_rows * (dim + 1) doubles.
 */
int ks_rk4(ks_fn f, int dim, const double *param, double t0, const double *y0, double t_end,
           double h, long out_every, double *out, long max_rows, double *work, ks_result *res);

/* Row helpers, so that a trajectory's rows are post-processed without a Python loop. */

/* A map of one state to another, as a model's ks_velocity: y = g(x; param); 0 or non-zero. */
typedef int (*ks_map_fn)(const double *x, const double *param, double *y);
/* as ks_kinetic_energy */
typedef double (*ks_energy_fn)(const double *y, const double *param);
/* as ks_potential_energy */
typedef double (*ks_timed_energy_fn)(double t, const double *y, const double *param);

/*
 * Replace the state x of each of the n_rows rows [t, x] (dim + 1 doubles each) by g(x); work
 * holds dim doubles. Returns -1, or the index of the first row where g failed (that row and the
 * later ones are left as they were).
 */
long ks_map_rows(ks_map_fn g, int dim, const double *param, double *rows, long n_rows,
                 double *work);

/* T_out[r] = kinetic(x_r), V_out[r] = potential(t_r, x_r) for the n_rows rows [t_r, x_r]. */
void ks_energy_rows(ks_energy_fn kinetic, ks_timed_energy_fn potential, int dim,
                    const double *param, const double *rows, long n_rows, double *T_out,
                    double *V_out);

#endif
