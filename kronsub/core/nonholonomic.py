"""Non-holonomic constraints: a velocity-level transformation ``xdot = C(x) u + d(x, t)``.

Constraints linear in the velocities, ``A(x) xdot + b(x, t) = 0`` (rolling, a knife edge), and
speeds ``u = Y(x) xdot`` (by default some of the velocities themselves) together fix

    [A; Y] xdot = [-b; u],   xdot = C u + d,   A C = 0

where ``C`` spans the null space of ``A`` but is the Jacobian of no ``x(xbar)``: Kron's
non-holonomic reference frame. The projection keeps (9'), (D)-(F), with ``Cdot`` taken along
the motion (Boltzmann-Hamel):

    Mbar = C^T M C                                            (9'), (D)
    hbar = C^T (M (dC/dx^k xdot^k u + dd/dx^k xdot^k + dd/dt) + h(x, xdot))   (E)
    fbar = C^T f(x, xdot, t)                                  (8'), (F)

with ``xdot = C u + d`` throughout; the state is ``[x; u]``, its kinematic equations
``xdot = C u + d``. A constraint that is integrable (Frobenius: ``omega ^ d omega = 0`` for
``omega = A_i dx``) is a configuration constraint in disguise and is reported as such.
"""
from __future__ import annotations

import functools
import itertools
import random
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy

from .deferred import DeferredMatrix, Once
from .derivative import derivative, jacobian, where_defined
from .known_system import Constraint, KnownSystem, SpeedEquations
from .numeric_jacobian import value_and_jacobian
from .scales import row_sizes, rows_scaled
from .symbols import TIME, acceleration_symbol, velocity_symbol

GENERIC_POINTS = 3  # a rank is taken at this many random points (a generic one is almost sure)
NOT_CLOSED = 1e-9  # omega ^ d omega larger than this (relative) at a random point: not integrable


class VelocityConstraintError(ValueError):
    """A velocity constraint or a choice of speeds that cannot be used; ``index`` is the
    constraint (or speed) it concerns, ``hint`` how to fix it."""

    def __init__(self, message: str, hint: str, index: int | None = None, kind: str = "constraint"):
        super().__init__(message)
        self.hint, self.index, self.kind = hint, index, kind


def tidy_entry(e: sympy.Expr) -> sympy.Expr:
    """An entry of ``C``, ``Mbar``, ``hbar``, ``fbar`` in the speeds, simplified."""
    return sympy.trigsimp(sympy.cancel(sympy.expand(e)))


def frame_entry(e: sympy.Expr) -> sympy.Expr:
    """An entry of ``Mbar``, ``hbar``, ``fbar`` in a frame's speeds, simplified: the sines and
    cosines of shifted and multiple angles (Park's ``theta - 2 pi/3``, the saliency's
    ``2 theta``) written in those of the angle, so that ``sin^2 + cos^2`` collapses and
    Park's constant inductances show."""
    return sympy.factor_terms(sympy.trigsimp(sympy.expand(sympy.expand_trig(sympy.expand(e)))))


#: how the entries in the speeds are simplified, by name (a name is what a cached derivation keeps)
TIDY: dict[str, Callable[[sympy.Expr], sympy.Expr]] = {"entry": tidy_entry, "frame": frame_entry}


