"""Trigonometric polynomials in the coordinates: the compact form of every entry.

An expression is held as a finite sum

    sum_k  c_k(atoms) * cos(k . q)   +   s_k(atoms) * sin(k . q)

where ``k`` is a vector of rational frequencies over the coordinates ``q`` and
the coefficients are polynomials (with rational exponents) in *atoms*: every
other factor (parameters, velocities, coordinates appearing algebraically,
``sqrt(...)``, ``asin(...)``...). Products of sines and cosines are turned into
sums by the product-to-sum identities, so ``cos a cos b + sin a sin b``
collapses to ``cos(a - b)`` as the product is formed. This keeps
``Mbar = C^T M C`` (9'), (D) compact without any after-the-fact trigonometric
simplification, which is what makes long chains cheap. A sum constant in the
coordinates that many entries share (the masses below a link of a chain) may be
held as one atom of its own (`TrigAlgebra.shared_sum`), written out again, each
distinct coefficient once, when an entry is turned back into an expression.
"""
from __future__ import annotations

import math
from fractions import Fraction

try:  # exact rationals in C when gmpy2 is installed (the `fast` extra); Python's otherwise
    from gmpy2 import mpq as Q
except ImportError:  # pragma: no cover - depends on the installation
    Q = Fraction
from collections.abc import Mapping
from types import MappingProxyType
from typing import Iterable, Iterator

import sympy

from ..budget import charge
from ..errors import Location, ModelError, Problem
from . import canonical
from .derivative import derivative
from .doubles import Unsupported, complex_value

MAX_EXPANDED_POWER = 8
"""Highest integer power of a sum that is expanded (``(x + y)**8``); a higher one is an error."""
MAX_EXPANSION_TERMS = 120
"""Most terms a power of a sum may expand to, by the multinomial count (`expansion_terms`)."""
MAX_SQUARE_TERMS = 2000
"""The same for a square, whose terms grow only as the square of the sum's: kronsub's own
``|p_b - p_a|^2`` of a spring at a point of a turning 3-D body counts some 500."""


class ExpansionTooLarge(ModelError):
    """A power of a sum that would expand beyond `MAX_EXPANDED_POWER` or `MAX_EXPANSION_TERMS`."""

    def __init__(self, message: str, location: Location | None = None):
        self.message = message
        super().__init__([Problem(location, message, EXPANSION_HINT)])

    def at(self, location: Location) -> "ExpansionTooLarge":
        """The same error, placed at ``location`` (the model file it arose in)."""
        return ExpansionTooLarge(self.message, location)


EXPANSION_HINT = (f"powers of sums are expanded up to **{MAX_EXPANDED_POWER} and {MAX_EXPANSION_TERMS} terms "
                  f"({MAX_SQUARE_TERMS} for a square): "
                  "write a lower power, or fewer terms inside the parentheses")


def expansion_terms(terms: int, power: int) -> int:
    """The most terms ``(a_1 + ... + a_terms)**power`` can expand to: the multinomial
    count ``C(power + terms - 1, terms - 1)`` of the distinct products."""
    return math.comb(power + terms - 1, terms - 1) if terms > 0 else 0


def expansion_problem(terms: int, power: int, width: int | None = None) -> str | None:
    """Why ``(sum of terms)**power`` must not be expanded, or None if it may be.

    ``width`` counts the terms as exponentials (a sine or cosine is two), which
    makes `expansion_terms` an upper bound; it defaults to ``terms``. A single
    term (``cos(x)**9``) is not a sum: only the count of terms limits it.
    """
    width = terms if width is None else width
    if terms > 1 and power > MAX_EXPANDED_POWER:
        return f"a power of a sum higher than **{MAX_EXPANDED_POWER} is not expanded (it would take too long)"
    count = expansion_terms(width, power)
    limit = MAX_SQUARE_TERMS if power == 2 else MAX_EXPANSION_TERMS
    if count > limit:
        return f"the power would expand to {count} terms (more than {limit})"
    return None


def check_expansion(p: "TrigPoly", power: int, shown: str = "a sum") -> None:
    """Raise `ExpansionTooLarge` before expanding ``p**power`` if it is too large."""
    terms = sum(len(coef) for coef in p.terms.values())
    problem = expansion_problem(terms, power, _expansion_width(p))
    if problem is not None:
        raise ExpansionTooLarge(f"({shown})**{power}: {problem}")


# A frequency vector: sorted tuple of (coordinate index, nonzero rational).
Freq = tuple[tuple[int, int | Fraction], ...]
# A monomial in atoms: sorted tuple of (atom index, nonzero rational exponent).
Mono = tuple[tuple[int, int | Fraction], ...]
Coef = dict[Mono, int | Fraction]
COS, SIN = 0, 1
ZERO_FREQ: Freq = ()
ONE: Mono = ()


def _num(value: Fraction) -> int | Fraction:
    return int(value.numerator) if value.denominator == 1 else value


