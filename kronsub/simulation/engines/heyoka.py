"""The engine of ``heyoka``: heyoka's Taylor integrator (optional extra, :mod:`..heyoka_backend`)."""
from __future__ import annotations


from ..grid import chunk_ranges
from ..rows import Block, SimulationError

__all__ = ["blocks"]


def blocks(run, system, param, y0, grid, tol, chunks: int):
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
