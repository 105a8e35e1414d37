"""The transition to a subspace: Kron's projection of a primitive system.

Given the interconnection ``x^a = x^a(xbar)`` (19), (20), (26) and
``C^a_alpha = dx^a / dxbar^alpha`` (7'), (21):

    Mbar = C^T M C                                  (9'), (D)
    hbar = C^T (M Cdot xbardot + h(x(xbar), C xbardot))    (E)
    fbar = C^T f(x(xbar), C xbardot, t)             (8'), (F)

A connection that names time, ``x = x(xbar, t)`` (a prescribed motion, :mod:`.rheonomic`),
adds the drive's velocity ``dx/dt`` to ``xdot`` and its ``d(xdot)/dt`` to ``Cdot xbardot``.

Every product is formed in the trigonometric-polynomial algebra
(:mod:`.trigpoly`), so the results are compact as they are built; ``Mbar`` and
``M Cdot xbardot`` are summed over the distinct pairs of values of ``C``, each
with its sum of inertias formed once (:func:`_shared_sums`).
"""
from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import sympy

from ..budget import charge
from ..components.base import Body
from . import canonical
from .deferred import DeferredMatrix, Once
from .inverse_trig import Radicands
from .known_system import KnownSystem, ParameterInfo, ProjectedEffect, Transition
from .placed import PlacedBodies, PlacedPoints, Placer
from .primitive import Primitive, body_label, point_symbols
from .simplify import compact
from .rheonomic import depends_on_time
from .derivative import derivative
from .symbols import TIME, free_symbols_of, velocity_symbol
from .trigpoly import TrigAlgebra, TrigPoly


SHARED_FROM = 12
"""Coordinates from which ``Mbar`` and ``hbar`` are summed over shared sums of inertias
(:func:`_shared_sums`); below, row by row (:func:`_row_by_row`), as every small model's equations
were printed: the two routes give equal entries, but the order in which the algebra meets a
coefficient's terms decides the sign a printed factor takes (``-2*c*(-3*a1**2 + ...)`` or
``2*c*(3*a1**2 - ...)``). The same bound as the generated code's projected route."""


