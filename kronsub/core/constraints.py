"""The subspace of implicit constraints ``g(y) = 0`` (Hoffmann's (25)-(29)).

The coordinates ``y`` of the primitive (after any explicit connection) split into
independent ones ``xbar`` (the paper's ``theta``) and dependent ones ``y_d`` (its
``phi``). By the implicit-function theorem, with ``G_d = dg/dy_d`` and
``G_i = dg/dxbar``,

    C = [I; Lambda],   Lambda = -G_d^-1 G_i                       (27), (28)
    Cdot xbardot = [0; gamma],  gamma = -G_d^-1 (ydot^T (d2 g/dy2) ydot)

(differentiate ``G ydot = 0`` once more). The projection is the usual one,

    Mbar = C^T M C  (9'),  hbar = C^T (M Cdot xbardot + h)  (E),  fbar = C^T f  (8'),

formed exactly in the trigonometric-polynomial algebra with ``y_d``, the entries of
``Lambda`` and ``gamma`` kept as named intermediates: no division by ``det G_d``
and no square root enters ``Mbar``, ``hbar``, ``fbar``; they are defined in the
"where" block (``phi(theta)``, ``lambda = dphi/dtheta``) and evaluated numerically
(Newton's method on ``g`` for ``y_d``, one solve with ``G_d`` for ``Lambda`` and
``gamma``), or from a closed form of ``y_d`` where sympy finds a unique one on the
branch of the initial configuration.
"""
from __future__ import annotations

import numpy as np
import sympy

from .derivative import derivative, jacobian
from .doubles import complex_value
from .finite import nonfinite_cause
from .known_system import Constraint, ImplicitSubspace, KnownSystem
from .simplify import compact
from .symbols import symbol, velocity_symbol
from .trigpoly import TrigAlgebra, TrigPoly

SYMBOLIC_INVERSE = 3  # Lambda and gamma are printed in closed form for at most this many dependents


def multiplier_name(constraint: str) -> str:
    """The name of a constraint's multiplier among the reactions: ``mu_B_x`` for ``B.x``."""
    return f"mu_{constraint.replace('.', '_')}"


# --------------------------------------------------------------------------------------------
# Naming the intermediates
# --------------------------------------------------------------------------------------------

def intermediate_symbols(independent, dependent, taken: set[str]):
    """``lambda_<dep>_<indep>`` (the paper's lambda of (26)-(29)) and ``gamma[_<dep>]``: names that
    clash with the model's own get a trailing underscore."""

    def fresh(name: str) -> sympy.Symbol:
        while name in taken:
            name += "_"
        taken.add(name)
        return symbol(name)

    k = len(dependent)
    # never a bare ``lambda``: a Python keyword, so a printed entry would not parse back
    lam = sympy.Matrix(k, len(independent), lambda a, j: fresh(f"lambda_{dependent[a].name}_{independent[j].name}"))
    gamma = tuple(fresh("gamma" if k == 1 else f"gamma_{d.name}") for d in dependent)
    return lam, gamma


# --------------------------------------------------------------------------------------------
# The projection
# --------------------------------------------------------------------------------------------

