"""A block of generated code: the body of one function of the equations, as expressions."""
from __future__ import annotations

from dataclasses import dataclass

import sympy


@dataclass(frozen=True)
class Block:
    """A function body: ``temporaries`` (name, expr) then ``outputs`` (target, expr)."""

    temporaries: tuple[tuple[sympy.Symbol, sympy.Expr], ...]
    outputs: tuple[tuple[str, sympy.Expr], ...]

    def part(self, targets) -> Block:
        """The outputs to ``targets`` with the temporaries they need, in their order."""
        outputs = tuple((target, e) for target, e in self.outputs if target in targets)
        needed = set().union(*(e.free_symbols for _, e in outputs))
        kept = []
        for name, e in reversed(self.temporaries):
            if name in needed:
                kept.append((name, e))
                needed |= e.free_symbols
        return Block(tuple(kept[::-1]), outputs)


__all__ = ["Block"]
