"""Inverse trigonometric functions in a connection, kept compact in the trigonometric algebra.

A connection may give a primitive angle through ``atan2``, ``asin`` or ``acos`` of the new
coordinates (a body's Z-Y-X angles computed from Z-X-Z ones). Sympy already writes the sines
and cosines of such angles algebraically as they are substituted,

    sin(asin u) = u,   cos(asin u) = sqrt(1 - u^2),
    cos(atan2(y, x)) = x / sqrt(x^2 + y^2),   sin(atan2(y, x)) = y / sqrt(x^2 + y^2),

and ``d atan2(y, x) = (x dy - y dx) / (x^2 + y^2)``. Two things are left to make the
projection ``Mbar = C^T M C`` (9'), (D) as short as with the angles given directly:

* :func:`canonical_radicands`: a radicand or denominator is replaced by the first equal
  one met, equality judged in the algebra, so that ``x^2 + y^2`` and ``1 - u^2`` become one
  atom when they are the same trigonometric polynomial (orthogonality of the rotation):
  ``cos(psi) cos(theta) = x A^(-1/2) A^(1/2) = x``;
* :func:`divide_out`: a sum ``S A^e`` (``A`` such an atom, ``e < 0``) whose ``S`` is an exact
  multiple of the polynomial ``A`` is divided, exactly, in the ring of Laurent polynomials
  in ``z_j = exp(i q_j)``; ``sin``/``cos`` of a multiple of an inverse function
  (``sin(2 asin u)``) are expanded first (:func:`expand_multiple`).
"""
from __future__ import annotations

import math
from fractions import Fraction

import sympy
from sympy.polys.domains import QQ, QQ_I
from sympy.polys.rings import ring

from .doubles import graph_nodes
from .symbols import free_symbols_of
from .trigpoly import COS, SIN, TrigAlgebra, TrigPoly, Q

INVERSE = (sympy.asin, sympy.acos, sympy.atan, sympy.atan2)
MAX_DIVISIONS = 8
"""Most powers of one atom divided out of an entry."""


class Radicands:
    """Radicands and denominators of one algebra, each trigonometric polynomial once.

    Active only for a connection that holds an inverse function or a radical of the
    coordinates (:func:`needed`); otherwise :meth:`rewrite` returns its argument.
    """

    def __init__(self, algebra: TrigAlgebra, connection=()):
        self.algebra = algebra
        self.active = needed(connection, algebra.index)
        if self.active:
            algebra.prepare = self.rewrite  # the derivatives of atoms too (d atan2, d asin)
        self._seen: dict[tuple, sympy.Expr] = {}
        self._memo: dict[sympy.Expr, sympy.Expr] = {}

    def rewrite(self, expr: sympy.Expr) -> sympy.Expr:
        """``expr`` with every coordinate-dependent radicand or denominator made canonical."""
        if not self.active or not expr.has(sympy.Pow, *INVERSE):
            return expr
        return self._walk(expr)

    def _walk(self, e: sympy.Expr) -> sympy.Expr:
        if e.is_Atom:
            return e
        hit = self._memo.get(e)
        if hit is not None:
            return hit
        args = [self._walk(a) for a in e.args]
        out = e.func(*args) if args != list(e.args) else e
        if isinstance(out, (sympy.sin, sympy.cos)):
            expanded = expand_multiple(out)
            if expanded is not None:
                out = self._walk(expanded)
        if isinstance(out, sympy.Pow) and out.base.is_Add and _radical(out.exp) \
                and self._depends(out.base):
            base = self._canonical(out.base)
            if base is not out.base:
                out = sympy.Pow(base, out.exp)
        self._memo[e] = out
        return out

    def _depends(self, e: sympy.Expr) -> bool:
        return any(s in self.algebra.index for s in e.free_symbols)

    def _canonical(self, base: sympy.Expr) -> sympy.Expr:
        key = _frozen(self.algebra.from_expr(base))
        first = self._seen.setdefault(key, base)
        return first


def needed(connection, coordinates) -> bool:
    """Whether a connection holds an inverse trigonometric function, or a radical or a
    denominator that depends on the coordinates."""
    nodes = graph_nodes(connection)  # each shared part once (definitions used twice)
    if any(isinstance(node, INVERSE) for node in nodes):
        return True
    for p in nodes:
        if p.is_Pow and _radical(p.exp) and any(s in coordinates for s in free_symbols_of([p.base])):
            return True
    return False


