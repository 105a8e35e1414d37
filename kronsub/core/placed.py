"""A derived system's points and bodies, placed at ``x(xbar)`` when they are first read.

``Mbar``, ``hbar`` and ``fbar`` (D), (E), (F) need neither; the energies, the animation, a
scene's outputs, the cache and the next model do. A chain's link ends are sums over every
link above, and a rod's rotation ``cos(q - pi/2)`` costs sympy milliseconds: building them
only when read keeps them out of a derivation that does not use them.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import sympy

from ..components.base import Body, in_world


class Placer:
    """Moves a position or a rotation to ``x(xbar)``: ``x -> x(xbar)`` is all that moves either
    (`Subspace.placement`), so the subspace itself is not kept."""

    def __init__(self, placement: dict, dimension: int):
        self.placement = placement
        self.dimension = dimension

    def position(self, pos: tuple) -> tuple:
        return self.in_world(tuple(self.expr(c) for c in pos))

    def in_world(self, moved: tuple) -> tuple:
        """A point of a line, in a system that also has parts in the plane: ``(x, 0)``."""
        return in_world(moved, self.dimension) if self.dimension == 2 else moved

    def expr(self, e) -> sympy.Expr:
        e = sympy.sympify(e)
        return e.xreplace(self.placement) if self.placement else e

    def matrix(self, m: sympy.MatrixBase) -> sympy.MatrixBase:
        return m.xreplace(self.placement) if self.placement else m


class _PlacedOnRead:
    """Items of a derived system placed at ``x(xbar)`` when first read, each once."""

    def __init__(self, unplaced, placer: Placer):
        self._unplaced = unplaced
        self._placer = placer
        self._placed: dict = {}

    @property
    def unplaced(self):
        """The items where the primitive has them, before they are placed."""
        return self._unplaced

    def place(self, key, item) -> None:
        """Give ``key`` its placed item now."""
        self._placed[key] = item

    def _item(self, key):
        hit = self._placed.get(key)
        if hit is None:
            hit = self._placed[key] = self._placing(self._unplaced[key])
        return hit

    def _placing(self, item):
        raise NotImplementedError


class PlacedPoints(_PlacedOnRead, Mapping):
    """A derived system's named points, each placed at ``x(xbar)`` when it is first read.

    A long chain's link ends are sums over every link above, which sympy rebuilds term by
    term; ``Mbar``, ``hbar`` and ``fbar`` do not need them, the energies, the animation, a
    scene's outputs and the next model do."""

    def _placing(self, position: tuple) -> tuple:
        return self._placer.position(position)

    def __getitem__(self, label: str) -> tuple:
        return self._item(label)

    def __iter__(self):
        return iter(self._unplaced)

    def __len__(self) -> int:
        return len(self._unplaced)

    def __repr__(self) -> str:
        return f"PlacedPoints({dict(self)!r})"


class PlacedBodies(_PlacedOnRead, Sequence):
    """A derived system's bodies, each placed at ``x(xbar)`` when it is first read: a rod's
    rotation ``cos(q - pi/2)`` costs sympy milliseconds to evaluate, and the equations of
    motion do not need it (energies, torques on a body and the next model do)."""

    def _placing(self, body: Body) -> Body:
        return dataclasses.replace(body, centre=self._placer.position(body.centre),
                                   rotation=None if body.rotation is None else self._placer.matrix(body.rotation))

    def __getitem__(self, i):
        if isinstance(i, slice):
            return tuple(self._item(k) for k in range(len(self._unplaced))[i])
        return self._item(range(len(self._unplaced))[i])

    def __len__(self) -> int:
        return len(self._unplaced)

    def __eq__(self, other) -> bool:
        if isinstance(other, Sequence) and not isinstance(other, (str, bytes)):
            return tuple(self) == tuple(other)
        return NotImplemented

    __hash__ = None

    def __repr__(self) -> str:
        return f"PlacedBodies({tuple(self)!r})"


__all__ = ["PlacedBodies", "PlacedPoints", "Placer"]
