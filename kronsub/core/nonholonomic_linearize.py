"""Linearisation of a constrained system about a steady motion, dependent coordinates and
speeds taken along (Peterson, Gede & Hubbard 2014).

The system in its coordinates ``x`` (n), with configuration constraints ``g(x, t) = 0`` (l),
velocity constraints ``A(x) xdot + b(x, t) = 0`` (m) and speeds ``u = Y(x) xdot`` (p = n - l - m):

    S(x) xdot = r(x, u, t),   S = [G; A; Y],   r = [-dg/dt; -b; u],   G = dg/dx
    xdot = w(x, u, t) = C u + d,   C = S^-1 [0; I]                      (non-holonomic frame)
    Mbar udot = fbar - hbar                                              (9'), (D)-(F)
    Mbar = C^T M C,   hbar = C^T (M (Cdot u + ddot) + h(x, xdot)),   fbar = C^T f(x, xdot, t)
    Cdot u + ddot = sum_k (dw/dx_k) w_k + dw/dt,   dw/dx_k = S^-1 (dr/dx_k - dS/dx_k w)

``M(x) = J^T W J`` (a primitive ``W`` and its projection ``J``; ``J = I`` for a metric given
as it is) and ``h`` its Christoffel terms (A), ``h_a = (d_c M_ab - 1/2 d_a M_bc) xdot^b xdot^c``,
unless the system brings its own.

A naive Jacobian goes wrong in two ways. Holding the dependent speeds (``w``) or ``C``
fixed while ``x`` moves misses ``dC/dx`` acting on the constraint forces ``C^T`` turns away,
which are not zero at a steady motion: with ``G C = 0``, ``(dC/dx)^T G^T mu = -C^T (d^2 g/dx^2) mu``,
the curvature of the contact times the load ``mu`` on it (a bicycle's front wheel). And
moving the dependent coordinates independently of the others leaves ``g = 0``. Here
the rates ``F(x, u) = [w; Mbar^-1 (fbar - hbar)]`` are differentiated whole, every dependence
taken, and the result restricted to the tangent of ``g = 0``, ``dx_D = -G_D^-1 G_K dx_K``:
``G dx`` is constant along the linearised motion (``d(G dx)/dt = 0`` because ``dG_ij/dx_k``
is symmetric in ``j, k``), so that subspace is invariant and the restriction exact. The
coordinates that are neither kept nor dependent are ignorable (cyclic): the kept rates
must not depend on them, which is checked.

The derivatives of ``F`` are taken by the complex step (Squire & Trapp 1998):
``dF/dz_j = Im F(z + i h e_j) / h`` with no difference taken, so exact to rounding for a tiny
``h``; ``F`` needs only ``W, J, dJ/dx, S, dS/dx, r, dr/dx`` and ``f`` symbolically.
"""
from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy

from .derivative import derivative, jacobian, where_defined
from .known_system import KnownSystem
from .linearize_numerics import Linearization, LinearizationError, numeric_value, parameter_numbers
from .symbols import TIME, velocity_symbol
from ..errors import assignment, option

COMPLEX_STEP = 1e-30
"""The step ``h`` of the complex step: ``Im F(z + i h)`` is ``h F'(z)`` to ``O(h^3)``, no cancellation."""
STEADY_TOLERANCE = 1e-8
"""Largest rate of a kept coordinate or of a speed (relative to the speeds' size) at a point called steady."""
IGNORABLE_TOLERANCE = 1e-9
"""Largest dependence of a kept rate on an ignorable coordinate (relative to the Jacobian's size)."""
NEWTON_STEPS = 50  # iterations allowed to put the dependent coordinates on g = 0


@dataclass(frozen=True)
class ProjectedMetric:
    """``M(x) = J(x)^T W(x) J(x)``: a primitive metric ``W`` and its projection ``J``; with the
    primitive's own velocity terms ``h_p(x, v)`` (in its ``velocities`` ``v = J xdot``),
    ``h = J^T (W (dJ/dx^k xdot^k) xdot + h_p)`` (E) instead of the Christoffel terms of ``M``."""

    weights: sympy.Matrix
    projection: sympy.Matrix
    velocity_terms: sympy.Matrix | None = None
    velocities: tuple[sympy.Symbol, ...] = ()


