"""The engine of ``gbs-long`` and ``gbs-quad`` (``accuracy`` only): Gragg-Bulirsch-Stoer
extrapolation in the generated C in long double and ``_Float128`` (:mod:`..extended`)."""
from __future__ import annotations

import time

import numpy as np

from ..grid import Grid, Tail
from ..methods import Method
from ..rows import RunInProgress, SimulationError
from .interface import Problem, ProgressBar, Rows, Steps, Timed

__all__ = ["COMPILED_RHS", "EVENTS", "ExtendedRunner", "final_state", "runner"]

COMPILED_RHS = False
EVENTS = False


class ExtendedRunner:
    """Extrapolation in the method's precision on the problem's system (:class:`.interface.Runner`),
    compiled once."""

    def __init__(self, problem: Problem, method: Method):
        self.problem, self.method = problem, method
        self.model = self.why = None
        self.compile_seconds: float | None = None
        self.backend = "C"

    def unavailable(self) -> str:
        from ..extended import ExtendedError, ExtendedModel
        from ..native import NativeError

        if self.why is None:
            t0 = time.perf_counter()
            try:
                self.model, self.why = ExtendedModel(self.problem.system, self.method.precision), ""
            except (ExtendedError, NativeError) as exc:
                self.why = str(exc).splitlines()[0]
            self.compile_seconds = time.perf_counter() - t0
        return self.why

    def blocks(self, run: RunInProgress, grid: Grid | Tail, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        raise SimulationError(f"method '{self.method.name}' is a method of accuracy only (it returns the state "
                              "at the end, not rows)")

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        model, param, start = self.model, [float(v) for v in self.problem.param], [float(v) for v in y0]
        return Timed(lambda: final_state(model, param, start, t_end, tol), self.compile_seconds)

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError(f"{self.method.name} runs explicit equations only: no closed loop to trace")


def runner(problem: Problem, method: Method) -> ExtendedRunner:
    return ExtendedRunner(problem, method)


def final_state(model, param: list[float], y0: list[float], t_end: float, tol: float) -> tuple[list, int, int, str]:
    """One run of ``model`` (:class:`..extended.ExtendedModel`) from t = 0 to ``t_end`` at
    ``tol``: ``(y_end, evaluations, steps, status)``, ``y_end`` in the type's precision
    (status '' when it got there)."""
    r = model.integrate(param, y0, t_end, tol=tol)
    status = "" if r.status == 0 else f"extrapolation status {r.status}"
    return r.state, r.evaluations, r.steps, status