def _freq_combine(a: Freq, b: Freq, sign: int) -> Freq:
    """The frequency vector ``a + sign * b``."""
    if not b:
        return a
    out = dict(a)
    for i, v in b:
        w = out.get(i, 0) + sign * v
        if w:
            out[i] = w
        else:
            out.pop(i, None)
    return tuple(sorted(out.items()))


def _freq_negative(f: Freq) -> bool:
    return bool(f) and f[0][1] < 0


def _freq_neg(f: Freq) -> Freq:
    return tuple((i, -v) for i, v in f)


def _mono_mul(a: Mono, b: Mono) -> Mono:
    """The product of two monomials: a merge of their (atom, exponent) lists, both sorted."""
    if not a:
        return b
    if not b:
        return a
    if len(b) == 1:
        return _times_atom(a, b)
    if len(a) == 1:
        return _times_atom(b, a)
    out = []
    x = y = 0
    while x < len(a) and y < len(b):
        i, e = a[x]
        j, f = b[y]
        if i < j:
            out.append(a[x])
            x += 1
        elif j < i:
            out.append(b[y])
            y += 1
        else:
            if e + f:
                out.append((i, e + f))
            x += 1
            y += 1
    out.extend(a[x:])
    out.extend(b[y:])
    return tuple(out)


def _times_atom(a: Mono, b: Mono) -> Mono:
    """`_mono_mul` of ``a`` and a monomial ``b`` of one atom."""
    (i, e), = b
    for pos, (j, f) in enumerate(a):
        if j == i:
            w = f + e
            return a[:pos] + ((i, w),) + a[pos + 1:] if w else a[:pos] + a[pos + 1:]
        if j > i:
            return a[:pos] + b + a[pos:]
    return a + b


def _coef_mul(a: Coef, b: Coef) -> Coef:
    out: Coef = {}
    for ma, ca in a.items():
        for mb, cb in b.items():
            m = _mono_mul(ma, mb)
            v = out.get(m, 0) + ca * cb
            if v:
                out[m] = v
            else:
                out.pop(m, None)
    return out


def coef_add_into(target: Coef, src: Coef, scale: int | Fraction = 1) -> None:
    if type(scale) is int and scale == 1:  # no product to form (and the types stay as they are)
        for m, c in src.items():
            v = target.get(m, 0) + c
            if v:
                target[m] = v
            else:
                target.pop(m, None)
        return
    for m, c in src.items():
        v = target.get(m, 0) + scale * c
        if v:
            target[m] = v
        else:
            target.pop(m, None)


def _add_derivative(out: dict, kind: int, freq: Freq, k, coef: Coef) -> None:
    """Add ``coef * d trig(f.q) / dq`` into the terms ``out``, for ``k`` the coordinate's
    frequency: ``d cos(f.q) = -k sin(f.q)``, ``d sin(f.q) = k cos(f.q)``."""
    key, scale = ((SIN, freq), -k) if kind == COS else ((COS, freq), k)
    tgt = out.setdefault(key, {})
    coef_add_into(tgt, coef, scale)
    if not tgt:
        del out[key]


class TrigPoly:
    """An element of the algebra: ``{(kind, freq): coefficient}`` (immutable by convention)."""

    __slots__ = ("terms",)

    def __init__(self, terms: dict[tuple[int, Freq], Coef] | None = None):
        self.terms = terms or {}

    def is_zero(self) -> bool:
        return not self.terms

    def key(self) -> tuple:
        """A hashable value equal for equal polynomials (for grouping equal entries)."""
        return tuple(sorted((k, tuple(sorted(c.items()))) for k, c in self.terms.items()))

    def copy(self) -> "TrigPoly":
        return TrigPoly({k: dict(v) for k, v in self.terms.items()})

    def __add__(self, other: "TrigPoly") -> "TrigPoly":
        return self.copy().add(other)

    def add(self, other: "TrigPoly") -> "TrigPoly":
        """Add ``other`` into this polynomial in place (for accumulators); returns self."""
        out = self.terms
        for k, c in other.terms.items():
            tgt = out.setdefault(k, {})
            coef_add_into(tgt, c)
            if not tgt:
                del out[k]
        return self

    def add_product(self, a: "TrigPoly", b: "TrigPoly") -> "TrigPoly":
        """``self += a * b`` in place; returns self. Charged to the work budget (`kronsub.budget`):
        one unit per product of two monomials, before they are formed."""
        out = self.terms
        (na, ta), (nb, tb) = _size(a), _size(b)
        charge(na * nb + na * tb + nb * ta, "the terms of products of sines and cosines")
        for (ka, fa), ca in a.terms.items():
            for (kb, fb), cb in b.terms.items():
                coef = _coef_mul(ca, cb)
                if not coef:
                    continue
                for key, scale in _product_to_sum(ka, fa, kb, fb):
                    tgt = out.setdefault(key, {})
                    coef_add_into(tgt, coef, scale)
                    if not tgt:
                        del out[key]
        return self

    def __neg__(self) -> "TrigPoly":
        return self.scaled(-1)

    def __sub__(self, other: "TrigPoly") -> "TrigPoly":
        return self + other.scaled(-1)

    def scaled(self, factor: int | Fraction) -> "TrigPoly":
        if factor == 0:
            return TrigPoly()
        return TrigPoly({k: {m: c * factor for m, c in v.items()} for k, v in self.terms.items()})

    def __mul__(self, other: "TrigPoly") -> "TrigPoly":
        return TrigPoly().add_product(self, other)