def _radical(exp: sympy.Expr) -> bool:
    """An exponent that keeps its base as an atom: a fraction or a negative integer."""
    return exp.is_Rational and (not exp.is_Integer or exp < 0)


def _frozen(p: TrigPoly) -> tuple:
    return tuple(sorted((key, tuple(sorted(coef.items()))) for key, coef in p.terms.items()))


def expand_multiple(expr: sympy.Expr) -> sympy.Expr | None:
    """``sin``/``cos`` of a sum or multiple holding an inverse function, expanded
    (``sin(2 asin u) = 2 u sqrt(1 - u^2)``); None when there is nothing to expand."""
    if not expr.args[0].has(*INVERSE):
        return None
    expanded = sympy.expand_trig(expr)
    return None if expanded == expr else expanded


# ------------------------------------------------------------------ exact division
def divide_out(algebra: TrigAlgebra, p: TrigPoly) -> TrigPoly:
    """``p`` with negative powers of radicand atoms divided out where exact.

    ``p = sum_e S_e A^e`` over the exponents of an atom ``A`` whose expression is a
    trigonometric polynomial ``P``; within each class of exponents equal modulo 1,
    ``S = sum_j S_(e0+j) P^j`` and, while ``P`` divides ``S`` exactly, ``S A^e0 = (S / P) A^(e0+1)``
    (an integer class stops at ``A^0``).
    """
    for atom in _radicand_atoms(algebra, p):
        poly = algebra.from_expr(algebra.atom_expr(atom))
        p = _divide_atom(p, atom, poly)
    return p


def _radicand_atoms(algebra: TrigAlgebra, p: TrigPoly) -> list[int]:
    atoms = set()
    for coef in p.terms.values():
        for mono in coef:
            for atom, e in mono:
                if e < 0 and algebra.atom_expr(atom).is_Add and algebra.atom_depends(atom):
                    atoms.add(atom)
    return sorted(atoms)


def _divide_atom(p: TrigPoly, atom: int, poly: TrigPoly) -> TrigPoly:
    classes: dict[Fraction, dict[tuple, dict]] = {}
    rest = TrigPoly()
    for key, coef in p.terms.items():
        for mono, c in coef.items():
            e = dict(mono).get(atom, 0)
            if e == 0:
                rest.add(TrigPoly({key: {mono: c}}))
                continue
            e = _fraction(e)
            frac = e - math.floor(e)
            others = tuple((i, x) for i, x in mono if i != atom)
            classes.setdefault(frac, {}).setdefault(e, []).append((key, others, c))
    for frac, by_exp in sorted(classes.items()):
        e0 = min(by_exp)
        total = TrigPoly()
        power, cur = TrigPoly({(COS, ()): {(): 1}}), 0
        for e in sorted(by_exp):
            while cur < e - e0:
                power, cur = power * poly, cur + 1
            part = TrigPoly()
            for key, others, c in by_exp[e]:
                part.add(TrigPoly({key: {others: c}}))
            total.add_product(part, power)
        e = e0
        for _ in range(MAX_DIVISIONS):
            if frac == 0 and e >= 0:
                break
            quotient = exact_quotient(total, poly)
            if quotient is None:
                break
            total, e = quotient, e + 1
        rest.add(_times_atom(total, atom, e))
    return rest


def _fraction(value) -> Fraction:
    """A rational of the algebra (int, Fraction or gmpy2's mpq) as a Fraction."""
    return Fraction(int(value.numerator), int(value.denominator))


def _times_atom(p: TrigPoly, atom: int, e: Fraction) -> TrigPoly:
    if e == 0:
        return p
    e = e.numerator if e.denominator == 1 else e
    out = {}
    for key, coef in p.terms.items():
        out[key] = {tuple(sorted(mono + ((atom, e),))): c for mono, c in coef.items()}
    return TrigPoly(out)