class Subspace:
    """The interconnection ``x = x(xbar)`` in the algebra: ``C``, ``xdot``, ``Cdot xbardot``;
    shared by the projection of the inertia and of each effect."""

    def __init__(self, primitive: Primitive, coordinates, connection):
        self.coords = tuple(coordinates)
        self.n = len(self.coords)
        self.algebra = algebra = TrigAlgebra(self.coords)
        self.qdots = [algebra.atom(velocity_symbol(q)) for q in self.coords]
        self.x = primitive.coordinates
        self.connection = connection
        self.radicands = Radicands(algebra, connection.values())  # atan2/asin in it (inverse_trig)
        self.velocities = primitive.velocities

    # C and what follows from it are built when first asked for (before any other image, so
    # the algebra meets its atoms in one order): a subspace that only renames the
    # coordinates of known systems carries their parts over without them

    @functools.cached_property
    def C(self) -> list[list[TrigPoly]]:
        """``C^a_alpha = dx^a / dxbar^alpha`` (7'), (21)."""
        algebra = self.algebra
        images = [algebra.from_expr(self.radicands.rewrite(self.connection[x])) for x in self.x]
        return [algebra.gradient(img) for img in images]

    @functools.cached_property
    def nonzero(self) -> list[list[int]]:
        """The columns where each row of ``C`` is not zero."""
        return [[j for j in range(self.n) if not row[j].is_zero()] for row in self.C]

    @functools.cached_property
    def shape_of(self) -> list[dict]:
        """Rows of ``C`` equal within a column share their products: ``C^T y = sum`` over the
        distinct values ``u`` of column ``j`` of ``u * (sum of y over the rows where C_aj = u)``."""
        return [{j: row[j].key() for j in nz} for row, nz in zip(self.C, self.nonzero)]

    @functools.cached_property
    def driven(self) -> bool:
        """The connection names time: ``x = x(xbar, t)``, a prescribed motion."""
        return depends_on_time(self.connection)

    @functools.cached_property
    def velocity(self) -> list[TrigPoly]:
        """``xdot^a = C^a_alpha xbardot^alpha`` (``+ dx^a/dt`` when driven)."""
        out = [_sum(self.C[a][j] * self.qdots[j] for j in self.nonzero[a]) for a in range(len(self.x))]
        if self.driven:
            for a, x in enumerate(self.x):
                drive = derivative(self.radicands.rewrite(self.connection[x]), TIME)
                if drive != 0:
                    out[a].add(self.algebra.from_expr(drive))
        return out

    def transformation(self, primitive: Primitive) -> sympy.Matrix:
        """``C`` as a matrix of expressions; a renaming's ones and zeros written directly."""
        if self.only_renames(primitive):
            index = {q: j for j, q in enumerate(self.coords)}
            return canonical.ones_at(len(self.x), self.n, [index[self.connection[x]] for x in self.x])
        return canonical.matrix(len(self.x), self.n, [compact(self.algebra, c) for row in self.C for c in row])

    @functools.cached_property
    def substitution(self) -> dict:
        """x -> x(xbar), xdot -> C xbardot (identities left out: they would only rebuild).
        A coordinate whose image is a coordinate of the subspace has that one's velocity."""
        substitution = dict(self.placement)
        coords = set(self.coords)
        for a, (x, v) in enumerate(zip(self.x, self.velocities)):
            image = self.connection[x]
            e = velocity_symbol(image) if image in coords else self.algebra.to_expr(self.velocity[a])
            if v != e:
                substitution[v] = e
        return substitution

    @functools.cached_property
    def placement(self) -> dict:
        """x -> x(xbar) alone: what an expression without velocities needs (the velocities'
        images are built only when an expression has some)."""
        return {x: image for x in self.x if x != (image := self.connection[x])}

    @property
    def moves_nothing(self) -> bool:
        """Every primitive coordinate is a coordinate of the subspace under its own name
        (``x = xbar``): an expression is its own image."""
        return not self.placement and not self.substitution

    def _substitution_for(self, expr: sympy.Expr) -> dict:
        """What moves ``expr``: the velocities' images too once they are built, or when the
        positions do not move at all (then they are only renamed symbols), or when ``expr``
        has a velocity."""
        if "substitution" in self.__dict__ or not self.placement \
                or not expr.free_symbols.isdisjoint(self.velocities):
            return self.substitution
        return self.placement

    @functools.cached_property
    def convective(self) -> list[TrigPoly]:
        """``Cdot xbardot = d(xdot)/dxbar^k xbardot^k``: the convective acceleration (the
        inertia needs it, an effect does not)."""
        algebra = self.algebra
        out = []
        for vel in self.velocity:
            gradient = algebra.gradient(vel)
            total = _sum(gradient[k] * self.qdots[k] for k in sorted(algebra.depends_on(vel)))
            if self.driven:  # + d(xdot)/dt: the drive's 2 dC/dt xbardot + d2x/dt2
                drive = derivative(algebra.to_expr(vel), TIME)
                if drive != 0:
                    total.add(algebra.from_expr(drive))
            out.append(total)
        return out

    def image(self, expr: sympy.Expr) -> TrigPoly:
        """``expr(x(xbar), C xbardot)`` in the algebra."""
        self.C  # noqa: B018  (built first: see above)
        return self.algebra.from_expr(self.radicands.rewrite(self.moved(expr)))

    def moved(self, expr: sympy.Expr) -> sympy.Expr:
        """``expr`` at ``x(xbar)``, ``xdot = C xbardot`` (itself when the connection only names
        the primitive's coordinates again)."""
        expr = sympy.sympify(expr)
        substitution = self._substitution_for(expr)
        return expr.xreplace(substitution) if substitution else expr

    def transpose_times(self, f: list[TrigPoly]) -> list[TrigPoly]:
        """``C^T f`` (8'), (F): rows with equal ``C_aj`` are summed before the product."""
        groups: list[dict] = [{} for _ in range(self.n)]  # j -> {C_aj key: [C_aj, sum of f_a]}
        for a, fa in enumerate(f):
            if not fa.is_zero():
                for j in self.nonzero[a]:
                    group = groups[j].get(self.shape_of[a][j])
                    if group is None:
                        groups[j][self.shape_of[a][j]] = [self.C[a][j], fa.copy()]
                    else:
                        group[1].add(fa)
        out = [TrigPoly() for _ in range(self.n)]
        for j, group in enumerate(groups):
            for u, total in group.values():
                out[j].add_product(u, total)
        return out

    def renamed_parts(self, primitive: Primitive) -> dict[str, list[int]]:
        """A part whose coordinates are only renamed (C a permutation, Cdot = 0) is carried
        over as it is: a cached known system then costs almost nothing."""
        return {part.name: t for part in primitive.parts if (t := self.renaming(part)) is not None}

    def only_renames(self, primitive: Primitive) -> bool:
        """Every coordinate is one primitive coordinate renamed, each exactly once: ``C`` is a
        permutation, of full rank everywhere."""
        renamed = self.renamed_parts(primitive)
        return len(renamed) == len(primitive.parts) and \
            sorted(j for targets in renamed.values() for j in targets) == list(range(self.n))

    @property
    def is_identity(self) -> bool:
        """``x = xbar``, coordinate for coordinate in the same order: ``C`` is the unit matrix,
        the transition gives back the primitive as it is (a known system reused unchanged)."""
        return self.x == self.coords and self.moves_nothing

    def renaming(self, part) -> list[int] | None:
        """Indices of the new coordinates when the part's coordinates are only renamed."""
        index = {q: j for j, q in enumerate(self.coords)}
        targets = [index.get(self.connection[x]) for x in part.coordinates]
        if None in targets or len(set(targets)) != len(targets):
            return None
        return targets