def _size(p: TrigPoly) -> tuple[int, int]:
    """``(monomials, atoms in them)`` of ``p``: a product of ``a`` and ``b`` forms ``na * nb``
    monomials by merging ``ta`` and ``tb`` atoms."""
    monomials = atoms = 0
    for coef in p.terms.values():
        monomials += len(coef)
        for mono in coef:
            atoms += len(mono)
    return monomials, atoms


def _trig_key(kind: int, freq: Freq, scale: int | Fraction) -> tuple[tuple[int, Freq], int | Fraction] | None:
    """Normalise ``scale * trig(freq)``: cos is even, sin odd, sin(0) = 0."""
    if _freq_negative(freq):
        freq = _freq_neg(freq)
        if kind == SIN:
            scale = -scale
    if kind == SIN and not freq:
        return None
    return (kind, freq), scale


_HALF = Q(1, 2)


def _product_to_sum(ka: int, fa: Freq, kb: int, fb: Freq):
    """Product-to-sum identities for trig(fa) * trig(fb)."""
    if not fb:  # trig(fa) * cos(0)
        return [((ka, fa), 1)]
    if not fa:
        return [((kb, fb), 1)]
    diff = _freq_combine(fa, fb, -1)
    summ = _freq_combine(fa, fb, +1)
    if ka == COS and kb == COS:
        parts = ((COS, diff, _HALF), (COS, summ, _HALF))
    elif ka == SIN and kb == SIN:
        parts = ((COS, diff, _HALF), (COS, summ, -_HALF))
    elif ka == SIN:  # sin a cos b
        parts = ((SIN, summ, _HALF), (SIN, diff, _HALF))
    else:  # cos a sin b
        parts = ((SIN, summ, _HALF), (SIN, diff, -_HALF))
    out = []
    for kind, freq, scale in parts:
        norm = _trig_key(kind, freq, scale)
        if norm is not None:
            out.append(norm)
    return out