@dataclass(frozen=True)
class VelocityTransformation:
    """``xdot = C u + d`` with ``A C = 0``: the speeds ``u`` and what they mean. The symbolic
    solve of ``[A; Y] xdot = [-b; u]`` is done when ``C``, ``d`` or the kinematic equations are
    first read (a linearisation needs only ``A``, ``b`` and ``Y``, solved numerically)."""

    coordinates: tuple[sympy.Symbol, ...]
    speeds: tuple[sympy.Symbol, ...]
    constraint_matrix: sympy.Matrix  # A
    constraint_offset: sympy.Matrix  # b
    speed_matrix: sympy.Matrix  # Y of u = Y xdot
    holonomic: tuple[sympy.Expr, ...] = ()  # configuration constraints g(x, t) = 0, their rates the last rows of A
    dependent: tuple[sympy.Symbol, ...] = ()  # one coordinate per configuration constraint, set by it
    # the velocity constraints A xdot + b as numbers are taken from (a contact's rows as made, not
    # reduced); empty: those of A and b, which then hold the constraints as printed
    rows: tuple[sympy.Expr, ...] = ()

    @functools.cached_property
    def kinematics(self) -> sympy.Matrix:
        """``xdot = C u + d``: ``[A; Y] xdot = [-b; u]`` solved."""
        stacked = self.constraint_matrix.col_join(self.speed_matrix)
        solved = stacked.LUsolve(sympy.Matrix([-e for e in self.constraint_offset] + list(self.speeds)))
        return solved.applyfunc(lambda e: sympy.trigsimp(sympy.cancel(sympy.expand(e))))

    def analysed(self) -> tuple[sympy.Matrix, sympy.Matrix]:
        """``A`` and ``b`` as numbers are taken from, without their printed form: the rows as made
        (:func:`differentiated_form`), the configuration constraints' rates last."""
        if not self.rows:
            return self.constraint_matrix, self.constraint_offset
        A, b = differentiated_form(self.rows, self.coordinates)
        if self.holonomic:
            g = sympy.Matrix(list(self.holonomic))
            A, b = A.col_join(jacobian(g, list(self.coordinates))), b.col_join(where_defined(g.diff(TIME)))
        return A, b

    @property
    def transformation(self) -> sympy.Matrix:
        """``C``."""
        return self.kinematics.jacobian(self.speeds)

    @property
    def offset(self) -> sympy.Matrix:
        """``d``."""
        return (self.kinematics - self.transformation * sympy.Matrix(self.speeds)).applyfunc(sympy.expand)


@dataclass(frozen=True)
class NonholonomicProjection:
    """``Mbar udot + hbar = fbar`` in the speeds, with the kinematic equations ``xdot = C u + d``."""

    velocity: VelocityTransformation
    mass_matrix: sympy.Matrix
    velocity_terms: sympy.Matrix
    forcing: sympy.Matrix
    convective: sympy.Matrix  # Cdot u + ddot along the motion


def linear_form(constraints: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol]
                ) -> tuple[sympy.Matrix, sympy.Matrix]:
    """``A`` and ``b`` of ``A(x) xdot + b(x, t) = 0``; a constraint not linear in the
    velocities raises :class:`VelocityConstraintError`."""
    velocities = [velocity_symbol(q) for q in coordinates]
    rows, offsets = [], []
    for i, c in enumerate(constraints):
        c = sympy.expand(sympy.sympify(c))
        if not set(velocities) & c.free_symbols:
            raise VelocityConstraintError(
                f"velocity constraint {i + 1} has no velocity in it", "a relation between coordinates alone is a "
                "configuration constraint: write it under `constraints:`", i)
        row = [sympy.diff(c, v) for v in velocities]
        if any(set(velocities) & set(e.free_symbols) for e in row):
            raise VelocityConstraintError(
                f"velocity constraint {i + 1} is not linear in the velocities",
                "write it as A(x) xdot + b(x, t) = 0: each velocity to the first power, times a function of the "
                "coordinates", i)
        rows.append(row)
        offsets.append(sympy.expand(c - sum(r * v for r, v in zip(row, velocities))))
    return sympy.Matrix(rows), sympy.Matrix(offsets)


def differentiated_form(constraints: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol]
                        ) -> tuple[sympy.Matrix, sympy.Matrix]:
    """``A`` and ``b`` as :func:`linear_form` gives them, by differentiation without expanding (a
    rolling wheel's rows are long products, whose expansion is far longer): the form numbers
    are taken from. A constraint the velocities are left in after it is not linear."""
    velocities = [velocity_symbol(q) for q in coordinates]
    rows, offsets = [], []
    for c in constraints:
        c = sympy.sympify(c)
        row = [derivative(c, v) for v in velocities]
        if not any(e != 0 for e in row) or any(set(velocities) & e.free_symbols for e in row):
            return linear_form([c], coordinates)  # its error, as linear_form finds it
        rows.append(row)
        offsets.append(c.xreplace({v: 0 for v in velocities}))
    return sympy.Matrix(rows), sympy.Matrix(offsets)


