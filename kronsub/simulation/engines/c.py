"""The engine of the methods wholly in C (:mod:`..native`: dop853, gauss4, rk4) on the compiled
model: blocks of rows, one per chunk of the grid; fixed-step methods step ``--dt`` at a time."""
from __future__ import annotations

import math

import numpy as np

from ..failure import at_configuration, cause_of, not_finite, rank_loss_note, real_at
from ...core.known_system import KnownSystem
from ..methods import Method
from ..native import NativeModel
from ..rows import RunInProgress
from .interface import Problem, ProgressBar, Rows, Steps, Timed
from ..grid import Grid, Tail, integrated_pieces

__all__ = ["COMPILED_RHS", "EVENTS", "CRunner", "blocks", "final_state", "runner"]

COMPILED_RHS = True
EVENTS = False


class CRunner:
    """A method wholly in C on the problem's compiled model (:class:`.interface.Runner`)."""

    def __init__(self, problem: Problem, method: Method):
        self.problem, self.method = problem, method

    @property
    def backend(self) -> str:
        return "C" if self.problem.native is not None else "numpy"

    def unavailable(self) -> str:
        return "" if self.problem.native is not None else self.problem.missing or "the model is not compiled"

    def blocks(self, run: RunInProgress, grid: Grid | Tail, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        p = self.problem
        return blocks(run, p.native, self.method, grid, y0, p.param, steps.rtol, steps.atol, steps.dt, steps.chunks,
                      bar, p.system)

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        p, method = self.problem, self.method

        def run():
            p.restart(tol)  # (a closed loop's Newton's method from y_d(0), at this tolerance)
            return final_state(p.native, method, y0, t_end, p.param, tol, h)
        return Timed(run)

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        p, method = self.problem, self.method
        p.restart(tol)
        if not method.fixed_step:
            T, Y, _ = p.native.integrate(method.name, 0.0, y0, t_end, 0.0, p.param, rtol=tol, atol=tol)
        else:  # the step of the timed run: t_end over a whole number of steps
            h = t_end / max(1, math.ceil(t_end / h - 1e-9))
            T, Y, _ = p.native.integrate(method.name, 0.0, y0, t_end, h, p.param, h=h)
        return T, Y


def runner(problem: Problem, method: Method) -> CRunner:
    return CRunner(problem, method)


def blocks(run: RunInProgress, native: NativeModel, method: Method, grid: Grid | Tail, y0: np.ndarray, param: np.ndarray,
           rtol: float, atol: float, dt: float, chunks: int, bar: ProgressBar, system: KnownSystem) -> Rows:
    """Blocks ``(t, Y)`` of a run wholly in C, one per chunk of the grid."""
    yield np.array([grid[0]]), np.array([y0])
    stats = run.stats = {"steps": 0, "rejected": 0, "evaluations": 0}
    fixed, name = method.fixed_step, method.name

    def integrate(t0, y, t1):
        return native.integrate(name, t0, y, t1, dt, param, rtol=rtol, atol=atol, h=dt if fixed else None,
                                interruptible=True)

    for t0, y, t1, t, Y, result in integrated_pieces(integrate, grid, y0, dt, chunks, fixed, stats):
        if len(t):
            yield t, Y
        if result.status != 0:
            message = result.message
            at_finite = result.status in (1, 2) and result.y_fail is not None and np.all(np.isfinite(result.y_fail))
            if result.status in (1, 2) and not real_at(native, t0, y, param):  # not finite at the start
                message = not_finite(system, t0, y, param)
            elif at_finite:
                # NaN forces at a finite state (a spring whose ends meet): which effect, if any; Mbar
                # without a real value where the run got to is the edge of the coordinates' range, where
                # it is singular (System II's lower rod on the line): said so, the cause beside it
                cause = cause_of(system, result.t_fail, result.y_fail, param, mass_only=result.status == 1)
                if cause is not None and result.status == 1 and not cause.overflow and cause.label.startswith("Mbar"):
                    message = f"{message}: {cause}"
                elif cause is not None:
                    message = cause.stated()
            message += at_configuration(system, result.y_fail) if result.status in (1, 2) else ""
            if at_finite:
                message += rank_loss_note(system, result.t_fail, result.y_fail, param)
            run.stop(message, result.t_fail, y_fail=result.y_fail)
            return
        bar.update(t1)


def final_state(native: NativeModel, method: Method, y0: np.ndarray, t_end: float, param: np.ndarray, tol: float,
                h: float | None) -> tuple[np.ndarray, int, int, str]:
    """One run of ``method`` from t = 0 to ``t_end`` with a row at the end only: ``(y_end,
    evaluations, steps, status)`` (status '' when it got there). A fixed-step method takes the
    step ``h``, an adaptive one ``rtol = atol = tol``."""
    if method.fixed_step:
        _, Y, res = native.integrate(method.name, 0.0, y0, t_end, t_end, param, h=h)
    else:
        _, Y, res = native.integrate(method.name, 0.0, y0, t_end, t_end, param, rtol=tol, atol=tol)
    return Y[-1], res.n_evals, res.n_steps, "" if res.ok else res.message