@dataclass(frozen=True)
class ConstrainedMotion:
    """A system in coordinates ``x`` with configuration and velocity constraints, and its speeds.

    ``metric`` is ``M(x)`` or a :class:`ProjectedMetric` (blocks stacked: one per body);
    ``force`` is ``f(x, xdot, t)``; ``speeds`` maps each speed to ``Y(x) xdot``;
    ``velocity_constraints`` are expressions ``A(x) xdot + b(x, t)`` (``= 0``),
    ``configuration_constraints`` expressions ``g(x, t)`` (``= 0``); ``velocity_terms`` is
    ``h(x, xdot)`` when it is not the metric's own (Christoffel) terms.
    """

    coordinates: tuple[sympy.Symbol, ...]
    metric: sympy.Matrix | ProjectedMetric
    force: sympy.Matrix
    speeds: Mapping[sympy.Symbol, sympy.Expr]
    velocity_constraints: tuple[sympy.Expr, ...] = ()
    configuration_constraints: tuple[sympy.Expr, ...] = ()
    velocity_terms: sympy.Matrix | None = None


@dataclass(frozen=True)
class MotionParts:
    """The pieces of the rates at one state ``(x, u, t)``: ``S = [G; A; Y]``, ``xdot = w = C u + d``,
    ``C``, ``Cdot u + ddot`` along the motion, and ``M``, ``h``, ``f`` in ``x`` at ``xdot = w``."""

    frame: np.ndarray  # S
    rates: np.ndarray  # w
    transformation: np.ndarray  # C
    convective: np.ndarray  # Cdot u + ddot
    metric: np.ndarray  # M
    velocity_terms: np.ndarray  # h
    force: np.ndarray  # f

    def speed_rates(self) -> np.ndarray:
        """``udot = Mbar^-1 (fbar - hbar)``, ``Mbar = C^T M C`` (9'), (D),
        ``fbar - hbar = C^T (f - h - M (Cdot u + ddot))`` (E), (F)."""
        C, M = self.transformation, self.metric
        return np.linalg.solve(C.T @ M @ C, C.T @ (self.force - self.velocity_terms - M @ self.convective))


def linear_rows(exprs: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol], what: str
                ) -> tuple[sympy.Matrix, sympy.Matrix]:
    """``A`` and ``b`` of ``A(x) xdot + b`` for expressions linear in the velocities, taken by
    differentiation without expanding (a rolling wheel's rows are long products); an
    expression the velocities are left in after it is not linear (:func:`.nonholonomic.linear_form`
    expands, then checks the same)."""
    velocities = [velocity_symbol(q) for q in coordinates]
    rows, offsets = [], []
    for i, e in enumerate(exprs):
        row = [derivative(e, v) for v in velocities]
        if any(set(velocities) & r.free_symbols for r in row):
            raise LinearizationError(f"{what} {i + 1} is not linear in the velocities\n  hint: write it as "
                                     "A(x) xdot + b(x, t)")
        rows.append(row)
        offsets.append(e.xreplace({v: 0 for v in velocities}))
    return (sympy.Matrix(rows) if rows else sympy.zeros(0, len(coordinates))), \
        (sympy.Matrix(offsets) if offsets else sympy.zeros(0, 1))


class _Compiled:
    """One numpy function of the coordinates, velocities, time and inputs for a list of matrices."""

    def __init__(self, matrices: Sequence[sympy.Matrix], arguments: Sequence[sympy.Symbol]):
        self.shapes = [m.shape for m in matrices]
        flat = [e for m in matrices for e in m]
        self.fn = sympy.lambdify([list(arguments)], flat, modules=["numpy"], cse=True)

    def __call__(self, arguments) -> list[np.ndarray]:
        flat = np.array(self.fn(arguments), dtype=complex).ravel() if self.shapes else np.zeros(0)
        out, start = [], 0
        for rows, cols in self.shapes:
            out.append(flat[start:start + rows * cols].reshape(rows, cols))
            start += rows * cols
        return out


