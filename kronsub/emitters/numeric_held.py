"""What generated code needs to hold coordinates on configuration constraints beside velocity
constraints (:mod:`kronsub.core.held`): ``g(q, t)`` and ``G_D = dg/dq_D``, for Newton's method
on the held coordinates ``q_D`` from their integrated values at every evaluation (25), (26).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from .block import Block


@dataclass(frozen=True)
class HeldCode:
    """Sizes, the held coordinates' indices in ``q`` and the block of ``g`` and ``G_D``."""

    nh: int  # configuration constraints, one held coordinate each
    indices: tuple[int, ...]  # of the held coordinates in q
    names: tuple[str, ...]  # the held coordinates
    constraints: tuple[str, ...]  # the configuration constraints' names
    residual: Block  # g[nh], Gd[nh*nh] from t, q, pre


def held_code(system, slot, block) -> HeldCode:
    """The block, with ``slot`` mapping symbols to array entries and ``block(targets, exprs)``
    making a Block."""
    s = system.speeds
    q = list(system.coordinates)
    held = list(s.dependent)
    g = sympy.Matrix([c.expression for c in s.holonomic])
    Gd = g.jacobian(held)
    nh = len(held)
    residual = block([f"g[{a}]" for a in range(nh)] + [f"Gd[{a * nh + b}]" for a in range(nh) for b in range(nh)],
                     [slot(e) for e in g] + [slot(Gd[a, b]) for a in range(nh) for b in range(nh)])
    return HeldCode(nh=nh, indices=tuple(q.index(d) for d in held), names=tuple(d.name for d in held),
                    constraints=tuple(c.name for c in s.holonomic), residual=residual)


__all__ = ["HeldCode", "held_code"]
