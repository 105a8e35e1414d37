"""What accuracy costs in time: a work-precision table of every integration method.

Each method runs from t = 0 to ``t_end`` at each tolerance; its state at ``t_end`` is compared
with a high-precision reference (:mod:`kronsub.simulation.reference`: Taylor series and
Gragg-Bulirsch-Stoer routes in mpmath, cross-checked). A point records

- ``error``: ``max_i |y_i(t_end) - y_ref,i(t_end)|`` over the state ``y = [q; qdot]``;
- ``energy_drift``: ``|E(t_end) - E(0)| / |E|``, ``E = T + V`` (24), when the model conserves
  energy (judged on the reference trajectory);
- ``seconds``: the median wall time of repeated integrations (compilation apart);
- right-hand-side evaluations and steps;
- with implicit constraints (a closed loop, (25)-(29)): ``constraint_residual``, the largest
  ``|g(y)|`` over the run's steps, ``y = [xbar; y_d]`` with ``y_d`` found as the run finds it
  (Newton's method at the run's tolerance, from the last solution), and
  ``velocity_residual``, the largest ``|G ydot|`` with ``ydot = [xbardot; Lambda xbardot]``
  (27). The state is ``[xbar; xbardot]`` (the independent coordinates): the error is measured
  there, and the residuals show how well each method's run keeps the loop closed.

Each method runs through its engine's runner (:mod:`.engines`, the interface ``simulate`` uses);
what is measured comes from the options (:mod:`.accuracy_options`); the reports
(:mod:`.accuracy_report`): the points go to a plain CSV, everything else (model, reference,
skipped methods, failures) to JSON metadata beside it.

Adaptive methods take ``rtol = atol = tol``; ``taylor`` is a Taylor integrator generated as C for
the model (:mod:`.taylor_c`), of order ``2 ceil(ln(1/tol)/4) + 4`` (:func:`.taylor_c.order_for`; one library per order, its
compile time reported apart); ``gbs-long`` and ``gbs-quad`` (extrapolation in the
generated C in long double and ``_Float128``, :mod:`.extended`) take ``tol`` as their tolerance. The fixed-step methods (``gauss4``, ``rk4``, both of
order 4) take the step ``h = tol^(1/4)`` (at most ``t_end / 8``), so their error also scales
like ``tol``.
"""
from __future__ import annotations

import math
import statistics
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import mpmath
import numpy as np

from ..core.first_order import zero_rows
from ..core.held import held_coordinates
from ..core.known_system import KnownSystem
from ..core.projection_work import projected_in_numbers
from ..errors import option
from ..interrupts import signal_of
from . import native as native_module
from .accuracy_options import (ALL_METHODS, CLOSED_LOOP, KNOWN_METHODS, AccuracyError, fixed_step, parse_methods,
                               parse_tolerances, quick_tolerances, setting)
from .engines import Problem, Runner, Timed
from .engines import runner as runner_of
from .fallback import numpy_module
from .methods import METHODS
from .reference import Reference, reference as compute_reference
from .values import RunValues

__all__ = ["ALL_METHODS", "AccuracyError", "Bench", "CLOSED_LOOP", "FLOAT64_FLOOR", "KNOWN_METHODS", "Point",
           "Progress", "REFERENCE_MARGIN", "RESIDUAL_ROWS", "SLOW_SECONDS", "WorkPrecision", "fixed_step", "measure",
           "parse_methods", "parse_tolerances", "quick_tolerances", "sample_times"]

REFERENCE_MARGIN = 100.0  # the reference must be this much more accurate than the best point
SLOW_SECONDS = 5.0  # a method whose run took longer skips its tighter tolerances
FLOAT64_FLOOR = 1e-15  # float64 methods skip tighter tolerances
RESIDUAL_ROWS = 2000  # the constraint residuals are evaluated at most at this many steps of a run


@dataclass(frozen=True)
class Point:
    """One method at one tolerance."""

    method: str
    tolerance: float
    setting: str
    error: float
    energy_drift: float | None
    seconds: float
    evaluations: int | None
    steps: int | None
    repeats: int
    compile_seconds: float | None = None
    status: str = ""
    constraint_residual: float | None = None  # max |g(y)| over the run (closed loops)
    velocity_residual: float | None = None  # max |G ydot| over the run (closed loops)

    @property
    def ok(self) -> bool:
        return not self.status and math.isfinite(self.error)