class TrigAlgebra:
    """Converts sympy expressions in ``coordinates`` to and from :class:`TrigPoly`.

    The algebra remembers the atoms it has met (in the order met, which is
    deterministic) and their derivatives with respect to the coordinates.
    """

    def __init__(self, coordinates: Iterable[sympy.Symbol]):
        self.coordinates = tuple(coordinates)
        self.index = {q: i for i, q in enumerate(self.coordinates)}
        self.atoms: list[sympy.Expr] = []
        self._atom_index: dict[sympy.Expr, int] = {}
        self._atom_deps: list[frozenset[int]] = []
        self._atom_diff: dict[tuple[int, int], TrigPoly] = {}
        self._cache: dict[sympy.Expr, TrigPoly] = {}
        self._trig_cache: dict[tuple[int, Freq], sympy.Expr] = {}
        self._trig_factors: dict[tuple[int, Freq], tuple] = {}
        self._angles: dict[Freq, tuple[int, sympy.Expr]] = {}
        self._signed: dict[tuple, sympy.Rational] = {}
        self._mono_cache: dict[Mono, sympy.Expr] = {}
        self._coefficient_cache: dict[frozenset, sympy.Expr] = {}
        self._power_cache: dict[tuple[int, int | Fraction], sympy.Expr] = {}
        self._shared: dict[tuple, int] = {}
        self._expansions: dict[int, TrigPoly] = {}
        self._expansion_atoms: dict[int, frozenset[int]] = {}
        self._written: dict[frozenset, tuple | None] = {}
        self.prepare = None
        """A rewrite applied to an atom's derivative before it is converted (see inverse_trig)."""

    # ----------------------------------------------------------- construction
    def constant(self, value: int | Fraction) -> TrigPoly:
        return TrigPoly({(COS, ZERO_FREQ): {ONE: value}}) if value else TrigPoly()

    def atom(self, expr: sympy.Expr, exponent: int | Fraction = 1) -> TrigPoly:
        return TrigPoly({(COS, ZERO_FREQ): {((self._atom_id(expr), exponent),): 1}})

    def _atom_id(self, expr: sympy.Expr) -> int:
        idx = self._atom_index.get(expr)
        if idx is None:
            idx = len(self.atoms)
            self.atoms.append(expr)
            self._atom_index[expr] = idx
            deps = frozenset(self.index[s] for s in expr.free_symbols if s in self.index)
            self._atom_deps.append(deps)
        return idx

    def atom_expr(self, atom: int) -> sympy.Expr:
        """The expression of an atom (by its index in the monomials)."""
        return self.atoms[atom]

    def atom_depends(self, atom: int) -> bool:
        """Whether an atom depends on the coordinates."""
        return bool(self._atom_deps[atom])

    def shared_sum(self, p: TrigPoly) -> TrigPoly:
        """``p``, a sum constant in the coordinates (the masses below a link of a chain), as one
        atom of its own: a product with it stays one term, and the equal sums of many entries
        are one. `to_expr` and `flat` write it out again; nothing printed names it."""
        key = p.key()
        atom = self._shared.get(key)
        if atom is None:
            if self.depends_on(p) or self.has_shared(p):
                raise ValueError("a shared sum is constant in the coordinates and written in plain atoms")
            atom = self._shared[key] = len(self.atoms)
            self.atoms.append(sympy.Dummy(f"shared{len(self._expansions)}"))
            self._atom_deps.append(frozenset())
            self._expansions[atom] = p
            self._expansion_atoms[atom] = frozenset(used_atoms(p))
        return TrigPoly({(COS, ZERO_FREQ): {((atom, 1),): 1}})

    @property
    def shared_sums(self) -> Mapping[int, TrigPoly]:
        """Every `shared_sum` made in this algebra: its atom -> the sum it stands for (read only)."""
        return MappingProxyType(self._expansions)

    def has_shared(self, p: TrigPoly) -> bool:
        """Whether ``p`` holds a `shared_sum`."""
        shared = self._expansions
        return bool(shared) and any(i in shared for coef in p.terms.values() for mono in coef for i, _ in mono)

    def flat(self, p: TrigPoly) -> TrigPoly:
        """``p`` with every `shared_sum` written out (``p`` itself when it has none)."""
        if not self.has_shared(p):
            return p
        shared = self._expansions
        out = TrigPoly()
        for key, coef in p.terms.items():
            for mono, c in coef.items():
                term = TrigPoly({key: {tuple((i, e) for i, e in mono if i not in shared): c}})
                for i, e in mono:
                    if i in shared:
                        if not (isinstance(e, int) and e > 0):
                            raise ValueError("a shared sum is raised to a positive integer power only")
                        term = term * _power(shared[i], e, self.constant(1))
                out.add(term)
        return out

    def sum_atoms(self, atom: int) -> frozenset[int]:
        """The atoms a `shared_sum` is written in."""
        return self._expansion_atoms[atom]

    def from_expr(self, expr: sympy.Expr) -> TrigPoly:
        """The trigonometric-polynomial form of a sympy expression."""
        expr = sympy.sympify(expr)
        hit = self._cache.get(expr)
        if hit is None:
            hit = self._convert(expr)
            self._cache[expr] = hit
        return hit

    def _convert(self, e: sympy.Expr) -> TrigPoly:
        if e.is_Rational:
            return self.constant(_num(Q(int(e.p), int(e.q))))
        if e.is_Add:
            out = TrigPoly()
            for a in e.args:
                out.add(self.from_expr(a))
            return out
        if e.is_Mul:
            out = self.constant(1)
            for a in e.args:
                out = out * self.from_expr(a)
            return out
        if e.is_Pow:
            return self._convert_pow(e)
        if isinstance(e, (sympy.sin, sympy.cos)):
            return self._convert_trig(e)
        if not self._has_coordinates(e) or e.is_Symbol:
            return self.atom(e)
        return self.atom(e)

    def _has_coordinates(self, e: sympy.Expr) -> bool:
        return any(s in self.index for s in e.free_symbols)

    def _convert_pow(self, e: sympy.Pow) -> TrigPoly:
        base, exp = e.args
        if not exp.is_Rational:
            return self.atom(e)
        inner = self.from_expr(base)
        single = _single_monomial(inner)
        if exp.is_Integer:
            n = int(exp)
            if single is not None:
                mono, c = single
                return TrigPoly({(COS, ZERO_FREQ): {tuple((i, _num(Q(k) * n)) for i, k in mono): _num(Q(c) ** n)}})
            if n > 0:
                check_expansion(inner, n, _short(base))
                return _power(inner, n, self.constant(1))
        if single is not None:
            mono, c = single
            if c == 1 and len(mono) == 1:  # (atom**k)**r -> atom**(k r) only for k = 1
                (i, k), = mono
                if k == 1:
                    return TrigPoly({(COS, ZERO_FREQ): {((i, _num(Q(int(exp.p), int(exp.q)))),): 1}})
        return self.atom(base, _num(Q(int(exp.p), int(exp.q))))

    def _convert_trig(self, e: sympy.Expr) -> TrigPoly:
        arg = e.args[0]
        linear: dict[int, Fraction] = {}
        rest = []
        for term in sympy.Add.make_args(arg):
            coeff, sym = term.as_coeff_Mul()
            if sym in self.index and coeff.is_Rational:
                i = self.index[sym]
                linear[i] = linear.get(i, 0) + Q(int(coeff.p), int(coeff.q))
            else:
                rest.append(term)
        freq = tuple(sorted((i, _num(v)) for i, v in linear.items() if v))
        kind = SIN if isinstance(e, sympy.sin) else COS
        if not freq:
            return self.atom(e)
        pure = TrigPoly(dict([_pure_term(kind, freq)]))
        if not rest:
            return pure
        r = sympy.Add(*rest)
        other = TrigPoly(dict([_pure_term(COS if kind == SIN else SIN, freq)]))
        # sin(L + R) = sin L cos R + cos L sin R ; cos(L + R) = cos L cos R - sin L sin R
        cos_r, sin_r = self.from_expr(sympy.cos(r)), self.from_expr(sympy.sin(r))
        if kind == SIN:
            return pure * cos_r + other * sin_r
        return pure * cos_r - other * sin_r

    # ------------------------------------------------------------ derivatives
    def diff(self, p: TrigPoly, coordinate: int) -> TrigPoly:
        """``d p / d q[coordinate]``."""
        out: dict[tuple[int, Freq], Coef] = {}
        for (kind, freq), coef in p.terms.items():
            k = next((v for i, v in freq if i == coordinate), 0)
            if k:
                _add_derivative(out, kind, freq, k, coef)
        result = TrigPoly(out)
        for extra in self._chain_terms(p, coordinate):
            result.add(extra)
        return result

    def _chain_terms(self, p: TrigPoly, coordinate: int) -> list[TrigPoly]:
        """The chain rule's terms of ``d p / d q[coordinate]`` through atoms that depend on it."""
        chain: list[TrigPoly] = []
        for (kind, freq), coef in p.terms.items():
            for mono, c in coef.items():
                for pos, (atom, e) in enumerate(mono):
                    if coordinate not in self._atom_deps[atom]:
                        continue
                    d_atom = self._diff_atom(atom, coordinate)
                    if d_atom.is_zero():
                        continue
                    rest = list(mono)
                    if e == 1:
                        del rest[pos]
                    else:
                        rest[pos] = (atom, e - 1)
                    factor = TrigPoly({(kind, freq): {tuple(rest): c * e}})
                    chain.append(factor * d_atom)
        return chain

    def _diff_atom(self, atom: int, coordinate: int) -> TrigPoly:
        key = (atom, coordinate)
        hit = self._atom_diff.get(key)
        if hit is None:
            d = derivative(self.atoms[atom], self.coordinates[coordinate])
            hit = self.from_expr(d if self.prepare is None else self.prepare(d))
            self._atom_diff[key] = hit
        return hit

    # -------------------------------------------------------------- back out
    def monomial_expr(self, mono: Mono) -> sympy.Expr:
        """The product of atoms of a monomial (cached: the same ones recur across entries)."""
        hit = self._mono_cache.get(mono)
        if hit is None:
            hit = sympy.Mul(*[self.atoms[i] ** _rational(e) for i, e in mono])
            self._mono_cache[mono] = hit
        return hit

    def coefficient_expr(self, coef: Coef) -> sympy.Expr:
        return sympy.Add(*[_rational(c) * self.monomial_expr(mono) for mono, c in coef.items()])

    def trig_expr(self, kind: int, freq: Freq) -> sympy.Expr:
        key = (kind, freq)
        hit = self._trig_cache.get(key)
        if hit is None:
            # Built in canonical form, with sympy's own choice of sign, so the
            # result is the very object ``cos(arg)`` would evaluate to.
            sign, trig = self._trig_factor(kind, freq)
            hit = self._trig_cache[key] = canonical.mul(sign, list(trig)) if trig else sympy.Integer(1)
        return hit

    def _angle(self, freq: Freq) -> tuple[int, sympy.Expr]:
        """``(sign, arg)``: the argument sympy writes for ``freq . q`` (``q1 - q2``, never
        ``q2 - q1``) and the sign taken out for it; each once, for its sine and its cosine."""
        hit = self._angles.get(freq)
        if hit is None:
            sign = -1 if self._minus_sign(freq) else 1
            arg = canonical.add([canonical.mul(_rational(sign * v), [self.coordinates[i]]) for i, v in freq])
            hit = self._angles[freq] = sign, arg
        return hit

    def _minus_sign(self, freq: Freq) -> bool:
        """Whether sympy takes the sign out of ``freq . q`` (``cos(q2 - q1)`` is ``cos(q1 - q2)``).

        sympy breaks the tie between ``q1 - q2`` and ``q2 - q1`` by sort keys, which depend on
        plain symbols only through the order of their names: the answer is one per pattern of
        coefficients taken in that order, asked of sympy once."""
        symbols = [self.coordinates[i] for i, _ in freq]
        if not all(type(s) is sympy.Symbol for s in symbols):
            return bool(sympy.Add(*[_rational(v) * s for s, (_, v) in zip(symbols, freq)])
                        .could_extract_minus_sign())
        pattern = tuple(v for _, v in sorted(zip((s.name for s in symbols), (v for _, v in freq))))
        hit = _SIGN_PATTERNS.get(pattern)
        if hit is None:
            placeholders = [sympy.Symbol(f"x{i:06d}") for i in range(len(pattern))]  # in name order
            hit = _SIGN_PATTERNS[pattern] = bool(
                sympy.Add(*[_rational(v) * x for v, x in zip(pattern, placeholders)]).could_extract_minus_sign())
        return hit

    def factored_coefficient(self, coef: Coef) -> sympy.Expr:
        """A coefficient with the monomial common to all its terms pulled out."""
        if len(coef) == 1:
            return self.coefficient_expr(coef)
        common = common_monomial(coef)
        if not common:
            return self.coefficient_expr(coef)
        content = rational_content(coef.values())
        inner = _divided(coef, common, content)
        outer = [self.atoms[i] ** _rational(e) for i, e in common]
        return sympy.Mul(_rational(_num(Q(content))), *outer, self.coefficient_expr(inner))

    def to_expr(self, p: TrigPoly) -> sympy.Expr:
        """A compact sympy expression: common factors of each coefficient pulled out.

        Built in canonical form directly (:mod:`.canonical`): the same expression as
        `evaluated_expr`, without sympy collecting terms the algebra has already collected.
        A `shared_sum` is written out: the expression is that of `flat` of ``p``.
        """
        expr = self.written_out(p)
        return self.to_expr(self.flat(p)) if expr is None else expr

    def written_out(self, p: TrigPoly) -> sympy.Expr | None:
        """`to_expr` of ``p``, its shared sums written out coefficient by coefficient (each
        distinct one once), or None where that would not be the expression of `flat` of ``p``
        (a term that cancels once written out, a factor pulled out that a sum also holds)."""
        parts = []
        charge(sum(_size(p)), "the printed terms of an entry")
        shared = self._expansions
        for (kind, freq), coef in _sorted_terms(p):
            sign, trig = self._trig_factor(kind, freq)
            if shared and any(i in shared for mono in coef for i, _ in mono):
                written = self._written_coefficient(coef)
                if written is None:
                    return None
                outer, (single, content, common, inner, flat) = written
                if single is not None:
                    parts.append(self._monomial_term(_mono_mul(outer, single), content, sign, trig))
                    continue
                common = _mono_mul(outer, common)
                if not common:
                    inner = self._coefficient(flat)
            elif len(coef) == 1:
                (mono, c), = coef.items()
                parts.append(self._monomial_term(mono, c, sign, trig))
                continue
            else:
                common = common_monomial(coef)
                if common:
                    content = rational_content(coef.values())
                    inner = self._coefficient(_divided(coef, common, content))
                else:
                    inner = self._coefficient(coef)
            if not common:  # the content stays inside
                parts.append(canonical.mul(sign, [inner, *trig]))
                continue
            parts.append(canonical.mul(self._times_sign(content, sign), [*self._powers(common), inner, *trig]))
        return canonical.add(parts)

    def _monomial_term(self, mono: Mono, c, sign: sympy.Integer, trig: tuple) -> sympy.Expr:
        """``c * mono * sign * trig`` of a coefficient of one monomial."""
        powers = self._powers(mono)
        if len(powers) == 1 and powers[0].is_Add:  # c*(a + b) distributes before trig joins
            return canonical.mul(sign, [canonical.mul(_rational(c), powers), *trig])
        return canonical.mul(self._times_sign(c, sign), [*powers, *trig])

    def _written_coefficient(self, coef: Coef) -> tuple | None:
        """``(outer, (single, content, common, inner, flat))``: ``coef`` = ``outer * rest``, ``outer``
        the plain atoms common to its monomials, ``flat`` the ``rest`` with its shared sums written
        out: its one monomial ``single`` (``content`` its number), or its common factor ``common``,
        rational content and the expression of what remains (each distinct ``rest`` once). The common
        factor of the written-out ``coef`` is ``outer * common``. None when a shared sum holds
        an atom of ``outer`` or ``rest`` written out is zero."""
        shared = self._expansions
        outer = tuple((i, e) for i, e in common_monomial(coef) if i not in shared)
        if any(i in self._expansion_atoms[s] for mono in coef for s, _ in mono if s in shared for i, _ in outer):
            return None
        rest = _divided(coef, outer, 1) if outer else coef
        key = frozenset(rest.items())
        if key not in self._written:
            flat = self.flat(TrigPoly({(COS, ZERO_FREQ): rest})).terms.get((COS, ZERO_FREQ))
            if not flat:
                hit = None
            elif len(flat) == 1:
                (mono, c), = flat.items()
                hit = (mono, c, None, None, None)
            else:
                common = common_monomial(flat)
                content = rational_content(flat.values())
                hit = (None, content, common, self._coefficient(_divided(flat, common, content)), flat)
            self._written[key] = hit
        hit = self._written[key]
        return None if hit is None else (outer, hit)

    def evaluated_expr(self, p: TrigPoly) -> sympy.Expr:
        """`to_expr` through sympy's own evaluating constructors (the reference it must equal)."""
        parts = []
        for (kind, freq), coef in _sorted_terms(p):
            parts.append(self.factored_coefficient(coef) * self.trig_expr(kind, freq))
        return sympy.Add(*parts)

    def _powers(self, mono: Mono) -> list[sympy.Expr]:
        out = []
        for i, e in mono:
            key = (i, e)
            hit = self._power_cache.get(key)
            if hit is None:
                hit = self._power_cache[key] = self.atoms[i] ** _rational(e)
            out.append(hit)
        return out

    def _coefficient(self, coef: Coef) -> sympy.Expr:
        """`coefficient_expr`, built in canonical form; each distinct one once (a chain's sums of
        masses below a link recur in every entry of that link's row and column)."""
        key = frozenset(coef.items())
        hit = self._coefficient_cache.get(key)
        if hit is None:
            hit = self._coefficient_cache[key] = canonical.add(
                [canonical.mul(_rational(c), self._powers(mono)) for mono, c in coef.items()])
        return hit

    def _trig_factor(self, kind: int, freq: Freq) -> tuple[sympy.Integer, tuple[sympy.Expr, ...]]:
        """`trig_expr` as (sign, (function value,)): ``()`` for ``cos(0)`` (each once): sympy
        takes the sign out of a sine, ``sin(q2 - q1) = -sin(q1 - q2)``, not out of a cosine."""
        key = (kind, freq)
        hit = self._trig_factors.get(key)
        if hit is None:
            if not freq:
                hit = sympy.S.One, ()
            else:
                sign, arg = self._angle(freq)
                if kind == COS:
                    hit = sympy.S.One, (canonical.function(sympy.cos, arg),)
                else:
                    hit = sympy.Integer(sign), (canonical.function(sympy.sin, arg),)
            self._trig_factors[key] = hit
        return hit

    def _times_sign(self, c, sign: sympy.Integer) -> sympy.Rational:
        """``c * sign`` as a sympy number (each once: the same few recur in every entry)."""
        key = (c, sign)
        hit = self._signed.get(key)
        if hit is None:
            hit = self._signed[key] = _rational(_num(Q(c))) * sign
        return hit

    def numeric(self, values: dict) -> "NumericPoint":
        """The algebra at a point (``values``: every coordinate and the atoms' other
        symbols as floats), for evaluating many of its polynomials there."""
        return NumericPoint(self, values)

    def atoms_of(self, p: TrigPoly) -> list[sympy.Expr]:
        """The atoms ``p``'s coefficients are made of, in the order met."""
        return [self.atoms[i] for i in sorted(used_atoms(p))]

    def gradient(self, p: TrigPoly) -> list[TrigPoly]:
        """``[d p / d q[j] for every coordinate j]``: zero, untouched, where ``p`` does not
        depend on ``q[j]``; the same polynomials as `diff`, built in one pass over the terms
        for the sines and cosines (the chain rule through atoms, rarer, as `diff` does it)."""
        deps = self.depends_on(p)
        trig: dict[int, dict] = {j: {} for j in deps}
        varying = False
        for (kind, freq), coef in p.terms.items():
            for j, k in freq:
                _add_derivative(trig[j], kind, freq, k, coef)
            varying = varying or any(self._atom_deps[atom] for mono in coef for atom, _ in mono)
        result = []
        for j in range(len(self.coordinates)):
            if j not in deps:
                result.append(TrigPoly())
                continue
            derivative = TrigPoly(trig[j])
            if varying:
                for extra in self._chain_terms(p, j):
                    derivative.add(extra)
            result.append(derivative)
        return result

    def depends_on(self, p: TrigPoly) -> frozenset[int]:
        """Indices of the coordinates that ``p`` depends on."""
        deps: set[int] = set()
        for (_, freq), coef in p.terms.items():
            deps.update(i for i, _ in freq)
            for mono in coef:
                for atom, _ in mono:
                    deps.update(self._atom_deps[atom])
        return frozenset(deps)

    def has_multiple_angles(self, p: TrigPoly) -> bool:
        return any(abs(v) != 1 for (_, freq) in p.terms for _, v in freq)


