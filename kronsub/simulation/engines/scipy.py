"""The engine of scipy's solvers (RK45, DOP853, Radau, LSODA) calling the compiled right-hand
side (or the numpy module): stepped here, the rows of each step written from its dense output."""
from __future__ import annotations

import numpy as np

from collections.abc import Callable

from ...core.known_system import KnownSystem
from ..methods import Method
from ..native import NativeModel, SingularMassMatrix
from ..rows import RunInProgress
from .interface import Problem, ProgressBar, Rhs, Rows, Steps, Timed
from ..failure import at_configuration, not_finite, rank_loss_note, Singular
from ..grid import Cursor, Grid, Tail

__all__ = ["COMPILED_RHS", "EVENTS", "IMPLICIT", "RUN_STEPS", "STALLED_STEPS", "STALL_STEPS", "STALL_SPAN",
           "ScipyRunner", "blocks", "exact_jacobian", "final_state", "native_rhs", "runner"]

COMPILED_RHS = True
EVENTS = True


STALL_STEPS = 1000
"""A scipy run whose last this many steps advanced time by less than `STALL_SPAN` of ``max(1, |t|)``
has stalled (an implicit method creeping towards a singular configuration takes steps of 1e-12)."""
STALL_SPAN = 1e-8
RUN_STEPS = 1_000_000  # a timed run that takes more steps is a failed point
STALLED_STEPS = 100  # so is one whose time stays where it is for this many steps (a step size of 0)


