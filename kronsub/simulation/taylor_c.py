"""A Taylor integrator generated as C for the model (issue 9, section 2).

The tape of :mod:`.reference` (the equations as elementary operations) is written out as C:
one array of Taylor coefficients per operation, filled order by order with the recurrences of
automatic differentiation, ``Mbar_0 x_k = r_k - sum_{j>=1} Mbar_j x_{k-j}`` solved by
``L D L^T`` of ``Mbar_0`` once per step, then ``q_{k+1} = qdot_k / (k+1)``,
``qdot_{k+1} = x_k / (k+1)``. Order ``N = ceil(ln(1/tol) / 2) + 1`` and step
``h = rho / e^2 exp(-0.7 / (N - 1))``, ``rho = min_{k = N-1, N} (max(1, |y|) / |y_k|)^(1/k)``
(Jorba and Zou's choice, as heyoka makes it) are chosen at run time.
Parameters stay run-time inputs. The C is plain C99 with libc and libm, in ``double``; like the
model's C it can be retyped to ``long double`` or ``_Float128`` (:func:`.extended.retype`).
"""
from __future__ import annotations

import ctypes

import mpmath
import sympy

from ..core.known_system import KnownSystem
from .native import compile_library
from .reference import _Tape

MAX_ORDER = 60
_INTEGRALS = {"atan": "atan", "asin": "asin", "acos": "acos"}


def _literal(value) -> str:
    with mpmath.workdps(40):
        text = mpmath.nstr(mpmath.mpf(value), 36, min_fixed=-1, max_fixed=1, strip_zeros=False)
    return text if ("." in text or "e" in text) else text + ".0"


def emit_taylor_c(system: KnownSystem) -> str:
    """The C source of ``ks_taylor`` for ``system`` (see the module docstring)."""
    n = len(system.coordinates)
    tape = _Tape([*system.coordinates, *system.velocities], {}, tuple(p.symbol for p in system.parameters))
    M, r = system.mass_matrix, system.forces - system.velocity_terms
    M_nodes = [[tape.node(sympy.sympify(M[a, b])) for b in range(n)] for a in range(n)]
    r_nodes = [tape.node(sympy.sympify(r[a])) for a in range(n)]
    nodes = tape.nodes

    def name(i: int) -> str:
        kind, args, data = nodes[i]
        if kind == "state":
            return f"Y{data}"
        if kind == "sin":
            return f"S{args[0]}"
        if kind == "cos":
            return f"C{args[0]}"
        return f"v{i}"

    arrays, init, body = [], [], []
    for i, (kind, args, data) in enumerate(nodes):
        a = name(args[0]) if args else ""
        if kind in ("state", "sin", "cos"):
            continue
        if kind == "sincos":
            arrays += [f"S{i}", f"C{i}"]
            body.append(f"if (k == 0) {{ S{i}[0] = sin({a}[0]); C{i}[0] = cos({a}[0]); }} else {{ "
                        f"double s = 0, c = 0; for (j = 1; j <= k; ++j) {{ double ja = j * {a}[j]; "
                        f"s += ja * C{i}[k - j]; c += ja * S{i}[k - j]; }} S{i}[k] = s / k; C{i}[k] = -c / k; }}")
            continue
        v = f"v{i}"
        arrays.append(v)
        if kind == "const":
            init.append(f"{v}[0] = {_literal(data)};")
        elif kind == "param":
            init.append(f"{v}[0] = param[{data}];")
        elif kind == "time":
            init.append(f"{v}[1] = 1;")
            body.append(f"if (k == 0) {v}[0] = t;")
        elif kind == "add":
            body.append(f"{v}[k] = " + " + ".join(f"{name(x)}[k]" for x in args) + ";")
        elif kind == "scale":
            body.append(f"{v}[k] = {_literal(data)} * {a}[k];")
        elif kind == "mul":
            b = name(args[1])
            body.append(f"{{ double s = 0; for (j = 0; j <= k; ++j) s += {a}[j] * {b}[k - j]; {v}[k] = s; }}")
        elif kind == "exp":
            body.append(f"if (k == 0) {v}[0] = exp({a}[0]); else {{ double s = 0; for (j = 1; j <= k; ++j) "
                        f"s += j * {a}[j] * {v}[k - j]; {v}[k] = s / k; }}")
        elif kind == "log":
            body.append(f"if (k == 0) {v}[0] = log({a}[0]); else {{ double s = 0; for (j = 1; j < k; ++j) "
                        f"s += j * {v}[j] * {a}[k - j]; {v}[k] = ({a}[k] - s / k) / {a}[0]; }}")
        elif kind == "pow":
            p = _literal(data)
            body.append(f"if (k == 0) {v}[0] = pow({a}[0], {p}); else {{ double s = 0; for (j = 1; j <= k; ++j) "
                        f"s += ({p} * j - (k - j)) * {a}[j] * {v}[k - j]; {v}[k] = s / (k * {a}[0]); }}")
        elif kind == "integral":
            g, fn = name(args[1]), _INTEGRALS[data]
            body.append(f"if (k == 0) {v}[0] = {fn}({a}[0]); else {{ double s = 0; for (j = 1; j <= k; ++j) "
                        f"s += j * {a}[j] * {g}[k - j]; {v}[k] = s / k; }}")
        elif kind == "abs":
            body.append(f"{v}[k] = {a}[0] >= 0 ? {a}[k] : -{a}[k];")
        elif kind == "sign":
            body.append(f"if (k == 0) {v}[0] = ({a}[0] > 0) - ({a}[0] < 0);")
        else:
            raise AssertionError(kind)
    M_names = ", ".join(name(M_nodes[a][b]) for a in range(n) for b in range(n))
    r_names = ", ".join(name(x) for x in r_nodes)
    count = len(arrays) + 2 * n + 2 * n  # node arrays, Y, and X (+ spare)
    declare = "\n".join(f"    double *{x} = W + {k} * L;" for k, x in enumerate(arrays))
    declare += "\n    " + " ".join(f"(void){x};" for x in arrays)
    ydecl = "\n".join(f"    double *Y{j} = W + {len(arrays) + j} * L;" for j in range(2 * n))
    return TEMPLATE.format(
        n=n, ny=2 * n, nparam=len(system.parameters), max_order=MAX_ORDER, count=count,
        declare=declare, ydecl=ydecl, init="\n".join("    " + x for x in init),
        body="\n".join("            " + x for x in body), M_names=M_names, r_names=r_names,
        n_arrays=len(arrays), name=system.name.replace("*/", "* /"),
        ylist=", ".join(f"Y{j}" for j in range(2 * n)))