def project_implicit(system: KnownSystem, independent, dependent, constraints, *, closed_form=(), branch=(),
                     choice: str = "given", taken: set[str] | None = None) -> KnownSystem:
    """Project ``system`` (coordinates ``y = independent + dependent``, any order) onto
    ``g(y) = 0``: ``Mbar = C^T M C``, ``hbar = C^T (M [0; gamma] + h)``, ``fbar = C^T f`` with
    ``C = [I; Lambda]`` (27), everything exact in the algebra over ``y``."""
    independent, dependent = tuple(independent), tuple(dependent)
    y = tuple(system.coordinates)
    n, k = len(independent), len(dependent)
    g = sympy.Matrix([c.expression for c in constraints])
    G_d = jacobian(g, dependent) if k else sympy.zeros(0, 0)
    G_i = jacobian(g, independent)
    lam, gamma = intermediate_symbols(independent, dependent,
                                      set(taken or ()) | {s.name for s in y} | {p.name for p in system.parameters})
    # ydot = C xbardot: independent velocities as they are, dependent ones Lambda xbardot
    xdots = [velocity_symbol(q) for q in independent]
    vel_sub = {velocity_symbol(d): sympy.Add(*[lam[a, j] * xdots[j] for j in range(n)])
               for a, d in enumerate(dependent)}
    ydot = {velocity_symbol(q): velocity_symbol(q) for q in independent}
    ydot.update(vel_sub)
    ydot_list = [ydot[velocity_symbol(q)] for q in y]
    # quadratic term of the second derivative of g: -(ydot^T H ydot), with ydot in Lambda
    quadratic = []
    for c in constraints:
        grad = [derivative(c.expression, q) for q in y]
        total = sympy.Integer(0)
        for a, qa in enumerate(y):
            if grad[a] == 0:
                continue
            for b, qb in enumerate(y):
                h = derivative(grad[a], qb)
                if h != 0:
                    total += h * ydot_list[a] * ydot_list[b]
        quadratic.append(-total)

    algebra = TrigAlgebra(y)
    index = {q: i for i, q in enumerate(y)}
    # C rows: one per y; independent rows unit vectors, dependent rows Lambda
    C: list[list[TrigPoly]] = [[TrigPoly() for _ in range(n)] for _ in y]
    for j, q in enumerate(independent):
        C[index[q]][j] = algebra.constant(1)
    for a, d in enumerate(dependent):
        for j in range(n):
            C[index[d]][j] = algebra.atom(lam[a, j])
    conv = [TrigPoly() for _ in y]  # Cdot xbardot = [0; gamma]
    for a, d in enumerate(dependent):
        conv[index[d]] = algebra.atom(gamma[a])

    def image(e) -> TrigPoly:
        return algebra.from_expr(sympy.sympify(e).xreplace(vel_sub))

    M = [[image(system.mass_matrix[a, b]) for b in range(len(y))] for a in range(len(y))]
    inertial = []
    for a in range(len(y)):
        acc = image(system.velocity_terms[a]).copy()
        for b in range(len(y)):
            if not conv[b].is_zero() and not M[a][b].is_zero():
                acc.add_product(M[a][b], conv[b])
        inertial.append(acc)

    def ct(vec: list[TrigPoly]) -> list[TrigPoly]:
        out = [TrigPoly() for _ in range(n)]
        for a, va in enumerate(vec):
            if va.is_zero():
                continue
            for j in range(n):
                if not C[a][j].is_zero():
                    out[j].add_product(C[a][j], va)
        return out

    MC = [[TrigPoly() for _ in range(n)] for _ in y]
    for a in range(len(y)):
        for b in range(len(y)):
            if M[a][b].is_zero():
                continue
            for j in range(n):
                if not C[b][j].is_zero():
                    MC[a][j].add_product(M[a][b], C[b][j])
    mass = sympy.zeros(n, n)
    for j in range(n):
        column = ct([MC[a][j] for a in range(len(y))])
        for i in range(j, n):
            mass[i, j] = mass[j, i] = compact(algebra, column[i])
    hbar = sympy.Matrix([compact(algebra, p) for p in ct(inertial)])
    effect_forces = {}
    for label, f in system.effect_forces.items():
        effect_forces[label] = sympy.Matrix([compact(algebra, p) for p in ct([image(e) for e in f])])

    definitions = []
    if 0 < k <= SYMBOLIC_INVERSE:
        # adjugate over determinant, without sympy's (costly) invertibility proof
        inverse = G_d.adjugate() / G_d.det(method="berkowitz") if k > 1 else sympy.Matrix([[1 / G_d[0, 0]]])
        lam_expr = -(inverse * G_i)
        for a in range(k):
            for j in range(n):
                definitions.append((lam[a, j], _tidy(algebra, lam_expr[a, j])))
        gam_expr = inverse * sympy.Matrix(quadratic)
        for a in range(k):
            definitions.append((gamma[a], _tidy(algebra, gam_expr[a])))
    implicit = ImplicitSubspace(
        independent=independent, dependent=dependent, constraints=tuple(constraints),
        jacobian_dependent=G_d, jacobian_independent=G_i, sensitivities=lam, convective=gamma,
        quadratic=tuple(quadratic), closed_form=tuple(closed_form), branch=tuple(branch), choice=choice,
        definitions=tuple(definitions), intermediate=y, metric=system.mass_matrix,
        velocity_terms=system.velocity_terms, forces=system.forces, effect_forces=dict(system.effect_forces))
    return KnownSystem(
        name=system.name,
        coordinates=independent,
        mass_matrix=mass,
        velocity_terms=hbar,
        effect_forces=effect_forces,
        potential_energy=system.potential_energy,
        points=dict(system.points),
        bodies=system.bodies,
        dimension=system.dimension,
        parameters=system.parameters,
        transition=system.transition,
        description=system.description,
        implicit=implicit,
        effect_potentials=dict(system.effect_potentials),
        effect_translations=dict(system.effect_translations),
    )