def effect_labels(primitive: Primitive, effects: Sequence) -> tuple[str, ...]:
    """The names of every effect, in the order of ``fbar``: a known system's own effects
    first, as ``part.effect``, then the model's."""
    labels = [f"{part.name}.{label}" for part in primitive.parts
              for label in dict.fromkeys([*part.forces, *part.potentials])]
    return tuple(labels) + tuple(e.name for e in effects)


def project_inertia(sub: Subspace, primitive: Primitive, *, name: str = "",
                    parameters: Sequence[ParameterInfo] = (), description: str = "",
                    deferred: bool = False) -> KnownSystem:
    """``Mbar`` (9'), (D) and ``hbar`` (E): the part of the projection no effect changes.

    The result has no effects; :func:`assemble` adds the ones a scene switches on. ``deferred``:
    ``Mbar`` and ``hbar`` are projected when first read (:class:`.DeferredMatrix`), in a
    subspace of their own, as they would be now; the transition (``C``) is built at once.
    """
    metric = primitive.metric
    h = DeferredMatrix(len(sub.x), 1, lambda: primitive.velocity_terms) if deferred else primitive.velocity_terms
    if sub.is_identity:  # x = xbar: Mbar = M, hbar = h, nothing to project
        mass_matrix, velocity_terms = _mutable(metric), _mutable(h)
    elif deferred:
        projected = Once(lambda: _projected_inertia(Subspace(primitive, sub.coords, sub.connection), primitive))
        mass_matrix = DeferredMatrix(sub.n, sub.n, lambda: projected()[0])
        velocity_terms = DeferredMatrix(sub.n, 1, lambda: projected()[1])
    else:
        mass_matrix, velocity_terms = _projected_inertia(sub, primitive)
    transition = Transition(
        primitive_coordinates=sub.x,
        primitive_metric=metric,
        primitive_velocity_terms=h,
        primitive_forces={},
        connection=tuple((x, sub.connection[x]) for x in sub.x),
        transformation=sub.transformation(primitive),
        parts=tuple((p.name, p.type_name) for p in primitive.parts),
        christoffel=all(p.christoffel for p in primitive.parts),
    )
    dimension = world_dimension(primitive)

    placer = Placer(sub.placement, dimension)
    points = PlacedPoints(primitive.points(), placer)  # each part's built when first read
    bodies = PlacedBodies([Body(body.mass, body.centre, body.rotation, body.inertia, name=body_label(part, body))
                           for part in primitive.parts for body in part.bodies], placer)
    # a point or body that moves with a velocity is placed at once: a component tells which
    # symbols its points may hold without building them; the bodies are walked once together
    # (when the subspace moves nothing, placing is the identity: there is nothing to look for)
    if not sub.moves_nothing:
        moving = [part for part in primitive.parts if not point_symbols(part.points).isdisjoint(sub.velocities)]
        located = [c for body in bodies.unplaced for c in _located(body)]
        if moving or not free_symbols_of(located).isdisjoint(sub.velocities):
            _place_moving(sub, placer, points, bodies, moving)
    return KnownSystem(
        name=name,
        coordinates=sub.coords,
        mass_matrix=mass_matrix,
        velocity_terms=velocity_terms,
        effect_forces={},
        points=points,
        bodies=bodies,
        dimension=dimension,
        parameters=tuple(parameters),
        transition=transition,
        description=description,
    )


