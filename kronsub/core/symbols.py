"""The one place symbols are made, so the same name always means the same symbol."""
from __future__ import annotations

import functools

import sympy

TIME = sympy.Symbol("t", real=True)


def symbol(name: str) -> sympy.Symbol:
    """A parameter or coordinate symbol (real)."""
    return sympy.Symbol(name, real=True)


@functools.lru_cache(maxsize=1 << 14)
def velocity_symbol(coordinate: sympy.Symbol) -> sympy.Symbol:
    """The velocity of a coordinate is named ``<coordinate>_dot`` (made once per coordinate:
    a projection asks for each velocity at every image it builds)."""
    return sympy.Symbol(f"{coordinate.name}_dot", real=True)


@functools.lru_cache(maxsize=1 << 14)
def acceleration_symbol(coordinate: sympy.Symbol) -> sympy.Symbol:
    """The acceleration of a coordinate is named ``<coordinate>_ddot``."""
    return sympy.Symbol(f"{coordinate.name}_ddot", real=True)


def free_symbols_of(exprs) -> set:
    """The free symbols of ``exprs`` (expressions or matrices), each shared subexpression
    walked once: a known system read from the cache shares its subtrees, which
    ``expr.free_symbols`` would walk again at every use."""
    found: set = set()
    seen: set[int] = set()
    stack = []
    for e in exprs:
        stack.extend(e if isinstance(e, sympy.MatrixBase) else (sympy.sympify(e),))
    while stack:
        e = stack.pop()
        if id(e) in seen:
            continue
        seen.add(id(e))
        if isinstance(e, sympy.Symbol):
            found.add(e)
        elif getattr(e, "bound_symbols", ()):  # a Lambda, Integral...: its own free symbols
            found |= e.free_symbols
        else:
            stack.extend(e.args)
    return found


__all__ = ["TIME", "acceleration_symbol", "free_symbols_of", "symbol", "velocity_symbol"]
