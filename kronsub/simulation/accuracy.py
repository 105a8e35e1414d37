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

The reports (:mod:`.accuracy_report`): the points go to a plain CSV, everything else (model,
reference, skipped methods, failures) to JSON metadata beside it.

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
import warnings
from dataclasses import dataclass, field
from typing import Callable

import mpmath
import numpy as np

from ..core.known_system import KnownSystem
from ..errors import KronsubError
from . import native as native_module
from .engines import c as c_engine
from .engines import extended as extended_engine
from .engines import heyoka as heyoka_engine
from .engines import scipy as scipy_engine
from .engines import taylor as taylor_engine
from .fallback import numpy_module
from .methods import MEASURED, METHODS, by_engine
from .reference import Reference, reference as compute_reference
from .values import RunValues

__all__ = ["ALL_METHODS", "AccuracyError", "CLOSED_LOOP", "EXTENDED", "FIXED_STEP_ORDER", "FLOAT64_FLOOR",
           "GENERATED", "HEYOKA", "KNOWN_METHODS", "NATIVE", "Point", "Progress", "REFERENCE_MARGIN",
           "RESIDUAL_ROWS", "RUN_STEPS", "SCIPY", "SLOW_SECONDS", "STALLED_STEPS", "WorkPrecision", "fixed_step",
           "measure", "parse_methods", "parse_tolerances", "quick_tolerances", "sample_times"]

# the method table's (.methods) lists, as this module reads them
NATIVE = by_engine("c")
SCIPY = by_engine("scipy")
HEYOKA = by_engine("heyoka")
GENERATED = by_engine("taylor")  # a Taylor integrator generated as C for the model (.taylor_c)
EXTENDED = {name: METHODS[name].precision for name in by_engine("extended")}  # long double / _Float128 C
KNOWN_METHODS = MEASURED
ALL_METHODS = tuple(name for name in MEASURED if name not in EXTENDED)  # "all"; the extended ones by name
CLOSED_LOOP = tuple(name for name in MEASURED if METHODS[name].closed_loops)  # Newton's method finds y_d
FIXED_STEP_ORDER = {name: METHODS[name].order for name in MEASURED if METHODS[name].fixed_step}
REFERENCE_MARGIN = 100.0  # the reference must be this much more accurate than the best point
SLOW_SECONDS = 5.0  # a method whose run took longer skips its tighter tolerances
FLOAT64_FLOOR = 1e-15  # float64 methods skip tighter tolerances
RESIDUAL_ROWS = 2000  # the constraint residuals are evaluated at most at this many steps of a run
RUN_STEPS = 1_000_000  # a SciPy run that takes more steps is a failed point
STALLED_STEPS = 100  # so is one whose time stays where it is for this many steps (a step size of 0)


class AccuracyError(KronsubError):
    """A work-precision measurement that could not be made."""


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
# Tolerances
# ---------------------------------------------------------------------------------------------

def parse_tolerances(text: str) -> tuple[float, ...]:
    """``1e-4:1e-14`` (every decade between, both ends included), ``1e-4:1e-14:2`` (every
    second decade) or a list ``1e-6,1e-9``."""
    hint = "write e.g. --tolerances 1e-4:1e-14, 1e-4:1e-14:2 or 1e-6,1e-9,1e-12"
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) not in (2, 3):
                raise ValueError
            first, last = float(parts[0]), float(parts[1])
            every = int(parts[2]) if len(parts) == 3 else 1
            if not (0 < first < 1 and 0 < last < 1 and every >= 1):
                raise ValueError
            a, b = math.log10(first), math.log10(last)
            count = int(math.floor(abs(b - a) / every + 1e-9)) + 1
            sign = -1 if b < a else 1
            values = [first * 10.0 ** (sign * every * i) for i in range(count)]
        else:
            values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise AccuracyError(f"--tolerances '{text}' is not a range or list of positive numbers below 1\n"
                            f"  hint: {hint}") \
            from None
    if not values or not all(0 < v < 1 for v in values):
        raise AccuracyError(f"--tolerances '{text}' must give positive numbers below 1 (relative tolerances)\n"
                            f"  hint: {hint}")
    return tuple(dict.fromkeys(float(f"{v:.6g}") for v in values))


