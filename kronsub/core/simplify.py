"""Choosing the printed form of an entry: the compact closed forms of the paper.

The trigonometric-polynomial form is already compact for sums of angles
(``2 a1 a2 m2 cos(theta - phi)`` in (22)). Where it holds multiple angles, a
power form may be shorter: ``l^2 m (1 - cos 2 alpha)`` is ``2 l^2 m sin(alpha)^2``.
:func:`compact` offers, angle by angle, the polynomial in ``sin`` and ``cos`` of
the single angle (``cos 2b = 1 - 2 sin(b)^2`` or ``2 cos(b)^2 - 1``, chosen by
counting operations), collapses ``sin(a)^2 + cos(a)^2`` among the other factors
(an incline's angle ``alpha``), re-expresses the insides of those factors
through the same algebra (``sqrt(r^2 sin(a)^2 + r^2 cos(a)^2)`` is ``sqrt(r^2)``),
writes sums and differences of angles as products where that is shorter (a top's
``cos(2 phi - 2 theta)``), and collects terms over factors that vary with the
coordinates (System II's ``1/sqrt(1 - u^2)``, as in the paper's (29)).
The rules are arithmetic on the algebra's terms; of sympy only ``factor_terms`` and,
for entries up to `FACTORED` operations, ``factor`` are called, never ``trigsimp``
or ``fu``. An entry with none of the above (every entry of a chain) keeps the
algebra's own form at no cost.
"""
from __future__ import annotations

import math
import weakref
from fractions import Fraction

import sympy

from ..budget import PER_OPERATION, charge
from .inverse_trig import divide_out
from .operations import count_ops
from .printed import LexStrPrinter
from .seeded import seeded, sympy_seeded
from .sympy_internals import keep_coeff
from . import trigpoly
from .trigpoly import TrigAlgebra, TrigPoly, coef_add_into, common_monomial

COS, SIN = 0, 1
SMALL = 40
"""Operations up to which ``factor_terms`` of a candidate is also tried."""
FACTORED = 60
"""Operations up to which the polynomial factorization of the chosen form is tried (an entry
of multiple angles or varying factors only: ``(a1 sin(theta) - c)^2`` in System II)."""


MULTIPLE = 16
"""Highest multiple ``k`` of an angle whose ``sin(k b)``, ``cos(k b)`` are offered as polynomials in
``sin b`` and ``cos b`` (the power form has some ``k/2`` terms, never shorter beyond it, and its
reduction grows as ``2^(k/2)``): a higher one keeps its multiple-angle form."""


VARIANTS = 8
"""Most variants of a coefficient weighed for ``sin(a)^2 + cos(a)^2`` (two per pair of atoms
``sin(a)``, ``cos(a)`` squared in it): the pairs beyond the first three keep their squares."""


ATOM_SYMBOLS = 24
"""Free symbols up to which an entry with trigonometric atoms is offered to ``trigsimp``
(whose ``factor`` grows steeply with them)."""


def compact(algebra: TrigAlgebra, p: TrigPoly) -> sympy.Expr:
    """The shortest of a few equivalent forms of ``p`` (deterministic).

    Shortest by ``sympy.count_ops``, ties broken by the printed length, so that
    ``2*l**2*m*sin(alpha)**2`` wins over ``l**2*m*(1 - cos(2*alpha))``.
    """
    if not p.terms:
        return sympy.S.Zero
    memo = algebra.__dict__.setdefault("_compacted", {})  # per derivation: each distinct entry once
    key = p.key()
    if key not in memo:
        memo[key] = _compact(algebra, p)
    return memo[key]