_SIGN_PATTERNS: dict[tuple, bool] = {}
"""`TrigAlgebra._minus_sign` by the coefficients of a frequency in the order of the names."""


def used_atoms(p: TrigPoly) -> set[int]:
    """Indices of the atoms ``p``'s coefficients are made of."""
    return {i for coef in p.terms.values() for mono in coef for i, _ in mono}


def _divided(coef: Coef, common: Mono, content) -> Coef:
    """``coef / (content * common)``, term by term (``common`` divides every monomial, so each
    of its atoms is in every monomial: subtracted, or left out where it goes to zero)."""
    divisor = dict(common)
    out: Coef = {}
    for m, c in coef.items():
        mono = tuple([(i, e - divisor[i]) if i in divisor else (i, e) for i, e in m if divisor.get(i) != e])
        out[mono] = c if content == 1 else c / content
    return out


def common_monomial(coef: Coef) -> Mono:
    """Atoms (with exponents) that divide every monomial of ``coef``."""
    monos = iter(coef)
    exps = dict(next(monos))
    for mono in monos:
        if not exps:
            return ()
        here = dict(mono)
        for i, e in list(exps.items()):
            f = here.get(i)
            if f is None or (e > 0) != (f > 0):
                del exps[i]
            elif (f < e) if e > 0 else (f > e):
                exps[i] = f
    return tuple(sorted(exps.items()))