def _mutable(m: sympy.MatrixBase) -> sympy.Matrix:
    """A mutable copy of ``m`` (copied as it is stored, not rebuilt entry by entry)."""
    return m.copy() if isinstance(m, sympy.MutableDenseMatrix) else m.as_mutable()


def _projected_inertia(sub: Subspace, primitive: Primitive) -> tuple[sympy.Matrix, sympy.Matrix]:
    """``Mbar`` and ``hbar`` as matrices: the projected sums, plus what renamed parts carry over."""
    n, algebra = sub.n, sub.algebra
    mass, velocity_terms, direct_mass, direct_h = _inertia(sub, primitive, sub.renamed_parts(primitive))
    entries = [[None] * n for _ in range(n)]
    for j in range(n):
        for k in range(j, n):
            entries[j][k] = entries[k][j] = _plus(compact(algebra, mass[j][k]), direct_mass.get((j, k), ()))
    return (canonical.matrix(n, n, [e for row in entries for e in row]),
            canonical.matrix(n, 1, [_plus(compact(algebra, p), direct_h.get(j, ())) for j, p in enumerate(velocity_terms)]))


def _place_moving(sub: Subspace, placer: Placer, points: PlacedPoints, bodies: PlacedBodies, parts) -> None:
    """Place at once the points (of ``parts``) and bodies whose positions have a velocity in
    them (no bundled model has one): placing them later would put those velocities through
    ``x -> x(xbar)``."""
    for part in parts:
        for label, pos in part.points.items():
            if not free_symbols_of(pos).isdisjoint(sub.velocities):
                points.place(f"{part.name}.{label}", placer.in_world(tuple(sub.moved(c) for c in pos)))
    for i, body in enumerate(bodies.unplaced):
        if not free_symbols_of(_located(body)).isdisjoint(sub.velocities):
            bodies.place(i, dataclasses.replace(body, centre=placer.in_world(tuple(sub.moved(c) for c in body.centre)),
                                                rotation=None if body.rotation is None
                                                else body.rotation.applyfunc(sub.moved)))


def _located(body: Body) -> list:
    """What places a body: its centre's coordinates and its rotation, if it has one."""
    return [*body.centre, *([body.rotation] if body.rotation is not None else [])]


def _plus(projected: sympy.Expr, direct) -> sympy.Expr:
    """``projected + sum(direct)`` (a renamed part's entries carried over, :meth:`Subspace.renaming`),
    not rebuilt when one side is all there is: sympy's cache would compare a large entry
    read from the known-system cache node by node with the one it holds."""
    return canonical.total([projected, *direct] if canonical.nonzero(projected) else direct)


