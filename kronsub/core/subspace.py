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
    coords = tuple(coordinates)
    n = len(coords)
    algebra = TrigAlgebra(coords)
    qdots = [algebra.atom(velocity_symbol(q)) for q in coords]

    x_prim = primitive.coordinates
    images = [algebra.from_expr(connection[x]) for x in x_prim]
    # C^a_alpha = dx^a / dxbar^alpha  (7'), (21)
    C = [[algebra.diff(img, j) for j in range(n)] for img in images]
    nonzero = [[j for j in range(n) if not C[a][j].is_zero()] for a in range(len(x_prim))]

    # xdot^a = C^a_alpha xbardot^alpha, and the substitution x -> x(xbar), xdot -> C xbardot
    velocity = [_sum(C[a][j] * qdots[j] for j in nonzero[a]) for a in range(len(x_prim))]
    substitution = {x: connection[x] for x in x_prim}
    substitution.update({v: algebra.to_expr(vel) for v, vel in zip(primitive.velocities, velocity)})
    substitution = {k: v for k, v in substitution.items() if k != v}  # identities would only rebuild

    def image(expr: sympy.Expr) -> TrigPoly:
        return algebra.from_expr(sympy.sympify(expr).xreplace(substitution))

    # Cdot xbardot = d(xdot)/dxbar^k xbardot^k: the convective acceleration
    convective = [
        _sum(algebra.diff(velocity[a], k) * qdots[k] for k in _coordinates_of(algebra, velocity[a]))
        for a in range(len(x_prim))
    ]

    mass = [[TrigPoly() for _ in range(n)] for _ in range(n)]
    inertial = [TrigPoly() for _ in range(len(x_prim))]  # M Cdot xbardot + h
    # A part whose coordinates are only renamed (C a permutation, Cdot = 0) is
    # carried over as it is: a cached known system then costs almost nothing.
    direct_mass: dict[tuple[int, int], list[sympy.Expr]] = {}
    direct_h: dict[int, list[sympy.Expr]] = {}
    renamed: dict[str, list[int]] = {}
    for offset, part in primitive.blocks():
        size = len(part.coordinates)
        targets = _renaming(part, connection, coords)
        if targets is not None:
            renamed[part.name] = targets
            for i, j in enumerate(targets):
                if part.velocity_terms[i] != 0:
                    direct_h.setdefault(j, []).append(part.velocity_terms[i].xreplace(substitution))
                for i2, k in enumerate(targets):
                    if j <= k and part.metric[i, i2] != 0:
                        direct_mass.setdefault((j, k), []).append(part.metric[i, i2].xreplace(substitution))
            continue
        block = [[image(part.metric[i, j]) for j in range(size)] for i in range(size)]
        h_part = [image(part.velocity_terms[i]) for i in range(size)]
        for i in range(size):
            a = offset + i
            # (M C)_a,k and (M Cdot xbardot + h)_a within the block
            mc: dict[int, TrigPoly] = {}
            acc = h_part[i].copy()
            for j in range(size):
                if block[i][j].is_zero():
                    continue
                b = offset + j
                for k in nonzero[b]:
                    mc.setdefault(k, TrigPoly()).add_product(block[i][j], C[b][k])
                if not convective[b].is_zero():
                    acc.add_product(block[i][j], convective[b])
            inertial[a] = acc
            for j in nonzero[a]:
                for k, mck in mc.items():
                    if k >= j:
                        mass[j][k].add_product(C[a][j], mck)

    velocity_terms = [TrigPoly() for _ in range(n)]
    for a in range(len(x_prim)):
        for j in nonzero[a]:
            velocity_terms[j].add_product(C[a][j], inertial[a])

    effect_forces: dict[str, sympy.Matrix] = {}
    primitive_forces: dict[str, sympy.Matrix] = {}
    potential = sympy.Integer(0)
    direct_forces: dict[str, sympy.Matrix] = {}
    for part in primitive.parts:  # a known system's own effects come along
        for label, f in part.forces.items():
            if part.name in renamed:
                vec = [sympy.Integer(0)] * n
                for i, j in enumerate(renamed[part.name]):
                    vec[j] = f[i].xreplace(substitution)
                direct_forces[f"{part.name}.{label}"] = sympy.Matrix(vec)
            full = [sympy.Integer(0)] * len(x_prim)
            offset = x_prim.index(part.coordinates[0])
            for i in range(len(part.coordinates)):
                full[offset + i] = f[i]
            primitive_forces[f"{part.name}.{label}"] = sympy.Matrix(full)
        potential += part.potential.xreplace(substitution)
    for effect in effects:
        primitive_forces[effect.name] = sympy.Matrix(effect.generalized_force(primitive))
        potential += effect.potential(primitive).xreplace(substitution)
    for label, f in primitive_forces.items():
        if label in direct_forces:
            effect_forces[label] = direct_forces[label]
            continue
        f_img = [image(fa) if fa != 0 else TrigPoly() for fa in f]
        fbar = [_sum(C[a][j] * f_img[a] for a in range(len(x_prim)) if j in nonzero[a] and not f_img[a].is_zero())
                for j in range(n)]
        effect_forces[label] = sympy.Matrix([compact(algebra, p) for p in fbar])

    mass_matrix = sympy.zeros(n, n)
    for j in range(n):
        for k in range(j, n):
            mass_matrix[j, k] = mass_matrix[k, j] = compact(algebra, mass[j][k]) + sympy.Add(
                *direct_mass.get((j, k), ()))

    C_matrix = sympy.Matrix(len(x_prim), n, lambda a, j: compact(algebra, C[a][j]))
    transition = Transition(
        primitive_coordinates=x_prim,
        primitive_metric=primitive.metric,
        primitive_velocity_terms=primitive.velocity_terms,
        primitive_forces=primitive_forces,
        connection=tuple((x, connection[x]) for x in x_prim),
        transformation=C_matrix,
        parts=tuple((p.name, p.type_name) for p in primitive.parts),
    )
    def moved(expr, part):
        return sympy.sympify(expr).xreplace(substitution)

    points = {f"{part.name}.{label}": tuple(moved(c, part) for c in pos)
              for part in primitive.parts for label, pos in part.points.items()}
    bodies = tuple(
        Body(body.mass, tuple(moved(c, part) for c in body.centre),
             None if body.rotation is None else body.rotation.applyfunc(lambda e, part=part: moved(e, part)),
             body.inertia)
        for part in primitive.parts for body in part.bodies)
    dims = {part.dimension for part in primitive.parts if part.dimension}
    return KnownSystem(
        name=name,
        coordinates=coords,
        mass_matrix=mass_matrix,
        velocity_terms=sympy.Matrix([compact(algebra, p) + sympy.Add(*direct_h.get(j, ()))
                                     for j, p in enumerate(velocity_terms)]),
        effect_forces=effect_forces,
        potential_energy=_simplified(algebra, potential),
        points=points,
        bodies=bodies,
        dimension=max(dims) if len(dims) == 1 else 0,
        parameters=tuple(parameters),
        transition=transition,
        description=description,
    )


def _renaming(part, connection, coords) -> list[int] | None:
    """Indices of the new coordinates when the part's coordinates are only renamed."""
    index = {q: j for j, q in enumerate(coords)}
    targets = [index.get(connection[x]) for x in part.coordinates]
    if None in targets or len(set(targets)) != len(targets):
        return None
    return targets


def _sum(polys) -> TrigPoly:
    total = TrigPoly()
    for p in polys:
        total.add(p)
    return total


def _coordinates_of(algebra: TrigAlgebra, p: TrigPoly):
    return sorted(algebra.depends_on(p))


def _simplified(algebra: TrigAlgebra, expr: sympy.Expr) -> sympy.Expr:
    return compact(algebra, algebra.from_expr(expr))