@dataclass
class WorkPrecision:
    """Every point, the reference they were measured against, and what was skipped."""

    system: str
    t_end: float
    points: list[Point]
    reference: Reference
    compile_seconds: float | None
    conservative: bool
    skipped: dict[str, str] = field(default_factory=dict)
    constraints: tuple[str, ...] = ()  # the names of implicit constraints (a closed loop)
    parameters: dict[str, float] = field(default_factory=dict)  # name -> value, as run
    initial_state: dict[str, float] = field(default_factory=dict)  # [q; qdot] at t = 0, by name
    dependent: dict[str, float] = field(default_factory=dict)  # a closed loop's y_d at t = 0
    speeds: tuple[str, ...] = ()  # under velocity constraints: the speeds u of the state [q; u]
    interrupted: int | None = None  # the signal that stopped the measurement after these points (Ctrl-C: SIGINT)

    def best_error(self) -> float | None:
        errors = [p.error for p in self.points if p.ok]
        return min(errors) if errors else None

    def reference_sufficient(self) -> bool:
        """Whether the reference is at least 100x more accurate than the best point."""
        best = self.best_error()
        return best is None or self.reference.error * REFERENCE_MARGIN <= best

    def cheapest(self, target: float) -> Point | None:
        """The fastest point whose error is at most ``target``, at its tolerance and at every tighter
        one its method ran at (failed runs aside): on a chaotic model the error scatters from one
        tolerance to the next, and a point that met the target by that scatter alone is not named
        (:meth:`by_chance`)."""
        meeting = [p for p in self.points if p.ok and p.error <= target and self._holds(p, target)]
        return min(meeting, key=lambda p: (p.seconds, p.error)) if meeting else None

    def by_chance(self, target: float) -> Point | None:
        """The fastest point quicker than :meth:`cheapest` that met ``target`` while a tighter
        tolerance of its method did not, or None."""
        best = self.cheapest(target)
        chance = [p for p in self.points if p.ok and p.error <= target and not self._holds(p, target)
                  and (best is None or p.seconds < best.seconds)]
        return min(chance, key=lambda p: (p.seconds, p.error)) if chance else None

    def _holds(self, point: Point, target: float) -> bool:
        return all(q.error <= target for q in self.points
                   if q.method == point.method and q.ok and q.tolerance < point.tolerance)


# ---------------------------------------------------------------------------------------------
# Measuring
# ---------------------------------------------------------------------------------------------

class Progress:
    """A progress bar on stderr, shown only on a terminal."""

    def __init__(self, total: int, enabled: bool | None = None):
        self.total, self.done = total, 0
        self.enabled = sys.stderr.isatty() if enabled is None else enabled

    def step(self, label: str) -> None:
        self.done += 1
        if self.enabled:
            frac = self.done / max(1, self.total)
            sys.stderr.write(f"\r[{'#' * int(30 * frac):<30}] {self.done}/{self.total} {label:<24}")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


def _timed(run: Callable[[], tuple], budget: float, max_repeats: int) -> tuple[tuple, float, int]:
    """Run until ``budget`` seconds are spent or ``max_repeats`` runs: (result, median, runs)."""
    times, result = [], None
    spent = 0.0
    while len(times) < max_repeats and (not times or spent < budget):
        t0 = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - t0)
        spent += times[-1]
    return result, statistics.median(times), len(times)