def frame_matrix(g: sympy.Matrix, rows, speeds, x) -> tuple[sympy.Matrix, sympy.Matrix, sympy.Matrix]:
    """``S = [G; A; Y]`` and ``r0 = [-dg/dt; -b; 0]`` of ``S xdot = r0 + [0; u]``: the
    configuration constraints ``g`` (``G = dg/dx``), the velocity constraints' ``rows``
    ``A xdot + b`` and the ``speeds`` ``u = Y xdot`` in the coordinates ``x``; and ``G``. Raises
    :class:`LinearizationError` where they do not make one: a speed with a term free of the
    velocities, a count that is not the coordinates', coefficients that depend on ``t``."""
    n = len(x)
    G = jacobian(g, list(x)) if g.rows else sympy.zeros(0, n)
    A, b = linear_rows(list(rows), x, "velocity constraint")
    Y, c = linear_rows(list(speeds), x, "speed")
    if any(e != 0 for e in c):
        raise LinearizationError("a speed has a term without a velocity\n  hint: define each speed as Y(x) xdot")
    p = len(speeds)
    if G.rows + A.rows + p != n:
        raise LinearizationError(
            f"{p} speed(s) for {n - G.rows - A.rows} degree(s) of freedom\n  hint: name as many speeds as the "
            f"{n} coordinates less the {G.rows} configuration and {A.rows} velocity constraints")
    S = G.col_join(A).col_join(Y)
    if any(e.has(TIME) for e in S):
        raise LinearizationError("a constraint's velocity coefficients depend on time\n  hint: only the offset "
                                 "b(x, t) of A(x) xdot + b(x, t) = 0 may depend on t")
    r0 = (-where_defined(g.diff(TIME)) if g.rows else sympy.zeros(0, 1)).col_join(-b).col_join(sympy.zeros(p, 1))
    return S, r0, G