def exact_quotient(num: TrigPoly, den: TrigPoly) -> TrigPoly | None:
    """``num / den`` when ``den`` divides ``num`` exactly as trigonometric polynomials (over
    polynomials in the atoms), else None: division of Laurent polynomials in ``exp(i q)``."""
    if den.is_zero() or num.is_zero():
        return None if den.is_zero() else TrigPoly()
    coords = sorted({i for p in (num, den) for (_, f) in p.terms for i, _ in f})
    atoms = sorted({a for p in (num, den) for c in p.terms.values() for m in c for a, _ in m})
    scale = {i: _lcm(v for p in (num, den) for (_, f) in p.terms for j, v in f if j == i) for i in coords}
    ascale = {a: _lcm(e for p in (num, den) for c in p.terms.values() for m in c for b, e in m if b == a)
              for a in atoms}
    names = [f"z{i}" for i in coords] + [f"a{a}" for a in atoms]
    R, *_ = ring(",".join(names), QQ_I)
    place = {("z", i): k for k, i in enumerate(coords)}
    place.update({("a", a): len(coords) + k for k, a in enumerate(atoms)})
    n_dict, n_shift = _laurent(num, place, scale, ascale, len(names))
    d_dict, d_shift = _laurent(den, place, scale, ascale, len(names))
    q, r = R.from_dict(n_dict).div([R.from_dict(d_dict)])
    if r:
        return None
    shift = [a - b for a, b in zip(n_shift, d_shift)]
    return _from_laurent(q[0], shift, coords, atoms, scale, ascale)


def _lcm(values) -> int:
    out = 1
    for v in values:
        d = _fraction(v).denominator
        out = out * d // math.gcd(out, d)
    return out


def _laurent(p: TrigPoly, place, scale, ascale, size):
    terms: dict[tuple, object] = {}

    def put(exps, c):
        v = terms.get(exps, QQ_I.zero) + c
        if v:
            terms[exps] = v
        else:
            terms.pop(exps, None)

    half = QQ_I(QQ(1, 2), 0)
    for (kind, freq), coef in p.terms.items():
        k = [0] * size
        for i, v in freq:
            k[place[("z", i)]] = int(_fraction(v) * scale[i])
        minus = [-x for x in k]
        for mono, c in coef.items():
            base = [0] * size
            for a, e in mono:
                base[place[("a", a)]] = int(_fraction(e) * ascale[a])
            cc = QQ_I(QQ(_fraction(c).numerator, _fraction(c).denominator), 0)
            if not freq:
                put(tuple(base), cc)
            elif kind == COS:  # cos x = (e^ix + e^-ix) / 2
                put(tuple(x + y for x, y in zip(base, k)), cc * half)
                put(tuple(x + y for x, y in zip(base, minus)), cc * half)
            else:  # sin x = (e^ix - e^-ix) / 2i = -i/2 e^ix + i/2 e^-ix
                put(tuple(x + y for x, y in zip(base, k)), cc * QQ_I(0, QQ(-1, 2)))
                put(tuple(x + y for x, y in zip(base, minus)), cc * QQ_I(0, QQ(1, 2)))
    shift = [min((e[j] for e in terms), default=0) for j in range(size)]
    return {tuple(x - s for x, s in zip(e, shift)): c for e, c in terms.items()}, shift


def _from_laurent(q, shift, coords, atoms, scale, ascale) -> TrigPoly | None:
    """The real trigonometric polynomial of a Laurent polynomial (None if it is not real)."""
    nz = len(coords)
    pairs: dict[tuple, dict] = {}
    for exps, c in q.items():
        exps = [x + s for x, s in zip(exps, shift)]
        k = tuple(exps[:nz])
        mono = tuple((a, _num(Q(int(exps[nz + j]), int(ascale[a])))) for j, a in enumerate(atoms) if exps[nz + j])
        neg = next((x < 0 for x in k if x), False)
        canon = tuple(-x for x in k) if neg else k
        slot = pairs.setdefault((canon, mono), {"plus": QQ_I.zero, "minus": QQ_I.zero})
        slot["minus" if neg else "plus"] += c
    out: dict[tuple, dict] = {}
    for (k, mono), slot in pairs.items():
        cp, cm = slot["plus"], slot["minus"]
        freq = tuple((coords[j], _num(Q(int(x), int(scale[coords[j]])))) for j, x in enumerate(k) if x)
        if not freq:
            if cp.y != 0:
                return None
            _put(out, (COS, ()), mono, cp.x)
            continue
        cos_c, sin_c = cp + cm, (cp - cm) * QQ_I(0, 1)  # c+ e^ix + c- e^-ix
        if cos_c.y != 0 or sin_c.y != 0:
            return None
        _put(out, (COS, freq), mono, cos_c.x)
        _put(out, (SIN, freq), mono, sin_c.x)
    return TrigPoly({k: v for k, v in out.items() if v})


def _put(out, key, mono, value) -> None:
    if value:
        out.setdefault(key, {})[mono] = _num(Q(int(value.numerator), int(value.denominator)))


def _num(value: Fraction):
    return value.numerator if value.denominator == 1 else value


__all__ = ["INVERSE", "MAX_DIVISIONS", "Radicands", "divide_out", "exact_quotient", "expand_multiple", "needed"]
