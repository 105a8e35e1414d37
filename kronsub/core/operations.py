"""``sympy.count_ops``, the same number, remembered per subexpression.

Choosing the printed form of an entry (:mod:`.simplify`) weighs many candidate forms
that share most of their parts (coefficients, monomials, the insides of roots), and
``sympy.count_ops`` walks each candidate whole, building a symbolic sum of operation
names as it goes. The count is a sum over the nodes the walk visits, each node adding
what its own kind adds, so it is computed here node by node, with sympy's rules in
sympy's order, and each distinct subexpression is counted once.
``tests/test_operations.py`` checks it against ``sympy.count_ops``.
"""
from __future__ import annotations

import sympy
from sympy.core.function import Derivative
from sympy.core.operations import LatticeOp
from sympy.simplify.radsimp import fraction

S = sympy.S
LIMIT = 200_000
"""Remembered subexpressions at most; the memory is emptied when it is full."""

_counted: dict = {}


def count_ops(expr) -> int:
    """``sympy.count_ops(expr)`` (``visual=False``) for an expression; other arguments
    (lists, relations) are handed to sympy."""
    if not isinstance(expr, sympy.Expr) or expr.is_Relational:
        return sympy.count_ops(expr)
    if len(_counted) > LIMIT:
        _counted.clear()
    return _count(expr)


def _count(a) -> int:
    hit = _counted.get(a)
    if hit is None:
        hit = _counted[a] = _own(a)
    return hit


def _coeff_isneg(a) -> bool:
    """``sympy.core.function._coeff_isneg``: whether the leading number is negative (a
    rational's sign read off its numerator, not asked of a number built a moment ago)."""
    if a.is_MatMul:
        a = a.args[0]
    if a.is_Mul:
        a = a.args[0]
    if a.is_Rational:
        return a.p < 0
    return a.is_Number and a.is_extended_negative


def _whole(a) -> bool:
    """Whether ``fraction(a)`` of the product ``a`` is ``(a, 1)`` for certain: no factor a
    power or exponential (unless to a positive rational power), no non-integer rational."""
    for t in a.args:
        if t.is_Pow:
            if not (t.exp.is_Rational and t.exp.p > 0):
                return False
        elif t.is_Rational:
            if t.q != 1:
                return False
        elif isinstance(t, sympy.exp) or not t.is_commutative:
            return False
    return True


def _plain_product(args) -> bool:
    """Whether a product ``c * rest`` (``c = args[0]`` rational) is counted by `_scaled`: at
    least two factors besides ``c``, or one over a denominator (``x/2``), each whole (a
    positive power, no number, no base twice: ``fraction`` keeps it above the line and sympy
    multiplies the numerator ``|p| * rest`` back without changing it)."""
    c = args[0]
    if len(args) < 3 and not (len(args) == 2 and c.q != 1 and abs(c.p) == 1):
        return False
    bases = set()
    for t in args[1:]:
        if t.is_Pow:
            if not (t.exp.is_Rational and t.exp.p > 0):
                return False
        elif isinstance(t, sympy.exp) or not t.is_commutative or t.is_Mul:
            return False
        if _is_number(t):
            return False
        bases.add(t.base if t.is_Pow else t)
    return len(bases) == len(args) - 1  # (an unevaluated x**2*x**2 would be joined)


_numbers: dict = {}


def _is_number(t) -> bool:
    """``t.is_number``, remembered: sympy walks the whole of a sum to answer, and a large
    system's sums (the masses below a link) are factors of many entries."""
    hit = _numbers.get(t)
    if hit is None:
        if len(_numbers) > LIMIT:
            _numbers.clear()
        hit = _numbers[t] = t.is_number
    return hit


def _scaled(c, rest) -> int:
    """``_own`` of the product ``c * rest`` told by `_plain_product`, without building the
    products ``-a`` and ``fraction`` build on the way (a large system's entries are such
    products, each a distinct one): ``NEG`` for ``c < 0``, ``DIV`` for a denominator, one
    ``MUL`` between each two factors of the numerator ``|p| * rest``, and the factors."""
    p, q = abs(int(c.p)), int(c.q)
    factors = len(rest) + (p != 1)
    return int(c.p < 0) + int(q != 1) + factors - 1 + sum(_count(t) for t in rest)


def _own(a) -> int:
    """The operations ``count_ops`` records at node ``a`` plus those of the nodes it
    visits next (sympy's ``count_ops``, branch by branch)."""
    n = 0
    if a.is_Rational:
        if a is not S.One:
            return (a.p < 0) + (a.q != 1)
    elif a.is_Mul and all(t.is_number for t in a.args):
        return sympy.count_ops(a)  # a product of numbers left unevaluated: sympy's fraction() multiplies it out
    elif a.is_Mul and a.args[0].is_Rational and _plain_product(a.args):
        return _scaled(a.args[0], a.args[1:])
    elif a.is_Mul or a.is_MatMul:
        if _coeff_isneg(a):
            n += 1  # NEG
            a = a.as_two_terms()[1] if a.args[0] is S.NegativeOne else -a
        numer, denom = (a, S.One) if a.is_Mul and _whole(a) else fraction(a)
        if numer.is_Integer:
            return n + 1 + (numer.p < 0) + _count(denom)  # DIV (NEG)
        if denom is not S.One:
            return n + 1 + (0 if denom.is_Integer else _count(denom)) + _count(numer)
    elif a.is_Add or a.is_MatAdd:
        terms = a.args
        negative = 0
        for term in terms:
            if _coeff_isneg(term):
                negative += 1
                n += _count(-term)
            else:
                n += _count(term)
        # one ADD or SUB per join; all terms negative: one NEG more
        return n + len(terms) - 1 + (negative == len(terms))
    if a.is_Pow and a.exp is S.NegativeOne:
        return n + 1 + _count(a.base)  # DIV
    if a is S.Exp1:
        return n + 1
    if a.is_Pow and a.base is S.Exp1:
        return n + 1 + _count(a.exp)
    if a.is_Mul or isinstance(a, LatticeOp):
        n += len(a.args) - 1
    elif a.args and (a.is_Pow or a.is_Function or isinstance(a, (Derivative, sympy.Integral, sympy.Sum))):
        n += 1
    if not a.is_Symbol:
        for arg in a.args:
            n += _count(arg)
    return n


__all__ = ["LIMIT", "S", "count_ops"]
