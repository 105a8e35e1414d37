"""High-precision reference solutions of ``Mbar qddot + hbar = fbar`` (10'), in mpmath.

Two independent routes integrate ``y = [q; qdot]``, ``qddot = Mbar^-1 (fbar - hbar)`` from the
derived sympy expressions, at ``digits`` significant digits:

- :func:`taylor`: a Taylor series method. The expressions are turned into a tape of elementary
  operations (sums, products, powers, sin/cos, exp, log, ...) whose Taylor coefficients follow
  from the classical recurrences of automatic differentiation; ``Mbar x = r`` is solved order by
  order, ``Mbar_0 x_k = r_k - sum_{j>=1} Mbar_j x_{k-j}``. Order ``N ~ ln(1/eps)/2`` and step
  ``h = min_k (eps / |y_k|)^(1/k)`` over the last four orders (Jorba and Zou take the last two;
  four also see a series with gaps, such as that of two rods released from rest level with their
  hinge, whose every third and fourth coefficient is zero).
- :func:`extrapolation`: Gragg-Bulirsch-Stoer extrapolation of the explicit midpoint rule, with
  its own step control; the right-hand side is the tape's first coefficient.

First-order coordinates (:mod:`kronsub.core.first_order`) move with their solved velocities;
their slots of ``qdot`` are carried unchanged, as the generated right-hand side does.
With implicit constraints (a closed loop, (25)-(29)) ``Mbar``, ``hbar`` and ``fbar`` are written in the
dependent coordinates ``y_d``, ``Lambda`` and ``gamma`` as well. The Taylor route carries ``y_d``
as a series with ``y_d' = Lambda qdot`` and solves ``G_d Lambda = -G_i``, ``G_d gamma = -(ydot^T
g'' ydot)`` order by order as it solves ``Mbar``; ``y_d``'s value is put back on ``g = 0`` by
Newton's method in mpmath at every step. The extrapolation route finds ``y_d`` by Newton's method
in every evaluation of the right-hand side. Both report the state ``[q; qdot]`` of the
independent coordinates.

Both compute in fixed point (a number ``x`` is the integer ``round(x 2^bits)``), which makes the
convolutions exact integer sums. :func:`reference` runs the Taylor route at two precisions (their
difference estimates the error) and the extrapolation route as a cross-check up to the first
sample time. The tape itself is checked against ``sympy.lambdify`` in the tests.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field

import mpmath
import sympy

from ..core.first_order import first_order
from ..core.known_system import KnownSystem
from ..core.symbols import velocity_symbol
from ..emitters.projected_speeds import applies as frame_applies
from ..core.projection_work import projected_in_numbers
from ..emitters.projected_speeds import frame_equations
from ..emitters.tape import Tape
from ..errors import KronsubError

__all__ = ["REFERENCE_STEPS", "Reference", "ReferenceFailure", "RouteResult", "extrapolation", "reference",
           "taylor"]


class ReferenceFailure(KronsubError):
    """A reference solution could not be computed."""


REFERENCE_STEPS = 10_000
"""Steps a reference route may take to its last time (a bundled model takes about 450 to
t = 10): a state that changes faster (an initial velocity of 1e154) is refused at its first
step, from the step it takes there, instead of running for hours."""


def _within_budget(steps: int, t: int, h: int, end: int, bits: int) -> None:
    """Raise when the steps so far and those of size ``h`` still needed to ``end`` (fixed point)
    exceed `REFERENCE_STEPS`."""
    if h > 0 and steps + (end - t) // h < REFERENCE_STEPS:
        return
    size = f"{float(_real(h, bits)):.2g}" if h > 0 else "below the reference's resolution"
    raise ReferenceFailure(
        f"the reference would take more than {REFERENCE_STEPS:,} steps to t = {float(_real(end, bits)):g}: "
        f"its step at t = {float(_real(t, bits)):.6g} is {size} (the state changes too fast to measure "
        "against)\n  hint: a shorter --t, or smaller initial velocities or parameters (--set)")


# ---------------------------------------------------------------------------------------------
# The Taylor route: the coefficient recurrences over the tape (..emitters.tape)
# ---------------------------------------------------------------------------------------------

def _fixed(value, bits: int) -> int:
    """``round(value 2^bits)`` of an mpf."""
    if not isinstance(value, mpmath.mpf) or not mpmath.isfinite(value):
        raise ReferenceFailure(f"the equations leave the real numbers ({mpmath.nstr(value, 6)}) on the "
                              "reference trajectory: a square root or logarithm of a negative number, or a "
                              "division by zero")
    return int(mpmath.nint(mpmath.ldexp(value, bits)))


def _real(value: int, bits: int):
    return mpmath.mpf((value, -bits))


class _Series:
    """Taylor coefficients of the solution, computed in fixed point: a number ``x`` is the
    integer ``round(x 2^bits)``, so a convolution is one exact integer sum of products."""

    def __init__(self, tape: Tape, derivatives: list[int], bits: int):
        """``derivatives[i]``: the node of the time derivative of the tape's state ``i``."""
        self.tape, self.derivatives, self.bits = tape, list(derivatives), bits
        self.const = {i: _fixed(data, bits) for i, (kind, _, data) in enumerate(tape.nodes) if kind == "const"}
        self.program = [(i, kind, args, data if kind != "scale" and kind != "pow" else _fixed(data, bits))
                        for i, (kind, args, data) in enumerate(tape.nodes) if kind != "const"]

    def coefficients(self, t0: int, y0: list[int], order: int) -> list[list[int]]:
        """``y[i][k]``, k = 0..order, for the state ``y0`` at ``t0`` (fixed point); ``order = 1``
        gives the right-hand side ``y[i][1]``."""
        P, mul = self.bits, operator.mul
        one = 1 << P
        c: list[list] = [None] * len(self.tape.nodes)
        for i, value in self.const.items():
            c[i] = [value] + [0] * order
        d: dict[int, list] = {}  # d[a] = [j a_j]: the scaled derivative of argument a
        y = [[v] for v in y0]
        blocks: dict[int, tuple] = {}  # a solve node -> (LU, perm, the coefficients of X per entry)
        for i, *_ in self.program:
            c[i] = []

        def scaled(a: int, k: int) -> list[int]:
            da, coeff = d.setdefault(a, [0]), c[a]
            while len(da) <= k:
                da.append(len(da) * coeff[len(da)])
            return da

        for k in range(order):
            for i, kind, args, data in self.program:
                if kind == "state":
                    v = y[data][k]
                elif kind == "time":
                    v = t0 if k == 0 else (one if k == 1 else 0)
                elif kind == "add":
                    v = sum(c[a][k] for a in args)
                elif kind == "scale":
                    v = (data * c[args[0]][k]) >> P
                elif kind == "mul":
                    v = sum(map(mul, c[args[0]][:k + 1], c[args[1]][k::-1])) >> P
                elif kind == "pick":
                    v = c[args[0]][k][data]
                elif kind == "solve":
                    v = self._solve(c, blocks, i, args, data, k)
                elif kind == "sin":
                    v = c[args[0]][k][0]
                elif kind == "cos":
                    v = c[args[0]][k][1]
                else:
                    a = c[args[0]]
                    if kind == "sincos":  # s' = c a', c' = -s a'
                        if k == 0:
                            arg = _real(a[0], P)
                            v = (_fixed(mpmath.sin(arg), P), _fixed(mpmath.cos(arg), P))
                        else:
                            da, own = scaled(args[0], k)[1:k + 1], c[i][k - 1::-1]
                            v = (sum(map(mul, da, [o[1] for o in own])) // k >> P,
                                 -(sum(map(mul, da, [o[0] for o in own])) // k >> P))
                    elif kind == "exp":  # v' = v a'
                        v = _fixed(mpmath.exp(_real(a[0], P)), P) if k == 0 else \
                            sum(map(mul, scaled(args[0], k)[1:k + 1], c[i][k - 1::-1])) // k >> P
                    elif kind == "log":  # a v' = a'
                        v = _fixed(mpmath.log(_real(a[0], P)), P) if k == 0 else \
                            ((a[k] << P) - sum(map(mul, scaled(i, k - 1)[1:k], a[k - 1:0:-1])) // k) // a[0]
                    elif kind == "pow":  # a v' = p v a'
                        if k == 0:
                            v = _fixed(_real(a[0], P) ** _real(data, P), P)
                        else:
                            w = [((data * j - ((k - j) << P)) * a[j]) >> P for j in range(1, k + 1)]
                            v = sum(map(mul, w, c[i][k - 1::-1])) // (k * a[0])
                    elif kind == "integral":  # v' = g(a) a'
                        v = _fixed(getattr(mpmath, data)(_real(a[0], P)), P) if k == 0 else \
                            sum(map(mul, scaled(args[0], k)[1:k + 1], c[args[1]][k - 1::-1])) // k >> P
                    elif kind == "abs":
                        v = a[k] if a[0] >= 0 else -a[k]
                    elif kind == "sign":
                        v = ((a[0] > 0) - (a[0] < 0)) * one if k == 0 else 0
                    else:
                        raise AssertionError(kind)
                c[i].append(v)
            for state, node in zip(y, self.derivatives):
                state.append(c[node][k] // (k + 1))
        return y

    def _solve(self, c, blocks, i, args, data, k) -> tuple:
        """Order ``k`` of ``X`` in ``A X = B``: ``A_0 X_k = B_k - sum_{j=1..k} A_j X_{k-j}``, with
        ``A_0`` factored once (at order 0)."""
        P, mul = self.bits, operator.mul
        m, cols, what = data
        A, B = args[:m * m], args[m * m:]
        if k == 0:
            factors, perm = _lu([[_real(c[A[a * m + b]][0], P) for b in range(m)] for a in range(m)], what)
            blocks[i] = ([[_fixed(v, P) for v in row] for row in factors], perm, [[] for _ in range(m * cols)])
        LU, perm, X = blocks[i]
        for col in range(cols):
            rhs = []
            for a in range(m):
                s = c[B[a * cols + col]][k]
                if k:
                    s -= sum(sum(map(mul, c[A[a * m + b]][1:k + 1], X[b * cols + col][k - 1::-1]))
                             for b in range(m)) >> P
                rhs.append(s)
            sol = [rhs[p] for p in perm]
            for a in range(m):
                sol[a] -= sum(map(mul, LU[a][:a], sol[:a])) >> P
            for a in reversed(range(m)):
                sol[a] = ((sol[a] << P) - sum(map(mul, LU[a][a + 1:], sol[a + 1:]))) // LU[a][a]
            for a in range(m):
                X[a * cols + col].append(sol[a])
        return tuple(X[e][k] for e in range(m * cols))


def _lu(A, what: str = "the mass matrix Mbar"):
    """Doolittle LU with partial pivoting of a small mpf matrix: (LU, perm)."""
    n = len(A)
    A = [row[:] for row in A]
    perm = list(range(n))
    for j in range(n):
        p = max(range(j, n), key=lambda i: abs(A[i][j]))
        if A[p][j] == 0:
            raise ReferenceFailure(f"{what} is singular on the reference trajectory")
        A[j], A[p] = A[p], A[j]
        perm[j], perm[p] = perm[p], perm[j]
        for i in range(j + 1, n):
            A[i][j] /= A[j][j]
            for m in range(j + 1, n):
                A[i][m] -= A[i][j] * A[j][m]
    return A, perm


# ---------------------------------------------------------------------------------------------
# The routes
# ---------------------------------------------------------------------------------------------

def _mpf(value):
    """An mpf at the working precision from a float (exactly), a string or a sympy number."""
    if isinstance(value, (sympy.Basic,)):
        return mpmath.mpf(str(sympy.N(value, mpmath.mp.dps + 5)))
    return mpmath.mpf(value)


def _norm(v) -> object:
    return max(abs(a) for a in v)


@dataclass
class RouteResult:
    """States ``[q; qdot]`` (mpf) at the requested times, and how many steps it took."""

    states: list[list]
    steps: int
    route: str
    dependent: list[list] = field(default_factory=list)  # y_d (mpf) at the times, with constraints


def _targets(times):
    times = [_mpf(t) for t in times]
    if any(b < a for a, b in zip(times, times[1:])) or times[0] < 0:
        raise ValueError("times must be non-negative and non-decreasing")
    return times


def _series_of(system: KnownSystem, param, bits: int) -> _Series:
    """The series of ``y = [q; qdot]`` and, with implicit constraints, of the dependent
    coordinates ``y_d`` after them: ``y_d' = Lambda qdot`` (the derivative of ``g = 0``, (28)),
    ``G_d Lambda = -G_i`` and ``G_d gamma = -(ydot^T g'' ydot)`` solved order by order as
    ``Mbar qddot = fbar - hbar`` is. Only ``y_d``'s own value comes from ``g = 0`` itself
    (:class:`_Closure`, at the start of every step)."""
    n = len(system.coordinates)
    constants = {p.symbol: _mpf(v) for p, v in zip(system.parameters, param)}
    imp = system.implicit
    dependent = tuple(imp.dependent) if imp is not None else ()
    tape = Tape([*system.coordinates, *system.state_velocities, *dependent], constants)

    def nodes(matrix) -> list[list[int]]:
        return [[tape.node(sympy.sympify(matrix[a, b])) for b in range(matrix.cols)] for a in range(matrix.rows)]

    if imp is not None:
        k = len(dependent)
        G_d = nodes(imp.jacobian_dependent)
        lam = tape.solve(G_d, nodes(-imp.jacobian_independent), "dg/d(" + ", ".join(d.name for d in dependent) + ")")
        for a in range(k):
            for j in range(n):
                tape.memo[imp.sensitivities[a, j]] = lam[a][j]
        quadratic = sympy.Matrix([sympy.sympify(e) for e in imp.quadratic])
        gamma = tape.solve(G_d, nodes(quadratic), "dg/d(" + ", ".join(d.name for d in dependent) + ")")
        for a in range(k):
            tape.memo[imp.convective[a]] = gamma[a][0]
    s = system.speeds  # under velocity constraints: y = [q; u], q' = C(q) u, Mbar u' = fbar - hbar
    if s is not None and projected_in_numbers(system) and frame_applies(system):  # projected on the tape
        return _Series(tape, _frame_derivatives(system, tape, nodes), bits)
    if s is not None:
        M, r = s.mass_matrix, s.forces - s.velocity_terms
        velocities = [sympy.sympify(e) for e in s.kinematics]
    else:
        M, r = system.mass_matrix, system.forces - system.velocity_terms
        velocities = list(system.velocities)
        first = first_order(system)
        if first is not None:  # the mixed system: qdot_J solved, M_JJ = 1 and r_J = 0 (core/first_order.py)
            r = r.xreplace(first.substitution(system))
            M = sympy.Matrix(n, n, lambda i, j: int(i == j) if i in first.indices else M[i, j])
            r = sympy.Matrix([0 if i in first.indices else r[i] for i in range(n)])
            for j, v in zip(first.indices, first.velocities):
                velocities[j] = v
    accelerations = tape.solve(nodes(M), nodes(sympy.Matrix(r)), "the mass matrix Mbar")
    derivatives = [tape.node(v) for v in velocities] + [row[0] for row in accelerations]
    if imp is not None:
        derivatives += [tape.node(sympy.Add(*[imp.sensitivities[a, j] * system.velocities[j] for j in range(n)]))
                        for a in range(len(dependent))]
    return _Series(tape, derivatives, bits)


class _Closure:
    """The dependent coordinates on ``g(xbar, y_d) = 0`` (25) at given independent ones:
    Newton's method in mpmath, ``G_d dy = -g``, warm-started from the last solution (the
    branch of the initial configuration); nothing when the system has no constraints."""

    def __init__(self, system: KnownSystem, param, bits: int, guess=None):
        imp = system.implicit
        self.bits, self.n = bits, len(system.coordinates)
        self.k = len(imp.dependent) if imp is not None else 0
        if not self.k:
            return
        y = [*imp.independent, *imp.dependent]
        g = sympy.Matrix([sympy.sympify(e) for e in imp.residuals])
        symbols = [p.symbol for p in system.parameters]
        unknown = sorted((g.free_symbols - set(y) - set(symbols)), key=lambda v: v.name)
        if unknown:
            raise ReferenceFailure(f"the constraints use {', '.join(v.name for v in unknown)}, which is neither "
                                   "a coordinate nor a parameter")
        self._g = sympy.lambdify([y, symbols], list(g), modules="mpmath")
        self._G = sympy.lambdify([y, symbols], imp.jacobian_dependent.tolist(), modules="mpmath")
        self.param = [_mpf(v) for v in param]
        self.names = ", ".join(f"'{c.name}'" for c in imp.constraints)
        branch = dict(imp.branch)
        start = guess if guess is not None else [branch.get(d, 0.0) for d in imp.dependent]
        self.guess = [_mpf(v) for v in start]

    def dependent(self, q_fixed: list[int]) -> list[int]:
        """``y_d`` (fixed point) at the independent coordinates ``q_fixed`` (fixed point)."""
        if not self.k:
            return []
        P = self.bits
        q = [_real(v, P) for v in q_fixed]
        yd = list(self.guess)
        tol = mpmath.ldexp(1, 24 - P)
        for _ in range(60):
            r = [mpmath.mpf(v) for v in self._g([*q, *yd], self.param)]
            G = [[mpmath.mpf(v) for v in row] for row in self._G([*q, *yd], self.param)]
            LU, perm = _lu(G, "dg/d(dependent coordinates)")
            step = [-r[p] for p in perm]
            for a in range(self.k):
                step[a] -= mpmath.fsum(LU[a][b] * step[b] for b in range(a))
            for a in reversed(range(self.k)):
                step[a] = (step[a] - mpmath.fsum(LU[a][b] * step[b] for b in range(a + 1, self.k))) / LU[a][a]
            yd = [v + dv for v, dv in zip(yd, step)]
            if max(abs(dv) for dv in step) <= tol * (1 + max(abs(v) for v in yd)):
                self.guess = yd
                return [_fixed(v, P) for v in yd]
        raise ReferenceFailure(f"Newton's method on the constraints {self.names} does not converge on the "
                               "reference trajectory (a toggle position?)")


def _frame_derivatives(system: KnownSystem, tape: Tape, nodes) -> list[int]:
    """The nodes of ``[qdot; udot]`` of a system whose projection onto the speeds is too large to
    make symbolically, projected on the tape as the generated C does at run time
    (:mod:`kronsub.emitters.projected_speeds`): ``S w = r0 + [0; u]``, ``S C = [0; I]``,
    ``S c = -rho'`` at ``qdot = w``, then ``Mbar = C^T M C`` (9'), (D) and
    ``Mbar udot = C^T (f - h - M c)`` (E), (F), each solve order by order."""
    eq = frame_equations(system)
    n, p = eq.S.rows, len(system.speeds.speeds)
    S = nodes(eq.S)
    w = tape.solve(S, nodes(eq.r0 + sympy.Matrix([0] * (n - p) + list(system.speeds.speeds))), "S = [G; A; Y]")
    for k, q in enumerate(system.coordinates):
        tape.memo[velocity_symbol(q)] = w[k][0]
    c = tape.solve(S, nodes(-eq.rates), "S = [G; A; Y]")
    C = tape.solve(S, nodes(sympy.zeros(n - p, p).col_join(sympy.eye(p))), "S = [G; A; Y]")
    Cs = [[sympy.Dummy(f"C{a}_{i}") for i in range(p)] for a in range(n)]
    cs = [sympy.Dummy(f"c{a}") for a in range(n)]
    for a in range(n):
        tape.memo[cs[a]] = c[a][0]
        for i in range(p):
            tape.memo[Cs[a][i]] = C[a][i]
    M, r = eq.metric, eq.forces
    rx = [sympy.Add(r[a], -sympy.Add(*[M[a, b] * cs[b] for b in range(n) if M[a, b] != 0])) for a in range(n)]
    Mbar = sympy.Matrix(p, p, lambda i, j: sympy.Add(*[Cs[a][i] * M[a, b] * Cs[b][j] for a in range(n)
                                                       for b in range(n) if M[a, b] != 0]))
    rbar = sympy.Matrix([sympy.Add(*[Cs[a][i] * rx[a] for a in range(n)]) for i in range(p)])
    accelerations = tape.solve(nodes(Mbar), nodes(rbar), "the mass matrix Mbar")
    return [row[0] for row in w] + [row[0] for row in accelerations]


def taylor(system: KnownSystem, param, y0, times, digits: int = 30, dependent=None) -> RouteResult:
    """The Taylor series route: states at ``times`` (from ``y0`` at t = 0), ``digits`` digits.
    With implicit constraints, ``dependent`` (floats) picks the branch; the dependent coordinates
    are series too (:func:`_series_of`), their value put back on ``g = 0`` at every step."""
    with mpmath.workdps(digits + 10):
        eps = mpmath.mpf(10) ** -(digits + 2)
        order = int(math.ceil(0.5 * (digits + 2) * math.log(10))) + 2
        P = int((digits + 10) * math.log2(10)) + 16
        series = _series_of(system, param, P)
        closure = _Closure(system, param, P, dependent)
        n = len(system.coordinates)
        ny = n + len(system.state_velocities)
        t, y, steps, out, deps = 0, [_fixed(_mpf(v), P) for v in y0], 0, [], []
        end = _fixed(_targets(times)[-1], P)
        for target in _targets(times):
            target = _fixed(target, P)
            while t < target:
                coeff = series.coefficients(t, y + closure.dependent(y[:n]), order)
                scale = max(1, _norm([_real(s[0], P) for s in coeff]))
                h = None
                for k in range(order - 3, order + 1):
                    size = _norm([_real(s[k], P) for s in coeff])
                    if size:
                        hk = _fixed((eps * scale / size) ** (mpmath.mpf(1) / k), P)
                        h = hk if h is None else min(h, hk)
                if h is not None:
                    _within_budget(steps, t, h, end, P)
                h = target - t if h is None or t + h >= target else h
                new = []
                for s in coeff:  # Horner
                    v = s[order]
                    for a in s[order - 1::-1]:
                        v = ((v * h) >> P) + a
                    new.append(v)
                y = new[:ny]
                if closure.k:  # the series' y_d at the step's end: the next warm start
                    closure.guess = [_real(v, P) for v in new[ny:]]
                t += h
                steps += 1
            out.append([_real(v, P) for v in y])
            if closure.k:
                deps.append([_real(v, P) for v in closure.dependent(y[:n])])
        return RouteResult(out, steps, f"Taylor series, order {order}", deps)


def extrapolation(system: KnownSystem, param, y0, times, digits: int = 30, dependent=None) -> RouteResult:
    """The Gragg-Bulirsch-Stoer route: the explicit midpoint rule with n = 2, 4, ..., 2K
    substeps, Aitken-Neville extrapolation in h^2 and step control on the last two columns,
    in fixed point; the right-hand side is the tape's order-1 coefficient, with implicit
    constraints at the dependent coordinates found by Newton's method in every evaluation."""
    with mpmath.workdps(digits + 10):
        P = int((digits + 10) * math.log2(10)) + 16
        series = _series_of(system, param, P)
        closure = _Closure(system, param, P, dependent)
        n = len(system.coordinates)
        ny = n + len(system.state_velocities)
        K = max(6, (digits + 3) // 2)
        tol = mpmath.mpf(10) ** -(digits + 2)
        t, y, steps, out, h = 0, [_fixed(_mpf(v), P) for v in y0], 0, [], 1 << (P - 5)
        end = _fixed(_targets(times)[-1], P)
        deps = []

        def f(tt, z):
            return [s[1] for s in series.coefficients(tt, z + closure.dependent(z[:n]), 1)[:ny]]

        for target in _targets(times):
            target = _fixed(target, P)
            while t < target:
                step = min(h, target - t)
                f0 = f(t, y)
                table: list[list] = []
                for j in range(K):
                    m = 2 * (j + 1)
                    hh = step // m
                    z0, z1 = y, [a + ((hh * b) >> P) for a, b in zip(y, f0)]
                    for i in range(1, m):
                        z0, z1 = z1, [a + ((2 * hh * b) >> P) for a, b in zip(z0, f(t + i * hh, z1))]
                    row = [z1]
                    for k in range(1, j + 1):  # T_jk = T_j,k-1 + (T_j,k-1 - T_j-1,k-1) / ((n_j/n_j-k)^2 - 1)
                        num, den = (j + 1) ** 2 - (j + 1 - k) ** 2, (j + 1 - k) ** 2
                        row.append([a + (a - b) * den // num for a, b in zip(row[k - 1], table[j - 1][k - 1])])
                    table.append(row)
                best, second = table[-1][-1], table[-1][-2]
                scale = max(1, _norm([_real(v, P) for v in y]))
                err = _real(max(abs(a - b) for a, b in zip(best, second)), P) / (tol * scale)
                factor = 4 if err == 0 else min(4, max(0.2, float(0.9 * err ** (-mpmath.mpf(1) / (2 * K - 1)))))
                if err <= 1:
                    t += step
                    y = best
                    steps += 1
                h = int(step * factor)
                if h < (1 << P) // 10 ** (digits // 2):
                    raise ReferenceFailure(f"the extrapolation route's step underflowed at t = {float(_real(t, P)):.6g}")
                _within_budget(steps, t, h, end, P)
            out.append([_real(v, P) for v in y])
            if closure.k:
                deps.append([_real(v, P) for v in closure.dependent(y[:n])])
        return RouteResult(out, steps, f"Gragg-Bulirsch-Stoer extrapolation, {K} stages", deps)


@dataclass
class Reference:
    """The reference states ``[q; qdot]`` (mpf) at ``times``; ``error`` estimates their largest
    error, ``routes`` say how they were computed and cross-checked."""

    times: list[float]
    states: list[list]
    error: float
    digits: int
    routes: tuple[str, ...]
    dependent: list[list] = field(default_factory=list)  # y_d (mpf) at ``times``, with constraints

    def at(self, i: int):
        """The state at ``times[i]`` as float64."""
        return [float(v) for v in self.states[i]]


def _difference(a: list[list], b: list[list]) -> float:
    return float(max(abs(x - y) for sa, sb in zip(a, b) for x, y in zip(sa, sb)))


def reference(system: KnownSystem, param, y0, times, digits: int = 20, dependent=None) -> Reference:
    """The Taylor route at ``digits + 8`` digits, at every time of ``times``.

    Its error is estimated by the Taylor route at ``digits`` digits (another order, other
    steps, less precision): their largest difference bounds the lower run's error, and the
    higher run is far better. The extrapolation route at ``digits`` digits cross-checks it up
    to the first time (where it is cheap); a worse agreement raises the estimate. With
    implicit constraints, ``dependent`` picks the branch, and the two routes find the
    dependent coordinates in two ways (series from ``y_d' = Lambda qdot``; Newton's method in
    every evaluation)."""
    with mpmath.workdps(digits + 20):
        try:
            high = taylor(system, param, y0, times, digits + 8, dependent)
            low = taylor(system, param, y0, times, digits, dependent)
            check = extrapolation(system, param, y0, times[:1], digits, dependent)
        except ZeroDivisionError:
            raise ReferenceFailure("the equations divide by zero on the reference trajectory (a singular "
                                   "configuration?)\n  hint: start elsewhere with --set") from None
        error = _difference(high.states, low.states)
        agreement = _difference(high.states[:1], check.states)
    first = float(times[0])
    return Reference([float(t) for t in times], high.states, max(error, agreement), digits + 8,
                     (f"{high.route} at {digits + 8} digits",
                      f"the same at {digits} digits: largest difference {error:.1e}",
                      f"{check.route} at {digits} digits to t = {first:g}: agrees to {agreement:.1e}"),
                     high.dependent)
