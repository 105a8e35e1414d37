"""The projection kept in the generated code: ``Mbar``, ``hbar`` and ``fbar`` formed at run time.

The transition to the subspace is carried out numerically at every evaluation,

    Mbar = C^T M C                          (9'), (D)
    hbar = C^T (M Cdot xbardot + h)         (E)
    fbar = C^T f                            (8'), (F)

from the primitive's metric ``M``, velocity terms ``h`` and forces ``f`` (blocks of a few
entries, one per component) and the transformation ``C = dx/dxbar`` (7'), (21), all written as
short expressions: the distinct entries of ``C`` (``cv``) and their rates ``d C/dt`` (``dv``,
so ``Cdot xbardot`` and ``Cdot`` are sums over the same pattern), the nonzero entries of ``M``
(``Mp``), ``h`` and ``f`` (``hp``, ``fp``), the primitive velocities written as ``C xbardot``.
``Mbar_jk = sum_ab C_aj M_ab C_bk`` is summed over the distinct pairs of values
``(C_aj, C_bk) = (cv_u, cv_v)``, each with the sum of the ``M_ab`` it meets (``Mw``: for
constant inertias a constant, which ``prepare`` computes once), so rows of ``C`` equal within
a column (the links below a joint) are multiplied once.
The canonical form's ``dT/dxbar = Cdot^T M xdot + C^T dT/dx`` (Lagrange's (A) through the
connection; ``Cdot^a_alpha = d xdot^a / d xbar^alpha``) takes ``dT/dx`` of the primitive
(``tp``). The sparse patterns of ``C`` and ``M`` become tables the generated loops walk.

The expanded equations grow with the cube of a chain's length and so do ``cse`` and the
compiler's times; these expressions grow with the number of nonzero entries of ``C``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import sympy

from ..core.derivative import derivative
from ..core.known_system import KnownSystem
from ..core.first_order import zero_rows
from ..core.rheonomic import depends_on_time
from ..core.symbols import velocity_symbol
from .block import Block

ROUTES = ("auto", "expanded", "projected")
"""How the C's ``Mbar``, ``hbar`` and ``fbar`` are computed: ``expanded`` (the derived
expressions), ``projected`` (this module), ``auto`` (by :func:`projected_by_size`)."""

PROJECTED_FROM = 12
"""Coordinates from which ``auto`` takes the projected route (benchmarks/README.md,
``first_trajectory.py``): below it the expanded right-hand side is quicker per call."""


@dataclass(frozen=True)
class ProjectedCode:
    """The run-time projection's expressions and the sparse patterns of ``C`` and ``M``.

    ``c_rows[a]``: the nonzero entries of row ``a`` of ``C`` as (column, index into ``cv``);
    ``m_rows[a]``: the nonzero entries of row ``a`` of ``M`` as (column, index into ``Mp``);
    ``terms``: ``Mbar``'s upper triangle as (index ``j n + k``, ``u``, ``v``, index into ``Mw``),
    ``Mbar_jk`` the sum of ``cv_u cv_v Mw_w`` over its terms."""

    n_primitive: int
    n_values: int
    n_metric: int
    n_weights: int
    c_rows: tuple[tuple[tuple[int, int], ...], ...]
    m_rows: tuple[tuple[tuple[int, int], ...], ...]
    terms: tuple[tuple[int, int, int, int], ...]
    block: Block  # cv, dv, Mp, Mw, hp, fp
    kinetic: Block  # tp = dT/dx of the primitive (its entries not zero)

    @property
    def tables(self) -> dict[str, list[int]]:
        """The patterns as the flat arrays of the generated C (rows by their starts)."""
        out: dict[str, list[int]] = {}
        for name, rows, parts in (("c", self.c_rows, ("column", "value")), ("m", self.m_rows, ("column", "entry"))):
            out[f"{name}_start"] = _starts(rows)
            out[f"{name}_{parts[0]}"] = [e[0] for row in rows for e in row]
            out[f"{name}_{parts[1]}"] = [e[1] for row in rows for e in row]
        for index, name in enumerate(("target", "u", "v", "weight")):
            out[f"t_{name}"] = [t[index] for t in self.terms]
        return out


def _starts(rows) -> list[int]:
    starts = [0]
    for row in rows:
        starts.append(starts[-1] + len(row))
    return starts


def applies(system: KnownSystem) -> bool:
    """Whether the projection can be kept at run time: a transition from a primitive, no
    closed loop, no prescribed motion, no velocity constraints, no first-order coordinates, every
    effect acting on the primitive."""
    tr = system.transition
    return (tr is not None and system.implicit is None and system.speeds is None and not tr.direct_effects
            and set(tr.primitive_forces) == set(system.effect_forces) and len(tr.primitive_coordinates) > 0
            and not depends_on_time(dict(tr.connection)) and not zero_rows(system))


def projected_by_size(system: KnownSystem) -> bool:
    """``auto``'s choice: the projected route from :data:`PROJECTED_FROM` coordinates on."""
    return len(system.coordinates) >= PROJECTED_FROM and applies(system)


