"""The engine of ``heyoka``: heyoka's Taylor integrator (optional extra, :mod:`..heyoka_backend`)."""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from ...core.known_system import KnownSystem
from ..grid import Grid, chunk_ranges
from ..methods import Method
from ..rows import RunInProgress, SimulationError
from .interface import Problem, ProgressBar, Rows, Steps, Timed

if TYPE_CHECKING:
    from ..heyoka_backend import HeyokaIntegrator

__all__ = ["COMPILED_RHS", "EVENTS", "HeyokaRunner", "blocks", "final_state", "runner"]

COMPILED_RHS = False
EVENTS = False


class HeyokaRunner:
    """heyoka's Taylor integrator on the problem's system (:class:`.interface.Runner`), built
    per tolerance."""

    def __init__(self, problem: Problem, method: Method):
        self.problem, self.method = problem, method
        self.backend = "heyoka"

    def unavailable(self) -> str:
        from .. import heyoka_backend

        return "" if heyoka_backend.available() else f"heyoka is not installed ({heyoka_backend.INSTALL_HINT})"

    def blocks(self, run: RunInProgress, grid: Grid, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        return blocks(run, self.problem.system, self.problem.param, y0, grid, steps.rtol, steps.chunks)

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        from ..heyoka_backend import HeyokaIntegrator

        t0 = time.perf_counter()
        integrator = HeyokaIntegrator(self.problem.system, tol)
        seconds = time.perf_counter() - t0
        param, grid = self.problem.param, np.array([0.0, t_end])
        return Timed(lambda: final_state(integrator, param, y0, grid), seconds)

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError("heyoka runs explicit equations only: no closed loop to trace")


def runner(problem: Problem, method: Method) -> HeyokaRunner:
    return HeyokaRunner(problem, method)


def blocks(run: RunInProgress, system: KnownSystem, param: np.ndarray, y0: np.ndarray, grid: Grid, tol: float,
           chunks: int) -> Rows:
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
            yield t[start:], Y[start:]
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
