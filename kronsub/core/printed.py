"""sympy's printed forms, the same to the last character, in less time.

A large system prints thousands of entries that share their sums (a chain's
``m2/2 + m3 + ... + mn`` in a row of ``Mbar``), and sympy orders the terms of every
sum by a key that turns each coefficient into a complex number through ``evalf``.
`Remembering` prints each distinct subexpression once per printer, and orders a
sum's terms by sympy's own key with rational coefficients converted exactly and
directly. `RememberingStr` (the ``str`` form) also orders a product's factors by sort
keys it remembers, builds the keys of sums and function values from their parts, and
remembers each node's precedence, and prints a sum of products of entries and velocities
(a large system's ``Mbar qddot + hbar`` and kinetic energy) from the entries' printed factors,
without forming the products or the sum (`RememberingStr.sum_of_products`).
``tests/test_printed.py`` checks them against sympy's printers and keys.
"""
from __future__ import annotations

import sympy
from mpmath.libmp import dps_to_prec, from_rational, to_float
from sympy.core.exprtools import decompose_power
from sympy.core.numbers import mpf_norm
from sympy.printing.precedence import PRECEDENCE, precedence
from sympy.printing.str import StrPrinter

from .canonical import plain_factor
from .sympy_internals import parse_order

_PREC = dps_to_prec(15)
"""The bits of ``Expr.evalf()``'s default 15 digits; it evaluates with 4 more, then rounds."""


_SORT_KEYS: dict = {}
_ORDERED: dict = {}
"""The ordered terms of the sums whose sort keys `_SORT_KEYS` holds."""
_RATIONALS: dict = {}
_DESCRIBED: dict = {}
_REMEMBERED = 100_000


def _complex(number) -> complex:
    """``complex(number)`` as sympy computes it, without ``evalf``'s machinery for a rational:
    the quotient truncated to ``_PREC + 4`` bits, then rounded to nearest at ``_PREC`` (the
    two roundings of ``Expr.__complex__``; not always the correctly rounded quotient),
    remembered (a large system's terms share a few coefficients)."""
    if number.is_Rational:
        fraction = (int(number.p), int(number.q))
        value = _RATIONALS.get(fraction)
        if value is None:
            if len(_RATIONALS) > _REMEMBERED:
                _RATIONALS.clear()
            value = _RATIONALS[fraction] = complex(to_float(mpf_norm(from_rational(*fraction, _PREC + 4), _PREC)))
        return value
    return complex(number)


def _sort_key(expr):
    """``sympy.default_sort_key(expr)``, remembered: the sums of a large system share their
    factors (a coordinate's velocity, a sine), whose keys sympy builds anew at every sum."""
    key = _SORT_KEYS.get((type(expr), expr))
    if key is None:
        if len(_SORT_KEYS) > _REMEMBERED:
            _SORT_KEYS.clear()
            _ORDERED.clear()
        key = _SORT_KEYS[(type(expr), expr)] = _new_sort_key(expr)
    return key


def _new_sort_key(expr):
    """``Expr.sort_key`` of a sum (its terms' keys in ``lex`` order, `ordered_terms`) or of a
    function's value (its arguments' keys), the keys of the parts remembered: a large system's
    factors ``cos(q1 - q2)`` each hold a sum whose key sympy builds through ``evalf``."""
    if isinstance(expr, sympy.Expr) and expr.is_commutative and (expr.is_Function or (
            expr.is_Add and not any(isinstance(t, (sympy.Number, sympy.NumberSymbol)) for t in expr.args))):
        # (a number and a negative product: sympy's own); a sum's terms kept for its printing
        parts = _ORDERED.setdefault((type(expr), expr), _ordered_terms(expr, "lex")) if expr.is_Add else expr.args
        return expr.class_key(), (len(parts), tuple(_sort_key(p) for p in parts)), _ONE_KEY, sympy.S.One
    return sympy.default_sort_key(expr)


_ONE_KEY = sympy.S.One.sort_key()


