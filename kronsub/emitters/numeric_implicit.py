"""What generated code needs to evaluate the named intermediates of implicit constraints.

``w = [y_d; Lambda (row-major); gamma]`` at a state (Hoffmann (26)-(28)): ``y_d`` by
Newton's method on ``g(q, y_d) = 0`` from the last solution (warm start; the first guess
is the branch of the initial configuration), or from its closed form on that branch;
then ``G_d Lambda = -G_i`` and ``G_d gamma = quadratic``, one factorization of ``G_d``.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy

from .block import Block


@dataclass(frozen=True)
class ImplicitCode:
    """Sizes, the branch and the blocks of the dependent-coordinate solve."""

    nd: int  # dependent coordinates
    nw: int  # nd + nd*n + nd
    dependent: tuple[str, ...]
    constraints: tuple[str, ...]
    branch: tuple[float, ...]
    closed: bool  # every dependent coordinate has a closed form
    closed_form: Block  # w[0:nd] from q, param
    residual: Block  # g[nd], Gd[nd*nd] from q, w, param
    sensitivity: Block  # Gi[nd*n] from q, w, param
    quadratic: Block  # c[nd] from q, qd, w, param


def intermediate_slots(system) -> dict:
    """``y_d -> w[i]``, ``lambda -> w[nd + ...]``, ``gamma -> w[nd + nd n + ...]``."""
    imp = system.implicit
    return {s: sympy.Symbol(f"w[{i}]") for i, s in enumerate(imp.intermediates)}


def implicit_code(system, slot, block) -> ImplicitCode:
    """The blocks, with ``slot`` mapping symbols to array entries and ``block`` making a Block."""
    imp = system.implicit
    nd, n = len(imp.dependent), len(imp.independent)
    g = sympy.Matrix([c.expression for c in imp.constraints])
    gd, gi = imp.jacobian_dependent, imp.jacobian_independent
    closed = dict(imp.closed_form)
    all_closed = nd > 0 and all(d in closed for d in imp.dependent)
    qs = ()
    closed_block = block([f"w[{i}]" for i in range(nd)],
                         [slot(closed[d]) if d in closed else sympy.Integer(0) for d in imp.dependent], qs)
    residual = block([f"g[{a}]" for a in range(nd)] + [f"Gd[{a * nd + b}]" for a in range(nd) for b in range(nd)],
                     [slot(e) for e in g] + [slot(gd[a, b]) for a in range(nd) for b in range(nd)], qs)
    sensitivity = block([f"Gi[{a * n + j}]" for a in range(nd) for j in range(n)],
                        [slot(gi[a, j]) for a in range(nd) for j in range(n)], qs)
    quadratic = block([f"c[{a}]" for a in range(nd)], [slot(e) for e in imp.quadratic], qs)
    branch = dict(imp.branch)
    return ImplicitCode(nd=nd, nw=len(imp.intermediates), dependent=tuple(d.name for d in imp.dependent),
                        constraints=tuple(c.name for c in imp.constraints),
                        branch=tuple(float(branch.get(d, 0.0)) for d in imp.dependent), closed=all_closed,
                        closed_form=closed_block, residual=residual, sensitivity=sensitivity, quadratic=quadratic)


__all__ = ["ImplicitCode", "implicit_code", "intermediate_slots"]