class Bench:
    """Integrations of one system with one parameter set, each method through its engine's
    runner (:mod:`.engines`): ``prepare(method, tol)`` is the timed run, ``available(method)``
    why it cannot run. With implicit constraints, ``dependent`` is ``y_d`` at ``y0``: every run
    starts its Newton's method from it."""

    def __init__(self, system: KnownSystem, param: np.ndarray, y0: np.ndarray, t_end: float, dependent=None):
        self.system, self.param, self.y0, self.t_end = system, param, y0, t_end
        self.dependent = None if system.implicit is None else np.array(dependent, dtype=float)
        self.native = None
        self.compile_seconds = None
        missing = ""
        from .compiled import native_model

        t0 = time.perf_counter()
        try:  # the library simulate built, when the equations are the same (compiled.fingerprint)
            self.native = native_model(system)
            self.compile_seconds = time.perf_counter() - t0
        except native_module.CompilerNotFound as exc:
            missing = f"no C compiler ({exc})"
        if self.native is not None:
            self.rhs = self.native.scipy_rhs(param)
        else:
            module = self.module = numpy_module(system)
            self.rhs = lambda t, y: module["rhs"](t, y, param)
        self.problem = Problem(system, param, self.native, self._fresh_rhs, missing=missing)
        self.runners: dict[str, Runner] = {}

    def _fresh_rhs(self, tol: float) -> Callable:
        """The right-hand side for one run: with implicit constraints, Newton's method starts
        afresh from ``y_d(0)`` at the run's tolerance (``min(rtol, atol) / 100``)."""
        if self.dependent is None:
            return self.rhs
        from .constrained import configure_module, newton_tolerance

        if self.native is not None:
            self.native.set_newton(self.dependent, newton_tolerance(tol, tol))
            return self.native.scipy_rhs(self.param)
        configure_module(self.module, self.dependent, newton_tolerance(tol, tol))
        return self.rhs

    def runner(self, method: str) -> Runner:
        """The runner of ``method`` on this system, from its engine (one per method)."""
        if method not in METHODS:
            raise AccuracyError(f"unknown method '{method}'")
        if method not in self.runners:
            self.runners[method] = runner_of(self.problem, METHODS[method])
        return self.runners[method]

    def available(self, method: str) -> str:
        """Why ``method`` cannot run, or '' (what it needs is built now)."""
        method_runner = self.runner(method)
        if self.dependent is not None and not METHODS[method].closed_loops:
            return ("it runs explicit equations only, and a closed loop's dependent coordinates come from "
                    "Newton's method on the constraints (methods here: " + ", ".join(CLOSED_LOOP) + ")")
        if not METHODS[method].closed_loops and zero_rows(self.system):
            return ("it integrates second-order equations of its own in every coordinate, and this system has "
                    "first-order coordinates (methods here: " + ", ".join(CLOSED_LOOP) + ")")
        if self.problem.system.speeds is not None and not METHODS[method].closed_loops:
            return ("it is not supported yet with velocity constraints, whose state [q; u] it does not run "
                    "(methods here: " + ", ".join(CLOSED_LOOP) + ")")
        return method_runner.unavailable()

    def _step(self, method: str, tol: float) -> float | None:
        return fixed_step(method, tol, self.t_end) if METHODS[method].fixed_step else None

    def prepare(self, method: str, tol: float) -> Timed:
        """The timed run of ``method`` at ``tol`` (what it compiles for this tolerance is timed apart)."""
        return self.runner(method).timed(self.y0, self.t_end, tol, self._step(method, tol))

    def intermediates(self):
        """The constraints' numbers at this run's parameters (:class:`~kronsub.core.constraints.Intermediates`)."""
        if getattr(self, "_intermediates", None) is None:
            from ..core.constraints import Intermediates

            values = {p.symbol: v for p, v in zip(self.system.parameters, self.param)}
            self._intermediates = Intermediates(self.system.implicit, values)
        return self._intermediates

    def energy(self, y: np.ndarray, dependent=None) -> float | None:
        """``E = T + V`` at ``y``; with constraints, Newton's method starts from ``dependent``
        (from ``y_d(0)`` when not given)."""
        if self.native is None:
            return None
        try:
            if self.dependent is not None:
                if dependent is None:
                    from ..core.constraints import ConstraintFailure

                    closure = self.intermediates()
                    closure.tol, closure.guess = 1e-14, self.dependent.copy()
                    try:
                        dependent = closure.dependent(np.asarray(y)[:len(self.system.coordinates)])
                    except ConstraintFailure:
                        return None
                self.native.set_newton(dependent, 1e-14)
            return self.native.kinetic_energy(y, self.param) + self.native.potential_energy(self.t_end, y, self.param)
        except native_module.NativeError:
            return None

    def trace(self, method: str, tol: float) -> tuple[np.ndarray, np.ndarray]:
        """One more (untimed) run of ``method`` at ``tol``: the times and states of its steps."""
        return self.runner(method).trace(self.y0, self.t_end, tol, self._step(method, tol))

    def residuals(self, method: str, tol: float) -> tuple[float, float, np.ndarray | None]:
        """The largest ``|g(y)|`` and ``|G ydot|`` over the steps of a run (at most
        :data:`RESIDUAL_ROWS` of them, evenly spread, the last included), ``y_d`` found at
        each from the one before by Newton's method at the run's tolerance, as the run finds
        it; and ``y_d`` at the last step."""
        from ..core.constraints import ConstraintFailure
        from .constrained import newton_tolerance

        T, Y = self.trace(method, tol)
        if len(Y) > RESIDUAL_ROWS:
            pick = np.unique(np.linspace(0, len(Y) - 1, RESIDUAL_ROWS).round().astype(int))
            T, Y = T[pick], Y[pick]
        n = len(self.system.coordinates)
        ntol = newton_tolerance(tol, tol)
        closure = self.intermediates()
        closure.tol, guess = ntol, self.dependent.copy()
        worst_g = worst_v = 0.0
        for t, y in zip(T, Y):
            try:
                if self.native is not None:  # the compiled Newton's method, as in the run
                    self.native.set_newton(guess, ntol)
                    self.native.rhs(float(t), y, self.param)
                    dep = self.native.dependent
                else:
                    closure.guess = guess
                    dep = closure.dependent(y[:n])
            except (ConstraintFailure, native_module.NativeError, np.linalg.LinAlgError):
                return math.nan, math.nan, None
            full = np.concatenate([y[:n], dep])
            G = closure.numeric.jacobian(full)
            qdot = y[n:]
            try:
                dep_dot = np.linalg.solve(G[:, n:], -G[:, :n] @ qdot)
            except np.linalg.LinAlgError:
                return math.nan, math.nan, None
            worst_g = max(worst_g, float(np.max(np.abs(closure.numeric.residual(full)))))
            worst_v = max(worst_v, float(np.max(np.abs(G[:, :n] @ qdot + G[:, n:] @ dep_dot))))
            guess = dep
        return worst_g, worst_v, guess