def ordered_terms(expr, order: str = "lex") -> list:
    """``expr.as_ordered_terms(order)`` for a sum, by sympy's key (``Expr._parse_order``)
    over the terms as ``Expr.as_terms`` describes them. A sum inside a product was ordered
    already for the product's sort key (`_sort_key`): those terms are taken again, not to be
    changed."""
    if order == "lex":
        terms = _ORDERED.get((type(expr), expr))
        if terms is not None:
            return terms
    return _ordered_terms(expr, order)


def _ordered_terms(expr, order: str) -> list:
    """`ordered_terms`, made."""
    terms, gens = [], set()
    for term in sympy.Add.make_args(expr):
        if term.is_Order:
            return expr.as_ordered_terms(order=order)
        coeff, powers, noncommutative = _described(term)
        gens.update(powers)
        terms.append((term, coeff, powers, noncommutative))
    index = {g: i for i, g in enumerate(sorted(gens, key=_sort_key))}
    if order == "lex":  # the same order from the exponents that are not zero
        described = [(term, (_lex_key(powers, index), noncommutative, ((bool(coeff[1]), coeff[1]), coeff)))
                     for term, coeff, powers, noncommutative in terms]
        return [term for term, _ in sorted(described, key=_described_lex)]
    described = []
    for term, coeff, powers, noncommutative in terms:
        monom = [0] * len(index)
        for base, exp in powers.items():
            monom[index[base]] = exp
        described.append((term, (coeff, tuple(monom), noncommutative)))
    key, reverse = parse_order(order)
    return [term for term, _ in sorted(described, key=key, reverse=reverse)]


def _described(term) -> tuple:
    """``((re, im), powers, noncommutative)`` of a term of a sum, as ``Expr.as_terms`` describes
    it: its coefficient's value (times its factors that are numbers), the exponent of each
    other commutative factor's base, its non-commutative factors; remembered (the sums of a
    large system share their terms: a chain's masses), not to be changed."""
    key = (type(term), term)
    described = _DESCRIBED.get(key)
    if described is None:
        if len(_DESCRIBED) > _REMEMBERED:
            _DESCRIBED.clear()
        described = _DESCRIBED[key] = _description(term)
    return described


def _description(term) -> tuple:
    """`_described`, made."""
    coeff, rest = term.as_coeff_Mul()
    value = _complex(coeff)
    powers, noncommutative = {}, []
    if rest is not sympy.S.One:
        for factor in sympy.Mul.make_args(rest):
            if factor.is_number:
                try:
                    value *= _complex(factor)
                except (TypeError, ValueError):
                    pass
                else:
                    continue
            if factor.is_commutative:
                base, exp = decompose_power(factor)
                powers[base] = exp
            else:
                noncommutative.append(factor)
    return (value.real, value.imag), powers, tuple(noncommutative)


def _lex_order(coeff: tuple, powers: dict, index: dict) -> tuple:
    """The key of a commutative term in ``lex`` order (`_described_lex`)."""
    return _lex_key(powers, index), (), ((bool(coeff[1]), coeff[1]), coeff)


_ENDED = (0.5,)
"""`_lex_key`'s end: after every positive exponent, before every negative one."""


def _lex_key(powers: dict, index: dict) -> tuple:
    """A key of a term's exponent vector that sorts as sympy's ``lex`` key, the negated dense
    vector over every base of the sum (a sum of ``k`` terms over ``g`` bases builds ``k g``
    exponents: a large system's kinetic energy holds thousands of each), built from its
    nonzero exponents alone. Two dense vectors first differ where one has an exponent ``a``
    the other has not (or a different one): the one with ``a`` comes first when ``a > 0``,
    last when ``a < 0``; so an exponent at base ``i`` is ``(0, i, -a)`` when positive,
    ``(1, -i, -a)`` when negative, and the vector ends in `_ENDED`, between the two."""
    pairs = sorted((index[base], exp) for base, exp in powers.items() if exp != 0)
    return tuple((0, i, -a) if a > 0 else (1, -i, -a) for i, a in pairs) + (_ENDED,)


def _described_lex(described):
    """The key of a described term in ``lex`` order: exponents, non-commutative factors (by
    their sort keys), coefficient, as in ``Expr._parse_order``."""
    monom, noncommutative, coeff = described[1]
    return monom, tuple([e.sort_key(order="lex") for e in noncommutative]), coeff