TEMPLATE = r"""/* A Taylor integrator generated by kronsub for {name}: see kronsub/simulation/taylor_c.py. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TN {n}
#define TNY {ny}
#define TMAX {max_order}

/* Integrate y' = [qdot; Mbar^-1 (fbar - hbar)] from y0 at t0 to t_end with tolerance tol
   (order chosen from it, or given by order > 0). counts: [steps, highest order used].
   Returns 0, 1 (Mbar_0 not positive definite or no memory), 4 (max_steps reached),
   6 (bad argument). */
int ks_taylor(const double *param, double t0, const double *y0, double t_end, double tol, int order,
              long max_steps, double *y_out, long *counts)
{{
    const long L = TMAX + 2;
    double *W = calloc((size_t)({count}) * (size_t)L, sizeof(double));
    double *X[TN], *M[TN * TN], *R[TN], *Y[TNY], D[TN] = {{0}}, LL[TN * TN] = {{0}}, t = t0, y[TNY];
    int i, j, k, a, b, status = 0;
    long steps = 0;
    if (W == NULL) return 1;
{declare}
{ydecl}
    {{
        double *ys[TNY] = {{{ylist}}};
        for (i = 0; i < TNY; ++i) Y[i] = ys[i];
    }}
    for (i = 0; i < TN; ++i) X[i] = W + ({n_arrays} + TNY + i) * L;
    {{
        double *ms[TN * TN] = {{{M_names}}}, *rs[TN] = {{{r_names}}};
        for (i = 0; i < TN * TN; ++i) M[i] = ms[i];
        for (i = 0; i < TN; ++i) R[i] = rs[i];
    }}
{init}
    (void)param;
    if (!(tol > 0) || !(t_end >= t0)) {{ free(W); return 6; }}
    if (order <= 0) order = (int)ceil(-0.5 * log(tol)) + 1;
    if (order < 4) order = 4;
    if (order > TMAX) order = TMAX;
    counts[0] = 0;
    counts[1] = order;
    for (i = 0; i < TNY; ++i) y[i] = y0[i];
    while (t < t_end) {{
        double h = -1, scale = 1, size;
        if (max_steps > 0 && steps >= max_steps) {{ status = 4; break; }}
        for (i = 0; i < TNY; ++i) Y[i][0] = y[i];
        for (k = 0; k < order; ++k) {{
{body}
            if (k == 0) {{  /* Mbar_0 = L D L^T */
                for (a = 0; a < TN; ++a)
                    for (b = 0; b <= a; ++b) {{
                        double s = M[a * TN + b][0];
                        for (j = 0; j < b; ++j) s -= LL[a * TN + j] * LL[b * TN + j] * D[j];
                        if (a == b) {{ D[a] = s; LL[a * TN + a] = 1; }}
                        else LL[a * TN + b] = s / D[b];
                    }}
                for (a = 0; a < TN; ++a) if (!(D[a] > 0)) {{ status = 1; break; }}
                if (status) break;
            }}
            for (a = 0; a < TN; ++a) {{  /* r_k - sum_{{j>=1}} Mbar_j x_{{k-j}} */
                double s = R[a][k];
                for (b = 0; b < TN; ++b)
                    for (j = 1; j <= k; ++j) s -= M[a * TN + b][j] * X[b][k - j];
                X[a][k] = s;
            }}
            for (a = 0; a < TN; ++a)
                for (b = 0; b < a; ++b) X[a][k] -= LL[a * TN + b] * X[b][k];
            for (a = 0; a < TN; ++a) X[a][k] /= D[a];
            for (a = TN - 1; a >= 0; --a)
                for (b = a + 1; b < TN; ++b) X[a][k] -= LL[b * TN + a] * X[b][k];
            for (a = 0; a < TN; ++a) {{
                Y[a][k + 1] = Y[TN + a][k] / (k + 1);
                Y[TN + a][k + 1] = X[a][k] / (k + 1);
            }}
        }}
        if (status) break;
        for (i = 0; i < TNY; ++i) if (fabs(y[i]) > scale) scale = fabs(y[i]);
        for (k = order - 1; k <= order; ++k) {{  /* rho = min_k (|y| / |y_k|)^(1/k) */
            size = 0;
            for (i = 0; i < TNY; ++i) if (fabs(Y[i][k]) > size) size = fabs(Y[i][k]);
            if (size > 0) {{
                double hk = pow(scale / size, 1.0 / k);
                if (h < 0 || hk < h) h = hk;
            }}
        }}
        if (h > 0) h *= exp(-2.0 - 0.7 / (order - 1));  /* rho / e^2 exp(-0.7 / (N - 1)) */
        if (h < 0 || t + h >= t_end) h = t_end - t;
        for (i = 0; i < TNY; ++i) {{  /* Horner */
            double s = Y[i][order];
            for (k = order - 1; k >= 0; --k) s = s * h + Y[i][k];
            y[i] = s;
        }}
        t = (t + h >= t_end) ? t_end : t + h;
        ++steps;
        if (!(y[0] == y[0])) {{ status = 1; break; }}
    }}
    counts[0] = steps;
    for (i = 0; i < TNY; ++i) y_out[i] = y[i];
    free(W);
    return status;
}}
"""


