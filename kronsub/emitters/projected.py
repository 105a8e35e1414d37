"""The projection kept in the generated code: ``Mbar``, ``hbar`` and ``fbar`` formed at run time.

The transition to the subspace is carried out numerically at every evaluation,

    Mbar = C^T M C                          (9'), (D)
    hbar = C^T (M Cdot xbardot + h)         (E)
    fbar = C^T f                            (8'), (F)

from the primitive's metric ``M``, velocity terms ``h`` and forces ``f`` (blocks of a few
entries, one per component) and the transformation ``C = dx/dxbar`` (7'), (21), all written as
short expressions: the distinct entries of ``C`` (``cv``) and their rates ``d C/dt`` (``dv``),
the nonzero entries of ``M`` (``Mp``), ``h`` and ``f`` (``hp``, ``fp``), the primitive
velocities written as ``C xbardot``. The structure of ``C`` is kept in the generated code:

* each entry of ``C`` is a number times a constant of the parameters times a base of the
  coordinates (``l1*cos(q1)/2``: ``1/2``, ``l1``, ``cos(q1)``), so
  ``Mbar_jk = sum_ab C_aj M_ab C_bk`` is a sum over pairs of bases, each with a weight computed
  once per parameter set (``prepare``) where ``M``'s entries are constants; pairs under one weight
  share it (a chain's ``cos q_j cos q_k + sin q_j sin q_k``, and ``cos^2 + sin^2`` is 1);
* the rows of ``C`` below a joint share its entries, so ``Cdot xbardot`` row by row and
  ``C^T w`` column by column are sums over trees of their shared parts (one addition per link
  of a chain, not one per entry).

The canonical form's ``dT/dxbar = Cdot^T M xdot + C^T dT/dx`` (Lagrange's (A) through the
connection; ``Cdot^a_alpha = d xdot^a / d xbar^alpha``) takes ``dT/dx`` of the primitive
(``tp``) over ``C``'s sparse pattern. The expanded equations grow with the cube of a chain's
length and so do ``cse`` and the compiler's times; these expressions grow with the number of
entries of ``Mbar``.
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

PROJECTED_FROM = 10
"""Coordinates from which ``auto`` takes the projected route (benchmarks/README.md,
``first_trajectory.py`` and ``simulate.py --routes``): emitted and compiled in half the time of
the expanded equations there, within a tenth of their time per call, and the quicker from about
18; below it the expanded equations are emitted and compiled within a second."""

PART = 200
"""Entries of ``Mbar`` in each generated function that forms it: the compiler's time grows
faster than a function's length."""