class Remembering:
    """A printer mixin: each distinct compound subexpression printed once (sympy's printed
    form of a node depends on the node alone, not on where it stands), and sums ordered by
    `ordered_terms`. Atoms are printed each time (a ``Float`` prints by its depth)."""

    def _print(self, expr, **kwargs):
        if kwargs or not isinstance(expr, sympy.Basic) or expr.is_Atom:
            return super()._print(expr, **kwargs)
        memo = self.__dict__.setdefault("_printed", {})
        key = (type(expr), expr)
        text = memo.get(key)
        if text is None:
            text = memo[key] = super()._print(expr)
        return text

    def _as_ordered_terms(self, expr, order=None):
        order = order or self.order
        if order in ("old", "none"):
            return super()._as_ordered_terms(expr, order=order)
        return ordered_terms(expr, order)


def _plain_product(expr):
    """``(sign, factors)`` of a commutative product as sympy's ``str`` printer writes it
    (``StrPrinter._print_Mul``: the sign of a negative coefficient in front, the factors in
    the order of ``as_ordered_factors``, a rational coefficient split into its numerator among
    them and its denominator after them), each factor's sort key remembered (`_sort_key`);
    None for any other product (unevaluated, a reciprocal factor, a float coefficient, a
    coefficient times one sum or a number's power), which the printer's own method prints."""
    args = expr.args
    if not expr.is_commutative or args[0] is sympy.S.One or any(
            a.is_Number or (a.is_Pow and a.base.is_Integer and a.exp.is_Integer) for a in args[1:]):
        return None
    coeff, rest = expr.as_coeff_Mul()
    if not coeff.is_Rational or rest.is_Add or rest.is_Number or (rest.is_Pow and rest.base.is_Number):
        return None
    if coeff > 0:  # the product's own factors, as they stand (a product among them unflattened)
        sign, factors = "", list(args)
    elif rest.is_Mul and not rest.args[0].is_Number:  # the sign out of the coefficient: -coeff*rest's factors
        sign, factors = "-", ([] if coeff == -1 else [-coeff]) + list(rest.args)
    elif not rest.is_Mul and coeff == -1:
        sign, factors = "-", [rest]
    else:
        return None
    numerator, denominator, rational = [], 1, False
    for factor in sorted(factors, key=_sort_key):
        if factor.is_Pow and factor.exp.as_coeff_Mul()[0] < 0:
            return None
        if factor.is_Rational:
            if rational:
                return None
            rational = True
            if factor.p != 1:
                numerator.append(sympy.Integer(factor.p))
            denominator = factor.q
        else:
            numerator.append(factor)
    return sign, numerator, denominator


_ADD, _MUL = PRECEDENCE["Add"], PRECEDENCE["Mul"]


def _product_precedence(expr) -> int | None:
    """``precedence(expr)`` of a ``Mul`` of a rational coefficient, or of none, and factors
    without a precedence of their own: that of a sum if the coefficient is negative (what
    ``Mul.could_extract_minus_sign`` tells by negating the product), else a product's;
    None for anything else."""
    if type(expr) is not sympy.Mul:
        return None
    args = expr.args
    if any(hasattr(a, "precedence") for a in args):
        return None
    first = args[0]
    if first.is_Rational:
        return _ADD if first.p < 0 else _MUL
    return None if first.is_Number else _MUL