def _compact(algebra: TrigAlgebra, p: TrigPoly) -> sympy.Expr:
    view = _view(algebra)
    if algebra.has_shared(p):  # the sums written out where the entry has no other form (a chain's)
        used = trigpoly.used_atoms(p)
        shared = used & algebra.shared_sums.keys()
        used -= shared
        if not algebra.has_multiple_angles(p) and not _mixed(p) and not view.touches(used) \
                and not view.varying_in(used) and all(view.plain_sum(s) for s in shared) \
                and (expr := algebra.written_out(p)) is not None:
            return _atom_angles(algebra, used, expr)
        p = algebra.flat(p)
    p = divide_out(algebra, p)
    expr = algebra.to_expr(p)
    multiple = algebra.has_multiple_angles(p)
    used = trigpoly.used_atoms(p)
    if not multiple and not _mixed(p) and not view.touches(used) and not view.varying_in(used):
        return _atom_angles(algebra, used, expr)
    best, best_key = expr, _key(expr)

    def offer(candidate: sympy.Expr) -> None:
        nonlocal best, best_key
        key = _key(candidate)
        if key < best_key:
            best, best_key = candidate, key

    groups, rest = _angle_groups(p) if multiple else ({}, dict(p.terms))
    chosen: dict = {}  # base -> (variant, terms kept as multiple angles)

    seen: dict = {}

    def measure(trial) -> _Key:
        charge(len(p.terms), "the trial forms of an entry")
        rendered = view.render(groups, trial, rest)
        if rendered not in seen:
            seen[rendered] = _key(_factored(rendered))
        return seen[rendered]

    for base in sorted(groups):
        best_here = (measure(chosen), None)
        multiples = [t for t in sorted(groups[base]) if t[1] >= 2]
        for variant in (SIN, COS):
            for start in (frozenset(), frozenset(multiples)):
                kept = start
                key = measure({**chosen, base: (variant, kept)})
                for term in multiples:  # greedily flip one term at a time
                    flipped = kept ^ {term}
                    k = measure({**chosen, base: (variant, flipped)})
                    if k < key:
                        key, kept = k, flipped
                if key < best_here[0]:
                    best_here = (key, (variant, kept))
        if best_here[1] is not None:
            chosen[base] = best_here[1]
    offer(_factored(view.render(groups, chosen, rest)))
    if _mixed(p):
        offer(_products(view, p))
    collected = _collected(view, p)
    if collected is not None:
        offer(collected)
    offer(_factor_terms(best))
    if groups and best_key.ops <= FACTORED:
        for variant in (SIN, COS):  # all powers: a polynomial in sin and cos to factor
            powers = view.render(groups, {b: (variant, frozenset()) for b in groups}, rest)
            if count_ops(powers) <= 2 * FACTORED:
                offer(_factor(powers))
    return _atom_angles(algebra, used, best)


def _atom_angles(algebra: TrigAlgebra, used: set[int], best: sympy.Expr) -> sympy.Expr:
    """Sines and cosines the algebra holds as atoms (of an argument not a rational
    combination of coordinates, a gear's ``alpha/n``) miss the product-to-sum identities
    as products are formed; a small entry with them is also offered to ``trigsimp``."""
    coordinates = set(algebra.coordinates)
    held = [a for a in (algebra.atom_expr(i) for i in sorted(used))
            if isinstance(a, (sympy.sin, sympy.cos)) and a.args[0].free_symbols & coordinates]
    if not held or count_ops(best) > FACTORED or len(best.free_symbols) > ATOM_SYMBOLS:
        return best  # sin(t), cos(pi/7): no identity of a coordinate; many symbols: factor's cost
    with sympy_seeded():
        candidate = sympy.trigsimp(best)
    return candidate if _key(candidate) < _key(best) else best


def _mixed(p: TrigPoly) -> bool:
    """Whether the angle-sum formulas may shorten ``p``: a multiple angle over several
    coordinates (``cos(2 phi - 2 theta)``), or a sum and a difference of the same
    coordinates (``sin(phi - theta) + sin(phi + theta)``). A chain's ``cos(q1 - q2)``
    terms are neither, so its entries skip the search."""
    supports: dict = {}
    for _, freq in p.terms:
        if len(freq) > 1:
            if any(abs(v) != 1 for _, v in freq):
                return True
            support = tuple(i for i, _ in freq)
            signs = tuple(v for _, v in freq)
            if supports.setdefault(support, signs) != signs:
                return True
    return False