def rational_content(values) -> Fraction:
    """Rational content of the coefficients, signed like the first."""
    values = [Q(v) for v in values]
    num = 0
    den = 1
    for v in values:
        num = math.gcd(num, v.numerator)
        den = den * v.denominator // math.gcd(den, v.denominator)
    content = Q(num, den)
    return -content if values[0] < 0 else content


def _sorted_terms(p: TrigPoly) -> Iterator[tuple[tuple[int, Freq], Coef]]:
    return iter(sorted(p.terms.items(), key=lambda kv: (len(kv[0][1]), kv[0][1], kv[0][0])))


def _pure_term(kind: int, freq: Freq):
    key, scale = _trig_key(kind, freq, 1)
    return key, {ONE: scale}


def _single_monomial(p: TrigPoly):
    if len(p.terms) != 1:
        return None
    (key, coef), = p.terms.items()
    if key != (COS, ZERO_FREQ) or len(coef) != 1:
        return None
    (mono, c), = coef.items()
    return mono, c


def _expansion_width(p: TrigPoly) -> int:
    """Terms of ``p`` counted as exponentials (``cos f = (e^{if} + e^{-if})/2``), so that
    `expansion_terms` bounds the terms of a power of ``p`` (product-to-sum included)."""
    return sum(len(coef) * (2 if freq else 1) for (_, freq), coef in p.terms.items())