def integrable(A: sympy.Matrix, b: sympy.Matrix, coordinates: Sequence[sympy.Symbol],
               values: Mapping | None = None) -> list[int]:
    """The constraints (rows of ``A``, each with ``b_i = 0``) that are integrable on their own:
    ``omega = A_i dx`` with ``omega ^ d omega = 0`` (Frobenius), i.e. for every ``j < k < l``
    ``A_j (d_k A_l - d_l A_k) + A_k (d_l A_j - d_j A_l) + A_l (d_j A_k - d_k A_j) = 0``. With
    fewer than three coordinates, ``omega ^ d omega`` vanishes identically. A row whose
    ``omega ^ d omega`` is plainly not zero at a random point (:func:`_generic_points`, the
    parameters at ``values``) is not integrable; the others are simplified to be sure."""
    n = len(coordinates)
    found = []
    for i in range(A.rows):
        if b[i] != 0:
            continue  # an affine constraint: not a one-form of the coordinates alone
        a = list(A.row(i))
        if n >= 3 and _plainly_not_closed(a, coordinates, values):
            continue
        d = [[sympy.diff(a[k], coordinates[j]) for j in range(n)] for k in range(n)]  # d[k][j] = d_j A_k
        if all(sympy.simplify(a[j] * (d[l][k] - d[k][l]) + a[k] * (d[j][l] - d[l][j]) + a[l] * (d[k][j] - d[j][k])) == 0
               for j, k, l in itertools.combinations(range(n), 3)):
            found.append(i)
    return found


def _plainly_not_closed(a, coordinates, values) -> bool:
    """``omega ^ d omega`` of :func:`integrable` well away from zero at a random point, ``A_i``
    and its derivatives evaluated there in floating point (:func:`.numeric_jacobian.value_and_jacobian`)."""
    point = _generic_points(sympy.Matrix([a]), coordinates, values)[0]
    n = len(coordinates)
    try:
        av, dv = value_and_jacobian(a, coordinates, {s: float(v) for s, v in point.items()})
    except (TypeError, ValueError, ZeroDivisionError, OverflowError, KeyError):
        return False  # a symbol left without a value, or a point outside the domain: decide by simplifying
    scale = max(abs(x) for x in av) * max(abs(x) for row in dv for x in row)
    return any(abs(av[j] * (dv[l][k] - dv[k][l]) + av[k] * (dv[j][l] - dv[l][j]) + av[l] * (dv[k][j] - dv[j][k]))
               > NOT_CLOSED * scale for j, k, l in itertools.combinations(range(n), 3))