def _tidy(algebra: TrigAlgebra, expr) -> sympy.Expr:
    """Numerator over denominator, each compact in the algebra (``sin(phi2 - theta1)``)."""
    num, den = sympy.fraction(sympy.together(expr))
    num = compact(algebra, algebra.from_expr(sympy.expand(num)))
    den = compact(algebra, algebra.from_expr(sympy.expand(den)))
    return sympy.factor_terms(num / den)


# --------------------------------------------------------------------------------------------
# Numbers: Newton's method on the constraints, the pivoted choice, closed forms
# --------------------------------------------------------------------------------------------

class ConstraintFailure(Exception):
    """Newton's method or the Jacobian failed; ``kind`` is 'singular', 'diverged' or 'redundant'."""

    def __init__(self, kind: str, message: str, where=None):
        super().__init__(message)
        self.kind, self.message, self.where = kind, message, where


class NumericConstraints:
    """``g``, ``dg/dy`` and the quadratic terms as numpy functions at fixed parameter values."""

    def __init__(self, constraints, coordinates, parameters: dict):
        self.constraints = tuple(constraints)
        self.y = tuple(coordinates)
        g = sympy.Matrix([c.expression for c in self.constraints]).xreplace(parameters)
        G = jacobian(g, self.y) if len(self.y) else sympy.zeros(len(g), 0)
        extra = sorted((g.free_symbols | G.free_symbols) - set(self.y), key=lambda s: s.name)
        if extra:
            raise ConstraintFailure("parameters", ", ".join(s.name for s in extra))
        self._g = sympy.lambdify([self.y], list(g), modules="math")
        self._G = sympy.lambdify([self.y], G.tolist(), modules="math")
        self.k = len(g)

    def residual(self, y) -> np.ndarray:
        try:
            return np.array(self._g(list(map(float, y))), dtype=float).reshape(self.k)
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full(self.k, np.nan)

    def jacobian(self, y) -> np.ndarray:
        try:
            return np.array(self._G(list(map(float, y))), dtype=float).reshape(self.k, len(self.y))
        except (ValueError, ZeroDivisionError, OverflowError):
            return np.full((self.k, len(self.y)), np.nan)

    def names(self, rows) -> str:
        return ", ".join(f"'{self.constraints[i].name}'" for i in rows)

    def solve(self, y0, free, tol: float = 1e-12, max_iter: int = 50) -> np.ndarray:
        """Newton (least-norm steps) on the coordinates ``free`` (indices), the others held."""
        y = np.array(y0, dtype=float)
        free = list(free)
        for _ in range(max_iter):
            r = self.residual(y)
            if not np.all(np.isfinite(r)):
                break
            J = self.jacobian(y)[:, free]
            if not np.all(np.isfinite(J)):
                break
            step = np.linalg.lstsq(J, -r, rcond=None)[0]
            y[free] += step
            if np.max(np.abs(step), initial=0.0) <= tol * (1 + np.max(np.abs(y), initial=0.0)):
                row = np.max(np.abs(J), axis=1, initial=0.0)  # g over its gradient's size: in the coordinates' units
                if np.max(np.abs(self.residual(y)) / np.where(row > 0, row, 1.0), initial=0.0) \
                        <= 1e3 * tol * (1 + np.max(np.abs(y))):
                    return y
        r = self.residual(y)
        worst = int(np.nanargmax(np.abs(r))) if np.any(np.isfinite(r)) else 0
        raise ConstraintFailure("diverged", f"Newton's method did not converge; largest residual "
                                f"{abs(r[worst]):.3g} in {self.names([worst])}", y)

    def redundant_rows(self, y, tol: float = 1e-9) -> list[int]:
        """Constraints whose gradient lies in the span of the gradients listed before them
        (Gram-Schmidt on the rows of ``G`` in the order written)."""
        G = self.jacobian(y)
        if G.size == 0 or not np.all(np.isfinite(G)):
            return []
        basis, bad = [], []
        for i, row in enumerate(G):
            r = row.astype(float).copy()
            for u in basis:
                r -= u * (u @ r)
            norm = np.linalg.norm(r)
            if norm <= tol * np.linalg.norm(row):  # relative to the row: a constraint times a constant is the same
                bad.append(i)
            else:
                basis.append(r / norm)
        return bad

    def pivot(self, y) -> list[int]:
        """The ``k`` best-conditioned columns of ``G`` (pivoted QR): the dependent coordinates."""
        order, _ = _pivoted(self.jacobian(y))
        return sorted(order[: self.k])