class RememberingStr(Remembering):
    """`Remembering` for sympy's ``str`` printer: a product's factors also ordered by the
    remembered sort keys (`_plain_product`), for a large system's products share their
    factors (a row's sum of masses) whose keys sympy builds anew at every product."""

    def _precedence(self, expr) -> int:
        """``precedence(expr)``, remembered (a product's asks whether its sign comes out)."""
        if not isinstance(expr, sympy.Basic):
            return precedence(expr)
        memo = self.__dict__.setdefault("_precedences", {})
        key = (type(expr), expr)
        level = memo.get(key)
        if level is None:
            level = memo[key] = _product_precedence(expr) or precedence(expr)
        return level

    def parenthesize(self, item, level, strict=False):
        """``StrPrinter.parenthesize``, by the remembered precedence."""
        own = self._precedence(item)
        text = self._print(item)
        return f"({text})" if own < level or (not strict and own <= level) else text

    def _print_Add(self, expr, order=None):
        """``StrPrinter._print_Add``: the terms in order, each with its sign in front, a term
        below the sum's precedence (or a sum) in parentheses; precedences remembered."""
        level = self._precedence(expr)
        parts = []
        for term in self._as_ordered_terms(expr, order=order):
            text = self._print(term)
            sign = "+"
            if text.startswith("-") and not term.is_Add:
                sign, text = "-", text[1:]
            if term.is_Add or self._precedence(term) < level:
                text = f"({text})"
            parts.append(f"{sign} {text}")
        joined = " ".join(parts)
        return joined[2:] if joined.startswith("+ ") else joined[0] + joined[2:]

    def _print_Mul(self, expr):
        plain = _plain_product(expr)
        if plain is None:
            return super()._print_Mul(expr)
        sign, numerator, denominator = plain
        level = self._precedence(expr)
        text = "*".join([self.parenthesize(f, level, strict=False) for f in numerator] or ["1"])
        return sign + text + (f"/{denominator}" if denominator != 1 else "")

    def sum_of_products(self, products, others=()) -> str:
        """``self._print(sympy.Add(*[sympy.Mul(c, entry, *extra) for entry, c, extra in products],
        *others))``, the products and the sum not formed where sympy's rules leave nothing to
        do but order (distinct factors, distinct terms): each product's factors are its entry's,
        sorted and printed once, with the ``extra`` ones (symbols or their positive powers, of
        bases the entry has not) put in their places, and the terms ordered by their exponents
        (`ordered_terms`). ``c`` is rational; ``others`` are terms (not sums). A large system's
        ``Mbar qddot + hbar`` (10') and kinetic energy (24) are such sums of its printed entries."""
        def formed() -> str:
            return self._print(sympy.Add(*[sympy.Mul(c, e, *x) for e, c, x in products], *others))

        if self._settings.get("order") != "lex":
            return formed()
        terms = []  # (coefficient's value, powers, text, precedence)
        for entry, coefficient, extra in products:
            if entry is sympy.S.Zero or coefficient is sympy.S.Zero:  # (as the sum drops them)
                continue
            term = self._product_term(entry, coefficient, extra)
            if term is None:
                product = sympy.Mul(coefficient, entry, *extra)
                if product.is_Add or product.is_Number or product.is_Order or not product.is_commutative:
                    return formed()
                term = self._described_term(product)
            terms.append(term)
        for other in others:
            if other.is_Add or other.is_Number or other.is_Order or not other.is_commutative:
                return formed()
            terms.append(self._described_term(other))
        if not terms or len({frozenset(powers.items()) for _, powers, _, _ in terms}) < len(terms):
            return formed()  # terms sympy may collect (or none)
        gens = set()
        for _, powers, _, _ in terms:
            gens.update(powers)
        index = {g: i for i, g in enumerate(sorted(gens, key=_sort_key))}
        parts = []
        for _, _, text, level in sorted(terms, key=lambda t: _lex_order(t[0], t[1], index)):
            sign = "+"
            if text.startswith("-"):
                sign, text = "-", text[1:]
            if level < _ADD:
                text = f"({text})"
            parts.append(f"{sign} {text}")
        joined = " ".join(parts)
        return joined[2:] if joined.startswith("+ ") else joined[0] + joined[2:]

    def _described_term(self, term) -> tuple:
        """``(coefficient's value, powers, text, precedence)`` of a commutative term of a sum."""
        coeff, powers, _ = _described(term)
        return coeff, powers, self._print(term), self._precedence(term)

    def _product_term(self, entry, coefficient, extra) -> tuple | None:
        """`_described_term` of ``sympy.Mul(coefficient, entry, *extra)`` from the entry's
        remembered factors (`_entry_factors`), without forming the product; None where it
        does not apply (the product is then formed)."""
        form = self._entry_factors(entry)
        if form is None or not extra:
            return None
        own, factors, powers = form
        coeff = coefficient * own
        if not coeff.is_Rational or not coeff.p or len(factors) + len(extra) < 2:
            return None
        # StrPrinter._print_Mul by `_plain_product`: the sign in front, the factors by their
        # sort keys, the coefficient's numerator among them by its key, its denominator after
        level = _ADD if coeff.p < 0 else _MUL
        items = list(self._printed_factors(entry, factors, level))
        powers = dict(powers)
        for factor in extra:
            printed = self._extra_factor(factor, level)
            if printed is None or printed[0] in powers:
                return None
            base, exp, item = printed
            powers[base] = exp
            items.append(item)
        size = -coeff if coeff.p < 0 else coeff
        if size.p != 1 or size.q != 1:
            items.append((_sort_key(size), self._print(sympy.Integer(size.p)) if size.p != 1 else ""))
        items.sort(key=_first)
        if any(a[0] == b[0] for a, b in zip(items, items[1:])):
            return None  # factors sympy's key does not tell apart: the product's own order decides
        text = "*".join([t for _, t in items if t] or ["1"])
        text = ("-" if coeff.p < 0 else "") + text + (f"/{size.q}" if size.q != 1 else "")
        value = _complex(coeff)
        return (value.real, value.imag), powers, text, level

    def _extra_factor(self, factor, level: int) -> tuple | None:
        """``(base, exponent, (sort key, printed form in a product of precedence level))`` of a
        symbol or its positive integer power, remembered; None for anything else."""
        memo = self.__dict__.setdefault("_extra_factors", {})
        key = (type(factor), factor, level)
        if key not in memo:
            memo[key] = None
            if (factor.is_Symbol or (factor.is_Pow and factor.base.is_Symbol and factor.exp.is_Integer
                                     and factor.exp.p > 0)) and factor.is_commutative:
                base, exp = decompose_power(factor)
                memo[key] = base, exp, (_sort_key(factor), self.parenthesize(factor, level, strict=False))
        return memo[key]

    def _printed_factors(self, entry, factors, level: int) -> tuple:
        """``(sort key, printed form in a product of precedence level)`` of each of the entry's
        factors, remembered."""
        memo = self.__dict__.setdefault("_entry_texts", {})
        key = (type(entry), entry, level)
        printed = memo.get(key)
        if printed is None:
            printed = memo[key] = tuple((k, self.parenthesize(f, level, strict=False)) for k, f in factors)
        return printed

    def _entry_factors(self, entry):
        """``(coefficient, [(sort key, factor)...], powers)`` of a rational, a product of a
        rational and factors ``Mul`` keeps as they are, or one such factor, remembered; None
        for anything else (a number among the factors, a reciprocal, a factor with a precedence
        of its own, a non-commutative one)."""
        memo = self.__dict__.setdefault("_entry_forms", {})
        key = (type(entry), entry)
        if key in memo:
            return memo[key]
        form = None
        if entry.is_Rational:
            form = entry, (), {}
        else:
            own, factors = sympy.S.One, (entry,)
            if entry.is_Mul:
                own, rest = entry.as_coeff_Mul()
                factors = sympy.Mul.make_args(rest)
            powers = {}
            for factor in factors:
                if not (factor.is_Add or plain_factor(factor)) or factor.is_number or not factor.is_commutative \
                        or hasattr(factor, "precedence") or (factor.is_Pow and factor.exp.as_coeff_Mul()[0] < 0):
                    break
                base, exp = decompose_power(factor)
                if base in powers:
                    break
                powers[base] = exp
            else:
                if own.is_Rational:
                    form = own, tuple((_sort_key(f), f) for f in factors), powers
        memo[key] = form
        return form


def _first(item):
    return item[0]


class LexStrPrinter(RememberingStr, StrPrinter):
    """``sympy.sstr(expr, order="lex")``, remembering what it printed."""

    def __init__(self, settings=None):
        super().__init__({"order": "lex", **(settings or {})})


__all__ = ["LexStrPrinter", "Remembering", "RememberingStr", "ordered_terms"]
