/*
 * kronsub extended precision: Gragg-Bulirsch-Stoer extrapolation in the model's real type
 * (long double, or _Float128 when KS_REAL_QUAD is defined; see kronsub/simulation/extended.py).
 *
 * The explicit midpoint rule with n_j = 2, 4, ..., 2K substeps over a step H, Gragg's start
 * z_1 = z_0 + h f(z_0) and z_{m+1} = z_{m-1} + 2 h f(z_m), has an error expansion in even powers
 * of h = H / n_j; the Aitken-Neville scheme
 *     T_{j,k} = T_{j,k-1} + (T_{j,k-1} - T_{j-1,k-1}) / ((n_j / n_{j-k})^2 - 1)
 * eliminates them (Hairer, Norsett & Wanner, Solving ODEs I, Sec. II.9). Every coefficient is a
 * ratio of integers, exact in any type, so the method is as accurate as the type. A step is
 * accepted when err = max_i |T_{K,K} - T_{K,K-1}| / max(1, max_i |y_i|) <= tol, and the next is
 * H * clamp(0.9 (tol / err)^(1 / (2K - 1)), 0.2, 4).
 *
 * Numbers cross the interface as text (strtold / strtof128; hexadecimal floats are exact), so
 * inputs and results keep every digit of the type whatever the caller's float is.
 */
#include "model.h"  /* first: its prelude asks <math.h> for the _Float128 functions */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define KS_EXT_MAX_STAGES 32
#define KS_EXT_TEXT 64

static ks_real ks_ext_parse(const char *text)
{
#ifdef KS_REAL_QUAD
    return strtof128(text, NULL);
#else
    return strtold(text, NULL);
#endif
}

static void ks_ext_format(char *buf, ks_real x)
{
#ifdef KS_REAL_QUAD
    strfromf128(buf, KS_EXT_TEXT, "%.40g", x);
#else
    snprintf(buf, KS_EXT_TEXT, "%.25Lg", x);
#endif
}

static ks_real ks_ext_abs(ks_real x) { return x < 0 ? -x : x; }

/* Digits of the type: 33 for _Float128, 18 for the x87 long double. */
int ks_ext_digits(void)
{
#ifdef KS_REAL_QUAD
    return 33;
#else
    return (int)(sizeof(long double) > 8 ? 18 : 15);
#endif
}

/*
 * Integrate y' = f(t, y) of the model from y0 at t = 0 to t_end with `stages` = K columns and the
 * tolerance 10^log10_tol (log10_tol a whole number). param_text (KS_NPARAM entries), y0_text (KS_NY) and t_end_text are
 * numbers as text; out_text receives KS_NY numbers, KS_EXT_TEXT characters each. counts receives
 * [accepted steps, rejected steps, right-hand-side evaluations]. Returns 0, 1 (the right-hand
 * side failed), 3 (step underflow), 4 (max_steps attempts used) or 6 (bad argument).
 */
int ks_ext_gbs(const char *const *param_text, const char *const *y0_text, const char *t_end_text,
               int stages, double log10_tol, long max_steps, char *out_text, long *counts)
{
    static ks_real table[KS_EXT_MAX_STAGES][KS_EXT_MAX_STAGES][KS_NY];
    ks_real param[KS_NPARAM + 1], pre[KS_NPRE + 1], y[KS_NY], f0[KS_NY], z0[KS_NY], z1[KS_NY],
        fz[KS_NY], t = 0, t_end, h, tol;
    long attempts = 0;
    int i, j, k, m, status = 0;
    counts[0] = counts[1] = counts[2] = 0;
    if (stages < 2 || stages > KS_EXT_MAX_STAGES) return 6;
    for (i = 0; i < KS_NPARAM; ++i) param[i] = ks_ext_parse(param_text[i]);
    for (i = 0; i < KS_NY; ++i) y[i] = ks_ext_parse(y0_text[i]);
    t_end = ks_ext_parse(t_end_text);
    if (!(t_end >= 0)) return 6;
    tol = 1;
    for (i = 0; i < (int)(-log10_tol); ++i) tol /= 10;
    ks_prepare(param, pre);
    h = t_end / 100 > 0 ? t_end / 100 : 1;
    while (t < t_end) {
        ks_real H = h < t_end - t ? h : t_end - t, err = 0, scale = 1;
        int last = !(h < t_end - t);
        if (max_steps > 0 && attempts++ >= max_steps) { status = 4; break; }
        if (ks_rhs_pre(t, y, pre, f0)) { status = 1; break; }
        counts[2]++;
        for (j = 0; j < stages && !status; ++j) {
            int n = 2 * (j + 1);
            ks_real hh = H / n;
            for (i = 0; i < KS_NY; ++i) { z0[i] = y[i]; z1[i] = y[i] + hh * f0[i]; }
            for (m = 1; m < n; ++m) {
                if (ks_rhs_pre(t + m * hh, z1, pre, fz)) { status = 1; break; }
                counts[2]++;
                for (i = 0; i < KS_NY; ++i) {
                    ks_real next = z0[i] + 2 * hh * fz[i];
                    z0[i] = z1[i];
                    z1[i] = next;
                }
            }
            for (i = 0; i < KS_NY; ++i) table[j][0][i] = z1[i];
            for (k = 1; k <= j; ++k) {
                ks_real ratio = (ks_real)((j + 1) * (j + 1)) / (ks_real)((j + 1 - k) * (j + 1 - k)) - 1;
                for (i = 0; i < KS_NY; ++i)
                    table[j][k][i] = table[j][k - 1][i] + (table[j][k - 1][i] - table[j - 1][k - 1][i]) / ratio;
            }
        }
        if (status) break;
        for (i = 0; i < KS_NY; ++i) {
            ks_real d = ks_ext_abs(table[stages - 1][stages - 1][i] - table[stages - 1][stages - 2][i]);
            if (d > err) err = d;
            if (ks_ext_abs(y[i]) > scale) scale = ks_ext_abs(y[i]);
        }
        err /= scale * tol;
        if (!(err == err)) { status = 1; break; }
        if (err <= 1) {
            for (i = 0; i < KS_NY; ++i) y[i] = table[stages - 1][stages - 1][i];
            t = last ? t_end : t + H;
            counts[0]++;
        } else {
            counts[1]++;
        }
        {
            double e = (double)err, factor = e > 0 ? 0.9 * pow(1.0 / e, 1.0 / (2 * stages - 1)) : 4.0;
            h = H * (ks_real)(factor < 0.2 ? 0.2 : (factor > 4.0 ? 4.0 : factor));
        }
        if (!(h > t_end * 1e-25)) { status = 3; break; }
    }
    for (i = 0; i < KS_NY; ++i) ks_ext_format(out_text + i * KS_EXT_TEXT, y[i]);
    return status;
}