def _pivoted(A: np.ndarray):
    """Column order of a QR factorization with column pivoting (modified Gram-Schmidt, the
    largest remaining column first; ties to the first) and the diagonal of ``R``."""
    A = np.array(A, dtype=float)
    cols = list(range(A.shape[1]))
    order, norms = [], []
    while cols and len(order) < A.shape[0]:
        lengths = [np.linalg.norm(A[:, j]) for j in cols]
        best = cols[int(np.argmax(lengths))]
        length = max(lengths)
        order.append(best)
        norms.append(length)
        cols.remove(best)
        if length > 0:
            u = A[:, best] / length
            for j in cols:
                A[:, j] -= u * (u @ A[:, j])
    return order + cols, norms + [0.0] * len(cols)


def closed_forms(constraints, independent, dependent, branch: dict, parameters: dict):
    """``y_d = y_d(xbar)`` for every dependent coordinate, when the constraints can be solved one
    at a time (26): a constraint in which one dependent coordinate ``d`` is left fixes it in closed
    form, ``A + B d``, ``A + B sin d`` or ``A + B cos d`` (``A``, ``B`` free of ``d``), when exactly
    one of the solutions (``asin``, ``pi - asin``; ``+-acos``) passes through the initial
    configuration: then it holds on the whole branch. Each solution is put into the constraints
    left (a pin in space: one coordinate per axis). Empty unless every dependent coordinate has one
    (Newton's method then finds them all)."""
    point = {**parameters, **branch}
    numbers = {}
    for k, v in point.items():
        try:
            numbers[k] = float(v)
        except (TypeError, ValueError):
            pass  # not a number: a candidate using it is left out, as before
    left = [sympy.sympify(c.expression) for c in constraints]
    unsolved = list(dependent)
    solved: dict = {}
    while unsolved:
        for i, g in enumerate(left):
            here = [d for d in unsolved if g.has(d)]
            if len(here) != 1:
                continue
            form = _closed_form(g, here[0], branch, numbers)
            if form is not None:
                break
        else:
            return ()
        d = here[0]
        solved[d] = form
        unsolved.remove(d)
        del left[i]
        left = [e.xreplace({d: form}) for e in left]
    return tuple((d, solved[d]) for d in dependent)


def _closed_form(g, d, branch: dict, numbers: dict):
    """The one solution of ``g = 0`` for ``d`` through the initial configuration, or None."""
    g = sympy.expand(g)
    candidates = []
    for kernel in (d, sympy.sin(d), sympy.cos(d)):
        u = sympy.Dummy("u")
        e = g.xreplace({kernel: u}) if kernel is not d else g.subs(d, u)
        if e.has(d):
            continue
        poly = sympy.Poly(e, u) if e.is_polynomial(u) else None
        if poly is None or poly.degree() != 1:
            continue
        B, A = poly.all_coeffs()
        root = sympy.factor_terms(-A / B)
        if kernel is d:
            candidates = [root]
        elif kernel.func is sympy.sin:
            candidates = [sympy.asin(root), sympy.pi - sympy.asin(root)]
        else:
            candidates = [sympy.acos(root), -sympy.acos(root)]
        break
    hits = []
    for s in candidates:
        try:  # in doubles (`complex_value`): sympy's multiprecision can abort on exp(exp(...))
            value = complex_value(sympy.sympify(s), numbers)
        except (TypeError, ValueError, ArithmeticError):
            continue
        if abs(value.imag) < 1e-12 and abs(value.real - float(branch[d])) < 1e-8:
            hits.append(s)
    return hits[0] if len(hits) == 1 else None


