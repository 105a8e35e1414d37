"""The output grid of a run (0, dt, 2 dt, ..., t_end) and how an engine walks it: chunks, the
pieces of a fixed-step method's steps, the times not yet written."""
from __future__ import annotations

import math

import numpy as np



__all__ = ["MERGE", "Grid", "Cursor", "chunk_ranges", "fixed_pieces", "aligned_pieces", "integrated_pieces", "Tail"]


MERGE = 1e-7
"""A multiple of ``dt`` within ``MERGE dt`` of ``t_end`` is ``t_end`` itself (as in the C integrators'
``output_time``): no two rows are closer than that."""


class Grid:
    """Output times 0, dt, 2 dt, ... and exactly t_end, made a slice at a time.

    When ``dt`` is a short decimal ``m / 10**k`` (as ``repr`` writes it), the k-th time is the
    double nearest to the decimal ``k m / 10**k`` (``0.03``, not ``3 * 0.01 = 0.030000000000000002``),
    so times print in their short form; :meth:`snap` puts an integrator's own times on the grid."""

    def __init__(self, t_end: float, dt: float):
        self.t_end, self.dt = t_end, dt
        # every multiple of dt before t_end (one within MERGE dt of it is t_end), then t_end: the
        # rows the C integrators' dense output writes, whatever the remainder
        n = math.ceil(t_end / dt - MERGE) + 1
        self.n = max(n, 2)  # a run always starts at 0 (also when dt > t_end)
        self.decimal = _decimal(dt, self.n)
        # the closest two rows: dt, or less from the last multiple of dt to t_end
        self.spacing = min(dt, t_end - float(self._times(np.array([self.n - 2.0]))[0]))

    def __len__(self) -> int:
        return self.n

    def _times(self, index: np.ndarray) -> np.ndarray:
        if self.decimal is None:
            return index * self.dt
        m, scale = self.decimal  # index * m < 2**53: exact; the division rounds once
        return (index * float(m)) / scale

    def __getitem__(self, index):
        if isinstance(index, slice):
            a, b, _ = index.indices(self.n)
            times = self._times(np.arange(a, b, dtype=float))
            if b == self.n and b > a:
                times[-1] = self.t_end
            return times
        i = index + self.n if index < 0 else index
        return self.t_end if i == self.n - 1 else float(self._times(np.array([float(i)]))[0])

    def snap(self, t: np.ndarray) -> np.ndarray:
        """Times within a millionth of the rows' spacing of a grid time replaced by that grid time
        (the last rows may be closer than ``dt``: ``t_end`` is not a multiple of ``dt``, or below it)."""
        t = np.asarray(t, dtype=float)
        last = self.n - 1
        k = np.clip(np.rint(t / self.dt), 0, last)
        grid = self._times(k)
        grid[k == last] = self.t_end
        end = np.abs(t - self.t_end) < np.abs(t - grid)
        k, grid = np.where(end, last, k), np.where(end, self.t_end, grid)
        spacing = np.where(k >= last - 1, self.spacing, self.dt)
        return np.where(np.abs(t - grid) <= 1e-6 * spacing, grid, t)


def _decimal(dt: float, n: int) -> tuple[int, float] | None:
    """``(m, 10.0**k)`` with ``repr(dt)`` the decimal ``m / 10**k``, when ``n m < 2**53`` (the
    grid times are then correctly rounded decimals); else None."""
    from decimal import Decimal

    sign, digits, exponent = Decimal(repr(float(dt))).as_tuple()
    if not isinstance(exponent, int) or exponent > 0 or -exponent > 22:
        return None
    m = int("".join(map(str, digits)))
    return (m, float(10 ** -exponent)) if n * m < 2**53 else None


class Cursor:
    """The output times not yet written, read from the grid a block at a time."""

    BLOCK = 4096

    def __init__(self, grid):
        self.grid, self.i, self.start = grid, 1, 1
        self.block = grid[1:min(1 + self.BLOCK, len(grid))]

    def done(self) -> bool:
        return self.i >= len(self.grid)

    def upto(self, t: float) -> np.ndarray:
        """The times ``<= t`` not yet taken, now taken."""
        out = []
        while self.i < len(self.grid):
            k = self.i - self.start
            if k >= len(self.block):
                self.start = self.i
                self.block = self.grid[self.i:min(self.i + self.BLOCK, len(self.grid))]
                continue
            j = int(np.searchsorted(self.block, t, side="right"))
            if j > k:
                out.append(self.block[k:j])
                self.i += j - k
            if j < len(self.block):
                break
        return np.concatenate(out) if out else np.empty(0)