@seeded
def _factor(expr: sympy.Expr) -> sympy.Expr:
    """``sympy.factor``, with ``(sin(a) - 1)(sin(a) + 1)`` read back as ``-cos(a)^2``."""
    out = sympy.factor(expr)
    for t in sorted(out.atoms(sympy.sin, sympy.cos), key=sympy.default_sort_key):
        other = (sympy.cos if isinstance(t, sympy.sin) else sympy.sin)(t.args[0])
        if out.has(t - 1) and out.has(t + 1):
            out = out.subs((t - 1) * (t + 1), -other**2)
    return out


def _factored(expr: sympy.Expr) -> sympy.Expr:
    """``expr`` or, for a small one, its common factors pulled out if that is shorter."""
    if _joins_exceed(expr, SMALL) or count_ops(expr) > SMALL:
        return expr
    factored = _factor_terms(expr)
    if factored == expr:  # nothing common: the keys are equal, and ``min`` keeps the first
        return expr
    return min((expr, factored), key=_key)


def _joins_exceed(expr: sympy.Expr, limit: int) -> bool:
    """Whether the terms of the sums in ``expr`` (``k - 1`` joins for ``k`` terms, a lower
    bound of ``count_ops``) exceed ``limit``: a large entry is told in a walk that stops early,
    without counting every operation of it."""
    joins, stack = 0, [expr]
    while stack:
        node = stack.pop()
        if node.is_Add:
            joins += len(node.args) - 1
            if joins > limit:
                return True
        stack.extend(node.args)
    return False


TIE_OPS = 200
"""Above this many operations a tie in `count_ops` is left unbroken (the first form offered
stays): printing a large entry to measure it costs seconds, and no reader weighs its length."""


class _Key:
    """``(count_ops, printed length)``, the length computed only to break a tie between
    entries of at most `TIE_OPS` operations."""

    __slots__ = ("expr", "ops", "_length")

    def __init__(self, expr: sympy.Expr):
        self.expr, self.ops, self._length = expr, count_ops(expr), None

    def length(self) -> int:
        if self._length is None:
            self._length = _printed_length(self.expr)
        return self._length

    def __lt__(self, other: "_Key") -> bool:
        if self.ops != other.ops:
            return self.ops < other.ops
        return self.ops <= TIE_OPS and self.length() < other.length()

    def __getitem__(self, i: int) -> int:
        return (self.ops, self.length())[i]


def _key(expr: sympy.Expr) -> _Key:
    return _Key(expr)


_PRINTER = [LexStrPrinter()]
REMEMBERED = 100_000
"""Printed subexpressions, and ``factor_terms`` results, remembered at most between entries
(candidate forms share most of them)."""


_FACTORED_TERMS: dict = {}


def _factor_terms(expr: sympy.Expr) -> sympy.Expr:
    """``sympy.factor_terms(expr)``, remembered: an entry's candidates repeat between entries."""
    if len(_FACTORED_TERMS) > REMEMBERED:
        _FACTORED_TERMS.clear()
    hit = _FACTORED_TERMS.get((type(expr), expr))
    if hit is None:
        charge(PER_OPERATION["factor"] * count_ops(expr), "the printed forms of an entry")
        hit = _FACTORED_TERMS[(type(expr), expr)] = _factor_terms_of(expr)
    return hit


_FACTORED_PARTS: dict = {}


def _factor_terms_of(expr: sympy.Expr) -> sympy.Expr:
    """``sympy.factor_terms(expr)``, a product's factors each remembered: ``factor_terms`` of a
    product is its content before the product of its primitive factors' ``factor_terms``, and
    a large system's entries share those factors (a row's sum of masses in a chain's ``Mbar``)."""
    if not (isinstance(expr, sympy.Mul) and expr.is_commutative):
        return sympy.factor_terms(expr)
    if len(_FACTORED_PARTS) > REMEMBERED:
        _FACTORED_PARTS.clear()
        _CONTENTS.clear()
    content, parts = sympy.S.One, []  # expr.as_content_primitive(clear=False), factor by factor
    for factor in expr.args:
        c, p = _content_primitive(factor)
        content *= c
        if p is not sympy.S.One:
            parts.append(p)
    primitive = sympy.Mul(*parts)
    if not isinstance(primitive, sympy.Mul):
        return sympy.factor_terms(expr)
    return keep_coeff(content, primitive.func(*[_factor_terms_part(f) for f in primitive.args]), clear=False,
                      sign=True)