def velocity_transformation(constraints: Sequence[sympy.Expr], coordinates: Sequence[sympy.Symbol],
                            speeds: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                            values: Mapping | None = None,
                            holonomic: Sequence[sympy.Expr] = (),
                            printed: Sequence[Callable[[], sympy.Expr] | None] | None = None
                            ) -> VelocityTransformation:
    """``xdot = C u + d`` for velocity ``constraints`` (expressions ``= 0``). ``speeds`` maps each
    speed to its definition ``Y(x) xdot``; without it the speeds are the velocities of the
    coordinates left independent, the last coordinates taken as dependent first. ``values``
    (parameter -> number) fixes the parameters where ranks are taken. Configuration constraints
    ``holonomic`` ``g(x, t) = 0`` join by their rates ``G xdot + dg/dt`` (the last rows of ``A``),
    each setting a coordinate (``dependent``: the last ones first whose columns of ``G`` are
    independent). ``printed`` gives, for a constraint made rather than written (a contact's),
    its printed form (reduced, :func:`.contact.reduced`), made when ``A`` and ``b`` are first
    read; the analysis and the numbers take the constraint as made (:func:`differentiated_form`)."""
    coordinates = tuple(coordinates)
    velocities = [velocity_symbol(q) for q in coordinates]
    printed = list(printed) if printed is not None else [None] * len(constraints)
    made = [i for i, form in enumerate(printed) if form is not None]
    A, b = linear_form(constraints, coordinates) if not made else _analysed_form(constraints, printed, coordinates)
    holonomic = tuple(sympy.sympify(g) for g in holonomic)
    held: tuple = ()  # the coordinates the configuration constraints set
    if holonomic:
        g = sympy.Matrix(list(holonomic))
        G = jacobian(g, list(coordinates))
        at = _generic_points(G, coordinates, values)
        if _rank(G, at) < len(holonomic):
            raise VelocityConstraintError("the configuration constraints are not independent",
                                          "remove the constraint that follows from the others", kind="holonomic")
        for chosen in itertools.combinations(reversed(range(len(coordinates))), len(holonomic)):
            if _rank(G[:, sorted(chosen)], at) == len(holonomic):
                held = tuple(coordinates[j] for j in sorted(chosen))
                break
        A = A.col_join(G)
        b = b.col_join(where_defined(g.diff(TIME)))
    for i in integrable(A[:A.rows - len(holonomic), :], b, coordinates, values):
        raise VelocityConstraintError(
            f"velocity constraint {i + 1} is integrable: it is the time derivative of a relation between the "
            "coordinates", "write that relation under `constraints:` (a configuration constraint) instead", i)
    m, n = A.shape
    point = _generic_points(A, coordinates, values)
    if _rank(A, point) < m:
        raise VelocityConstraintError("the velocity constraints are not independent",
                                      "remove the constraint that follows from the others")
    if m >= n:
        raise VelocityConstraintError(
            f"the {m} constraints fix all {n} velocities: no speed is left, nothing can move",
            "remove a constraint, or add the coordinates the motion needs")
    if speeds is None:
        for dependent in itertools.combinations(reversed(range(n)), m):
            if _rank(A[:, sorted(dependent)], point) == m:
                break
        independent = [j for j in range(n) if j not in dependent]
        speeds = {velocities[j]: velocities[j] for j in independent}
    if len(speeds) != n - m:
        raise VelocityConstraintError(
            f"{len(speeds)} speed(s) for {n - m} degree(s) of freedom",
            f"name {n - m} speeds: the {n} velocities less the {m} velocity constraints", kind="speeds")
    try:
        Y, c = linear_form(list(speeds.values()), coordinates)
    except VelocityConstraintError as exc:  # of a speed, not of a constraint
        name = list(speeds)[exc.index].name
        raise VelocityConstraintError(str(exc).replace(f"velocity constraint {exc.index + 1}", f"speed '{name}'"),
                                      "define each speed as Y(x) xdot: each velocity to the first power, times a "
                                      "function of the coordinates", exc.index, kind="speeds") from None
    if any(e != 0 for e in c):
        raise VelocityConstraintError("a speed has a term without a velocity", "define each speed as Y(x) xdot",
                                      kind="speeds")
    stacked = A.col_join(Y)
    if _rank(stacked, _generic_points(stacked, coordinates, values)) < n:
        raise VelocityConstraintError(
            "the speeds do not span the null space of the velocity constraints",
            "choose speeds that stay independent once the constraints hold (the velocity of a coordinate the "
            "constraints do not fix, say)", kind="speeds")
    if made:  # A and b as printed: each constraint's printed form, made when first read
        rates = A[A.rows - len(holonomic):, :], b[b.rows - len(holonomic):, :]
        form = Once(lambda: linear_form([c if p is None else p() for c, p in zip(constraints, printed)], coordinates))
        A, b, rows = (DeferredMatrix(A.rows, n, lambda: form()[0].col_join(rates[0])),
                      DeferredMatrix(b.rows, 1, lambda: form()[1].col_join(rates[1])), tuple(constraints))
    else:
        rows = ()
    return VelocityTransformation(coordinates=coordinates, speeds=tuple(speeds), constraint_matrix=A,
                                  constraint_offset=b, speed_matrix=Y, holonomic=holonomic, dependent=held, rows=rows)