def world_dimension(primitive: Primitive) -> int:
    """The world of the derived system: that of its parts; the plane when some parts live on a
    line and the others in the plane (the line is the plane's x axis, as for `pivot:`); 0 (no
    one world) for parts in the plane and in space."""
    dims = {part.dimension for part in primitive.parts if part.dimension}
    if dims == {1, 2}:
        return 2
    return max(dims) if len(dims) == 1 else 0


def assembled_potentials(primitive: Primitive) -> tuple:
    """``(coordinates, sum of potentials, V)`` of the known systems in ``primitive``: sums that
    :func:`assemble` compacted to ``V`` when each was derived (``Part.assembled_potential``)."""
    return tuple(part.assembled_potential for part in primitive.parts if part.assembled_potential)


def assemble(inertia: KnownSystem, effects: Sequence[ProjectedEffect], known: Sequence = ()) -> KnownSystem:
    """``Mbar qddot + hbar = fbar`` with ``fbar`` the sum of the given effects' forces (8'), (F)
    and ``V`` the sum of their potentials: the effects left out contribute nothing at all.

    ``known`` (:func:`assembled_potentials`): a sum already compacted in these coordinates
    is taken as it is, so a model that only reuses a cached known system does not redo it."""
    potential = canonical.total(e.potential for e in effects)
    transition = inertia.transition
    if transition is not None:
        transition = dataclasses.replace(transition, primitive_forces={e.label: e.primitive_force for e in effects},
                                         direct_effects=tuple(e.label for e in effects if e.direct))
    return dataclasses.replace(
        inertia,
        effect_forces={e.label: e.force for e in effects},
        effect_potentials={e.label: e.potential for e in effects},
        effect_translations={e.label: e.translation for e in effects if e.translation},
        potential_energy=_compacted_potential(tuple(inertia.coordinates), potential, known),
        transition=transition,
    )


def _compacted_potential(coordinates: tuple, potential: sympy.Expr, known: Sequence) -> sympy.Expr:
    """``V`` compacted in the algebra of ``coordinates``, or as ``known`` already holds it."""
    for own, raw, compacted in known:
        if own == coordinates and raw == potential:
            return compacted
    algebra = TrigAlgebra(coordinates)
    return compact(algebra, algebra.from_expr(potential))


def _inertia(sub: Subspace, primitive: Primitive, renamed: dict[str, list[int]]):
    """``Mbar = C^T M C`` (9'), (D) and ``hbar = C^T (M Cdot xbardot + h)`` (E), block by block."""
    n = sub.n
    mass = [[TrigPoly() for _ in range(n)] for _ in range(n)]
    inertial = [TrigPoly() for _ in range(len(sub.x))]  # h (and M Cdot xbardot when driven)
    weights: dict[int, dict[int, TrigPoly]] = {}  # a -> {b: M_ab} over the projected parts
    direct_mass: dict[tuple[int, int], list[sympy.Expr]] = {}
    direct_h: dict[int, list[sympy.Expr]] = {}
    for offset, part in primitive.blocks():
        size = len(part.coordinates)
        targets = renamed.get(part.name)
        if targets is not None:
            metric, h = part.metric.tolist(), list(part.velocity_terms)
            for i, j in enumerate(targets):
                if canonical.nonzero(h[i]):
                    direct_h.setdefault(j, []).append(sub.moved(h[i]))
                for i2, k in enumerate(targets):
                    if j <= k and canonical.nonzero(metric[i][i2]):
                        direct_mass.setdefault((j, k), []).append(sub.moved(metric[i][i2]))
            continue
        sub.C  # noqa: B018  (built for the first part that needs it)
        block = [[sub.image(part.metric[i, j]) for j in range(size)] for i in range(size)]
        for i in range(size):
            a = offset + i
            inertial[a] = sub.image(part.velocity_terms[i])
            row = {offset + j: m for j, m in enumerate(block[i]) if not m.is_zero()}
            if row:
                weights[a] = row
    velocity_terms = _shared_sums(sub, weights, mass, with_convective=not sub.driven)
    if velocity_terms is None or sub.driven:  # M Cdot xbardot row by row (the drive's terms are not C's)
        for a, row in weights.items():
            inertial[a] = inertial[a].copy()
            for b, m in row.items():
                if not sub.convective[b].is_zero():
                    inertial[a].add_product(m, sub.convective[b])
    if velocity_terms is None:
        _row_by_row(sub, weights, mass)
        return mass, sub.transpose_times(inertial), direct_mass, direct_h
    for j, p in enumerate(sub.transpose_times(inertial)):
        velocity_terms[j].add(p)
    return mass, velocity_terms, direct_mass, direct_h