_CONTENTS: dict = {}


def _content_primitive(factor: sympy.Expr) -> tuple:
    """``factor.as_content_primitive(clear=False)``, remembered (a product's is its factors')."""
    key = (type(factor), factor)
    done = _CONTENTS.get(key)
    if done is None:
        done = _CONTENTS[key] = factor.as_content_primitive(clear=False)
    return done


def _factor_terms_part(expr: sympy.Expr) -> sympy.Expr:
    """``sympy.factor_terms`` of a factor, remembered; a function's (or power's) arguments
    each in turn, as ``factor_terms`` treats them; a difference of coordinates such as
    ``q1 - q2`` (distinct symbols, coefficients 1 and -1, one at least 1) has nothing to
    pull out and is its own."""
    if expr.is_Atom:
        return expr
    if expr.is_Add and all(t.is_Symbol or (t.is_Mul and len(t.args) == 2 and t.args[0] is sympy.S.NegativeOne
                                            and t.args[1].is_Symbol) for t in expr.args) \
            and any(t.is_Symbol for t in expr.args):
        return expr
    key = (type(expr), expr)
    done = _FACTORED_PARTS.get(key)
    if done is None:
        if expr.is_Pow or expr.is_Function:
            args = tuple(_factor_terms_part(a) for a in expr.args)
            done = expr if args == expr.args else expr.func(*args)
        else:
            done = sympy.factor_terms(expr)
        _FACTORED_PARTS[key] = done
    return done


def _printed_length(expr: sympy.Expr) -> int:
    """``len(sympy.sstr(expr, order="lex"))``, by one printer that remembers what it printed."""
    if len(_PRINTER[0].__dict__.get("_printed", ())) > REMEMBERED:
        _PRINTER[0] = LexStrPrinter()
    return len(_PRINTER[0].doprint(expr))


# ------------------------------------------------------------------ angle groups
def _angle_groups(p: TrigPoly):
    """Split ``p`` by base angle ``b`` (unit frequencies, e.g. ``phi - theta``): every
    term ``trig(k b)`` with integer ``k`` joins the group of ``b`` when some ``k >= 2`` and
    none exceeds `MULTIPLE`.

    Returns ``({base: {(kind, k): coef}}, rest)``, rest holding the other terms
    (with the constant one, which each group may absorb).
    """
    by_base: dict = {}
    rest: dict = {}
    for (kind, freq), coef in p.terms.items():
        mags = {abs(v) for _, v in freq}
        if len(mags) == 1:
            (k,) = mags
            if _fraction(k).denominator == 1:
                base = tuple((i, 1 if v > 0 else -1) for i, v in freq)
                by_base.setdefault(base, {})[(kind, int(k))] = coef
                continue
        rest[(kind, freq)] = coef
    groups = {}
    for base, terms in by_base.items():
        if any(k >= 2 for _, k in terms) and all(k <= MULTIPLE for _, k in terms):
            groups[base] = terms
        else:
            for (kind, k), coef in terms.items():
                rest[(kind, tuple((i, s * k) for i, s in base))] = coef
    return groups, rest