class ScipyRunner:
    """One of scipy's solvers on the problem's right-hand side (:class:`.interface.Runner`)."""

    def __init__(self, problem: Problem, method: Method):
        self.problem, self.method = problem, method

    @property
    def backend(self) -> str:
        return "C" if self.problem.native is not None else "numpy"

    def unavailable(self) -> str:
        return ""

    def blocks(self, run: RunInProgress, grid: Grid | Tail, y0: np.ndarray, steps: Steps, bar: ProgressBar) -> Rows:
        p = self.problem
        return blocks(run, p.restart(steps.rtol), self.method.name, grid, y0, steps.rtol, steps.atol, steps.chunks,
                      bar, p.system, events=p.events, param=p.param if p.diagnosed else None)

    def timed(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> Timed:
        p, name = self.problem, self.method.name
        return Timed(lambda: final_state(p.restart(tol), name, y0, t_end, tol, RUN_STEPS, STALLED_STEPS))

    def trace(self, y0: np.ndarray, t_end: float, tol: float, h: float | None) -> tuple[np.ndarray, np.ndarray]:
        import warnings

        from scipy import integrate

        rhs = self.problem.restart(tol)
        times, states = [0.0], [y0.copy()]
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            solver = getattr(integrate, self.method.name)(rhs, 0.0, y0.copy(), t_end, rtol=tol, atol=tol)
            try:
                while solver.status == "running":
                    solver.step()
                    times.append(solver.t)
                    states.append(solver.y.copy())
            except Exception:  # noqa: BLE001 - the timed run reports the failure
                pass
        return np.array(times), np.array(states)


def runner(problem: Problem, method: Method) -> ScipyRunner:
    return ScipyRunner(problem, method)


IMPLICIT = ("Radau", "BDF", "LSODA")
"""scipy's methods that take a Jacobian ``jac=`` (else they form it by finite differences)."""


def exact_jacobian(rhs: Rhs, method: str) -> dict:
    """``{"jac": J}`` when ``method`` takes one and ``rhs`` carries the generated exact Jacobian
    (:meth:`.native.NativeModel.scipy_jacobian`, a model built with ``jacobian``), else nothing."""
    jacobian = getattr(rhs, "jacobian", None)
    return {"jac": jacobian} if jacobian is not None and method in IMPLICIT else {}


def native_rhs(native: NativeModel, param: np.ndarray) -> Rhs:
    rhs = native.scipy_rhs(param)

    def f(t, y):
        try:
            return rhs(t, y)
        except SingularMassMatrix as exc:
            raise Singular(t, y) from exc

    jacobian = getattr(rhs, "jacobian", None)
    if jacobian is not None:
        def exact(t, y):
            try:
                return jacobian(t, y)
            except SingularMassMatrix as exc:
                raise Singular(t, y) from exc

        f.jacobian = exact
    return f


def blocks(run: RunInProgress, rhs: Rhs, method: str, grid: Grid | Tail, y0: np.ndarray, rtol: float, atol: float, chunks: int,
           bar: ProgressBar, system: KnownSystem, events: Callable[[float, np.ndarray], float] | None = None,
           param: np.ndarray | None = None) -> Rows:
    """Blocks ``(t, Y)`` of a run with one of scipy's solvers, stepped here: the rows of each
    step are written as it is taken (from its dense output), so a run that fails keeps every
    row before the failure, and a run whose steps stall (:data:`STALL_STEPS`) stops with the
    reason instead of creeping. A terminal ``events`` function (its sign turns) ends the
    blocks with ``run.pending = (t, y)`` where it turned. ``chunks`` is not needed: the progress
    bar follows the steps."""
    from collections import deque

    from scipy import integrate
    from scipy.optimize import brentq

    yield np.array([grid[0]]), np.array([y0])
    stats = run.stats = {"evaluations": 0, "steps": 0}
    cursor = Cursor(grid)
    recent: deque = deque(maxlen=STALL_STEPS)
    solver = None
    with np.errstate(all="ignore"):
        try:
            # NaN at the start makes scipy's first step size NaN, and its step loop never ends
            if not np.all(np.isfinite(rhs(grid[0], np.array(y0, dtype=float)))):
                message = "the derivative of the state is NaN or infinite at the initial state"
                run.stop(message if param is None else not_finite(system, grid[0], y0, param, message), grid[0],
                         y_fail=y0)
                return
            solver = getattr(integrate, method)(rhs, grid[0], np.array(y0, dtype=float), grid[len(grid) - 1],
                                                rtol=rtol, atol=atol, **exact_jacobian(rhs, method))
            before = events(solver.t, solver.y) if events is not None else None
            t_old, y_old = solver.t, np.array(solver.y)
            while not cursor.done():
                if solver.t != t_old:
                    t_old, y_old = solver.t, np.array(solver.y)
                message = solver.step()
                stats["evaluations"] = int(solver.nfev)
                stats["steps"] += 1
                if solver.status == "failed":
                    message = message or "the step failed"
                    if param is not None and np.all(np.isfinite(solver.y)) and \
                            not np.all(np.isfinite(rhs(solver.t, solver.y))):  # steps shrank at NaN forces
                        message = not_finite(system, solver.t, solver.y, param, otherwise=message)
                    run.stop(message, solver.t, y_fail=solver.y)
                    return
                if not np.all(np.isfinite(solver.y)):
                    message = "the state became NaN or infinite"
                    run.stop(message if param is None else not_finite(system, t_old, y_old, param, message), t_old,
                             y_fail=y_old)  # (the step from t_old went wrong: the last finite state)
                    return
                t_new, dense = solver.t, None
                if events is not None:
                    after = events(t_new, solver.y)
                    if after != before:
                        dense = solver.dense_output()
                        try:
                            t_event = brentq(lambda t: events(t, dense(t)), t_old, t_new,
                                             xtol=4 * np.finfo(float).eps * max(1.0, abs(t_new)))
                        except ValueError:
                            t_event = t_new
                        times = cursor.upto(t_event)
                        if len(times):
                            yield times, dense(times).T
                        run.pending = (float(t_event), np.asarray(dense(t_event), dtype=float))
                        return
                    before = after
                times = cursor.upto(t_new)
                if len(times):
                    dense = solver.dense_output() if dense is None else dense
                    yield times, dense(times).T
                    bar.update(float(times[-1]))
                recent.append(t_new)
                if len(recent) == STALL_STEPS and t_new - recent[0] < STALL_SPAN * max(1.0, abs(t_new)):
                    run.stop(f"the steps stalled: {STALL_STEPS} steps of {method} advanced t by only "
                             f"{t_new - recent[0]:.2g} (steps of {solver.step_size:.1e}: a singular "
                             f"configuration nearby, or a problem too stiff for the method)"
                             + at_configuration(system, solver.y), t_new, y_fail=solver.y)
                    return
        except Singular as exc:
            message = "the mass matrix is singular or not positive definite" + at_configuration(system, exc.y)
            if param is not None:  # NaN entries, not a singular matrix: an overflow, or outside the domain
                t, y = (exc.t, exc.y) if np.all(np.isfinite(exc.y)) else (t_old, y_old)  # (a stage overflowed)
                found = not_finite(system, t, y, param, otherwise="", mass_only=True)
                message = (found + at_configuration(system, y) if found else
                           message + rank_loss_note(system, exc.t, exc.y, param))
            run.stop(message, exc.t, y_fail=exc.y)
            return
        except (ValueError, RuntimeError, ArithmeticError, np.linalg.LinAlgError) as exc:
            t, y = (solver.t, solver.y) if solver is not None else (grid[0], y0)
            message = str(exc)
            if param is not None and np.all(np.isfinite(y)):  # scipy's "array must not contain infs or NaNs"
                message = not_finite(system, t, y, param, otherwise=message)
            run.stop(message, t, y_fail=y)
            return


def final_state(rhs: Rhs, method: str, y0: np.ndarray, t_end: float, tol: float, max_steps: int,
                stalled_steps: int) -> tuple[np.ndarray, int, int, str]:
    """One run of scipy's ``method`` from t = 0 to ``t_end`` at ``rtol = atol = tol``, stepped to
    the end: ``(y_end, evaluations, steps, status)`` (status '' when it got there). A run of more
    than ``max_steps`` steps, or of ``stalled_steps`` in a row that leave t where it is, stops."""
    import warnings

    from scipy import integrate

    solver_class = getattr(integrate, method)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        solver = solver_class(rhs, 0.0, y0.copy(), t_end, rtol=tol, atol=tol, **exact_jacobian(rhs, method))
        steps, still = 0, 0
        try:
            while solver.status == "running":
                if steps >= max_steps or still >= stalled_steps:
                    return (solver.y.copy(), solver.nfev, steps,
                            f"stopped at t = {solver.t:.6g}: " + (f"more than {max_steps:,} steps" if
                            still < stalled_steps else f"{still} steps in a row that did not advance"))
                t_before = solver.t
                message = solver.step()
                steps += 1
                still = still + 1 if solver.t == t_before else 0
        except Exception as exc:  # noqa: BLE001 - a singular mass matrix, a failing step: a failed point
            return np.full(len(y0), np.nan), solver.nfev, steps, str(exc) or type(exc).__name__
        status = "" if solver.status == "finished" else (message or "failed")
        return solver.y.copy(), solver.nfev, steps, status
