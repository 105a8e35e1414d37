"""The engine of ``heyoka``: heyoka's Taylor integrator (optional extra, :mod:`..heyoka_backend`)."""
from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from ...core.known_system import KnownSystem
from ..grid import Grid, chunk_ranges
from ..rows import Block, Run, SimulationError

if TYPE_CHECKING:
    from ..heyoka_backend import HeyokaIntegrator

__all__ = ["blocks", "final_state"]


def blocks(run: Run, system: KnownSystem, param: np.ndarray, y0: np.ndarray, grid: Grid, tol: float,
           chunks: int) -> Iterator[Block]:
    try:
        from .. import heyoka_backend
    except ImportError:
        heyoka_backend = None
    if heyoka_backend is None or not heyoka_backend.available():
        raise SimulationError("method 'heyoka' needs heyoka: pip install 'kronsub[heyoka]'")
    integrator = heyoka_backend.HeyokaIntegrator(system, tol)
    y, first = y0, True
    for a, b in chunk_ranges(grid, chunks) if len(grid) > 1 else [(0, 0)]:
        times = grid[a:b + 1]
        t, Y, complete, message = integrator.run(param, y, times)
        start = 0 if first else 1  # a chunk starts on the last row of the one before
        if len(t) > start:
            yield Block(t[start:], Y[start:])
        if not complete:
            run.stop(message, float(t[-1]) if len(t) else float(times[0]))
            return
        y, first = Y[-1], False


def final_state(integrator: HeyokaIntegrator, param: np.ndarray, y0: np.ndarray,
                grid: np.ndarray) -> tuple[np.ndarray, None, int, str]:
    """One run of heyoka's ``integrator`` (:class:`..heyoka_backend.HeyokaIntegrator`) over
    ``grid = [0, t_end]``: ``(y_end, None, steps, status)`` (status '' when it got there)."""
    integrator.start(0.0, y0, param)
    outcome, _, _, steps, _, Y = integrator.ta.propagate_grid(grid)
    ok = outcome == integrator.finished
    return np.asarray(Y)[-1], None, int(steps), "" if ok else f"heyoka outcome {outcome.name}"