def _chebyshev(kind: int, k: int) -> dict[tuple[int, int], int]:
    """``cos(k b)`` or ``sin(k b)`` as ``{(i, j): n}``: the sum of ``n s^i c^j``, ``s = sin b``,
    ``c = cos b`` (the real or imaginary part of ``(c + i s)^k``)."""
    out = {}
    for i in range(k + 1):
        if (i % 2 == 1) != (kind == SIN):
            continue
        sign = -1 if (i // 2) % 2 else 1
        out[(i, k - i)] = sign * math.comb(k, i)
    return out


def _reduced(poly: dict[tuple[int, int], int], variant: int) -> dict[tuple[int, int], int]:
    """``c^2 -> 1 - s^2`` (variant SIN) or ``s^2 -> 1 - c^2`` (variant COS), to the end."""
    out: dict[tuple[int, int], int] = {}
    todo = list(poly.items())
    while todo:
        charge(1, "the forms of an entry's multiple angles")
        (i, j), n = todo.pop()
        if variant == SIN and j >= 2:
            todo += [((i, j - 2), n), ((i + 2, j - 2), -n)]
        elif variant == COS and i >= 2:
            todo += [((i - 2, j), n), ((i - 2, j + 2), -n)]
        else:
            out[(i, j)] = out.get((i, j), 0) + n
    return {m: n for m, n in out.items() if n}


def _products(view: "_View", p: TrigPoly) -> sympy.Expr:
    """``p`` as a polynomial in ``sin q``, ``cos q`` of each coordinate (angle-sum formulas),
    ``cos(q)^2`` or ``sin(q)^2`` eliminated coordinate by coordinate, whichever prints
    shorter: ``cos(2 phi - 2 theta)`` terms of a top become products of single angles."""
    poly: dict = {}  # ((i, a, b), ...) -> coef: prod sin(q_i)^a cos(q_i)^b
    for (kind, freq), coef in p.terms.items():
        if any(_fraction(v).denominator != 1 or abs(v) > MULTIPLE for _, v in freq):
            return view.render({}, {}, dict(p.terms))
        expansion = {(): (1, 0)}  # monomial -> (real, imaginary) integer parts
        for i, v in freq:
            k, sign = abs(int(v)), (1 if v > 0 else -1)
            factor = {}
            for a in range(k + 1):
                # (c + i sign s)^k: C(k, a) c^(k - a) (i sign s)^a
                n = math.comb(k, a) * sign**a
                factor[a] = {0: (n, 0), 1: (0, n), 2: (-n, 0), 3: (0, -n)}[a % 4]
            out: dict = {}
            charge(len(expansion) * len(factor), "the forms of an entry's sums of angles")
            for mono, (re, im) in expansion.items():
                for a, (fr, fi) in factor.items():
                    key = mono + ((i, a, k - a),)
                    r0, i0 = out.get(key, (0, 0))
                    out[key] = (r0 + re * fr - im * fi, i0 + re * fi + im * fr)
            expansion = out
        for mono, (re, im) in expansion.items():
            n = re if kind == COS else im
            if n:
                coef_add_into(poly.setdefault(mono, {}), coef, n)
    coordinates = sorted({i for mono in poly for i, _, _ in mono})
    chosen: dict[int, int] = {}
    for i in coordinates:
        best = None
        for variant in (SIN, COS):
            trial = dict(chosen)
            trial[i] = variant
            candidate = view.render_products(_reduce_products(poly, trial))
            if best is None or _key(candidate) < best[0]:
                best = (_key(candidate), variant)
        chosen[i] = best[1]
    return view.render_products(_reduce_products(poly, chosen))


def _collected(view: "_View", p: TrigPoly) -> sympy.Expr | None:
    """Terms sharing their factors that vary with the coordinates other than by sines and
    cosines (``1/sqrt(1 - u^2)`` in System II) collected, the rest compacted inside:
    ``a1 g m2 cos(theta) (c - a1 sin(theta)) / sqrt(...)`` as in the paper's (29)."""
    groups: dict = {}
    for key, coef in p.terms.items():
        for mono, n in coef.items():
            varying = tuple((a, e) for a, e in mono if view.varies(a))
            fixed = tuple((a, e) for a, e in mono if not view.varies(a))
            groups.setdefault(varying, {}).setdefault(key, {})[fixed] = n
    if all(len(g) < 2 for v, g in groups.items() if v):
        return None
    parts = []
    for varying, terms in sorted(groups.items()):
        inner = compact(view.algebra, TrigPoly(terms))
        parts.append(view.monomial(varying) * inner)
    return sympy.Add(*parts)


def _reduce_products(poly: dict, chosen: dict[int, int]) -> dict:
    out: dict = {}
    for mono, coef in poly.items():
        terms = {(): 1}
        for i, a, b in mono:
            single = _reduced({(a, b): 1}, chosen[i]) if i in chosen else {(a, b): 1}
            charge(len(terms) * len(single), "the forms of an entry's sums of angles")
            terms = {t + ((i, x, y),): n * m for t, n in terms.items() for (x, y), m in single.items()}
        for t, n in terms.items():
            key = tuple(e for e in t if e[1] or e[2])
            coef_add_into(out.setdefault(key, {}), coef, n)
    return {k: v for k, v in out.items() if v}


# ------------------------------------------------------------------ rendering
class _View:
    """The algebra's atoms, each in its shortest equivalent form, and the renderers."""

    def __init__(self, algebra: TrigAlgebra):
        self.algebra = algebra
        self._atom: dict[int, sympy.Expr] = {}
        self._mono: dict = {}
        self._varies: dict[int, bool] = {}
        self._pairs: dict[int, int] | None = None
        self._seen = 0
        self._coefficients: dict = {}
        self._plain: dict[int, bool] = {}

    # atoms ---------------------------------------------------------------
    def atom(self, i: int) -> sympy.Expr:
        hit = self._atom.get(i)
        if hit is None:
            hit = self._atom[i] = _shorter_atom(self.algebra, self.algebra.atoms[i])
        return hit

    def pairs(self) -> dict[int, int]:
        """``cos`` atom index -> ``sin`` atom index of the same argument."""
        atoms = self.algebra.atoms
        if self._pairs is None or self._seen != len(atoms):
            sines = {a.args[0]: i for i, a in enumerate(atoms) if isinstance(a, sympy.sin)}
            self._pairs = {i: sines[a.args[0]] for i, a in enumerate(atoms)
                           if isinstance(a, sympy.cos) and a.args[0] in sines}
            self._seen = len(atoms)
            self._coefficients = {}  # a new pair may collapse a coefficient printed before
        return self._pairs

    def touches(self, used: set[int]) -> bool:
        """Whether some atom of an entry (``used``, `trigpoly.used_atoms`) has a shorter form,
        or a ``sin``/``cos`` pair occurs among them."""
        pairs = self.pairs()
        if any(c in used and s in used for c, s in pairs.items()):
            return True
        return any(self.atom(a) is not self.algebra.atoms[a] for a in used)

    def varies(self, i: int) -> bool:
        """Whether atom ``i`` depends on the coordinates (``sqrt(1 - (c - a1 sin(theta))^2)``)."""
        hit = self._varies.get(i)
        if hit is None:
            hit = self._varies[i] = bool(self.algebra.atoms[i].free_symbols & set(self.algebra.coordinates))
        return hit

    def plain_sum(self, atom: int) -> bool:
        """Whether a shared sum (`TrigAlgebra.shared_sum`) is written in atoms that offer no other
        form: no sine or cosine, nothing shorter, nothing that varies (each sum asked once)."""
        hit = self._plain.get(atom)
        if hit is None:
            atoms = self.algebra.sum_atoms(atom)
            hit = self._plain[atom] = not self.touches(atoms) and not self.varying_in(atoms) and not any(
                isinstance(self.algebra.atoms[a], (sympy.sin, sympy.cos)) for a in atoms)
        return hit

    def varying_in(self, used: set[int]) -> bool:
        """Whether some atom of an entry (``used``) depends on the coordinates."""
        return any(self.varies(a) for a in used)

    # expressions ---------------------------------------------------------
    def monomial(self, mono) -> sympy.Expr:
        hit = self._mono.get(mono)
        if hit is None:
            hit = self._mono[mono] = sympy.Mul(*[self.atom(i) ** _rational(e) for i, e in mono])
        return hit

    def coefficient(self, coef: dict) -> sympy.Expr:
        """The coefficient with ``sin(a)^2 + cos(a)^2`` collapsed and common factors pulled out
        (each distinct coefficient once: the trial forms of an entry share most of them)."""
        pairs = self.pairs()
        key = tuple(coef.items())  # in order: the sign pulled out is the first term's
        hit = self._coefficients.get(key)
        if hit is None:
            hit = self._coefficients[key] = self._coefficient(coef, pairs)
        return hit

    def _coefficient(self, coef: dict, pairs: dict) -> sympy.Expr:
        variants = [coef]
        for c, s in sorted(pairs.items()):
            if any(dict(m).get(c, 0) >= 2 or dict(m).get(s, 0) >= 2 for m in coef):
                if 2 * len(variants) > VARIANTS:
                    break  # the further pairs keep their squares
                variants = [_collapse(v, c, s, keep) for v in variants for keep in (SIN, COS)]
        if len(variants) == 1:
            return self.factored(coef)
        return min((self.factored(v) for v in variants), key=_key)

    def factored(self, coef: dict) -> sympy.Expr:
        charge(len(coef) + sum(len(m) for m in coef), "the printed forms of an entry")
        if not coef:
            return sympy.Integer(0)
        if len(coef) == 1:
            (mono, n), = coef.items()
            return _rational(n) * self.monomial(mono)
        common = common_monomial(coef)
        content = rational_content(coef.values())
        inner = sympy.Add(*[_rational(_fraction(n) / content) * self.monomial(_divide(m, common))
                            for m, n in coef.items()])
        return sympy.Mul(_rational(content), self.monomial(common), inner)

    def render(self, groups: dict, chosen: dict, rest: dict) -> sympy.Expr:
        """``rest`` as the algebra prints it, and each chosen group as a polynomial in
        ``sin b``, ``cos b`` (absorbing the constant term); unchosen groups as they are."""
        algebra = self.algebra
        rest = dict(rest)
        parts = []
        for base in sorted(groups):
            terms = groups[base]
            if base not in chosen:
                for (kind, k), coef in sorted(terms.items()):
                    freq = tuple((i, s * k) for i, s in base)
                    parts.append(self.coefficient(coef) * algebra.trig_expr(kind, freq))
                continue
            variant, kept = chosen[base]
            for (kind, k), coef in sorted(terms.items()):
                if (kind, k) in kept:
                    freq = tuple((i, s * k) for i, s in base)
                    parts.append(self.coefficient(coef) * algebra.trig_expr(kind, freq))
            poly: dict[tuple[int, int], dict] = {}
            constant = rest.pop((COS, ()), None)
            if constant:
                poly[(0, 0)] = dict(constant)
            for (kind, k), coef in terms.items():
                if (kind, k) in kept:
                    continue
                for m, n in _reduced(_chebyshev(kind, k), variant).items():
                    coef_add_into(poly.setdefault(m, {}), coef, n)
            s, c = algebra.trig_expr(SIN, base), algebra.trig_expr(COS, base)
            for (i, j), coef in sorted(poly.items()):
                if coef:
                    parts.append(self.coefficient(coef) * s**i * c**j)
        for key, coef in sorted(rest.items(), key=lambda kv: (len(kv[0][1]), kv[0][1], kv[0][0])):
            parts.append(self.coefficient(coef) * algebra.trig_expr(*key))
        return sympy.Add(*parts)


    def render_products(self, poly: dict) -> sympy.Expr:
        algebra = self.algebra
        parts = []
        for mono, coef in sorted(poly.items()):
            factor = sympy.Mul(*[algebra.trig_expr(SIN, ((i, 1),)) ** a * algebra.trig_expr(COS, ((i, 1),)) ** b
                                 for i, a, b in mono])
            parts.append(self.coefficient(coef) * factor)
        return sympy.Add(*parts)


_VIEWS: "weakref.WeakKeyDictionary[TrigAlgebra, _View]" = weakref.WeakKeyDictionary()


def _view(algebra: TrigAlgebra) -> _View:
    view = _VIEWS.get(algebra)
    if view is None:
        view = _VIEWS[algebra] = _View(algebra)
    return view


def _shorter_atom(algebra: TrigAlgebra, atom: sympy.Expr) -> sympy.Expr:
    """An atom whose inside holds sines or cosines, rebuilt through the algebra when shorter:
    ``r^2 sin(a)^2 + r^2 cos(a)^2`` is ``r^2``."""
    if not atom.has(sympy.sin, sympy.cos) or isinstance(atom, (sympy.sin, sympy.cos)):
        return atom
    try:
        if atom.is_Add or atom.is_Mul or atom.is_Pow:
            inner = TrigAlgebra(algebra.coordinates)
            rebuilt = compact(inner, inner.from_expr(atom))
        elif atom.args:
            rebuilt = atom.func(*[_shorter_atom(algebra, a) for a in atom.args])
        else:
            return atom
    except Exception:  # an inside too large to expand keeps its own form
        return atom
    return rebuilt if _key(rebuilt) < _key(atom) else atom


def _collapse(coef: dict, c: int, s: int, keep: int) -> dict:
    """``cos(a)^2 -> 1 - sin(a)^2`` (keep SIN) or the reverse, in every monomial."""
    drop, other = (c, s) if keep == SIN else (s, c)
    out: dict = {}
    todo = list(coef.items())
    while todo:
        charge(1, "the forms of an entry's powers of sines and cosines")
        mono, n = todo.pop()
        exps = dict(mono)
        e = exps.get(drop, 0)
        if isinstance(e, int) and e >= 2:
            lower = dict(exps)
            if e == 2:
                del lower[drop]
            else:
                lower[drop] = e - 2
            swapped = dict(lower)
            swapped[other] = swapped.get(other, 0) + 2
            todo += [(tuple(sorted(lower.items())), n), (tuple(sorted(swapped.items())), -n)]
        else:
            out[mono] = out.get(mono, 0) + n
    return {m: n for m, n in out.items() if n}


def _divide(mono, common):
    exps = dict(mono)
    for i, e in common:
        exps[i] -= e
        if not exps[i]:
            del exps[i]
    return tuple(sorted(exps.items()))


def _fraction(value) -> Fraction:
    """A rational of the algebra (int, Fraction or gmpy2's mpq) as a Fraction (never mixed)."""
    return Fraction(int(value.numerator), int(value.denominator))


def rational_content(values) -> Fraction:
    """Rational content of the coefficients, signed like the first (as a Fraction)."""
    return _fraction(trigpoly.rational_content(values))


def _rational(v) -> sympy.Rational:
    v = _fraction(v)
    return sympy.Rational(v.numerator, v.denominator)


def tidy(expr: sympy.Expr) -> sympy.Expr:
    """A printed entry with the factors common to its terms (a sign, a length) pulled out
    when that is shorter: ``-(P*lambda + g*r*sin(theta)/2)``. Small entries only."""
    return _factored(expr)


def recompact(expr: sympy.Expr, coordinates) -> sympy.Expr:
    """``expr`` (a sum of entries compacted one by one, such as ``fbar`` over several
    effects) compacted as a whole, if that is shorter: ``F*a2*cos(phi) - a2*g*m2*sin(phi)``
    is ``a2*(F*cos(phi) - g*m2*sin(phi))``."""
    algebra = TrigAlgebra(coordinates)
    try:
        whole = compact(algebra, algebra.from_expr(expr))
    except Exception:  # too large to expand: it keeps its form
        return expr
    return min((expr, whole, _factor_terms(whole)), key=_key)


__all__ = ["ATOM_SYMBOLS", "FACTORED", "MULTIPLE", "REMEMBERED", "SMALL", "TIE_OPS", "VARIANTS", "compact",
           "rational_content", "recompact", "tidy"]
