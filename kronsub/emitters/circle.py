"""The circle state: angles integrated as points of the unit circle.

A coordinate that enters ``Mbar``, ``hbar`` and ``fbar`` (10') only through the sine and cosine
of whole multiples of it (a rod's angle, with gravity and without a torsional spring) is needed
by the right-hand side only as ``(cos q, sin q)``. Integrating that point beside ``q``,

    ``d/dt cos q = -sin q qdot``,  ``d/dt sin q = cos q qdot``,

leaves the right-hand side no sine or cosine to evaluate: every ``sin(q1 - q2)`` becomes
``sin q1 cos q2 - cos q1 sin q2`` of the state. The state is ``z = [q; qdot; cos q_c; sin q_c]``
(``q_c`` the circle coordinates in their order), so its first ``2 n`` entries are ``y``.
``cos q_c^2 + sin q_c^2`` is a first integral of the extended system (its derivative is zero
for any ``z``), held by the integrator to its tolerance like every other entry.

The equations are read off the C right-hand side's block (:func:`numeric.prepare` with guarded
angles), which already takes every sine and cosine of several coordinates from single-angle
ones: those become state entries and the guards go (there is no angle to take a small sine
from: the state carries the circle point to its rounding, as ``y`` carries ``q``).
"""
from __future__ import annotations

import sympy

from .block import Block
from .numeric import NearAxis


def _depends(block: Block, coordinates) -> dict:
    """The coordinates each temporary of ``block`` depends on, through the temporaries before it."""
    qs = set(coordinates)
    deps: dict = {}
    for name, expr in block.temporaries:
        found = set()
        for s in expr.free_symbols:
            if s in qs:
                found.add(s)
            elif s in deps:
                found |= deps[s]
        deps[name] = frozenset(found)
    return deps


def _live(temporaries, outputs) -> list:
    """The temporaries the outputs need, in their order."""
    needed = set().union(*(e.free_symbols for _, e in outputs)) if outputs else set()
    keep = []
    for name, expr in reversed(temporaries):
        if name in needed:
            keep.append((name, expr))
            needed |= expr.free_symbols
    return keep[::-1]


def circle_equations(block: Block, coordinates) -> tuple[tuple[int, ...], Block | None]:
    """The circle coordinates of ``block`` (``Mbar`` and ``fbar - hbar`` of the C right-hand
    side, its coordinates the symbols ``coordinates``; their indices) and the block rewritten
    in the circle state: ``cos(q[i])`` and ``sin(q[i])`` the symbols ``cq[k]`` and ``sq[k]``.
    ``((), None)`` when no coordinate qualifies."""
    index = {q: i for i, q in enumerate(coordinates)}
    atoms = set()
    for expr in [e for _, e in block.temporaries] + [e for _, e in block.outputs]:
        atoms |= expr.atoms(sympy.sin, sympy.cos)
    circle = sorted({index[a.args[0]] for a in atoms if a.args[0] in index})
    deps = _depends(block, coordinates)
    while circle:
        chosen = {coordinates[i] for i in circle}
        mapping = {}
        for k, i in enumerate(circle):
            mapping[sympy.cos(coordinates[i])] = sympy.Symbol(f"cq[{k}]")
            mapping[sympy.sin(coordinates[i])] = sympy.Symbol(f"sq[{k}]")

        def unguarded(angle, kind, products, again):
            reach = set()
            for s in angle.free_symbols:
                reach |= {s} if s in index else deps.get(s, set())
            return products if reach & chosen else NearAxis(angle, kind, products, again)

        def rewrite(expr):
            if expr.has(NearAxis):
                expr = expr.replace(NearAxis, unguarded)
            return expr.xreplace(mapping)

        outputs = tuple((target, rewrite(e)) for target, e in block.outputs)
        temporaries = _live([(name, rewrite(e)) for name, e in block.temporaries], outputs)
        used = set().union(*(e.free_symbols for _, e in temporaries + list(outputs)))
        kept = [i for i in circle if coordinates[i] not in used]
        if kept == circle:
            return tuple(circle), Block(tuple(temporaries), outputs)
        circle = kept  # an angle still needed as itself (a spring's, inside sqrt): not a circle one
    return (), None


__all__ = ["circle_equations"]