def _row_by_row(sub: Subspace, weights: dict[int, dict[int, TrigPoly]], mass: list[list[TrigPoly]]) -> None:
    """``Mbar = C^T M C`` into ``mass`` as ``sum_a C_aj (M C)_ak``, with the rows of equal ``C_aj``
    summed first (see `Subspace.shape_of`): a system that shares no sum of inertias."""
    C, nonzero, shape_of = sub.C, sub.nonzero, sub.shape_of
    sums: list[dict] = [{} for _ in range(sub.n)]  # j -> {C_aj key: (C_aj, {k: sum of (M C)_ak})}
    for a, row in weights.items():
        mc: dict[int, TrigPoly] = {}  # (M C)_a,k
        for b, m in row.items():
            for k in nonzero[b]:
                mc.setdefault(k, TrigPoly()).add_product(m, C[b][k])
        for j in nonzero[a]:
            group = sums[j].get(shape_of[a][j])
            if group is None:
                group = sums[j][shape_of[a][j]] = (C[a][j], {})
            for k, mck in mc.items():
                if k >= j:
                    total = group[1].get(k)
                    if total is None:
                        group[1][k] = mck.copy()
                    else:
                        total.add(mck)
    for j in range(sub.n):
        for u, row in sums[j].values():
            for k, total in row.items():
                mass[j][k].add_product(u, total)


def _shared_sums(sub: Subspace, weights: dict[int, dict[int, TrigPoly]], mass: list[list[TrigPoly]], *,
                 with_convective: bool) -> list[TrigPoly] | None:
    """``Mbar`` into ``mass``, and the part ``C^T M Cdot xbardot`` of ``hbar`` (returned), summed
    over the pairs of values of ``C``:

        Mbar_jk = sum_(u, v) u v W,    (C^T M Cdot xbardot)_j = sum_(u, k, v) u D_k(v) W,

    ``W`` the sum of ``M_ab`` over the rows ``a`` with ``C_aj = u`` and ``b`` with ``C_bk = v``, and
    ``D_k(v) = xbardot^k dv/dxbar^l xbardot^l`` (``Cdot xbardot = sum_k D_k(C_bk)`` when the
    connection does not name time). Each distinct ``W`` is formed once, a sum of several terms
    constant in the coordinates as one shared atom (`TrigAlgebra.shared_sum`): the inertias below
    a link of a chain are one sum shared by a row and a column of ``Mbar``, not a sum in each.
    None, with nothing done, below `SHARED_FROM` coordinates or when no such sum is shared
    (`_row_by_row` then)."""
    C, nonzero, algebra = sub.C, sub.nonzero, sub.algebra
    n = sub.n
    if n < SHARED_FROM:
        return None
    values: dict = {}  # the key of a value of C -> its number
    numbered = [{k: values.setdefault(sub.shape_of[b][k], len(values)) for k in nonzero[b]} for b in range(len(C))]
    value_of = {}
    for b, row in enumerate(numbered):
        for k, v in row.items():
            value_of.setdefault(v, C[b][k])
    rows_of: list[list[int]] = [[] for _ in range(n)]  # column j -> the rows with inertia and C_aj != 0
    for a in weights:
        for j in nonzero[a]:
            rows_of[j].append(a)
    stride, width = len(C), len(values)
    sums: dict[tuple, tuple[int, TrigPoly]] = {}  # the pairs (a, b) -> (number, W)
    numbers: dict[tuple, int] = {}  # W's key -> its number
    plan: list[tuple[int, TrigPoly, int, int, int, TrigPoly]] = []  # (j, u, k, v, number, W)
    for j in range(n):
        groups: dict[int, list[int]] = {}  # the rows of column j by their value u
        for a in rows_of[j]:
            groups.setdefault(numbered[a][j], []).append(a)
        for u_number, rows in groups.items():
            u = value_of[u_number]
            buckets: dict[int, list[int]] = {}  # k * width + v -> the pairs
            for a in rows:
                for b in weights[a]:
                    pair = a * stride + b
                    for k, v in numbered[b].items():
                        if with_convective or k >= j:
                            bucket = buckets.get(k * width + v)
                            if bucket is None:
                                buckets[k * width + v] = [pair]
                            else:
                                bucket.append(pair)
            charge(sum(map(len, buckets.values())), "the sums of inertias of the projection")
            for key, pairs in buckets.items():
                k, v = divmod(key, width)
                number, W = _weight(algebra, weights, tuple(pairs), stride, sums, numbers)
                if not W.is_zero():
                    plan.append((j, u, k, v, number, W))
    if not algebra.shared_sums:
        return None
    hbar = [TrigPoly() for _ in range(n)]
    products: dict[tuple, TrigPoly] = {}  # (v, W) -> v W; (k, v, W) -> D_k(v) W
    rates: dict[tuple[int, int], TrigPoly] = {}
    for j, u, k, v, number, W in plan:
        if k >= j:
            vw = products.get((v, number))
            if vw is None:
                vw = products[(v, number)] = value_of[v] * W
            mass[j][k].add_product(u, vw)
        if with_convective:
            dw = products.get((k, v, number))
            if dw is None:
                rate = rates.get((k, v))
                if rate is None:
                    rate = rates[(k, v)] = _rate(sub, k, value_of[v])
                dw = products[(k, v, number)] = rate * W
            if not dw.is_zero():
                hbar[j].add_product(u, dw)
    return hbar


