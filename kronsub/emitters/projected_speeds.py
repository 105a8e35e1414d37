"""The projection onto the speeds kept in the generated code: ``C``, ``Cdot u + ddot``, ``Mbar``
and ``fbar - hbar`` formed at run time, for a system under velocity constraints.

With configuration constraints ``g(x, t) = 0`` (25), velocity constraints
``A(x) xdot + b(x, t) = 0`` and the speeds ``u = Y(x) xdot``, the coordinates' rates solve

    S xdot = r0 + [0; u],   S = [G; A; Y],   r0 = [-dg/dt; -b; 0],   G = dg/dx
    xdot = w = C u + d,     S C = [0; I]
    S (Cdot u + ddot) = -rho'

``rho = S xdot - r0`` being the rows ``G xdot + dg/dt``, ``A xdot + b`` (as made) and ``Y xdot``,
and ``rho'`` their rate along the motion at ``xdot = w`` with ``xddot = 0``
(``sum_k d rho/dx_k w_k + d rho/dt``). Then, Boltzmann-Hamel,

    Mbar = C^T M C                                  (9'), (D)
    fbar - hbar = C^T (f - M (Cdot u + ddot) - h)   (E), (F)

with ``M``, ``h``, ``f`` in ``x`` formed at ``xdot = w`` from the primitive's short pieces
(:mod:`.projected`: ``M = J^T W J`` over the transition ``J = dx_p/dx``). The generated code
evaluates ``S``, ``r0`` and ``rho'`` from short expressions (blocks ``frame`` and
``frame_rates``, in the coordinates ``q`` and the velocities ``qd = xdot``) and solves by an LU
with partial pivoting: the symbolic projection, whose solve of ``[A; Y]`` multiplies long entries,
is never made.

Which systems take this route by themselves is decided by
:func:`~kronsub.core.projection_work.projected_in_numbers` (the projection work, from
``NUMERIC_FROM``), the one criterion the printed report and the numpy route share.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import sympy

from ..core.derivative import derivative, where_defined
from ..core.known_system import KnownSystem
from ..core.linearize_numerics import LinearizationError
from ..core.nonholonomic_linearize import frame_matrix, velocity_rows
from ..core.rheonomic import depends_on_time
from ..core.symbols import TIME, velocity_symbol
from ..errors import KronsubError
from .block import Block
from .projected import ProjectedCode, projected_code

def applies(system: KnownSystem) -> bool:
    """Whether the projection onto the speeds can be kept for run time: a system in its speeds
    whose ``M``, ``h``, ``f`` in ``x`` come from a transition (no implicit subspace, no connection
    in time, every effect acting on the primitive)."""
    tr = system.transition
    return (system.speeds is not None and tr is not None and system.implicit is None and not tr.direct_effects
            and set(tr.primitive_forces) == set(system.effect_forces) and len(tr.primitive_coordinates) > 0
            and tr.transformation.shape == (len(tr.primitive_coordinates), len(system.coordinates))
            and not depends_on_time(dict(tr.connection)))


@dataclass(frozen=True)
class FrameEquations:
    """The pieces of the run-time projection as expressions: ``S`` (n x n) and ``r0`` in ``x``, ``t``;
    ``rates``, ``rho'`` in ``x``, ``xdot``, ``t``; ``metric``, ``M = J^T W J`` in ``x`` and ``forces``,
    ``f - h`` in ``x``, ``xdot``, ``t`` (sums of products over the transition, not expanded)."""

    S: sympy.Matrix
    r0: sympy.Matrix
    rates: sympy.Matrix
    metric: sympy.Matrix
    forces: sympy.Matrix


def _frame(system: KnownSystem) -> tuple[sympy.Matrix, sympy.Matrix, sympy.Matrix]:
    """``S``, ``r0`` and ``rho'`` of ``system`` (:func:`applies`)."""
    s = system.speeds
    x = list(system.coordinates)
    n = len(x)
    xd = [velocity_symbol(q) for q in x]
    g = sympy.Matrix([c.expression for c in s.holonomic]) if s.holonomic else sympy.zeros(0, 1)
    rows = velocity_rows(system)
    try:
        S, r0, G = frame_matrix(g, rows, [e for _, e in s.definitions], x)
    except LinearizationError as exc:
        raise KronsubError(f"cannot generate code: {exc}") from None
    dg = [where_defined(derivative(e, TIME)) for e in g]
    rho = [sympy.Add(*[G[i, k] * xd[k] for k in range(n)], dg[i]) for i in range(G.rows)] \
        + [sympy.sympify(e) for e in rows] + [e for _, e in s.definitions]
    rates = [where_defined(sympy.Add(*[derivative(e, x[k]) * xd[k] for k in range(n) if x[k] in free],
                                     derivative(e, TIME) if TIME in free else 0))
             for e in rho for free in [e.free_symbols]]
    return S, r0, sympy.Matrix(rates)