def quick_tolerances(tolerances: tuple[float, ...]) -> tuple[float, ...]:
    """A coarse grid: every third tolerance, and the last."""
    picked = list(tolerances[::3])
    if tolerances[-1] not in picked:
        picked.append(tolerances[-1])
    return tuple(picked)


def fixed_step(method: str, tol: float, t_end: float) -> float:
    """The step of a fixed-step method of order p at tolerance ``tol``: ``tol^(1/p)``."""
    return min(tol ** (1.0 / FIXED_STEP_ORDER[method]), t_end / 8)


def parse_methods(text: str | None) -> tuple[str, ...]:
    """``dop853,RK45`` or ``all`` (the default)."""
    if text is None or text.strip() == "all":
        return ALL_METHODS
    names = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in names if m not in KNOWN_METHODS]
    if unknown or not names:
        raise AccuracyError(f"unknown method{'s' if len(unknown) > 1 else ''} {', '.join(unknown) or '(none)'}\n"
                            f"  hint: choose from {', '.join(KNOWN_METHODS)} (comma-separated), or all")
    return tuple(dict.fromkeys(names))


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


class _Runners:
    """Integrations of one system with one parameter set: ``run(method, tol) -> (y_end,
    evaluations, steps, status)`` and what compiling cost. With implicit constraints,
    ``dependent`` is ``y_d`` at ``y0``: every run starts its Newton's method from it."""

    def __init__(self, system: KnownSystem, param: np.ndarray, y0: np.ndarray, t_end: float, dependent=None):
        self.system, self.param, self.y0, self.t_end = system, param, y0, t_end
        self.dependent = None if system.implicit is None else np.array(dependent, dtype=float)
        self.native = None
        self.compile_seconds = None
        self.skipped: dict[str, str] = {}
        from .compiled import native_model

        t0 = time.perf_counter()
        try:  # the library simulate built, when the equations are the same (compiled.fingerprint)
            self.native = native_model(system)
            self.compile_seconds = time.perf_counter() - t0
        except native_module.CompilerNotFound as exc:
            for m in NATIVE:
                self.skipped[m] = f"no C compiler ({exc})"
        if self.native is not None:
            self.rhs = self.native.scipy_rhs(param)
        else:
            module = self.module = numpy_module(system)
            self.rhs = lambda t, y: module["rhs"](t, y, param)
        self._heyoka = None
        self.heyoka_compile: dict[float, float] = {}
        self.extended: dict[str, object] = {}
        self.extended_compile: dict[str, float] = {}
        self.taylor_compile: dict[float, float] = {}  # per tolerance: generating and compiling its order

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

    def available(self, method: str) -> str:
        """Why ``method`` cannot run, or ''."""
        if method in self.skipped:
            return self.skipped[method]
        if self.dependent is not None and method not in CLOSED_LOOP:
            return ("it runs explicit equations only, and a closed loop's dependent coordinates come from "
                    "Newton's method on the constraints (methods here: " + ", ".join(CLOSED_LOOP) + ")")
        if method == "heyoka":
            from . import heyoka_backend

            if not heyoka_backend.available():
                return f"heyoka is not installed ({heyoka_backend.INSTALL_HINT})"
        if method == "taylor" and "taylor" not in self.extended:
            from .taylor_c import TaylorC, TaylorUnavailable

            t0 = time.perf_counter()
            try:
                self.extended["taylor"] = TaylorC(self.system)
            except (native_module.NativeError, TaylorUnavailable) as exc:
                self.extended["taylor"] = None
                self.skipped[method] = str(exc).splitlines()[0]
            self.extended_compile["taylor"] = time.perf_counter() - t0
        if method == "taylor" and self.extended["taylor"] is None:
            return self.skipped[method]
        if method in EXTENDED:
            from .extended import ExtendedError, ExtendedModel

            precision = EXTENDED[method]
            if precision not in self.extended:
                t0 = time.perf_counter()
                try:
                    self.extended[precision] = ExtendedModel(self.system, precision)
                except (ExtendedError, native_module.NativeError) as exc:
                    self.extended[precision] = None
                    self.skipped[method] = str(exc).splitlines()[0]
                self.extended_compile[precision] = time.perf_counter() - t0
            if self.extended[precision] is None:
                return self.skipped[method]
        return ""

    def prepare(self, method: str, tol: float) -> Callable[[], tuple]:
        """The timed run of ``method`` at ``tol``: a function returning ``(y_end, evaluations,
        steps, status)``, the ``final_state`` of the method's engine (:mod:`.engines`, as the
        method table says); what it compiles for this tolerance is timed apart."""
        t_end, y0, param = self.t_end, self.y0, self.param
        engine = METHODS[method].engine if method in KNOWN_METHODS else None
        if engine == "c":
            native, h = self.native, fixed_step(method, tol, t_end) if method in FIXED_STEP_ORDER else None
            restart = (lambda: self._fresh_rhs(tol)) if self.dependent is not None else (lambda: None)

            def run():
                restart()
                return c_engine.final_state(native, method, y0, t_end, param, tol, h)
            return run
        if engine == "scipy":
            return lambda: scipy_engine.final_state(self._fresh_rhs(tol), method, y0, t_end, tol, RUN_STEPS,
                                                    STALLED_STEPS)
        if engine == "taylor":
            from .taylor_c import order_for

            taylor = self.extended["taylor"]
            t0 = time.perf_counter()
            taylor.build(order_for(tol))  # one library per order, compiled apart from the timing
            self.taylor_compile[tol] = time.perf_counter() - t0
            return lambda: taylor_engine.final_state(taylor, param, y0, t_end, tol)
        if engine == "extended":
            model = self.extended[EXTENDED[method]]
            param_list, y0_list = [float(v) for v in param], [float(v) for v in y0]
            return lambda: extended_engine.final_state(model, param_list, y0_list, t_end, tol)
        if engine == "heyoka":
            from .heyoka_backend import HeyokaIntegrator

            t0 = time.perf_counter()
            integrator = HeyokaIntegrator(self.system, tol)
            self.heyoka_compile[tol] = time.perf_counter() - t0
            grid = np.array([0.0, t_end])
            return lambda: heyoka_engine.final_state(integrator, param, y0, grid)
        raise AccuracyError(f"unknown method '{method}'")

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
        t_end, y0, param = self.t_end, self.y0, self.param
        if METHODS[method].engine == "c":
            self._fresh_rhs(tol)
            if method == "dop853":
                T, Y, _ = self.native.integrate("dop853", 0.0, y0, t_end, 0.0, param, rtol=tol, atol=tol)
            else:  # the step of the timed run: t_end over a whole number of steps
                h = t_end / max(1, math.ceil(t_end / fixed_step(method, tol, t_end) - 1e-9))
                T, Y, _ = self.native.integrate(method, 0.0, y0, t_end, h, param, h=h)
            return T, Y
        import scipy.integrate

        rhs = self._fresh_rhs(tol)
        times, states = [0.0], [y0.copy()]
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            solver = getattr(scipy.integrate, method)(rhs, 0.0, y0.copy(), t_end, rtol=tol, atol=tol)
            try:
                while solver.status == "running":
                    solver.step()
                    times.append(solver.t)
                    states.append(solver.y.copy())
            except Exception:  # the timed run reports the failure
                pass
        return np.array(times), np.array(states)

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


