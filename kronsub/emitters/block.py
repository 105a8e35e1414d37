"""A block of generated code: the body of one function of the equations, as expressions."""
from __future__ import annotations

from dataclasses import dataclass

import sympy


@dataclass(frozen=True)
class Block:
    """A function body: ``temporaries`` (name, expr) then ``outputs`` (target, expr)."""

    temporaries: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    outputs: tuple[tuple[str, sympy.Expr], ...]


__all__ = ["Block"]