def chunk_ranges(grid, count: int):
    """Index ranges of the output grid, one per chunk (distinct edges sorted in Python: ``np.unique``
    would import ``numpy.ma`` into every run)."""
    edges = sorted({int(e) for e in np.linspace(0, len(grid) - 1, min(count, len(grid) - 1) + 1)})
    return list(zip(edges[:-1], edges[1:]))


def fixed_pieces(t0: float, t1: float, dt: float) -> list[tuple[float, float]]:
    """``t0 .. t1`` cut at multiples of ``dt`` (counted from t = 0) for a fixed-step method: whole
    steps of ``dt`` between them, a shorter step only up to the first multiple (a run going on
    after a switch of coordinates) and from the last one to ``t1`` (a ``t_end`` that is not a
    multiple), so its rows fall on the ``--dt`` grid as every other method's do."""
    tiny = MERGE * dt
    first = math.ceil(t0 / dt - MERGE) * dt
    # past a multiple (not one itself, to rounding): cut at the last row before t1, as Grid counts them
    past = t1 / dt - math.floor(t1 / dt + 1e-9) > 1e-9
    last = (math.ceil(t1 / dt - MERGE) - 1) * dt if past else t1
    cuts = [t0] + [first] * (t0 + tiny < first < t1 - tiny) + [last] * (t0 + tiny < last < t1) + [t1]
    cuts = sorted(set(cuts))
    return list(zip(cuts[:-1], cuts[1:]))


def aligned_pieces(t0: float, t1: float, dt: float) -> list[tuple[float, float]]:
    """``t0 .. t1`` for an adaptive method, cut at the first multiple of ``dt`` after a ``t0``
    between two rows (a run going on after a switch of coordinates there): C writes its rows
    every ``dt`` from the start of a piece, so each piece must start on the grid."""
    tiny = MERGE * dt
    first = math.ceil(t0 / dt - MERGE) * dt
    return [(t0, first), (first, t1)] if t0 + tiny < first < t1 - tiny else [(t0, t1)]


def integrated_pieces(integrate, grid, y0: np.ndarray, dt: float, chunks: int, fixed: bool, stats: dict):
    """A run wholly in C, piece by piece: the grid's chunks cut as :func:`fixed_pieces` or
    :func:`aligned_pieces` cut them, ``integrate(t0, y, t1)`` -> ``(t, Y, result)`` on each from the
    last state ``y``; yields ``(t0, y, t1, t, Y, result)`` with only the rows not given before (a piece's first
    row repeats the last one), the steps, rejections, evaluations and first stiff time summed into
    ``stats``. Stop iterating at a failed piece: the next starts from its last state."""
    last, y = grid[0], y0
    for a, b in chunk_ranges(grid, chunks):
        for t0, t1 in (fixed_pieces(grid[a], grid[b], dt) if fixed else aligned_pieces(grid[a], grid[b], dt)):
            t, Y, result = integrate(t0, y, t1)
            stats["steps"] += result.n_steps
            stats["rejected"] += result.n_rejected
            stats["evaluations"] += result.n_evals
            if result.t_stiff is not None and "stiff_from" not in stats:
                stats["stiff_from"] = result.t_stiff
            keep = t > last + 1e-6 * grid.spacing
            if np.any(keep):
                last = t[keep][-1]
            yield t0, y, t1, t[keep], Y[keep], result
            y = Y[-1]


class Tail:
    """The output grid from row ``offset`` on (a run going on after a switch of coordinates),
    after a first time ``start`` between two rows when given."""

    def __init__(self, grid, offset: int, start: float | None = None):
        self.grid, self.offset, self.start = grid, offset, start
        self.shift = offset - (1 if start is not None else 0)  # tail index -> grid index
        self.t_end, self.dt = grid.t_end, grid.dt
        self.spacing = grid.spacing if start is None else min(grid.spacing, grid[offset] - start)

    def __len__(self) -> int:
        return len(self.grid) - self.shift

    def __getitem__(self, index):
        if isinstance(index, slice):
            a, b, _ = index.indices(len(self))
            if self.start is not None and a == 0 and b > 0:
                return np.concatenate([[self.start], self.grid[self.offset:b + self.shift]])
            return self.grid[a + self.shift:b + self.shift]
        i = index + len(self) if index < 0 else index
        return self.start if (self.start is not None and i == 0) else self.grid[i + self.shift]
