"""Sympy expressions built straight in canonical form, without sympy re-simplifying them.

The algebra's terms are already collected (distinct monomials, distinct trigonometric
keys), so what sympy's ``Add`` and ``Mul`` would do on construction reduces to sorting
the arguments. These builders do just that and fall back to sympy's own construction
whenever its rules could do more (numbers, repeated bases, nested products, the
``2*(a + b)`` distribution), so the result is the very expression sympy would build:
printed output stays byte-identical, only cheaper to make.

sympy imports two modules only when it first flattens a sum (``sympy.tensor.tensor``, 75 ms)
and first evaluates a sine or cosine (``sympy.sets.setexpr``); they are imported here, with
sympy itself, so the first derivation of a process does not pay for them midway.
"""
from __future__ import annotations

import functools

import sympy
import sympy.sets.setexpr  # noqa: F401
import sympy.tensor.tensor  # noqa: F401
from sympy.polys.domains import ZZ
from sympy.polys.matrices import DomainMatrix

from .sympy_internals import (add_from_args, args_sortkey, basic_new, hashable_content, matrix_from_dod,
                              matrix_fromrep, matrix_new, mul_from_args, ordering_of_classes)

_ONE, _ZERO = sympy.S.One, sympy.S.Zero


def plain_factor(factor: sympy.Expr) -> bool:
    """A factor ``Mul`` keeps as it is: a symbol, a function value, or a power of one,
    or a power of a sum with a non-unit exponent."""
    if factor.is_Pow:
        base, exp = factor.args
        return exp.is_Rational and (_atomic(base) or base.is_Add)
    return _atomic(factor)


def _atomic(factor: sympy.Expr) -> bool:
    """A symbol or a function value other than ``exp`` (which ``Mul`` treats as a power)."""
    return factor.is_Symbol or (isinstance(factor, sympy.Function) and factor.func is not sympy.exp)


@functools.lru_cache(maxsize=None)
def _nargs(cls: type) -> sympy.Set:
    """The ``nargs`` set sympy gives every value of ``cls`` (made once, not per value)."""
    return cls(*[sympy.Dummy() for _ in range(min(cls.nargs) if isinstance(cls.nargs, sympy.FiniteSet)
                                                else 1)], evaluate=False).nargs


def function(cls: type, *args: sympy.Expr) -> sympy.Expr:
    """``cls(*args, evaluate=False)`` for a sympy ``Function`` class: the same object, built
    without sympy remaking the set of admitted argument counts for every value (a hundred
    microseconds each)."""
    value = basic_new(cls, *args)
    value.nargs = _nargs(cls)
    return value


def matrix(rows: int, cols: int, entries: list, cls: type = sympy.Matrix) -> sympy.MatrixBase:
    """``cls(rows, cols, entries)`` from a row-major list of sympy expressions: the same
    matrix, built as sympy builds it (``RepMatrix._flat_list_to_DomainMatrix``) but asking
    ``!= 0`` only of numbers, where any other expression is nonzero already by its kind
    (a twentieth of the time of ``M[i, j] = ...`` entry by entry)."""
    if len(entries) != rows * cols:
        raise ValueError(f"{len(entries)} entries for a {rows} x {cols} matrix")
    if not all(isinstance(e, sympy.Expr) for e in entries):
        return matrix_new(cls, rows, cols, list(entries))
    dod: dict[int, dict[int, sympy.Expr]] = {}
    for n, e in enumerate(entries):
        if nonzero(e):
            i, j = divmod(n, cols)
            dod.setdefault(i, {})[j] = e
    return matrix_from_dod(cls, rows, cols, dod, set(map(type, entries)))


def ones_at(rows: int, cols: int, columns: list[int]) -> sympy.Matrix:
    """The ``rows x cols`` matrix with a 1 in column ``columns[i]`` of each row ``i`` and zeros
    elsewhere (a renaming's ``C``): the same matrix :func:`matrix` makes of those integers."""
    return matrix_fromrep(sympy.Matrix, DomainMatrix({i: {j: ZZ(1)} for i, j in enumerate(columns)}, (rows, cols), ZZ))