def _weight(algebra: TrigAlgebra, weights, pairs: tuple, stride: int, sums: dict, numbers: dict):
    """``(number, W)``: ``W = sum of M_ab`` over ``pairs`` (``a * stride + b``), numbered by its
    value; a sum of several terms constant in the coordinates is one shared atom."""
    hit = sums.get(pairs)
    if hit is None:
        if len(pairs) == 1:
            a, b = divmod(pairs[0], stride)
            W = weights[a][b]
        else:
            W = TrigPoly()
            for pair in pairs:
                a, b = divmod(pair, stride)
                W.add(weights[a][b])
            if sum(map(len, W.terms.values())) > 1 and not algebra.depends_on(W) and not algebra.has_shared(W):
                W = algebra.shared_sum(W)
        hit = sums[pairs] = (numbers.setdefault(W.key(), len(numbers)), W)
    return hit


def _rate(sub: Subspace, k: int, v: TrigPoly) -> TrigPoly:
    """``D_k(v) = xbardot^k sum_l dv/dxbar^l xbardot^l``: the part of ``Cdot xbardot`` a value
    ``v`` of column ``k`` of ``C`` brings."""
    gradient = sub.algebra.gradient(v)
    total = _sum(gradient[l] * sub.qdots[l] for l in sorted(sub.algebra.depends_on(v)))
    return total * sub.qdots[k] if not total.is_zero() else total