def _conservative(bench: Bench, ref: Reference) -> tuple[bool, float | None, float]:
    """Whether energy is conserved along the reference (to 1e-9 relative): (flag, E(0), scale)."""
    E0 = bench.energy(bench.y0, bench.dependent)
    if E0 is None:
        return False, None, 1.0
    dependent = [[float(v) for v in d] for d in ref.dependent] or [None] * len(ref.times)
    energies, kinetic = [], []
    for i in range(len(ref.times)):
        energies.append(bench.energy(np.array(ref.at(i)), dependent[i]))
        kinetic.append(bench.native.kinetic_energy(np.array(ref.at(i)), bench.param))  # at that y_d
    scale = max([abs(E0), *map(abs, kinetic), 1e-300])
    conserved = all(e is not None and abs(e - E0) <= 1e-9 * scale for e in energies)
    return conserved, E0, scale


def sample_times(t_end: float, count: int = 4) -> list[float]:
    """The reference's times: ``t_end / count, 2 t_end / count, ..., t_end``."""
    return [t_end * (i + 1) / count for i in range(count)]


def _implicit_cause(system, y0, param, dependent):
    """:func:`..core.finite.at_state` at the initial state of a system with implicit constraints,
    its intermediates (``y_d`` from ``dependent``, ``Lambda``, ``gamma``) solved there; None when
    they cannot be (the constraints' own failure is reported where they are solved)."""
    import sympy

    from ..core.constraints import ConstraintFailure, Intermediates
    from ..core.finite import at_state

    n = len(system.coordinates)
    numbers = {p.symbol: sympy.Float(v, 17) for p, v in zip(system.parameters, param)}
    evaluator = Intermediates(system.implicit, numbers)
    evaluator.guess = np.array(dependent, dtype=float)
    try:
        with np.errstate(all="ignore"):
            intermediates = evaluator.at(y0[:n], y0[n:])
    except (ConstraintFailure, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    return at_state(system, 0.0, y0, param, intermediates)


def _on_constraints(held, t: float, y: np.ndarray) -> np.ndarray:
    """The state ``y = [x; u]`` at ``t`` with its held coordinates put on their configuration
    constraints, as a run's rows are (:meth:`kronsub.core.held.HeldCoordinates.rows`): the
    integrated values of the held coordinates are only Newton's starting guess, whose drift is no
    error of the motion. Unchanged without held coordinates, or where they cannot be put there."""
    if held is None or not np.all(np.isfinite(y)):
        return y
    return held.rows(t, y[None, :])[0]


def measure(system: KnownSystem, values: RunValues, t_end: float, methods: tuple[str, ...],
            tolerances: tuple[float, ...], *, ref: Reference | None = None, digits: int = 20,
            quick: bool = False, progress: bool | None = None, budget: float | None = None,
            max_repeats: int | None = None, dependent=None, keep_interrupted: bool = False) -> WorkPrecision:
    """Every method at every tolerance, against ``ref`` (computed at ``digits`` digits when
    not given; its last time must be ``t_end``). With implicit constraints, ``values`` must be
    on them and ``dependent`` is ``y_d`` there (:func:`.constrained.project_initial`; done
    here when not given). ``keep_interrupted``: an interrupt while the points are measured ends
    the measurement with the points so far (:attr:`WorkPrecision.interrupted`), else it is raised."""
    if not (t_end > 0 and math.isfinite(t_end)):
        raise AccuracyError(f"{option('t')} must be a positive number")
    implicit = system.implicit
    if implicit is not None and dependent is None:
        from .constrained import project_initial

        values, _, closure = project_initial(system, dict(system.initial), {}, values, 1e-14)
        dependent = closure.guess
    param, y0 = np.array(values.parameters, dtype=float), np.array(values.y0, dtype=float)
    from ..core.finite import at_state

    if projected_in_numbers(system):  # no symbolic equations in the speeds to look into: the reference says
        cause = None
    elif implicit is None:
        cause = at_state(system, 0.0, y0, param)
    else:
        cause = _implicit_cause(system, y0, param, dependent)
    if cause is not None:  # every method would fail at once, against a reference computed exactly
        raise AccuracyError(f"the equations have no {'finite' if cause.overflow else 'real'} value at the "
                            f"initial state: {cause.what}\n  hint: {cause.hint}")
    if ref is None:
        ref = compute_reference(system, values.parameters, values.y0, sample_times(t_end), digits,
                                dependent=None if implicit is None else [float(v) for v in dependent])
    if abs(ref.times[-1] - t_end) > 1e-12 * t_end:
        raise AccuracyError(f"the reference ends at t = {ref.times[-1]}, not at {t_end}")
    held = held_coordinates(system, {p.symbol: float(v) for p, v in zip(system.parameters, param)})
    want = _on_constraints(held, t_end, np.array(ref.at(len(ref.times) - 1)))
    bench = Bench(system, param, y0, t_end, dependent)
    conservative, E0, scale = _conservative(bench, ref)
    budget = (0.05 if quick else 0.3) if budget is None else budget
    max_repeats = (3 if quick else 9) if max_repeats is None else max_repeats
    skipped = {}
    plan = []
    for method in methods:
        why = bench.available(method)
        if why:
            skipped[method] = why
        else:
            plan.extend((method, tol) for tol in tolerances)
    bar = Progress(len(plan), progress)
    points = []
    slow: dict[str, float] = {}
    interrupted = None
    try:
        for method, tol in plan:
            bar.step(f"{method} {tol:.0e}")
            if METHODS[method].precision == "double" and tol < FLOAT64_FLOOR:
                skipped.setdefault(method, f"tolerances below {FLOAT64_FLOOR:.0e} skipped (float64 cannot meet them)")
                continue
            if method in slow:
                skipped.setdefault(method, f"tolerances {tol:.0e} and tighter skipped: one run took "
                                           f"{slow[method]:.1f} s (over {SLOW_SECONDS:g} s)")
                continue
            timed = bench.prepare(method, tol)
            (y_end, evals, steps, status), seconds, repeats = _timed(timed.run, budget, max_repeats)
            extended = METHODS[method].precision != "double"
            if extended:  # the error in the type's precision, before rounding to float64
                with mpmath.workdps(50):
                    error = float(max(abs(a - b) for a, b in zip(y_end, ref.states[-1])))
            y_end = _on_constraints(held, t_end, np.array([float(v) for v in y_end]))
            if not extended:
                error = float(np.max(np.abs(y_end - want))) if np.all(np.isfinite(y_end)) else math.nan
            residual = velocity_residual = dependent_end = None
            if implicit is not None:
                residual, velocity_residual, dependent_end = bench.residuals(method, tol)
            drift = None
            if conservative and not extended and np.all(np.isfinite(y_end)) and \
                    (implicit is None or dependent_end is not None):
                E = bench.energy(y_end, dependent_end)
                drift = None if E is None else abs(E - E0) / scale
            if status:  # a run that stopped measured no error at t_end
                error, drift, residual, velocity_residual = math.nan, None, None, None
            points.append(Point(method, tol, setting(method, tol, t_end), error, drift, seconds, evals, steps, repeats,
                                timed.compile_seconds, status, residual, velocity_residual))
            if seconds > SLOW_SECONDS:
                slow[method] = seconds
    except KeyboardInterrupt as exc:  # (Ctrl-C, SIGTERM, SIGHUP) the points so far are kept and said so
        if not keep_interrupted:
            raise
        interrupted = signal_of(exc)
    finally:
        bar.close()
    state = [q.name for q in system.coordinates] + [system.name_of(v) for v in system.state_velocities]
    return WorkPrecision(system.name, t_end, points, ref, bench.compile_seconds, conservative, skipped,
                         tuple(c.name for c in implicit.constraints) if implicit is not None else (),
                         {p.name: float(v) for p, v in zip(system.parameters, param)},
                         dict(zip(state, map(float, y0))),
                         {d.name: float(v) for d, v in zip(implicit.dependent, dependent)} if implicit is not None
                         else {}, tuple(u.name for u in system.speeds.speeds) if system.speeds is not None else (),
                         interrupted)