def _conservative(runners: _Runners, ref: Reference) -> tuple[bool, float | None, float]:
    """Whether energy is conserved along the reference (to 1e-9 relative): (flag, E(0), scale)."""
    E0 = runners.energy(runners.y0, runners.dependent)
    if E0 is None:
        return False, None, 1.0
    dependent = [[float(v) for v in d] for d in ref.dependent] or [None] * len(ref.times)
    energies, kinetic = [], []
    for i in range(len(ref.times)):
        energies.append(runners.energy(np.array(ref.at(i)), dependent[i]))
        kinetic.append(runners.native.kinetic_energy(np.array(ref.at(i)), runners.param))  # at that y_d
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


def measure(system: KnownSystem, values: RunValues, t_end: float, methods: tuple[str, ...],
            tolerances: tuple[float, ...], *, ref: Reference | None = None, digits: int = 20,
            quick: bool = False, progress: bool | None = None, budget: float | None = None,
            max_repeats: int | None = None, dependent=None) -> WorkPrecision:
    """Every method at every tolerance, against ``ref`` (computed at ``digits`` digits when
    not given; its last time must be ``t_end``). With implicit constraints, ``values`` must be
    on them and ``dependent`` is ``y_d`` there (:func:`.constrained.project_initial`; done
    here when not given)."""
    if not (t_end > 0 and math.isfinite(t_end)):
        raise AccuracyError("--t must be a positive number")
    implicit = system.implicit
    if implicit is not None and dependent is None:
        from .constrained import project_initial

        values, _, closure = project_initial(system, {}, {}, values, 1e-14)
        dependent = closure.guess
    param, y0 = np.array(values.parameters, dtype=float), np.array(values.y0, dtype=float)
    from ..core.finite import at_state

    cause = at_state(system, 0.0, y0, param) if implicit is None else _implicit_cause(system, y0, param, dependent)
    if cause is not None:  # every method would fail at once, against a reference computed exactly
        raise AccuracyError(f"the equations have no {'finite' if cause.overflow else 'real'} value at the "
                            f"initial state: {cause.what}\n  hint: {cause.hint}")
    if ref is None:
        ref = compute_reference(system, values.parameters, values.y0, sample_times(t_end), digits,
                                dependent=None if implicit is None else [float(v) for v in dependent])
    if abs(ref.times[-1] - t_end) > 1e-12 * t_end:
        raise AccuracyError(f"the reference ends at t = {ref.times[-1]}, not at {t_end}")
    want = np.array(ref.at(len(ref.times) - 1))
    runners = _Runners(system, param, y0, t_end, dependent)
    conservative, E0, scale = _conservative(runners, ref)
    budget = (0.05 if quick else 0.3) if budget is None else budget
    max_repeats = (3 if quick else 9) if max_repeats is None else max_repeats
    skipped = {}
    plan = []
    for method in methods:
        why = runners.available(method)
        if why:
            skipped[method] = why
        else:
            plan.extend((method, tol) for tol in tolerances)
    bar = Progress(len(plan), progress)
    points = []
    slow: dict[str, float] = {}
    try:
        for method, tol in plan:
            bar.step(f"{method} {tol:.0e}")
            if method not in EXTENDED and tol < FLOAT64_FLOOR:
                skipped.setdefault(method, f"tolerances below {FLOAT64_FLOOR:.0e} skipped (float64 cannot meet them)")
                continue
            if method in slow:
                skipped.setdefault(method, f"tolerances {tol:.0e} and tighter skipped: one run took "
                                           f"{slow[method]:.1f} s (over {SLOW_SECONDS:g} s)")
                continue
            run = runners.prepare(method, tol)
            (y_end, evals, steps, status), seconds, repeats = _timed(run, budget, max_repeats)
            if method in EXTENDED:  # the error in the type's precision, before rounding to float64
                with mpmath.workdps(50):
                    error = float(max(abs(a - b) for a, b in zip(y_end, ref.states[-1])))
            y_end = np.array([float(v) for v in y_end])
            if method not in EXTENDED:
                error = float(np.max(np.abs(y_end - want))) if np.all(np.isfinite(y_end)) else math.nan
            residual = velocity_residual = dependent_end = None
            if implicit is not None:
                residual, velocity_residual, dependent_end = runners.residuals(method, tol)
            drift = None
            if conservative and method not in EXTENDED and np.all(np.isfinite(y_end)) and \
                    (implicit is None or dependent_end is not None):
                E = runners.energy(y_end, dependent_end)
                drift = None if E is None else abs(E - E0) / scale
            if status:  # a run that stopped measured no error at t_end
                error, drift, residual, velocity_residual = math.nan, None, None, None
            setting = f"h {fixed_step(method, tol, t_end):.3g}" if method in FIXED_STEP_ORDER else f"tol {tol:.0e}"
            compiled = runners.heyoka_compile.get(tol) if method == "heyoka" else \
                runners.taylor_compile.get(tol) if method == "taylor" else \
                runners.extended_compile.get(EXTENDED.get(method, method))
            points.append(Point(method, tol, setting, error, drift, seconds, evals, steps, repeats, compiled, status,
                                residual, velocity_residual))
            if seconds > SLOW_SECONDS:
                slow[method] = seconds
    finally:
        bar.close()
    state = [q.name for q in system.coordinates] + [v.name for v in system.velocities]
    return WorkPrecision(system.name, t_end, points, ref, runners.compile_seconds, conservative,
                         {**runners.skipped, **skipped},
                         tuple(c.name for c in implicit.constraints) if implicit is not None else (),
                         {p.name: float(v) for p, v in zip(system.parameters, param)},
                         dict(zip(state, map(float, y0))),
                         {d.name: float(v) for d, v in zip(implicit.dependent, dependent)} if implicit is not None
                         else {})