def _analysed_form(constraints, printed, coordinates) -> tuple[sympy.Matrix, sympy.Matrix]:
    """``A`` and ``b`` to analyse: a written constraint's by :func:`linear_form`, a made one's
    (``printed`` not None) by :func:`differentiated_form`, row by row in order."""
    rows, offsets = [], []
    for index, (c, form) in enumerate(zip(constraints, printed)):
        try:
            A, b = (linear_form if form is None else differentiated_form)([c], coordinates)
        except VelocityConstraintError as exc:
            raise VelocityConstraintError(str(exc).replace("velocity constraint 1", f"velocity constraint {index + 1}"),
                                          exc.hint, index, exc.kind) from None
        rows.append(A)
        offsets.append(b)
    return sympy.Matrix.vstack(*rows), sympy.Matrix.vstack(*offsets)


def project_nonholonomic(metric: sympy.Matrix, velocity_terms: sympy.Matrix, force: sympy.Matrix,
                         velocity: VelocityTransformation,
                         tidy: Callable[[sympy.Expr], sympy.Expr] = tidy_entry) -> NonholonomicProjection:
    """(9'), (D)-(F) in the speeds: ``M(x)``, ``h(x, xdot)``, ``f(x, xdot, t)`` of the system in
    the coordinates ``x`` (velocities named by :func:`velocity_symbol`) projected by ``C``, each
    entry simplified by ``tidy``."""
    x = velocity.coordinates
    xdot = velocity.kinematics
    moved = {velocity_symbol(q): xdot[i] for i, q in enumerate(x)}
    # Cdot u + ddot along the motion: d(C u + d)/dx^k xdot^k + d(C u + d)/dt (u held)
    convective = jacobian(xdot, x) * xdot + where_defined(xdot.diff(TIME))
    C = velocity.transformation
    M = sympy.Matrix(metric)
    h = sympy.Matrix(velocity_terms).xreplace(moved)
    f = sympy.Matrix(force).xreplace(moved)
    return NonholonomicProjection(velocity=velocity, mass_matrix=(C.T * M * C).applyfunc(tidy),
                                  velocity_terms=(C.T * (M * convective + h)).applyfunc(tidy),
                                  forcing=(C.T * f).applyfunc(tidy), convective=convective)


@dataclass(frozen=True)
class SpeedProjection:
    """What :func:`speed_equations` projects, kept until the equations are first read."""

    mass_matrix: sympy.Matrix  # M in x
    velocity_terms: sympy.Matrix  # h in x
    effect_forces: tuple[tuple[str, sympy.Matrix], ...]  # f of each effect in x
    velocity: VelocityTransformation
    tidy: str = "entry"  # of TIDY

    def equations(self) -> dict:
        """(9'), (D)-(F) in the speeds, as :func:`project_nonholonomic`, ``fbar = C^T f`` of each
        effect apart (8'), (F), and ``T = 1/2 u^T Mbar u`` (24)."""
        velocity, tidy = self.velocity, TIDY[self.tidy]
        inertia = project_nonholonomic(self.mass_matrix, self.velocity_terms,
                                       sympy.zeros(len(velocity.coordinates), 1), velocity, tidy)
        moved = {velocity_symbol(q): velocity.kinematics[i] for i, q in enumerate(velocity.coordinates)}
        C = velocity.transformation
        forces = {name: (C.T * sympy.Matrix(f).xreplace(moved)).applyfunc(tidy) for name, f in self.effect_forces}
        u = sympy.Matrix(velocity.speeds)
        kinetic = tidy((u.T * inertia.mass_matrix * u)[0, 0] / 2)
        return {"transformation": C, "offset": velocity.offset, "kinematics": velocity.kinematics,
                "mass_matrix": inertia.mass_matrix, "velocity_terms": inertia.velocity_terms,
                "effect_forces": forces, "kinetic_energy": kinetic}


