"""The one place symbols are made, so the same name always means the same symbol."""
from __future__ import annotations

import sympy

TIME = sympy.Symbol("t", real=True)


def symbol(name: str) -> sympy.Symbol:
    """A parameter or coordinate symbol (real)."""
    return sympy.Symbol(name, real=True)


def velocity_symbol(coordinate: sympy.Symbol) -> sympy.Symbol:
    """The velocity of a coordinate is named ``<coordinate>_dot``."""
    return sympy.Symbol(f"{coordinate.name}_dot", real=True)


def acceleration_symbol(coordinate: sympy.Symbol) -> sympy.Symbol:
    """The acceleration of a coordinate is named ``<coordinate>_ddot``."""
    return sympy.Symbol(f"{coordinate.name}_ddot", real=True)