def project_effects(sub: Subspace, primitive: Primitive, effects, only=None) -> list[ProjectedEffect]:
    """``fbar = C^T f`` (8'), (F) and the potential ``V(x(xbar))``, effect by effect.

    A known system's own effects come along, named ``part.effect``. ``only`` (a set of
    labels) projects just those: an effect a scene switches off is never touched.
    """
    renamed = sub.renamed_parts(primitive)
    out: list[ProjectedEffect] = []
    for offset, part in primitive.blocks():
        labels = dict.fromkeys([*part.forces, *part.potentials])
        for label in labels:
            key = f"{part.name}.{label}"
            if only is not None and key not in only:
                continue
            f = part.forces.get(label, sympy.zeros(len(part.coordinates), 1))
            full = [sympy.Integer(0)] * len(sub.x)
            full[offset:offset + len(part.coordinates)] = list(f)
            if part.name in renamed:
                vec = [sympy.Integer(0)] * sub.n
                for i, j in enumerate(renamed[part.name]):
                    vec[j] = sub.moved(f[i])
                force = canonical.matrix(sub.n, 1, vec)
            else:
                force = _projected(sub, full)
            out.append(ProjectedEffect(label=key, primitive_force=canonical.matrix(len(full), 1, full), force=force,
                                       potential=sub.moved(part.potentials.get(label, sympy.Integer(0))),
                                       translation=tuple(part.translations.get(label, ()))))
    generalized = _generalized_only(sub, primitive)
    through = None  # found for the first effect that names a generalized coordinate
    for effect in effects:
        if only is not None and effect.name not in only:
            continue
        named = effect.symbols() & generalized
        if named:
            through = _through_primitive(sub, generalized) if through is None else through
            if named <= through.keys():  # in the primitive after all: its force acts there
                effect = effect.written_in(through)
        direct = None
        if generalized and effect.symbols() & generalized:
            direct = effect.direct_force(primitive, sub.coords, sub.moved)  # written in xbar
        if direct is not None:
            out.append(ProjectedEffect(label=effect.name, primitive_force=sympy.zeros(len(sub.x), 1),
                                       force=sympy.Matrix(direct), potential=sub.moved(effect.potential(primitive)),
                                       direct=True, translation=effect.translation(primitive)))
            continue
        f, V = effect.force_and_potential(primitive)
        out.append(ProjectedEffect(label=effect.name, primitive_force=sympy.Matrix(f), force=_projected(sub, f),
                                   potential=sub.moved(V), translation=effect.translation(primitive)))
    return out


def _through_primitive(sub: Subspace, generalized: set) -> dict:
    """``q -> x^a - c``, ``qdot -> xdot^a`` for each generalized coordinate ``q`` that exactly one
    primitive coordinate equals up to a constant, ``x^a = q + c`` (a pivoted rod's
    ``axis = angle - pi/2``, an identity line): an effect written in ``q`` is then one in ``x``,
    its force acts on the primitive (``fbar = C^T f`` (8') is unchanged, ``C^a_q = 1``) and the
    reactions are defined. With two such ``x^a`` the body it acts on is not said: left as it is."""
    found: dict = {}
    for x in sub.x:
        image = sympy.sympify(sub.connection[x])
        used = image.free_symbols & set(sub.coords)
        if len(used) == 1 and (q := used.pop()) in generalized:
            offset = sympy.expand(image - q)
            if not offset.free_symbols & {*sub.coords, TIME}:  # a drive's offset moves x^a apart from q
                found.setdefault(q, []).append((x, offset))
    out: dict = {}
    for q, images in found.items():
        if len(images) == 1:
            [(x, offset)] = images
            out[q], out[velocity_symbol(q)] = x - offset, velocity_symbol(x)
    return out


def _generalized_only(sub: Subspace, primitive: Primitive) -> set:
    """The subspace's coordinates and velocities that are not the primitive's: an effect
    naming one is applied in the subspace (``Effect.direct_force``)."""
    own = set(primitive.coordinates) | set(primitive.velocities)
    return {s for q in sub.coords for s in (q, velocity_symbol(q)) if s not in own}


def _projected(sub: Subspace, f) -> sympy.Matrix:
    fbar = sub.transpose_times([sub.image(fa) if fa != 0 else TrigPoly() for fa in f])
    return canonical.matrix(sub.n, 1, [compact(sub.algebra, p) for p in fbar])


def _sum(polys) -> TrigPoly:
    total = TrigPoly()
    for p in polys:
        total.add(p)
    return total


__all__ = ["SHARED_FROM", "Subspace", "assemble", "assembled_potentials", "effect_labels", "project_effects", "project_inertia",
           "world_dimension"]