def projected_code(system: KnownSystem, slot: Callable, constants: Callable,
                   block: Callable[[list[str], list[sympy.Expr]], Block], kinetic: bool = True) -> ProjectedCode:
    """The run-time projection of ``system`` (:func:`applies`): ``slot`` maps an expression in
    the subspace to the array slots, ``constants`` moves parameter products to ``pre``,
    ``block`` eliminates common subexpressions; ``kinetic``: also ``dT/dx`` (the canonical form)."""
    tr = system.transition
    xs = tr.primitive_coordinates
    nx, n = len(xs), len(system.coordinates)
    C, M = tr.transformation, tr.primitive_metric
    images = dict(tr.connection)
    qd = list(system.velocities)

    speeds = dict(zip(system.coordinates, qd))
    values: dict[sympy.Expr, int] = {}
    c_rows = []
    for entries_a in C.tolist():
        row = []
        for j, e in enumerate(entries_a):
            if e != 0:
                row.append((j, values.setdefault(e, len(values))))
        c_rows.append(tuple(row))
    distinct = list(values)
    rates = [sympy.Add(*[derivative(e, q) * speeds[q] for q in system.coordinates if q in free])
             for e in distinct for free in [e.free_symbols]]

    # x -> x(xbar), xdot -> C xbardot: the primitive's expressions in the subspace
    moved = {x: images[x] for x in xs if images[x] != x}
    for a, x in enumerate(xs):
        v = sympy.Add(*[distinct[u] * qd[j] for j, u in c_rows[a]])
        if v != velocity_symbol(x):
            moved[velocity_symbol(x)] = v

    def image(e: sympy.Expr) -> sympy.Expr:
        return constants(slot(e.xreplace(moved) if moved else e))

    entries: dict[tuple[int, int], int] = {}
    m_exprs = []
    m_rows = []
    for a, metric_a in enumerate(M.tolist()):
        row = []
        for b, e in enumerate(metric_a):
            if e == 0:
                continue
            key = (min(a, b), max(a, b))
            if key not in entries:
                entries[key] = len(m_exprs)
                m_exprs.append(e)
            row.append((b, entries[key]))
        m_rows.append(tuple(row))
    # Mbar_jk = sum over the pairs (cv_u, cv_v) met of cv_u cv_v (sum of the M_ab met with them)
    pairs: dict[tuple[int, int], dict[tuple[int, int], list[int]]] = {}
    for a in range(nx):
        for j, u in c_rows[a]:
            for b, e in m_rows[a]:
                for k, v in c_rows[b]:
                    if k >= j:
                        key = (u, v) if k > j or u <= v else (v, u)
                        pairs.setdefault((j, k), {}).setdefault(key, []).append(e)
    weights: dict[sympy.Expr, int] = {}
    summed: dict[tuple[int, ...], sympy.Expr] = {}  # the same entries met by many pairs: summed once
    terms = []
    for (j, k) in sorted(pairs):
        for (u, v), es in pairs[j, k].items():
            met = tuple(sorted(es))
            w = summed.get(met)
            if w is None:
                w = summed[met] = sympy.Add(*[m_exprs[e] for e in met])
            if w != 0:
                terms.append((j * n + k, u, v, weights.setdefault(w, len(weights))))

    xd = [velocity_symbol(x) for x in xs]
    h = tr.primitive_velocity_terms
    f = sympy.zeros(nx, 1)
    for label in sorted(tr.primitive_forces):
        f += tr.primitive_forces[label]
    dT = [sympy.Integer(0)] * nx  # dT/dx = 1/2 xdot^T (dM/dx) xdot
    index = {x: a for a, x in enumerate(xs)}
    for (b, c), k in entries.items() if kinetic else ():
        for x in m_exprs[k].free_symbols:
            if x in index:
                dT[index[x]] += derivative(m_exprs[k], x) * xd[b] * xd[c] * (1 if b == c else 2) / 2

    shared_targets = [f"cv[{u}]" for u in range(len(distinct))] + [f"dv[{u}]" for u in range(len(distinct))] \
        + [f"Mp[{k}]" for k in range(len(m_exprs))] + [f"Mw[{w}]" for w in range(len(weights))]
    shared = [constants(slot(e)) for e in distinct] + [constants(slot(e)) for e in rates] \
        + [image(e) for e in m_exprs] + [image(e) for e in weights]

    def vector(name: str, column) -> tuple[list[str], list[sympy.Expr]]:
        pairs = [(f"{name}[{a}]", e) for a, e in enumerate(column) if e != 0]
        return [t for t, _ in pairs], [image(e) for _, e in pairs]

    h_targets, h_exprs = vector("hp", h)
    f_targets, f_exprs = vector("fp", f)
    t_targets, t_exprs = vector("tp", dT)
    return ProjectedCode(
        n_primitive=nx,
        n_values=len(distinct),
        n_metric=len(m_exprs),
        n_weights=len(weights),
        c_rows=tuple(c_rows),
        m_rows=tuple(m_rows),
        terms=tuple(terms),
        block=block(shared_targets + h_targets + f_targets, shared + h_exprs + f_exprs),
        kinetic=block(t_targets, t_exprs),
    )


__all__ = ["PROJECTED_FROM", "ROUTES", "ProjectedCode", "applies", "projected_by_size", "projected_code"]