class Intermediates:
    """The named intermediates at a state, in numbers: ``y_d`` (closed form, else Newton from
    ``guess``, warm-started from the last solution), then ``Lambda`` and ``gamma`` by one
    solve with ``G_d`` each. Parameter values are fixed at construction."""

    def __init__(self, implicit: ImplicitSubspace, parameters: dict, tol: float = 1e-12):
        imp = self.implicit = implicit
        self.tol = tol
        y = imp.independent + imp.dependent
        params = self.numeric_parameters = {k: v for k, v in parameters.items()}
        self.numeric = NumericConstraints(imp.constraints, y, params)
        n, k = len(imp.independent), len(imp.dependent)
        self.n, self.k = n, k
        qd = [velocity_symbol(q) for q in imp.independent]
        lam = list(imp.sensitivities)
        sub = dict(params)
        self._quadratic = sympy.lambdify([list(y), qd, lam], [sympy.sympify(e).xreplace(sub) for e in imp.quadratic],
                                         modules="math")
        closed = dict(imp.closed_form)
        self._closed = (sympy.lambdify([list(imp.independent)], [closed[d].xreplace(sub) for d in imp.dependent],
                                       modules="math") if len(closed) == k and k else None)
        self.guess = np.array([dict(imp.branch).get(d, 0.0) for d in imp.dependent], dtype=float)

    @property
    def closed(self) -> bool:
        """Whether the dependent coordinates come from their closed form (else Newton's method)."""
        return self._closed is not None

    def dependent(self, q) -> np.ndarray:
        """``y_d`` on the branch (raises :class:`ConstraintFailure`)."""
        q = np.asarray(q, dtype=float)
        if self._closed is not None:
            try:
                yd = np.array(self._closed(list(q)), dtype=float)
            except (ValueError, ZeroDivisionError, OverflowError):
                yd = np.full(self.k, np.nan)
            if np.all(np.isfinite(yd)):
                self.guess = yd
                return yd
            raise ConstraintFailure("diverged", "the closed form of the dependent coordinates has no real "
                                    "value here" + self._closed_cause(q), q)
        y = np.concatenate([q, self.guess])
        y = self.numeric.solve(y, range(self.n, self.n + self.k), tol=self.tol)
        self.guess = y[self.n:]
        return y[self.n:].copy()

    def _closed_cause(self, q) -> str:
        """Which part of the closed form ``y_d(xbar)`` has no real (or finite) value at ``q`` (:mod:`.finite`),
        as ": ..." (empty without a verdict); the callers name the configuration."""
        imp, closed = self.implicit, dict(self.implicit.closed_form)
        values = {s: float(v) for s, v in self.numeric_parameters.items()}
        values.update(zip(imp.independent, (float(v) for v in q)))
        cause = nonfinite_cause([(d.name, closed[d]) for d in imp.dependent], values)
        return "" if cause is None else f": {cause.what}"

    def at(self, q, qdot) -> dict:
        """Every intermediate symbol -> its value at ``(q, qdot)``."""
        imp = self.implicit
        yd = self.dependent(q)
        y = np.concatenate([np.asarray(q, dtype=float), yd])
        G = self.numeric.jacobian(y)
        Gd, Gi = G[:, self.n:], G[:, :self.n]
        if not np.all(np.isfinite(G)) or np.linalg.cond(Gd) > 1e12:
            raise ConstraintFailure("singular", "dg/d(" + ", ".join(d.name for d in imp.dependent)
                                    + ") is singular here: the dependent coordinates are not determined", y)
        lam = np.linalg.solve(Gd, -Gi)
        quad = np.array(self._quadratic(list(y), list(map(float, qdot)), list(lam.ravel())), dtype=float)
        gamma = np.linalg.solve(Gd, quad)
        out = dict(zip(imp.dependent, yd))
        out.update(zip(imp.sensitivities, lam.ravel()))
        out.update(zip(imp.convective, gamma))
        return out


__all__ = ["SYMBOLIC_INVERSE", "Constraint", "ConstraintFailure", "ImplicitSubspace", "Intermediates",
           "NumericConstraints", "closed_forms", "intermediate_symbols", "multiplier_name", "project_implicit"]