def speed_equations(system: KnownSystem, velocity: VelocityTransformation, constraint_names: Sequence[str],
                    definitions: Mapping[sympy.Symbol, sympy.Expr],
                    tidy: str = "entry") -> SpeedEquations:
    """A known system in the coordinates ``x`` (``M``, ``h``, each effect's ``f``) carried to its
    speeds by ``xdot = C u + d``: (9'), (D)-(F) as in :func:`project_nonholonomic`, ``fbar = C^T f``
    of each effect apart (8'), (F), and ``T = 1/2 u^T Mbar u`` (24): the kinetic energy, ``xdot = C u``,
    less the motion ``d`` that constraints in time impose (as a prescribed motion's ``T``), each
    entry simplified by ``TIDY[tidy]``. The projection is made when first read
    (:class:`SpeedProjection`); a linearisation needs none of it."""
    holonomic = tuple(Constraint(name, g) for name, g in zip(constraint_names[len(constraint_names)
                                                                              - len(velocity.holonomic):],
                                                                velocity.holonomic))
    source = SpeedProjection(mass_matrix=system.mass_matrix, velocity_terms=system.velocity_terms,
                             effect_forces=tuple(system.effect_forces.items()), velocity=velocity, tidy=tidy)
    return SpeedEquations(speeds=velocity.speeds, definitions=tuple(definitions.items()),
                          holonomic=holonomic, dependent=velocity.dependent,
                          constraint_names=tuple(constraint_names), constraint_matrix=velocity.constraint_matrix,
                          constraint_offset=velocity.constraint_offset, source=source, rows=velocity.rows)


def speed_rates(speeds: Sequence[sympy.Symbol], coordinates: Sequence[sympy.Symbol]) -> list[sympy.Symbol]:
    """The symbols of ``udot`` as printed: ``q_ddot`` for a speed that is the velocity ``q_dot``
    of a coordinate, ``v_dot`` for a named speed ``v``."""
    own = {velocity_symbol(q): acceleration_symbol(q) for q in coordinates}
    return [own.get(u, velocity_symbol(u)) for u in speeds]


def velocity_multipliers(system: KnownSystem) -> list[tuple[str, sympy.Expr]]:
    """``(mu_<constraint>, expression)`` per velocity constraint: the multipliers of
    ``M xddot + h = f + A^T mu`` (viewpoint (alpha), the workless reactions of the constraints),
    with ``xdot = C u + d`` and ``xddot = C udot + Cdot u + ddot``; ``C^T (M xddot + h - f) = 0``
    is the equations of motion, so ``mu`` comes from ``m`` rows of ``A^T mu = M xddot + h - f``
    where ``A`` has full rank (the last coordinates first). In the coordinates, the speeds and
    their rates (:func:`speed_rates`)."""
    s = system.speeds
    x = system.coordinates
    A = s.constraint_matrix
    m, n = A.shape
    moved = {velocity_symbol(q): s.kinematics[i] for i, q in enumerate(x)}
    rates = sympy.Matrix(speed_rates(s.speeds, x))
    convective = jacobian(s.kinematics, x) * s.kinematics + where_defined(s.kinematics.diff(TIME))
    xddot = s.transformation * rates + convective
    residual = (sympy.Matrix(system.mass_matrix) * xddot
                + sympy.Matrix(system.velocity_terms).xreplace(moved)
                - sympy.Matrix(system.forces).xreplace(moved))
    point = _generic_points(A, x, {p.symbol: p.value for p in system.parameters
                                   if p.value is not None and sympy.sympify(p.value).is_number})
    rows = _simplest_minor(A, x, point)
    mu = A[:, rows].T.LUsolve(residual.extract(rows, [0]))
    return [(f"mu_{name}", tidy_entry(e)) for name, e in zip(s.constraint_names, mu)]


