"""The transition to a subspace: Kron's projection of a primitive system.

Given the interconnection ``x^a = x^a(xbar)`` (19), (20), (26) and
``C^a_alpha = dx^a / dxbar^alpha`` (7'), (21):

    Mbar = C^T M C                                  (9'), (D)
    hbar = C^T (M Cdot xbardot + h(x(xbar), C xbardot))    (E)
    fbar = C^T f(x(xbar), C xbardot, t)             (8'), (F)

Every product is formed in the trigonometric-polynomial algebra
(:mod:`.trigpoly`), so the results are compact as they are built.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import sympy

from ..components.base import Body
from .known_system import KnownSystem, ParameterInfo, Transition
from .primitive import Primitive
from .simplify import compact
from .symbols import velocity_symbol
from .trigpoly import TrigAlgebra, TrigPoly


class _Subspace:
    """The interconnection ``x = x(xbar)`` in the algebra: ``C``, ``xdot``, ``Cdot xbardot``."""

    def __init__(self, primitive: Primitive, coordinates, connection):
        self.coords = tuple(coordinates)
        self.n = len(self.coords)
        self.algebra = algebra = TrigAlgebra(self.coords)
        self.qdots = [algebra.atom(velocity_symbol(q)) for q in self.coords]
        self.x = primitive.coordinates
        self.connection = connection
        images = [algebra.from_expr(connection[x]) for x in self.x]
        # C^a_alpha = dx^a / dxbar^alpha  (7'), (21)
        self.C = [[algebra.diff(img, j) for j in range(self.n)] for img in images]
        self.nonzero = [[j for j in range(self.n) if not row[j].is_zero()] for row in self.C]
        # xdot^a = C^a_alpha xbardot^alpha; the substitution x -> x(xbar), xdot -> C xbardot
        self.velocity = [_sum(self.C[a][j] * self.qdots[j] for j in self.nonzero[a]) for a in range(len(self.x))]
        substitution = {x: connection[x] for x in self.x}
        substitution.update({v: algebra.to_expr(vel) for v, vel in zip(primitive.velocities, self.velocity)})
        self.substitution = {k: v for k, v in substitution.items() if k != v}  # identities would only rebuild
        # Cdot xbardot = d(xdot)/dxbar^k xbardot^k: the convective acceleration
        self.convective = [
            _sum(algebra.diff(vel, k) * self.qdots[k] for k in sorted(algebra.depends_on(vel)))
            for vel in self.velocity
        ]

    def image(self, expr: sympy.Expr) -> TrigPoly:
        """``expr(x(xbar), C xbardot)`` in the algebra."""
        return self.algebra.from_expr(sympy.sympify(expr).xreplace(self.substitution))

    def moved(self, expr: sympy.Expr) -> sympy.Expr:
        return sympy.sympify(expr).xreplace(self.substitution)

    def transpose_times(self, f: list[TrigPoly]) -> list[TrigPoly]:
        """``C^T f`` (8'), (F)."""
        out = [TrigPoly() for _ in range(self.n)]
        for a, fa in enumerate(f):
            if not fa.is_zero():
                for j in self.nonzero[a]:
                    out[j].add_product(self.C[a][j], fa)
        return out

    def renaming(self, part) -> list[int] | None:
        """Indices of the new coordinates when the part's coordinates are only renamed."""
        index = {q: j for j, q in enumerate(self.coords)}
        targets = [index.get(self.connection[x]) for x in part.coordinates]
        if None in targets or len(set(targets)) != len(targets):
            return None
        return targets


def project(
    primitive: Primitive,
    coordinates: Sequence[sympy.Symbol],
    connection: Mapping[sympy.Symbol, sympy.Expr],
    effects: Sequence,
    *,
    name: str = "",
    parameters: Sequence[ParameterInfo] = (),
    description: str = "",
) -> KnownSystem:
    """Project ``primitive`` onto the subspace ``x = connection(xbar)``.

    ``connection`` maps every primitive coordinate to an expression in the new
    ``coordinates``; ``effects`` are applied on the primitive and projected.
    """
    sub = _Subspace(primitive, coordinates, connection)
    n, algebra = sub.n, sub.algebra

    # A part whose coordinates are only renamed (C a permutation, Cdot = 0) is
    # carried over as it is: a cached known system then costs almost nothing.
    renamed = {part.name: t for part in primitive.parts if (t := sub.renaming(part)) is not None}
    mass, velocity_terms, direct_mass, direct_h = _inertia(sub, primitive, renamed)
    effect_forces, primitive_forces, potential = _forces(sub, primitive, effects, renamed)

    mass_matrix = sympy.zeros(n, n)
    for j in range(n):
        for k in range(j, n):
            mass_matrix[j, k] = mass_matrix[k, j] = compact(algebra, mass[j][k]) + sympy.Add(
                *direct_mass.get((j, k), ()))
    transition = Transition(
        primitive_coordinates=sub.x,
        primitive_metric=primitive.metric,
        primitive_velocity_terms=primitive.velocity_terms,
        primitive_forces=primitive_forces,
        connection=tuple((x, connection[x]) for x in sub.x),
        transformation=sympy.Matrix(len(sub.x), n, lambda a, j: compact(algebra, sub.C[a][j])),
        parts=tuple((p.name, p.type_name) for p in primitive.parts),
    )
    points = {f"{part.name}.{label}": tuple(sub.moved(c) for c in pos)
              for part in primitive.parts for label, pos in part.points.items()}
    bodies = tuple(
        Body(body.mass, tuple(sub.moved(c) for c in body.centre),
             None if body.rotation is None else body.rotation.applyfunc(sub.moved), body.inertia)
        for part in primitive.parts for body in part.bodies)
    dims = {part.dimension for part in primitive.parts if part.dimension}
    return KnownSystem(
        name=name,
        coordinates=sub.coords,
        mass_matrix=mass_matrix,
        velocity_terms=sympy.Matrix([compact(algebra, p) + sympy.Add(*direct_h.get(j, ()))
                                     for j, p in enumerate(velocity_terms)]),
        effect_forces=effect_forces,
        potential_energy=compact(algebra, algebra.from_expr(potential)),
        points=points,
        bodies=bodies,
        dimension=max(dims) if len(dims) == 1 else 0,
        parameters=tuple(parameters),
        transition=transition,
        description=description,
    )


def _inertia(sub: _Subspace, primitive: Primitive, renamed: dict[str, list[int]]):
    """``Mbar = C^T M C`` (9'), (D) and ``hbar = C^T (M Cdot xbardot + h)`` (E), block by block."""
    n, C, nonzero = sub.n, sub.C, sub.nonzero
    mass = [[TrigPoly() for _ in range(n)] for _ in range(n)]
    inertial = [TrigPoly() for _ in range(len(sub.x))]  # M Cdot xbardot + h
    direct_mass: dict[tuple[int, int], list[sympy.Expr]] = {}
    direct_h: dict[int, list[sympy.Expr]] = {}
    for offset, part in primitive.blocks():
        size = len(part.coordinates)
        targets = renamed.get(part.name)
        if targets is not None:
            for i, j in enumerate(targets):
                if part.velocity_terms[i] != 0:
                    direct_h.setdefault(j, []).append(sub.moved(part.velocity_terms[i]))
                for i2, k in enumerate(targets):
                    if j <= k and part.metric[i, i2] != 0:
                        direct_mass.setdefault((j, k), []).append(sub.moved(part.metric[i, i2]))
            continue
        block = [[sub.image(part.metric[i, j]) for j in range(size)] for i in range(size)]
        for i in range(size):
            a = offset + i
            mc: dict[int, TrigPoly] = {}  # (M C)_a,k within the block
            acc = sub.image(part.velocity_terms[i]).copy()
            for j in range(size):
                if block[i][j].is_zero():
                    continue
                b = offset + j
                for k in nonzero[b]:
                    mc.setdefault(k, TrigPoly()).add_product(block[i][j], C[b][k])
                if not sub.convective[b].is_zero():
                    acc.add_product(block[i][j], sub.convective[b])
            inertial[a] = acc
            for j in nonzero[a]:
                for k, mck in mc.items():
                    if k >= j:
                        mass[j][k].add_product(C[a][j], mck)
    return mass, sub.transpose_times(inertial), direct_mass, direct_h


def _forces(sub: _Subspace, primitive: Primitive, effects, renamed: dict[str, list[int]]):
    """``fbar = C^T f`` (8'), (F) per effect, and the potential ``V(x(xbar))``.

    A known system's own effects come along, named ``part.effect``.
    """
    primitive_forces: dict[str, sympy.Matrix] = {}
    direct: dict[str, sympy.Matrix] = {}
    potential = sympy.Integer(0)
    for offset, part in primitive.blocks():
        for label, f in part.forces.items():
            key = f"{part.name}.{label}"
            if part.name in renamed:
                vec = [sympy.Integer(0)] * sub.n
                for i, j in enumerate(renamed[part.name]):
                    vec[j] = sub.moved(f[i])
                direct[key] = sympy.Matrix(vec)
            full = [sympy.Integer(0)] * len(sub.x)
            full[offset:offset + len(part.coordinates)] = list(f)
            primitive_forces[key] = sympy.Matrix(full)
        potential += sub.moved(part.potential)
    for effect in effects:
        primitive_forces[effect.name] = sympy.Matrix(effect.generalized_force(primitive))
        potential += sub.moved(effect.potential(primitive))
    effect_forces: dict[str, sympy.Matrix] = {}
    for label, f in primitive_forces.items():
        if label in direct:
            effect_forces[label] = direct[label]
            continue
        fbar = sub.transpose_times([sub.image(fa) if fa != 0 else TrigPoly() for fa in f])
        effect_forces[label] = sympy.Matrix([compact(sub.algebra, p) for p in fbar])
    return effect_forces, primitive_forces, potential


def _sum(polys) -> TrigPoly:
    total = TrigPoly()
    for p in polys:
        total.add(p)
    return total