def frame_equations(system: KnownSystem) -> FrameEquations:
    """The run-time projection of ``system`` (:func:`applies`) as expressions, for a route that
    evaluates them otherwise (the high-precision reference's tape): ``M = J^T W J`` (9'), (D) and
    ``f - h = J^T (f_p - W Jdot xdot - h_p)`` (E), (F) over the transition ``J = dx_p/dx``, the
    primitive's ``W``, ``h_p``, ``f_p`` at ``x_p(x)``, ``xdot_p = J xdot``."""
    S, r0, rates = _frame(system)
    tr = system.transition
    x = list(system.coordinates)
    xd = [velocity_symbol(q) for q in x]
    J = tr.transformation
    nx, n = J.shape
    images = dict(tr.connection)
    moved = {q: images[q] for q in tr.primitive_coordinates if images[q] != q}
    for a, q in enumerate(tr.primitive_coordinates):
        moved[velocity_symbol(q)] = sympy.Add(*[J[a, j] * xd[j] for j in range(n) if J[a, j] != 0])
    W = sympy.Matrix(tr.primitive_metric).xreplace(moved)
    metric = sympy.Matrix(n, n, lambda i, j: sympy.Add(*[J[a, i] * W[a, b] * J[b, j] for a in range(nx)
                                                           for b in range(nx) if J[a, i] != 0 and J[b, j] != 0
                                                           and W[a, b] != 0]))
    f = sympy.zeros(nx, 1)
    for label in sorted(tr.primitive_forces):
        f += tr.primitive_forces[label]
    h = sympy.Matrix(tr.primitive_velocity_terms)
    convective = [sympy.Add(*[derivative(J[a, j], x[k]) * xd[k] * xd[j] for j in range(n) if J[a, j] != 0
                              for k in range(n) if x[k] in J[a, j].free_symbols]) for a in range(nx)]
    w = [sympy.Add(f[a].xreplace(moved), -h[a].xreplace(moved),
                   -sympy.Add(*[W[a, b] * convective[b] for b in range(nx) if W[a, b] != 0])) for a in range(nx)]
    forces = sympy.Matrix([sympy.Add(*[J[a, i] * w[a] for a in range(nx) if J[a, i] != 0]) for i in range(n)])
    return FrameEquations(S=S, r0=r0, rates=rates, metric=metric, forces=forces)


@dataclass(frozen=True)
class FrameCode:
    """The run-time projection onto the speeds: ``frame`` writes ``S`` (``S[n n]``, row-major) and
    ``r0`` (``r0[n]``), their entries not zero, from ``t``, ``q``; ``rates`` writes ``rho'``
    (``e[n]``) from ``t``, ``q``, ``qd = xdot``; ``metric`` is ``M``, ``h``, ``f`` in ``x`` from the
    primitive (:class:`.projected.ProjectedCode`, at ``qd = xdot``); ``timed``: ``r0`` or
    ``rho'`` name ``t`` (``d(x, t)``: ``hbar`` depends on ``t``)."""

    n: int
    p: int
    frame: Block
    rates: Block
    metric: ProjectedCode
    timed: bool


def frame_code(system: KnownSystem, slot: Callable, constants: Callable,
               block: Callable[[list[str], list[sympy.Expr]], Block]) -> FrameCode:
    """The run-time projection onto the speeds of ``system`` (:func:`applies`): ``slot`` maps the
    coordinates, their velocities and ``t`` to array slots, ``constants`` moves parameter products
    to ``pre``, ``block`` eliminates common subexpressions."""
    S, r0, rates = _frame(system)
    n, p = len(system.coordinates), len(system.speeds.speeds)
    targets, exprs = [], []
    for i in range(n):
        for j in range(n):
            if S[i, j] != 0:
                targets.append(f"S[{i * n + j}]")
                exprs.append(constants(slot(S[i, j])))
    for i, e in enumerate(r0):
        if e != 0:
            targets.append(f"r0[{i}]")
            exprs.append(constants(slot(e)))
    frame = block(targets, exprs)
    rate_block = block([f"e[{i}]" for i in range(n)], [constants(slot(e)) for e in rates])
    timed = any(TIME in sympy.sympify(e).free_symbols for e in list(r0) + list(rates))
    metric = projected_code(system, slot, constants, block, kinetic=False)  # no canonical form in the speeds
    return FrameCode(n=n, p=p, frame=frame, rates=rate_block, metric=metric, timed=timed)


__all__ = ["FrameCode", "FrameEquations", "applies", "frame_code", "frame_equations"]