class TaylorC:
    """The generated Taylor integrator of one system, compiled (``precision`` double only)."""

    def __init__(self, system: KnownSystem):
        self.ny = 2 * len(system.coordinates)
        self.nparam = len(system.parameters)
        library = compile_library([("taylor.c", emit_taylor_c(system))], "taylor")
        self._lib = ctypes.CDLL(str(library))
        fn = self._lib.ks_taylor
        D, P = ctypes.c_double, ctypes.c_void_p
        fn.restype = ctypes.c_int
        fn.argtypes = [P, D, P, D, D, ctypes.c_int, ctypes.c_long, P, P]
        self._fn = fn

    def integrate(self, param, y0, t_end: float, tol: float, order: int = 0, max_steps: int = 10_000_000):
        """``(y_end, status, steps, order)`` from ``y0`` at t = 0."""
        import numpy as np

        p = np.ascontiguousarray(param, dtype=float) if self.nparam else np.zeros(1)
        y = np.ascontiguousarray(y0, dtype=float)
        out = np.empty(self.ny)
        counts = (ctypes.c_long * 2)()
        status = self._fn(p.ctypes.data, 0.0, y.ctypes.data, float(t_end), float(tol), int(order),
                          int(max_steps), out.ctypes.data, counts)
        return out, int(status), int(counts[0]), int(counts[1])