def _simplest_minor(A: sympy.Matrix, coordinates, point) -> list[int]:
    """The columns of an ``m x m`` minor of ``A`` of full generic rank whose determinant is
    simplest: free of the coordinates if one is (a solve then divides by no function of the
    configuration), else of fewest operations; the last columns first among equals."""
    m, n = A.shape
    best, key = None, None
    for chosen in itertools.combinations(reversed(range(n)), m):
        columns = sorted(chosen)
        if _rank(A[:, columns], point) < m:
            continue
        det = tidy_entry(A[:, columns].det())
        score = (bool(det.free_symbols & set(coordinates)), sympy.count_ops(det))
        if key is None or score < key:
            best, key = columns, score
    return best


def speed_accelerations(projection: NonholonomicProjection) -> list[sympy.Symbol]:
    """The symbols of ``udot`` (named like accelerations of the speeds)."""
    return [acceleration_symbol(s) for s in projection.velocity.speeds]


def _generic_points(A: sympy.Matrix, coordinates, values) -> list[dict]:
    """Random points of the coordinates, parameters and time: a rank taken there is the
    generic rank (with probability one)."""
    rng = random.Random(20070509)
    free = sorted(set().union(*(sympy.sympify(e).free_symbols for e in A)) | set(coordinates), key=str)
    points = []
    for _ in range(GENERIC_POINTS):
        point = {s: sympy.Float(rng.uniform(0.2, 1.3)) for s in free}
        point.update(values or {})
        points.append(point)
    return points


def generic_rank(A: sympy.Matrix, coordinates, values=None) -> int:
    """The rank of ``A(x)`` at a generic configuration (:data:`GENERIC_POINTS` random ones)."""
    return _rank(A, _generic_points(A, coordinates, values))


def _rank(A: sympy.Matrix, points: list[dict]) -> int:
    """The largest rank of ``A`` at ``points``, complex values taken as they come (a random point
    may leave a function's real domain, ``asin`` of 1.3) and points where an entry is infinite or
    undefined left out; at none finite, :class:`VelocityConstraintError`."""
    found = [v for v in (_numeric(A, p) for p in points) if v is not None and np.all(np.isfinite(v))]
    scale = row_sizes(found)
    ranks = [int(np.linalg.matrix_rank(rows_scaled(v, scale), tol=1e-9)) if v.size else 0 for v in found]
    if not ranks:
        raise VelocityConstraintError(
            "the coefficients of the velocities are infinite or undefined at every configuration tried, the "
            "parameters at their values", "check divisions by a parameter expression that is zero, and the "
            "arguments of sqrt, log, asin and acos")
    return max(ranks)


def generic_values(A: sympy.Matrix, coordinates, values=None) -> list[np.ndarray]:
    """``A`` at :data:`GENERIC_POINTS` random configurations (the parameters at ``values``),
    where it has finite values (complex ones taken as they come)."""
    found = [_numeric(A, p) for p in _generic_points(A, coordinates, values)]
    return [v for v in found if v is not None and np.all(np.isfinite(v))]


def _numeric(A: sympy.Matrix, point: dict) -> np.ndarray | None:
    """``A`` at ``point`` in floating point, each shared subexpression once; by sympy's ``evalf``
    in complex numbers where that cannot be done (a value without a number, a complex one); None
    where an entry has no value."""
    try:
        values, _ = value_and_jacobian(list(A), (), {s: float(v) for s, v in point.items()})
        return np.array(values, dtype=float).reshape(A.shape)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError, KeyError):
        pass
    try:
        return np.array(A.xreplace(point).evalf(), dtype=complex).reshape(A.shape)
    except (TypeError, ValueError, OverflowError):
        return None


__all__ = ["GENERIC_POINTS", "NonholonomicProjection", "VelocityConstraintError", "VelocityTransformation",
           "SpeedProjection", "TIDY", "generic_values", "differentiated_form", "frame_entry", "generic_rank", "integrable", "linear_form",
           "project_nonholonomic", "speed_accelerations", "speed_equations", "speed_rates", "tidy_entry",
           "velocity_multipliers", "velocity_transformation"]