@dataclass(frozen=True)
class ProjectedCode:
    """The run-time projection's expressions and the sparse patterns of ``C`` and ``M``.

    ``c_rows[a]``: the nonzero entries of row ``a`` of ``C`` as (column, index into ``cv``);
    ``m_rows[a]``: the nonzero entries of row ``a`` of ``M`` as (column, index into ``Mp``).
    Each distinct entry of ``C`` is a constant (of the parameters) times a base (of the
    coordinates), ``cv_u = k_u b_u``; the bases follow the entries in ``cv`` (from ``n_entries``).
    ``metric[t]`` is ``Mbar``'s entry ``t`` of the upper triangle (``j <= k``, row by row) as its
    groups ``(g, products)``, ``pre[weights_from + g]`` times the sum of the products (each the
    indices into ``cv`` of the bases it multiplies, none for 1), and its ``terms`` ``(u, v, w)``,
    ``cv_u cv_v Mw_w`` where ``M``'s entries depend on ``x``.
    Group ``g``'s weight ``sum c pre[k] pre[k'] pre[w]`` over ``weights[g]`` is computed once
    per parameter set (``prepare``). ``row_nodes``/``row_node``: the rows' sums ``sum_s v_s qd``
    over a tree of their shared parts (node ``i`` = node ``parent`` + value times ``qd[column]``);
    ``column_nodes``/``column_sums``: ``C^T w`` as sums of ``w`` over sets of rows in a tree, each
    set taken by a (column, value) of ``C``."""

    n_primitive: int
    n_subspace: int
    n_entries: int
    n_values: int  # entries and bases
    n_metric: int
    n_weights: int
    weights_from: int
    c_rows: tuple[tuple[tuple[int, int], ...], ...]
    m_rows: tuple[tuple[tuple[int, int], ...], ...]
    metric: tuple[tuple[tuple[tuple[int, tuple[tuple[int, ...], ...]], ...], tuple[tuple[int, int, int], ...]], ...]
    weights: tuple[tuple[tuple[float, int, int, int], ...], ...]
    row_nodes: tuple[tuple[int, int, int], ...]  # (parent, value, column); node 0 the empty sum
    row_node: tuple[int, ...]
    column_nodes: tuple[tuple[int, int], ...]  # (parent, row); node 0 the empty sum
    column_sums: tuple[tuple[int, int, int], ...]  # (column, value, node)
    block: Block  # cv (entries, then bases), dv, Mp, Mw, hp, fp
    kinetic: Block  # tp = dT/dx of the primitive (its entries not zero)

    @property
    def entries(self):
        """``Mbar``'s upper triangle: (its index, its mirror's, its groups, its terms) in the flat ``Mbar``."""
        n = self.n_subspace
        upper = [(j, k) for j in range(n) for k in range(j, n)]
        return [(j * n + k, k * n + j, *parts) for (j, k), parts in zip(upper, self.metric)]

    @property
    def parts(self):
        """:attr:`entries` in parts of :data:`PART`, each a function of the generated C."""
        entries = self.entries
        return [entries[i:i + PART] for i in range(0, len(entries), PART)]

    @property
    def row_sums(self):
        """The rows' tree: (node, its parent, value, column) from node 1 on."""
        return [(i, *node) for i, node in enumerate(self.row_nodes) if i]

    @property
    def inertia(self):
        """``(M Cdot xbardot)_a``: (row ``a``, its terms (index into ``Mp``, node of the rows' tree))."""
        return [(a, [(e, self.row_node[b]) for b, e in row]) for a, row in enumerate(self.m_rows)]

    @property
    def set_sums(self):
        """The tree of the sets of rows: (node, its parent, row) from node 1 on."""
        return [(i, *node) for i, node in enumerate(self.column_nodes) if i]

    @property
    def columns(self):
        """``C^T w``: (column ``j``, its terms (index into ``cv``, node of the sets' tree))."""
        by_column: list[list[tuple[int, int]]] = [[] for _ in range(self.n_subspace)]
        for column, value, node in self.column_sums:
            by_column[column].append((value, node))
        return list(enumerate(by_column))

    @property
    def tables(self) -> dict[str, list]:
        """The patterns as the flat arrays of the generated code (rows by their starts)."""
        out: dict[str, list] = {}
        for name, rows, parts in (("c", self.c_rows, ("column", "value")), ("m", self.m_rows, ("column", "entry"))):
            out[f"{name}_start"] = _starts(rows)
            out[f"{name}_{parts[0]}"] = [e[0] for row in rows for e in row]
            out[f"{name}_{parts[1]}"] = [e[1] for row in rows for e in row]
        out["w_start"] = _starts(self.weights)
        for index, name in enumerate(("coefficient", "first", "second", "entry")):
            out[f"w_{name}"] = [c[index] for g in self.weights for c in g]
        return {k: v or [0] for k, v in out.items()}  # C99 has no empty arrays


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
    params = {p.symbol for p in system.parameters}
    # cv_u = c_u K_u b_u: a number, a constant of the parameters (in pre) and the base
    bases: dict[sympy.Expr, int] = {}
    factors = []
    for e in distinct:
        c, K, base = _split(e, params)
        factors.append((c, constants.index(slot(K)), bases.setdefault(base, len(bases))))
    n_entries = len(distinct)
    weights: dict[sympy.Expr, int] = {}  # the sums of M's entries that depend on x, in Mw
    summed: dict[tuple[int, ...], sympy.Expr] = {}  # the same entries met by many pairs: summed once
    groups: dict[tuple, int] = {}  # a group's weight, by its parts (c, k, k', w): one slot each
    metric = []
    for j in range(n):
        for k in range(j, n):
            by_bases: dict[tuple[int, int], list[tuple]] = {}
            terms = []
            for (u, v), es in pairs.get((j, k), {}).items():
                met = tuple(sorted(es))
                w = summed.get(met)
                if w is None:
                    w = summed[met] = sympy.Add(*[m_exprs[e] for e in met])
                if w == 0:
                    continue
                if not w.free_symbols <= params:
                    terms.append((u, v, weights.setdefault(w, len(weights))))
                    continue
                (cu, ku, bu), (cw, kw, bw) = factors[u], factors[v]
                key = (min(bu, bw), max(bu, bw))
                by_bases.setdefault(key, []).append((float(cu * cw), min(ku, kw), max(ku, kw),
                                                     constants.index(slot(w))))
            by_products: dict[tuple, list[tuple]] = {}  # the groups of equal products: their weights summed
            for products, parts in _shared_weights(by_bases, list(bases)):
                by_products.setdefault(tuple(tuple(n_entries + b for b in p) for p in products), []).extend(parts)
            metric.append((tuple((groups.setdefault(tuple(sorted(parts)), len(groups)), products)
                                 for products, parts in by_products.items()), tuple(terms)))
    weights_from = constants.reserve(len(groups))
    moving = {u for u, rate in enumerate(rates) if rate != 0}  # Cdot xbardot: the entries that change
    row_nodes, row_node = _row_tree([tuple(e for e in row if e[1] in moving) for row in c_rows])
    column_nodes, column_sums = _column_tree(c_rows, n)

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

    shared_targets = [f"cv[{u}]" for u in range(n_entries + len(bases))] \
        + [f"dv[{u}]" for u in range(n_entries)] + [f"Mp[{k}]" for k in range(len(m_exprs))] \
        + [f"Mw[{w}]" for w in range(len(weights))]
    shared = [constants(slot(e)) for e in [*distinct, *bases]] + [constants(slot(e)) for e in rates] \
        + [image(e) for e in m_exprs] + [image(e) for e in weights]

    def vector(name: str, column) -> tuple[list[str], list[sympy.Expr]]:
        pairs = [(f"{name}[{a}]", e) for a, e in enumerate(column) if e != 0]
        return [t for t, _ in pairs], [image(e) for _, e in pairs]

    h_targets, h_exprs = vector("hp", h)
    f_targets, f_exprs = vector("fp", f)
    t_targets, t_exprs = vector("tp", dT)
    return ProjectedCode(
        n_primitive=nx,
        n_subspace=n,
        n_entries=n_entries,
        n_values=n_entries + len(bases),
        n_metric=len(m_exprs),
        n_weights=len(weights),
        weights_from=weights_from,
        c_rows=tuple(c_rows),
        m_rows=tuple(m_rows),
        metric=tuple(metric),
        weights=tuple(sorted(groups, key=groups.__getitem__)),
        row_nodes=row_nodes,
        row_node=row_node,
        column_nodes=column_nodes,
        column_sums=column_sums,
        block=block(shared_targets + h_targets + f_targets, shared + h_exprs + f_exprs),
        kinetic=block(t_targets, t_exprs),
    )


