"""Units checked where they can be: a sum whose terms have different dimensions.

The parameters carry their units as text (``unit: V``, ``N m/A``, ``kg m^2``). Where every
factor of two terms of a sum has a known dimension (parameters with a unit this module reads,
numbers, ``t`` in seconds), the terms must have the same one: a voltage added to a force is
reported as a located warning. Coordinates and velocities have no declared unit (a charge, a
length and an angle are all coordinates), so a term that holds one is not compared; nothing
is refused on units alone, since a unit's text is free.

Dimensions are exponents of the SI base units (kg, m, s, A, K, mol, cd); radians are
dimensionless.
"""
from __future__ import annotations

import functools
import re
import warnings
from fractions import Fraction

import sympy

from ..core.symbols import TIME
from .source import excerpt

BASE = ("kg", "m", "s", "A", "K", "mol", "cd")


def _dim(**powers) -> tuple[Fraction, ...]:
    return tuple(Fraction(powers.get(b, 0)) for b in BASE)


UNITS = {
    "kg": _dim(kg=1), "g": _dim(kg=1), "m": _dim(m=1), "s": _dim(s=1), "A": _dim(A=1), "K": _dim(K=1),
    "mol": _dim(mol=1), "cd": _dim(cd=1), "rad": _dim(), "deg": _dim(), "1": _dim(), "-": _dim(),
    "N": _dim(kg=1, m=1, s=-2), "J": _dim(kg=1, m=2, s=-2), "W": _dim(kg=1, m=2, s=-3),
    "Pa": _dim(kg=1, m=-1, s=-2), "Hz": _dim(s=-1), "C": _dim(A=1, s=1),
    "V": _dim(kg=1, m=2, s=-3, A=-1), "ohm": _dim(kg=1, m=2, s=-3, A=-2), "Ohm": _dim(kg=1, m=2, s=-3, A=-2),
    "Ω": _dim(kg=1, m=2, s=-3, A=-2), "F": _dim(kg=-1, m=-2, s=4, A=2), "H": _dim(kg=1, m=2, s=-2, A=-2),
    "Wb": _dim(kg=1, m=2, s=-2, A=-1), "T": _dim(kg=1, s=-2, A=-1), "S": _dim(kg=-1, m=-2, s=3, A=2),
}
"""The unit names read (no prefixes: ``mH`` is not read, and a parameter in it is not compared)."""

_FACTOR = re.compile(r"^([^\^]+?)(?:\^(-?\d+))?$")

NAMES = {
    _dim(kg=1, m=2, s=-3, A=-1): "a voltage", _dim(kg=1, m=1, s=-2): "a force",
    _dim(kg=1, m=2, s=-2): "an energy or torque",
    _dim(A=1): "a current", _dim(A=1, s=1): "a charge", _dim(m=1): "a length", _dim(s=1): "a time",
    _dim(kg=1): "a mass", _dim(): "a number", _dim(kg=1, m=2, s=-3): "a power",
}


@functools.lru_cache(maxsize=1024)
def dimension(unit: str) -> tuple[Fraction, ...] | None:
    """The dimension of a unit's text (``N m/A``, ``kg m^2``, ``m/s^2``, ``V s/rad``), or None
    when a part of it is not read."""
    text = re.sub(r"\s*\*\*\s*", "^", unit.strip()).replace("·", " ").replace("*", " ")
    text = text.replace(" ^", "^").replace("^ ", "^")
    if not text:
        return None
    total = [Fraction(0)] * len(BASE)
    for k, part in enumerate(text.split("/")):
        if k > 1 or not part.strip() and k == 0:
            return None
        for token in part.split():
            match = _FACTOR.match(token)
            if match is None or match.group(1) not in UNITS:
                return None
            power = int(match.group(2) or 1) * (-1 if k else 1)
            total = [a + power * b for a, b in zip(total, UNITS[match.group(1)])]
    return tuple(total)


class UnitsWarning(UserWarning):
    """A sum in a model's expression whose terms have different units."""


def _describe(dim) -> str:
    return NAMES.get(dim) or " ".join(f"{b}^{p}" if p != 1 else b for b, p in zip(BASE, dim) if p) or "a number"


class _Dimensions:
    """The dimension of an expression from its parameters' units (None: not known)."""

    def __init__(self, units: dict[sympy.Symbol, tuple | None], memo: dict | None = None):
        self.units = units
        self.mismatch: tuple | None = None  # (term, its dimension, other term, its dimension)
        self.memo = {} if memo is None else memo  # e -> (dimension, the first mismatch within e)

    def __call__(self, e):
        if e.is_Atom:
            return self._dimension(e)
        hit = self.memo.get(e)
        if hit is None:
            outer, self.mismatch = self.mismatch, None
            hit = self.memo[e] = (self._dimension(e), self.mismatch)
            self.mismatch = outer
        if self.mismatch is None:
            self.mismatch = hit[1]
        return hit[0]

    def _dimension(self, e):
        if e.is_Number or e in (sympy.pi, sympy.E):
            return _dim()
        if e == TIME:
            return _dim(s=1)
        if e.is_Symbol:
            return self.units.get(e)
        if e.is_Mul:
            total = _dim()
            for a in e.args:
                d = self(a)
                if d is None:
                    return None
                total = tuple(x + y for x, y in zip(total, d))
            return total
        if e.is_Pow:
            base, exp = e.args
            d = self(base)
            if d is None or not exp.is_Rational:
                self(exp)
                return None
            return tuple(x * Fraction(int(exp.p), int(exp.q)) for x in d)
        if e.is_Add:
            known = [(a, self(a)) for a in e.args]
            known = [(a, d) for a, d in known if d is not None and not a.is_Number]
            for a, d in known[1:]:
                if d != known[0][1] and self.mismatch is None:
                    self.mismatch = (known[0][0], known[0][1], a, d)
            numbers = [a for a in e.args if a.is_Number]
            if len(known) + len(numbers) == len(e.args) and known and all(d == known[0][1] for _, d in known):
                return known[0][1]
            return None
        for a in e.args:  # a function: its arguments checked, its value a number
            self(a)
        return _dim() if isinstance(e, sympy.Function) else None


def check_units(expr: sympy.Expr, units: dict[sympy.Symbol, tuple | None], where: str,
                memo: dict | None = None) -> None:
    """Warn (:class:`UnitsWarning`, ``where`` first) when a sum in ``expr`` adds terms of
    different dimensions, each known from the parameters' units. ``memo`` (kept by the caller
    for one ``units``) remembers the subexpressions met, which the lines of a connection share."""
    finder = _Dimensions(units, memo)
    finder(expr)
    if finder.mismatch is not None:
        a, da, b, db = finder.mismatch
        a, b = (-x if x.could_extract_minus_sign() else x for x in (a, b))
        warnings.warn(UnitsWarning(
            f"{where}: the units do not match: {excerpt(str(a))} is {_describe(da)} and {excerpt(str(b))} is "
            f"{_describe(db)}, added in one sum (from the parameters' `unit:`)"), stacklevel=2)


__all__ = ["BASE", "NAMES", "UNITS", "UnitsWarning", "check_units", "dimension"]