def _short(expr: sympy.Expr, limit: int = 40) -> str:
    text = sympy.sstr(expr)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _power(p: TrigPoly, n: int, one: TrigPoly) -> TrigPoly:
    result, base = one, p
    while n:
        if n & 1:
            result = result * base
        n >>= 1
        if n:
            base = base * base
    return result


def _rational(v: int | Fraction) -> sympy.Rational:
    if isinstance(v, int):
        return sympy.Integer(v)
    return sympy.Rational(int(v.numerator), int(v.denominator))


class NumericPoint:
    """Polynomials of an algebra evaluated at one point, in floating point: the atoms are
    evaluated once, then each term is ``coefficient(atoms) * trig(freq . q)``."""

    def __init__(self, algebra: TrigAlgebra, values: dict):
        self.q = [float(values[c]) for c in algebra.coordinates]
        self.algebra = algebra
        self.values = {k: float(v) for k, v in values.items()}
        self.atoms: dict[int, complex] = {}
        self._memo: dict = {}

    def _atom(self, i: int) -> complex:
        """An atom's value in complex doubles (`complex_value`: never sympy's unbounded
        multiprecision, in which ``exp(exp(...))`` can abort the process)."""
        hit = self.atoms.get(i)
        if hit is None and i in self.algebra._expansions:  # a shared sum: its value written out
            hit = self.atoms[i] = self(self.algebra._expansions[i])
        if hit is None:
            atom = self.algebra.atoms[i]
            try:
                hit = complex_value(atom, self.values, self._memo)
            except Unsupported:  # a Piecewise: sympy's evaluation
                hit = complex(atom.xreplace({k: sympy.Float(v) for k, v in self.values.items()}).evalf())
            self.atoms[i] = hit
        return hit

    def __call__(self, p: TrigPoly) -> float:
        total = 0.0
        for (kind, freq), coef in p.terms.items():
            angle = sum(float(v) * self.q[i] for i, v in freq)
            trig = math.cos(angle) if kind == COS else math.sin(angle)
            for mono, c in coef.items():
                term = float(c) * trig
                for i, e in mono:
                    term *= self._atom(i) ** float(e)
                total += term
        if isinstance(total, complex):
            if abs(total.imag) > 1e-9 * max(1.0, abs(total.real)):
                raise ValueError("complex value: outside the domain")
            total = total.real
        return total


__all__ = ["Coef", "EXPANSION_HINT", "ExpansionTooLarge", "Freq", "MAX_EXPANDED_POWER", "MAX_EXPANSION_TERMS",
           "MAX_SQUARE_TERMS", "Mono", "NumericPoint", "ONE", "Q", "TrigAlgebra", "TrigPoly", "ZERO_FREQ",
           "check_expansion", "coef_add_into", "common_monomial", "expansion_problem", "expansion_terms",
           "rational_content", "used_atoms"]