def _split(e: sympy.Expr, params: set) -> tuple[sympy.Number, sympy.Expr, sympy.Expr]:
    """``e = c K b``: a number ``c``, a product of parameters ``K`` and the rest ``b`` (1 where
    ``e`` is constant), so that equal bases of entries that differ by a constant are shared."""
    factors = sympy.Mul.make_args(e)
    constant = [f for f in factors if f.free_symbols <= params]
    base = sympy.Mul(*[f for f in factors if not f.free_symbols <= params])
    c, K = sympy.Mul(*constant).as_coeff_Mul()
    return c, K, base


def _shared_weights(by_bases: dict, bases: list) -> list[tuple[tuple[tuple[int, ...], ...], list]]:
    """The pairs of bases of an entry of ``Mbar`` grouped by their weight (its parts), each group
    ``(products, parts)``: a product the bases it multiplies, the base 1 left out, and
    ``cos(a)^2 + sin(a)^2`` under one weight counted as 1."""
    shared: dict[tuple, list[tuple[int, int]]] = {}
    for key, parts in by_bases.items():
        shared.setdefault(tuple(sorted(parts)), []).append(key)
    out = []
    for parts, pairs in shared.items():
        squares = {b for b, c in pairs if b == c}
        for b in sorted(squares):
            if isinstance(bases[b], sympy.cos) and b in squares:
                partner = next((c for c in sorted(squares) if bases[c] == sympy.sin(bases[b].args[0])), None)
                if partner is not None:
                    pairs = [p for p in pairs if p not in ((b, b), (partner, partner))] + [(-1, -1)]
                    squares -= {b, partner}
        products = tuple(sorted(tuple(i for i in pair if i >= 0 and bases[i] != 1) for pair in pairs))
        out.append((products, list(parts)))
    return out


def _row_tree(c_rows) -> tuple[tuple[tuple[int, int, int], ...], tuple[int, ...]]:
    """The rows' sums ``sum_s value_s qd_column_s`` as paths from a root: each row's entries
    ordered by how many rows share them (then by column), so rows sharing entries share the
    partial sums of the path to them (a chain's rows below a joint: one addition each)."""
    shared: dict[tuple[int, int], int] = {}
    for row in c_rows:
        for entry in row:
            shared[entry] = shared.get(entry, 0) + 1
    nodes, children, ends = [(0, 0, 0)], {}, []
    for row in c_rows:
        node = 0
        for column, value in sorted(row, key=lambda e: (-shared[e], e)):
            child = children.get((node, column, value))
            if child is None:
                child = children[node, column, value] = len(nodes)
                nodes.append((node, value, column))
            node = child
        ends.append(node)
    return tuple(nodes), tuple(ends)


def _column_tree(c_rows, n: int) -> tuple[tuple[tuple[int, int], ...], tuple[tuple[int, int, int], ...]]:
    """``C^T w`` (8'): ``(C^T w)_j = sum_u cv_u (sum of w_a over the rows a where C_aj = cv_u)``,
    the sums over the sets of rows as paths from a root, the rows in the order of how many
    sets hold them (a chain's links below a joint: one addition per set)."""
    sets: dict[tuple[int, int], list[int]] = {}
    for a, row in enumerate(c_rows):
        for column, value in row:
            sets.setdefault((column, value), []).append(a)
    held = [len(row) for row in c_rows]
    nodes, children, sums = [(0, 0)], {}, []
    for (column, value) in sorted(sets):
        node = 0
        for a in sorted(sets[column, value], key=lambda a: (-held[a], a)):
            child = children.get((node, a))
            if child is None:
                child = children[node, a] = len(nodes)
                nodes.append((node, a))
            node = child
        sums.append((column, value, node))
    return tuple(nodes), tuple(sums)


__all__ = ["PROJECTED_FROM", "ROUTES", "ProjectedCode", "applies", "projected_by_size", "projected_code"]