class SteadyMotionRates:
    """The rates ``F(x, u) = [w; udot]`` of a :class:`ConstrainedMotion` at numeric parameter
    values, in complex arithmetic (for the complex step), and its linearisation."""

    def __init__(self, motion: ConstrainedMotion, values: Mapping[sympy.Symbol, float] | None = None,
                 inputs: Sequence[sympy.Symbol] = ()):
        self.motion = motion
        x = self.x = tuple(motion.coordinates)
        n = self.n = len(x)
        xd = [velocity_symbol(q) for q in x]
        self.speeds = tuple(motion.speeds)
        self.inputs = tuple(inputs)
        numbers = {s: sympy.Float(float(v), 17) for s, v in (values or {}).items()}
        self.values = tuple((s, float(v)) for s, v in (values or {}).items())

        def fixed(m):
            return sympy.Matrix(m).xreplace(numbers) if numbers else sympy.Matrix(m)

        g = fixed(sympy.Matrix(list(motion.configuration_constraints))) if motion.configuration_constraints \
            else sympy.zeros(0, 1)
        self.l = g.rows
        self.p = len(self.speeds)
        # r = [-dg/dt; -b; u] less its u part, which is added numerically
        S, r0, G = frame_matrix(g, [fixed(sympy.Matrix([c]))[0] for c in motion.velocity_constraints],
                                [fixed(sympy.Matrix([e]))[0] for e in motion.speeds.values()], x)
        primitive_h, primitive_v = None, ()
        if isinstance(motion.metric, ProjectedMetric):
            W, J = fixed(motion.metric.weights), fixed(motion.metric.projection)
            if motion.metric.velocity_terms is not None:
                primitive_h, primitive_v = fixed(motion.metric.velocity_terms), tuple(motion.metric.velocities)
        else:
            W, J = fixed(motion.metric), sympy.eye(n)
        f = fixed(motion.force)
        h = fixed(motion.velocity_terms) if motion.velocity_terms is not None else None
        # hbar: the system's own (h), J^T (W Jdot xdot + h_p) of the primitive's (h_p), or (A) of M
        self.h_from = "own" if h is not None else "primitive" if primitive_h is not None else "christoffel"
        args = [*x, TIME, *self.inputs]
        rates_args = [*x, *xd, TIME, *self.inputs]
        self._check_free([S, r0, W, J, f] + ([h] if h is not None else []) + [g], set(rates_args))
        if primitive_h is not None:
            self._check_free([primitive_h], set(rates_args) | set(primitive_v))

        def d(m, s):
            return m.applyfunc(lambda e: derivative(e, s))

        metric_rates = {"own": [], "primitive": [d(J, q) for q in x],
                        "christoffel": [d(J, q) for q in x] + [d(W, q) for q in x]}[self.h_from]
        self._position = _Compiled([S, r0, W, J]
                                   + [d(S, q) for q in x] + [d(r0, q) for q in x] + [d(r0, TIME)] + metric_rates, args)
        self._forces = _Compiled([f] + ([h] if h is not None else []), rates_args)
        if primitive_h is not None:
            self._primitive_h = _Compiled([primitive_h], [*x, *primitive_v, TIME, *self.inputs])
        self._g = _Compiled([g, G], args)

    @staticmethod
    def _check_free(matrices, allowed):
        left = set()
        for m in matrices:
            for e in m:
                left |= sympy.sympify(e).free_symbols - allowed
        if left:
            names = ", ".join(sorted(s.name for s in left))
            raise LinearizationError(f"no value for parameter{'s' if len(left) > 1 else ''} {names}\n  hint: give "
                                     "every parameter a value")

    def parts(self, x, u, t=0.0, inputs=()) -> MotionParts:
        """``S``, ``w = C u + d``, ``C``, ``Cdot u + ddot``, ``M``, ``h`` and ``f`` at ``(x, u, t)``
        (complex numbers allowed)."""
        n, p = self.n, self.p
        x = np.asarray(x, dtype=complex)
        u = np.asarray(u, dtype=complex)
        args = [*x, t, *inputs]
        out = self._position(args)
        S, r0, W, J = out[:4]
        dS, dr, dr_t = out[4:4 + n], out[4 + n:4 + 2 * n], out[4 + 2 * n]
        r = r0.ravel().copy()
        r[n - p:] += u
        try:
            w = np.linalg.solve(S, r)
            C = np.linalg.solve(S, np.vstack([np.zeros((n - p, p)), np.eye(p)]))
            convective = np.linalg.solve(S, dr_t.ravel() + sum(
                (dr[k].ravel() - dS[k] @ w) * w[k] for k in range(n)))
        except np.linalg.LinAlgError:
            raise LinearizationError("the constraints and speeds do not fix the velocities here\n  hint: choose "
                                     "speeds that stay independent at the operating point") from None
        M = J.T @ W @ J
        forces = self._forces([*x, *w, t, *inputs])
        f = forces[0].ravel()
        dJ = out[5 + 2 * n:5 + 3 * n]
        if self.h_from == "own":
            h = forces[1].ravel()
        elif self.h_from == "primitive":  # (E): J^T (W (dJ/dx^k w^k) w + h_p(x, J w))
            h_p = self._primitive_h([*x, *(J @ w), t, *inputs])[0].ravel()
            h = J.T @ (W @ (sum(dJ[k] * w[k] for k in range(n)) @ w) + h_p)
        else:  # (A): (d_c M_ab) w_b w_c - 1/2 w_b (d_a M_bc) w_c
            dW = out[5 + 3 * n:5 + 4 * n]
            dM = [dJ[k].T @ W @ J + J.T @ dW[k] @ J + J.T @ W @ dJ[k] for k in range(n)]
            h = sum(dM[k] * w[k] for k in range(n)) @ w - 0.5 * np.array([w @ dM[a] @ w for a in range(n)])
        return MotionParts(frame=S, rates=w, transformation=C, convective=convective, metric=M, velocity_terms=h,
                           force=f)

    def rates(self, x, u, t=0.0, inputs=()) -> np.ndarray:
        """``[xdot; udot]`` at ``(x, u, t)`` (complex numbers allowed): ``udot = Mbar^-1 (fbar - hbar)``
        of :meth:`MotionParts.speed_rates`."""
        parts = self.parts(x, u, t, inputs)
        return np.concatenate([parts.rates, parts.speed_rates()])

    def kinetic_energy(self, x, u, t=0.0, inputs=()) -> float:
        """``T = 1/2 (C u)^T M (C u)`` (24) at ``(x, u, t)``: the kinetic energy in the speeds, less
        the motion ``d`` that constraints in time impose (as :func:`.nonholonomic.speed_equations`)."""
        n, p = self.n, self.p
        S, _, W, J = self._position([*np.asarray(x, dtype=float), t, *inputs])[:4]
        C = np.linalg.solve(S.real, np.vstack([np.zeros((n - p, p)), np.eye(p)]))
        v = J.real @ (C @ np.asarray(u, dtype=float))
        return 0.5 * float(v @ W.real @ v)

    def constraint(self, x, t=0.0, inputs=()) -> np.ndarray:
        """``g(x, t)`` and ``G = dg/dx``."""
        g, G = self._g([*np.asarray(x, dtype=complex), t, *inputs])
        return g.ravel().real, G.real

    def on_constraints(self, x, dependent: Sequence[int], t=0.0, inputs=()) -> np.ndarray:
        """``x`` with its ``dependent`` coordinates moved onto ``g = 0`` (Newton's method)."""
        x = np.array(x, dtype=float)
        if not self.l:
            return x
        if len(dependent) != self.l:
            raise LinearizationError(f"{len(dependent)} dependent coordinate(s) for {self.l} configuration "
                                     "constraint(s)\n  hint: name one dependent coordinate per configuration "
                                     "constraint")
        for _ in range(NEWTON_STEPS):
            g, G = self.constraint(x, t, inputs)
            if np.max(np.abs(g)) <= 1e-14 * max(1.0, np.max(np.abs(x))):
                return x
            x[list(dependent)] -= np.linalg.solve(G[:, list(dependent)], g)
        raise LinearizationError("the configuration constraints cannot be met near the operating point\n  hint: "
                                 "give the dependent coordinates a value near a solution")

    def jacobian(self, x, u, t=0.0, inputs=()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``F`` and its Jacobians in ``[x; u]`` and in the inputs, by the complex step."""
        z = np.concatenate([np.asarray(x, dtype=float), np.asarray(u, dtype=float)])
        v = np.asarray(inputs, dtype=float)
        n = self.n
        F = self.rates(z[:n], z[n:], t, v).real
        cols = []
        for j in range(len(z)):
            zj = z.astype(complex)
            zj[j] += 1j * COMPLEX_STEP
            cols.append(self.rates(zj[:n], zj[n:], t, v).imag / COMPLEX_STEP)
        icols = []
        for j in range(len(v)):
            vj = v.astype(complex)
            vj[j] += 1j * COMPLEX_STEP
            icols.append(self.rates(z[:n], z[n:], t, vj).imag / COMPLEX_STEP)
        width = len(F)
        return (F, np.array(cols).T if cols else np.zeros((width, 0)),
                np.array(icols).T if icols else np.zeros((width, 0)))

    def linearize(self, point: Mapping[sympy.Symbol, float], keep: Sequence[sympy.Symbol] | None = None,
                  dependent: Sequence[sympy.Symbol] = (), time: float = 0.0,
                  inputs: Mapping[sympy.Symbol, float] | None = None) -> Linearization:
        """``A``, ``B`` in the state ``[kept coordinates; speeds]`` about the motion through
        ``point`` (coordinates and speeds; those not given are 0; the ``dependent``
        coordinates are moved onto ``g = 0`` from there). Without ``keep``, every coordinate
        that is not dependent and not ignorable there (:func:`ignorable`) is kept."""
        index = {q: i for i, q in enumerate(self.x)}
        unknown = [s for s in list(keep or ()) + list(dependent) if s not in index]
        if unknown:
            raise LinearizationError(f"'{unknown[0]}' is not a coordinate")
        D = [index[q] for q in dependent]
        x0 = np.array([float(point.get(q, 0.0)) for q in self.x])
        u0 = np.array([float(point.get(s, 0.0)) for s in self.speeds])
        v0 = [float((inputs or {}).get(s, 0.0)) for s in self.inputs]
        x0 = self.on_constraints(x0, D, time, v0)
        with np.errstate(all="ignore"):  # a point beyond the doubles is reported below, not warned of
            F, Jz, Jv = self.jacobian(x0, u0, time, v0)
        n, p = self.n, self.p
        scale = max(1.0, float(np.max(np.abs(Jz))))
        if keep is None:
            _, G = self.constraint(x0, time, v0)
            left_out = ignorable(Jz, G, D, n, IGNORABLE_TOLERANCE * scale)
            keep = [q for i, q in enumerate(self.x) if i not in left_out and i not in D]
        K = [index[q] for q in keep]
        if set(K) & set(D):
            raise LinearizationError("a coordinate is both kept and dependent")
        ignored = [i for i in range(self.n) if i not in K and i not in D]
        U = list(range(n, n + p))
        rows = K + D + U
        if ignored:
            worst = float(np.max(np.abs(Jz[np.ix_(rows, ignored)])))
            if worst > IGNORABLE_TOLERANCE * scale:
                culprit = ignored[int(np.argmax(np.max(np.abs(Jz[np.ix_(rows, ignored)]), axis=0)))]
                raise LinearizationError(
                    f"the motion depends on '{self.x[culprit]}', which is neither kept nor dependent\n  hint: keep it "
                    "in the state (only ignorable coordinates may be left out)")
        _, G = self.constraint(x0, time, v0)
        if self.l:
            if np.max(np.abs(G[:, ignored]), initial=0.0) > IGNORABLE_TOLERANCE * max(1.0, np.max(np.abs(G))):
                raise LinearizationError("a configuration constraint involves a coordinate that is neither kept nor "
                                         "dependent\n  hint: keep it in the state")
            tangent = -np.linalg.solve(G[:, D], G[:, K])  # dx_D = tangent dx_K
        else:
            tangent = np.zeros((0, len(K)))
        state_rows = K + U
        A = np.hstack([Jz[np.ix_(state_rows, K)] + Jz[np.ix_(state_rows, D)] @ tangent, Jz[np.ix_(state_rows, U)]])
        B = Jv[state_rows, :]
        speed_scale = max(1.0, float(np.max(np.abs(u0), initial=0.0)))
        steady = bool(np.max(np.abs(F[K + D + U]), initial=0.0) <= STEADY_TOLERANCE * speed_scale * speed_scale)
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
            raise LinearizationError("A is not finite at the operating point: the equations overflow a double "
                                     "there\n  hint: check the values given with " + option("at") + " and the parameters' values")
        eigenvalues = tuple(complex(e) for e in np.linalg.eigvals(A)) if A.size else ()
        return Linearization(
            state=tuple(self.x[i] for i in K) + self.speeds, inputs=self.inputs,
            point=tuple((q, float(v)) for q, v in zip(self.x, x0)) + tuple(zip(self.speeds, map(float, u0)))
            + tuple(zip(self.inputs, v0)),
            time=sympy.Float(time), parameters=self.values, A=A, B=B, eigenvalues=eigenvalues,
            acceleration=tuple(float(a) for a in F[U]), equilibrium=steady, found=tuple(dependent),
            notes=() if steady else ("not a steady motion: the kept state moves at this point",),
            dependent=tuple((self.x[i], float(x0[i])) for i in D))


def ignorable(jacobian: np.ndarray, G: np.ndarray, dependent: Sequence[int], n: int, tolerance: float) -> set[int]:
    """The largest set ``I`` of coordinates (not dependent) that neither the rates of the others
    nor those of the speeds, nor the configuration constraints, depend on at the point: the
    cyclic coordinates of a steady motion (a wheel's turn, the position and heading on the
    plane), found by dropping from all of them those some row outside the set depends on."""
    found = {i for i in range(n) if i not in dependent}
    while True:
        outside = [i for i in range(jacobian.shape[0]) if i not in found]
        drop = {i for i in found if np.max(np.abs(jacobian[outside, i]), initial=0.0) > tolerance
                or np.max(np.abs(G[:, i]), initial=0.0) > tolerance}
        if not drop:
            return found
        found -= drop


def linearize_steady_motion(motion: ConstrainedMotion, point: Mapping[sympy.Symbol, float],
                            keep: Sequence[sympy.Symbol] | None = None, dependent: Sequence[sympy.Symbol] = (),
                            values: Mapping[sympy.Symbol, float] | None = None,
                            inputs: Mapping[sympy.Symbol, float] | None = None, time: float = 0.0) -> Linearization:
    """:meth:`SteadyMotionRates.linearize` of ``motion`` at the parameter ``values``."""
    rates = SteadyMotionRates(motion, values, tuple(inputs or ()))
    return rates.linearize(point, keep, dependent, time, inputs)


def constrained_motion(system: KnownSystem) -> ConstrainedMotion:
    """A known system under velocity constraints (its :attr:`~.KnownSystem.speeds`) as a
    :class:`ConstrainedMotion`: its metric, ``h`` and ``f`` in the coordinates, the rows
    ``A xdot + b`` of its velocity constraints, its speeds ``Y xdot`` and its configuration
    constraints ``g(x, t)`` (:attr:`~.KnownSystem.holonomic`), the rows as made where they are
    kept (:attr:`~.SpeedEquations.rows`). The metric is the primitive's
    projected, ``C^T M C`` (:func:`primitive_metric`), where the transition allows; else ``Mbar``
    and ``hbar`` as derived."""
    s = system.speeds
    metric = primitive_metric(system)
    return ConstrainedMotion(tuple(system.coordinates), metric if metric is not None else sympy.Matrix(system.mass_matrix),
                             system.forces, dict(s.definitions), velocity_rows(system),
                             tuple(c.expression for c in s.holonomic),
                             None if metric is not None else sympy.Matrix(system.velocity_terms))


def velocity_rows(system: KnownSystem) -> tuple[sympy.Expr, ...]:
    """The velocity constraints ``A xdot + b`` of a system in its speeds as numbers are taken
    from: the rows as made (:attr:`~.SpeedEquations.rows`) where they are kept, else those of
    ``A`` and ``b`` without the configuration constraints' rates (their last rows)."""
    s = system.speeds
    xdot = sympy.Matrix(list(system.velocities))
    rates = len(s.holonomic)  # the configuration constraints' rates: the last rows of A
    return s.rows or tuple(s.constraint_matrix * xdot + s.constraint_offset)[:s.constraint_matrix.rows - rates]


def primitive_metric(system: KnownSystem) -> ProjectedMetric | None:
    """``Mbar = C^T M C`` (9'), (D) and ``hbar`` (E) of ``system`` unformed: the primitive's metric
    ``M`` and velocity terms ``h`` at ``x(xbar)`` (``h`` left out when it is the Christoffel terms
    (A) of ``M``), and ``C`` (7'), (21), from its transition;
    None when there is none to take them from (a connection in time or an implicit subspace,
    whose ``C`` is not the whole story)."""
    t = system.transition
    if t is None or system.implicit is not None or t.transformation.shape != (len(t.primitive_coordinates),
                                                                                len(system.coordinates)):
        return None
    connection = dict(t.connection)
    if any(TIME in sympy.sympify(image).free_symbols for image in connection.values()):
        return None
    placement = {x: image for x, image in connection.items() if x != image}
    weights, projection = sympy.Matrix(t.primitive_metric).xreplace(placement), sympy.Matrix(t.transformation)
    if t.christoffel:  # h of the primitive is (A) of its metric: that of the projected metric follows
        return ProjectedMetric(weights, projection)
    return ProjectedMetric(weights, projection, sympy.Matrix(t.primitive_velocity_terms).xreplace(placement),
                           tuple(velocity_symbol(x) for x in t.primitive_coordinates))


REMEMBERED_RATES = 4
"""Most sets of parameter values whose compiled rates a system keeps (the linearisations of a
sweep of operating points share one)."""
_RATES: dict[int, dict] = {}  # id of a living system -> {(values, inputs): SteadyMotionRates}


def steady_motion_rates(system: KnownSystem, values: Mapping[sympy.Symbol, float],
                        inputs: Sequence[sympy.Symbol] = ()) -> SteadyMotionRates:
    """:class:`SteadyMotionRates` of ``system`` at ``values``, compiled once per set of values
    and inputs while the system lives (kept beside it, not in it: a system stays picklable)."""
    key = (tuple(sorted((s.name, float(v)) for s, v in values.items())), tuple(inputs))
    kept = _RATES.get(id(system))
    if kept is None:
        kept = _RATES[id(system)] = {}
        weakref.finalize(system, _RATES.pop, id(system), None)
    if key not in kept:
        if len(kept) >= REMEMBERED_RATES:
            kept.pop(next(iter(kept)))
        kept[key] = SteadyMotionRates(constrained_motion(system), values, inputs)
    return kept[key]


def linearize_speeds(system: KnownSystem, *, inputs: Sequence[sympy.Symbol] = (),
                     point: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                     values: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                     initial: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                     symbolic: bool = False) -> Linearization:
    """``A``, ``B`` of a system under velocity constraints about the steady motion through
    ``point`` (coordinates, speeds and ``t``): :meth:`SteadyMotionRates.linearize` in the
    state ``[kept coordinates; speeds]``, the ignorable coordinates left out, the dependent
    coordinates of the configuration constraints moved onto ``g = 0``. Coordinates not in
    ``point`` take their ``initial`` values (else 0), speeds not in it are 0; ``values``
    overrides the parameters' defaults (an input's value is its operating value)."""
    if symbolic:
        raise LinearizationError("--symbolic is not supported for a model with velocity constraints\n  hint: "
                                 "linearise with numbers (give parameter values with " + assignment("at") + ")")
    point = dict(point or {})
    time = point.pop(TIME, 0)
    numbers, missing = parameter_numbers(system, dict(values or {}))
    if missing:
        raise LinearizationError("no value for parameter" + ("s " if len(missing) > 1 else " ")
                                 + ", ".join(missing) + "\n  hint: give it with " + assignment("at"))
    inputs = tuple(inputs)
    speeds = tuple(system.speeds.speeds)
    operating = {}
    for s in tuple(system.coordinates) + speeds:
        given = point.get(s, (initial or {}).get(s, 0) if s in system.coordinates else 0)
        operating[s] = numeric_value(given, numbers)
        if not np.isfinite(operating[s]):
            raise LinearizationError(f"the operating value of '{s}' is not a real number\n  hint: give it a "
                                     "number with " + option("at"))
    t0 = numeric_value(time, numbers)
    fixed = {p: v for p, v in numbers.items() if p not in inputs}
    rates = steady_motion_rates(system, fixed, inputs)
    lin = rates.linearize(operating, None, tuple(system.speeds.dependent), t0, {u: numbers[u] for u in inputs})
    return dataclasses.replace(lin, time=sympy.sympify(time), in_speeds=True)


__all__ = ["COMPLEX_STEP", "IGNORABLE_TOLERANCE", "NEWTON_STEPS", "STEADY_TOLERANCE", "ConstrainedMotion", "MotionParts",
           "ProjectedMetric", "SteadyMotionRates", "constrained_motion", "frame_matrix", "ignorable", "linear_rows", "linearize_speeds",
           "linearize_steady_motion", "primitive_metric", "steady_motion_rates", "velocity_rows", "REMEMBERED_RATES"]
