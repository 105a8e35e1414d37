"""The engine of ``taylor``: a Taylor integrator generated as C for the model (:mod:`..taylor_c`)."""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from ...core.known_system import KnownSystem
from ..failure import at_configuration, not_finite
from ..grid import Grid, chunk_ranges
from ..methods import Method
from ..native import NativeError
from ..rows import RunInProgress, SimulationError
from .interface import Problem, ProgressBar, Rows, Steps, Timed

if TYPE_CHECKING:
    from ..taylor_c import TaylorC

__all__ = ["COMPILED_RHS", "EVENTS", "TaylorRunner", "blocks", "final_state", "runner"]

COMPILED_RHS = False
EVENTS = False


class TaylorRunner:
    """The Taylor integrator generated as C for the problem's system (:class:`.interface.Runner`),
    built once, compiled once per order."""

    def __init__(self, problem: Problem, method: Method):
        self.problem, self.method = problem, method
        self.taylor: TaylorC | None = None
        self.why = None
        self.backend = "C"

    def unavailable(self) -> str:
        from ..taylor_c import TaylorC, TaylorUnavailable

        if self.why is None:
            try:
                self.taylor, self.why = TaylorC(self.problem.system), ""
            except (NativeError, TaylorUnavailable) as exc:
                self.why = str(exc).splitlines()[0]
        return self.why

    def blocks(self, run: RunInProgress, grid: Grid, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        return blocks(run, self.problem.system, self.problem.param, y0, grid, steps.rtol, steps.chunks)

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        from ..taylor_c import order_for

        taylor, param = self.taylor, self.problem.param
        t0 = time.perf_counter()
        taylor.build(order_for(tol))  # one library per order, compiled apart from the timing
        return Timed(lambda: final_state(taylor, param, y0, t_end, tol), time.perf_counter() - t0)

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError("taylor runs explicit equations only: no closed loop to trace")


def runner(problem: Problem, method: Method) -> TaylorRunner:
    return TaylorRunner(problem, method)


def blocks(run: RunInProgress, system: KnownSystem, param: np.ndarray, y0: np.ndarray, grid: Grid, tol: float,
           chunks: int) -> Rows:
    from ..taylor_c import TaylorC, TaylorUnavailable, order_for

    try:
        integrator = TaylorC(system)
        integrator.build(order_for(tol))
    except (TaylorUnavailable, NativeError) as exc:
        raise SimulationError(str(exc)) from None
    except ValueError as exc:
        raise SimulationError(f"--rtol: {exc}") from None
    stats = run.stats = {"steps": 0, "order": order_for(tol)}
    y, first = y0, True
    for a, b in chunk_ranges(grid, chunks) if len(grid) > 1 else [(0, 0)]:
        times = grid[a:b + 1]
        t, Y, complete, message = integrator.solve(param, y, times, tol)
        stats["steps"] += integrator.last_steps
        start = 0 if first else 1  # a chunk starts on the last row of the one before
        if len(t) > start:
            yield t[start:], Y[start:]
        if not complete:
            last = Y[-1] if len(Y) else y
            if np.all(np.isfinite(last)):  # from the last row: an overflow, or a function outside its domain
                message = not_finite(system, t[-1] if len(t) else times[0], last, param, message)
            run.stop(message + at_configuration(system, Y[-1] if len(Y) else None),
                     float(t[-1]) if len(t) else float(times[0]),
                     y_fail=last)
            return
        y, first = Y[-1], False


def final_state(taylor: TaylorC, param: np.ndarray, y0: np.ndarray, t_end: float,
                tol: float) -> tuple[np.ndarray, None, int, str]:
    """One run of the Taylor integrator ``taylor`` (:class:`..taylor_c.TaylorC`, built at the
    order for ``tol``) from t = 0 to ``t_end``: ``(y_end, None, steps, status)`` (it does not
    count evaluations; status '' when it got there)."""
    y_end, status, steps, order = taylor.integrate(param, y0, t_end, tol)
    return y_end, None, steps, "" if status == 0 else f"Taylor status {status}"