class _Unkeyed(Exception):
    """An expression whose canonical order the tuple key does not reproduce."""


@functools.lru_cache(maxsize=None)
def _class_key(cls: type) -> tuple:
    """The class part of ``Basic.compare``: the place in sympy's ``ordering_of_classes``,
    then the name (``_cmp_name``)."""
    order = ordering_of_classes
    unknown = len(order) + 1
    name = cls.__name__
    return (order.index(name) if name in order else unknown, name if name not in order else "")


@functools.lru_cache(maxsize=1 << 17)
def order_key(expr: sympy.Basic) -> tuple:
    """A tuple that sorts as ``Basic.compare`` does: class, length of the hashable content,
    then its items, recursively (computed once per expression, compared in C)."""
    content = hashable_content(expr)
    items = []
    for item in content:
        if isinstance(item, sympy.Basic):
            items.append(order_key(item))
        elif isinstance(item, (frozenset, set)):
            raise _Unkeyed
        else:
            items.append(item)
    return (_class_key(type(expr)), len(content), tuple(items))


def _sorted(args: list[sympy.Expr]) -> list[sympy.Expr]:
    """``args`` in sympy's canonical order (``_args_sortkey``), by `order_key` when it applies."""
    try:
        return sorted(args, key=order_key)
    except (_Unkeyed, TypeError):
        return sorted(args, key=args_sortkey)


def mul(coefficient: sympy.Rational, factors: list[sympy.Expr]) -> sympy.Expr:
    """``coefficient * prod(factors)`` as ``sympy.Mul`` would build it."""
    if coefficient == 0:
        return _ZERO
    if not factors:
        return coefficient
    bases = set()
    for f in factors:
        if f.is_Add:
            base = f
        elif plain_factor(f):
            base = f.base if f.is_Pow else f
        else:
            return sympy.Mul(coefficient, *factors)
        if base in bases:
            return sympy.Mul(coefficient, *factors)
        bases.add(base)
    if len(factors) == 1 and coefficient == 1:
        return factors[0]
    if len(factors) == 1 and factors[0].is_Add:
        return sympy.Mul(coefficient, *factors)  # the 2*(a + b) distribution
    args = _sorted(factors)
    if coefficient != 1:
        args.insert(0, coefficient)
    return mul_from_args(args)


def nonzero(e: sympy.Expr) -> bool:
    """``e != 0``, asked of a number only: any other expression is nonzero by its kind."""
    return e is not _ZERO and (not e.is_Number or e != 0)


def total(terms) -> sympy.Expr:
    """``sympy.Add(*terms)``, without sympy's cache lookup for no term or one: a large term
    read from the known-system cache would be compared there node by node with an equal
    one sympy holds."""
    terms = list(terms)
    if not terms:
        return _ZERO
    return terms[0] if len(terms) == 1 else sympy.Add(*terms)


def add(terms: list[sympy.Expr]) -> sympy.Expr:
    """The sum of ``terms`` as ``sympy.Add`` would build it, for terms whose non-numeric
    parts are distinct (collected like terms); nested sums are flattened first."""
    flat: list[sympy.Expr] = []
    number = _ZERO
    for t in terms:
        for u in (t.args if t.is_Add else (t,)):
            if u.is_Number:
                number += u
            else:
                flat.append(u)
    if not flat:
        return number
    seen = set()
    for u in flat:
        key = u.as_coeff_Mul()[1]
        if key in seen or not u.is_commutative:
            return sympy.Add(*terms)
        seen.add(key)
    if len(flat) == 1 and number == 0:
        return flat[0]
    flat = _sorted(flat)
    if number != 0:
        flat.insert(0, number)
    return add_from_args(flat)


__all__ = ["add", "function", "matrix", "mul", "nonzero", "ones_at", "order_key", "plain_factor", "total"]
