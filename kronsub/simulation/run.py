"""Integrating the equations of motion: the run driver.

The right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` is the generated
C, compiled once and cached by content hash; without a C compiler, or when
the compilation fails, the generated numpy module (:mod:`.fallback`) stands in
(with a one-line warning). The method table is :mod:`.methods`; each method's engine
(:mod:`.engines`, one interface) computes its rows. A run is split into chunks so
long runs can show progress and stream their rows (:func:`start` yields blocks
of at most :data:`.rows.BLOCK_ROWS` rows, so memory does not grow with the run); a
non-finite state or a mass matrix that is not positive definite stops it,
keeping the rows so far.
"""
from __future__ import annotations

import math
import sys
import warnings

import numpy as np

from ..core.first_order import zero_rows
from ..core.held import held_coordinates
from ..core.known_system import KnownSystem
from ..core.projection_work import projected_in_numbers
from ..errors import on_command_line, option
from .advice import EnergyWarning, StiffnessWarning, energy_advice, is_stiff, stiffness_advice
from .compiled import native_model
from .engines import Problem, Steps, engine_of, runner
from .engines.scipy import IMPLICIT, native_rhs
from .failure import failed_state
from .first_order import first_order_rows
from .fallback import module_energies, numpy_module, numpy_rhs, numpy_rhs_of
from .frame_crossing import SingularSpeedsWarning, frame_watch
from .grid import Grid, Tail
from .methods import METHODS as REGISTRY
from .methods import SIMULATE, unknown_method
from .native import CANONICAL_METHODS, CompileError, CompilerNotFound
from .numeric_speeds import NumericSpeeds
from .power import charge_coordinates
from .progress import Progress
from . import rows as streamed
from .rows import Block, RunInProgress, SimulationError, Trajectory
from .values import RunValues

__all__ = ["Block", "EnergyWarning", "FIXED_STEP", "MAX_ROWS", "METHODS", "MIN_ATOL", "MIN_TIME",
           "Progress", "RTOL_RANGE", "RunInProgress", "SimulationError", "StiffnessWarning", "Trajectory", "check_tolerances",
           "collect", "explicit_only", "row_count", "simulate", "start", "time_problem"]


METHODS = {name: REGISTRY[name] for name in SIMULATE}  # the methods of ``simulate``, by name


FIXED_STEP = tuple(name for name, m in METHODS.items() if m.fixed_step)  # the methods that step --dt at a time


MAX_ROWS = 10**8  # a run asking for more rows is a mistake (--dt far too small), not a plan


MIN_TIME = sys.float_info.min  # the smallest normal double: a subnormal one has too few bits to step by


RTOL_RANGE = (1e-15, 1.0)  # tighter is below the round-off of doubles; looser asks for no accuracy


MIN_ATOL = 1e-30  # tighter than any state of a mechanical model in SI units needs, and not met at t = 0


def time_problem(name: str, value: float) -> str | None:
    """Why the option ``name`` (``t`` or ``dt``) cannot be ``value`` (None: it can): a positive
    finite normal double."""
    if math.isfinite(value) and value >= MIN_TIME:
        return None
    what = "time" if name == "t" else "interval"
    return f"{option(name)} must be a positive finite {what} of at least {MIN_TIME:.3g} (got {value!r})"


def row_count(t_end: float, dt: float) -> int:
    """The number of output rows of a run from 0 to ``t_end`` every ``dt``; raises
    :class:`SimulationError` when ``t_end`` or ``dt`` is not a positive finite normal number
    (:func:`time_problem`) or the run would have more than :data:`MAX_ROWS` rows."""
    for name, value in (("t", t_end), ("dt", dt)):
        why = time_problem(name, value)
        if why is not None:
            raise SimulationError(why)
    ratio = t_end / dt
    if not ratio < MAX_ROWS:
        t, step = option("t"), option("dt")
        raise SimulationError(f"{t} {t_end:g} with {step} {dt:g} asks for {ratio:.3g} rows, more than "
                              f"{MAX_ROWS:.0e}; raise {step} or shorten {t}")
    return len(Grid(t_end, dt))


def check_tolerances(rtol: float, atol: float) -> None:
    """Raise :class:`SimulationError` unless ``rtol`` is in :data:`RTOL_RANGE` and ``atol`` is 0
    or finite and at least :data:`MIN_ATOL` (an adaptive method's error test is
    ``|err| <= atol + rtol |y|``: a tighter one is below round-off, and the run stops at t = 0;
    ``rtol`` 0 is refused, not raised quietly to SciPy's floor of 100 eps as SciPy does)."""
    low, high = RTOL_RANGE
    r, a = option("rtol"), option("atol")
    example = f"e.g. {r} 1e-10 {a} 1e-10" if on_command_line() else "e.g. rtol=1e-10, atol=1e-10"
    if not low <= rtol <= high:
        given = f"{r} {low:g}" if on_command_line() else f"rtol={low:g}"
        raise SimulationError(f"{r} must be a finite tolerance from {low:g} to {high:g} (got {rtol!r})\n"
                              f"  hint: a relative tolerance below {low:g} is under the round-off of doubles "
                              f"(for an error test on {a} alone, give {given}); {example}")
    if not (atol == 0 or MIN_ATOL <= atol < math.inf):
        raise SimulationError(f"{a} must be a finite tolerance of at least 0: 0, or at least {MIN_ATOL:g} "
                              f"(got {atol!r})\n"
                              f"  hint: it is in the units of the state; {example}")


def simulate(system: KnownSystem, values: RunValues, t_end: float, dt: float, method: str = "dop853",
             rtol: float = 1e-10, atol: float = 1e-10, chunks: int = 20, progress: bool | None = None,
             outputs=None, constrained=None, jacobian: bool = False) -> Trajectory:
    """Integrate from t = 0 to ``t_end`` with rows every ``dt`` (all rows in memory); the
    arguments as for :func:`start`."""
    run = start(system, values, t_end, dt, method, rtol, atol, chunks, progress, outputs, constrained, jacobian)
    return collect(run, list(run), len(system.coordinates), len(system.coordinates) + len(system.state_velocities))


def collect(run: RunInProgress, blocks: list[Block], nq: int, ny: int | None = None) -> Trajectory:
    """The trajectory of ``blocks`` of ``run`` (all of them, or those before an interrupt) in a
    state of ``ny`` entries (``[q; qdot]``, ``2 nq``; ``[q; u]`` under velocity constraints, as the
    blocks hold it when not given)."""
    n = ny if ny is not None else next((b.y.size // len(b.t) for b in blocks if len(b.t)), 2 * nq)
    t = np.concatenate([b.t for b in blocks]) if blocks else np.zeros(0)
    y = np.concatenate([b.y.reshape(-1, n) for b in blocks]) if blocks else np.zeros((0, n))
    energies = dependent = None
    if blocks and all(b.energies is not None for b in blocks):
        energies = (np.concatenate([b.energies[0] for b in blocks]), np.concatenate([b.energies[1] for b in blocks]))
    if blocks and all(b.dependent is not None for b in blocks):
        dependent = np.concatenate([b.dependent for b in blocks])
    segments = None
    if blocks and all(b.split is not None for b in blocks):
        segments, start = [], 0
        for b in blocks:
            segments.append((start, start + len(b.t), b.split, b.own))
            start += len(b.t)
    return Trajectory(t, y, run.method, run.complete, run.message, run.t_fail, run.stats, run.backend, energies,
                      run.y_fail, dependent, list(run.switches), segments)


def explicit_only(system: KnownSystem, method: str) -> None:
    """Raise :class:`SimulationError` when ``method`` needs explicit equations (a Taylor series) and
    ``system`` has implicit constraints, or first-order coordinates (those methods integrate
    ``qddot = Mbar^-1 (fbar - hbar)`` of their own; the others take the generated right-hand side)."""
    if method not in METHODS or METHODS[method].closed_loops:
        return
    if system.implicit is not None:
        raise SimulationError(f"method '{method}' needs explicit equations (its Taylor series), which a system "
                              "with implicit constraints does not have; use dop853 (default), gauss4, Radau or LSODA")
    if system.speeds is not None:
        raise SimulationError(f"method '{method}' is not supported yet with velocity constraints (the state [q; u] "
                              "has no Taylor series or canonical form here); use dop853 (default), gauss4, Radau "
                              "or LSODA")
    rows = zero_rows(system)
    if rows:
        names = ", ".join(system.coordinates[j].name for j in rows)
        which = "is a first-order coordinate" if len(rows) == 1 else "are first-order coordinates"
        raise SimulationError(f"method '{method}' needs second-order equations in every coordinate (its Taylor "
                              f"series), and {names} {which} (no inertia: its velocity is solved, not integrated); "
                              "use dop853 (default), gauss4, Radau or LSODA")


def start(system: KnownSystem, values: RunValues, t_end: float, dt: float, method: str = "dop853",
          rtol: float = 1e-10, atol: float = 1e-10, chunks: int = 20, progress: bool | None = None,
          outputs=None, constrained=None, jacobian: bool = False) -> RunInProgress:
    """A run from t = 0 to ``t_end`` with rows every ``dt``, streamed: the model is compiled
    now, the rows are computed in blocks (at most :data:`.rows.BLOCK_ROWS` each) while the
    :class:`RunInProgress` is iterated.

    ``outputs`` (a scene's; None: everything) decides whether the energies are computed. With
    implicit constraints, ``constrained`` is the :class:`~kronsub.core.constraints.Intermediates`
    of the projected initial conditions (:func:`.constrained.project_initial`). ``jacobian``: the
    implicit methods (Radau, LSODA) take the generated exact ``d ydot/dy`` instead of finite
    differences (not with implicit constraints)."""
    if method not in METHODS:
        raise SimulationError(unknown_method(method))
    explicit_only(system, method)
    row_count(t_end, dt)
    check_tolerances(rtol, atol)
    if system.implicit is not None and constrained is None:
        from .constrained import project_initial

        values, _, constrained = project_initial(system, dict(system.initial), {}, values, _newton_tol(rtol, atol))
    param = np.array(values.parameters, dtype=float)
    y0 = np.array(values.y0, dtype=float)
    grid = Grid(t_end, dt)
    spec = METHODS[method]
    with_energies = outputs is None or outputs.energies
    if not engine_of(spec).COMPILED_RHS:  # its own integrator; the compiled model for the energies and their check
        native = _compiled_quietly(system, outputs) if with_energies else None
        rows_of = runner(_problem(system, param, native, outputs, constrained, rtol, atol), spec)
        run = RunInProgress(spec.name, rows_of.backend)
        bar = Progress(t_end, False)
        rows = rows_of.blocks(run, grid, y0, Steps(rtol, atol, dt, math.ceil(len(grid) / streamed.BLOCK_ROWS)), bar)
        run.blocks = _finish(run, rows, bar, native, param, system, None, with_energies)
        return run
    native = _compiled(system, outputs, jacobian and spec.name in IMPLICIT and system.implicit is None
                       and system.speeds is None, spec.name in CANONICAL_METHODS)
    if constrained is not None and native is not None:
        from .constrained import configure_native

        configure_native(native, constrained.guess, _newton_tol(rtol, atol))
    if native is None and projected_in_numbers(system):  # no C, and the equations in the speeds too large for numpy's
        return _numeric_run(system, param, spec, grid, y0, Steps(rtol, atol, dt, chunks), progress, with_energies)
    if native is None and spec.fallback is not None:
        warnings.warn(f"method '{method}' runs in compiled C; using scipy's {spec.fallback} instead")
        spec = METHODS[spec.fallback]
    rows_of = runner(_problem(system, param, native, outputs, constrained, rtol, atol), spec)
    run = RunInProgress(spec.name, rows_of.backend, library=native.path if native is not None else None)
    bar = Progress(t_end, progress)
    if not bar.enabled:
        chunks = 1  # one call: no restarts of the step-size control
    chunks = max(chunks, math.ceil(len(grid) / streamed.BLOCK_ROWS))
    if system.implicit is not None and system.implicit.choice == "auto":  # may switch coordinates
        run.blocks = _auto_blocks(run, system, spec, native, constrained, grid, y0, param,
                                  Steps(rtol, atol, dt, chunks), bar, outputs, with_energies)
        return run
    rows = rows_of.blocks(run, grid, y0, Steps(rtol, atol, dt, chunks), bar)
    first = zero_rows(system)
    if first:  # the first-order coordinates' velocities in the rows, from the right-hand side
        rows = first_order_rows(rows, _problem(system, param, native, outputs, constrained, rtol, atol).restart(None),
                                first, len(system.coordinates))
    run.blocks = _finish(run, rows, bar, native, param, system, constrained, with_energies, grid)
    return run


def _numeric_run(system, param, spec, grid, y0, steps, progress, with_energies) -> RunInProgress:
    """A run without compiled C of a system whose equations in the speeds are too large to project
    symbolically (the generated C projects them at run time, :mod:`kronsub.emitters.projected_speeds`):
    projected in numbers at every evaluation (:mod:`.numeric_speeds`), a method wholly in C as its
    scipy fallback."""
    if spec.engine != "scipy":
        if spec.fallback is None:
            raise SimulationError(f"method '{spec.name}' needs compiled C, which is not available here (this "
                                  "model's equations in the speeds are projected in numpy at every step); use "
                                  "DOP853, RK45, Radau or LSODA")
        warnings.warn(f"method '{spec.name}' runs in compiled C, which is not available here (this model's "
                      f"equations in the speeds are projected in numpy at every step); using scipy's "
                      f"{spec.fallback} instead")
        spec = METHODS[spec.fallback]
    numeric = NumericSpeeds(system, param)
    rows_of = runner(Problem(system, param, None, numeric.restart), spec)
    run = RunInProgress(spec.name, rows_of.backend)
    bar = Progress(grid.t_end, progress)
    chunks = steps.chunks if bar.enabled else 1
    steps = Steps(steps.rtol, steps.atol, steps.dt, max(chunks, math.ceil(len(grid) / streamed.BLOCK_ROWS)))
    rows = rows_of.blocks(run, grid, y0, steps, bar)
    run.blocks = _finish(run, rows, bar, None, param, system, None, with_energies, grid, numeric)
    return run


def _problem(system, param, native, outputs, constrained, rtol, atol) -> Problem:
    """What the engines receive: the right-hand side is the compiled model's, or the numpy
    module's when nothing compiled (made when an engine asks for it; a run's tolerances, and
    with them its Newton's method, are set already, so it does not depend on ``tol``)."""
    def restart(tol):
        return (native_rhs(native, param) if native is not None else
                numpy_rhs(system, param, outputs, constrained, _newton_tol(rtol, atol)))

    return Problem(system, param, native, restart)


def _compiled(system, outputs, jacobian: bool = False, canonical: bool = True):
    """The model compiled from its generated C (``jacobian``: with ``ks_jacobian``; ``canonical``:
    with the canonical right-hand side), or None (with a warning) to use the numpy module."""
    try:
        return native_model(system, outputs, jacobian, canonical)
    except CompilerNotFound:
        warnings.warn("no C compiler found: using the generated numpy module (slower)")
    except CompileError as exc:
        first = next((line for line in exc.stderr.splitlines() if "error" in line), "") or str(exc).splitlines()[0]
        warnings.warn(f"compiling the generated C failed ({first.strip()}): using the generated numpy module (slower)")
    return None


def _compiled_quietly(system, outputs):
    """The compiled model for the energies of rows computed without it (heyoka, taylor), or None:
    those rows do not need it, so a missing compiler says nothing here."""
    try:
        return native_model(system, outputs, canonical=False)
    except (CompilerNotFound, CompileError):
        return None


def _auto_blocks(run, system, spec, native, constrained, grid, y0, param, steps, bar, outputs, with_energies):
    """The blocks of a run with ``coordinates: auto``, switching the independent coordinates where
    ``G_d`` nears singular (:mod:`.switching`); rows in the layout of the first choice. An engine
    that does not watch events between rows runs a stretch again in the method's fallback, which
    does, when it stopped in Newton's method or at a singular ``G_d``."""
    from ..core.constraints import ConstraintFailure
    from . import switching as sw
    from .constrained import configure_module, configure_native, diagnose

    tol = _newton_tol(steps.rtol, steps.atol)
    first = split = sw.Split(system, constrained)
    offset, start, total = 0, None, {}
    last = None  # (t, y, ydot) of the last row written
    watched = False  # this stretch again in the fallback, whose event watches G_d between the rows
    try:
        while True:
            if offset:
                native = _compiled(split.system, outputs, canonical=spec.name in CANONICAL_METHODS)
                if native is None and spec.fallback is not None:
                    spec = METHODS[spec.fallback]
            module = None
            if native is not None:
                configure_native(native, split.evaluator.guess, tol)
            else:
                module = numpy_module(split.system, outputs)
                configure_module(module, split.evaluator.guess, tol)

            def restart(_, native=native, module=module):
                return native_rhs(native, param) if native is not None else numpy_rhs_of(module, param)

            problem = Problem(split.system, param, native, restart, events=_toggle_event(split), diagnosed=False)
            rows = runner(problem, METHODS[spec.fallback] if watched and spec.fallback else spec).blocks(
                run, Tail(grid, offset, start), y0, steps, bar)
            switch = None
            for index, (t, Y) in enumerate(rows):
                if last is not None and index == 0:
                    continue  # the row it went on from, written already (or between two rows)
                Y = np.asarray(Y).reshape(len(t), -1)
                out, dependent, cut = [], [], len(t)
                for i, row in enumerate(Y):
                    try:
                        y, ydot = split.full(row)
                    except ConstraintFailure:
                        out.append(np.full(2 * len(first.independent_idx), np.nan))
                        dependent.append(np.full(len(first.dependent_idx), np.nan))
                        continue
                    out.append(first.row(y, ydot))
                    dependent.append(y[first.dependent_idx])
                    last = (float(t[i]), y, ydot)
                    best = sw.watch(split, y) if len(run.switches) < sw.MAX_SWITCHES else None
                    if best is not None:
                        switch, cut = best, i + 1
                        break
                energies = None
                if with_energies:
                    energies = (native.energies(t[:cut], Y[:cut], param) if native is not None else
                                module_energies(module, t[:cut], Y[:cut], param))
                yield Block(np.asarray(t[:cut]), np.array(out), energies, np.array(dependent), split,
                            np.array(Y[:cut], dtype=float))
                if switch is not None:
                    rows.close()
                    break
            for k, v in run.stats.items():
                total[k] = total.get(k, v) if k == "stiff_from" else total.get(k, 0) + v
            if run.pending is not None:  # scipy's event: the switch where it fired
                t_event, y_event = run.pending
                run.pending = None
                y, ydot = split.full(y_event)
                switch = split.numeric.pivot(y)
                last = (t_event, y, ydot)
            again = False
            if switch is None and not run.complete and last is not None:
                # stopped in Newton's method or at a singular G_d: another choice from the last row
                best = split.numeric.pivot(last[1])
                if sorted(best) != sorted(split.dependent_idx) and len(run.switches) < sw.MAX_SWITCHES:
                    switch = best
                elif not engine_of(spec).EVENTS and not watched and len(run.switches) < sw.MAX_SWITCHES:
                    again = True  # it watched only the rows: from the last one again, watched between rows
                if switch is not None or again:
                    run.complete, run.message, run.t_fail, run.y_fail = True, "", None, None
            watched = again
            if switch is None and not again:
                break
            t_switch, y, ydot = last
            if switch is not None:
                new = sw.switched_split(split, switch, y, tol)
                run.switches.append((t_switch, sw.describe(t_switch, split, new)))
                split = new
            y0 = split.row(y, ydot)
            # go on from the switch: the grid rows after it (a switch between rows starts off the grid)
            offset = min(int(round(t_switch / grid.dt)), len(grid) - 1)
            if abs(grid[offset] - t_switch) <= 1e-6 * grid.spacing:
                start = None
            else:
                offset = next((i for i in range(max(offset - 1, 0), len(grid)) if grid[i] > t_switch), len(grid) - 1)
                start = t_switch
    finally:
        bar.close()
    run.stats = total
    if not run.complete and last is not None:
        guess = split.evaluator.guess.copy()
        run.message = diagnose(split.system, split.evaluator, run.t_fail, failed_state(run, split.row(*last[1:])),
                               guess)


def _toggle_event(split):
    """A terminal event of scipy's integration: the sign turns where the current independent
    coordinates near a toggle (an implicit method would otherwise creep towards it)."""
    from ..core.constraints import ConstraintFailure
    from .switching import watch

    def event(t, y):
        try:
            full, _ = split.full(y)
        except ConstraintFailure:
            return -1.0
        return -1.0 if watch(split, full) is not None else 1.0

    event.terminal = True
    return event


def _newton_tol(rtol: float, atol: float) -> float:
    from .constrained import newton_tolerance

    return newton_tolerance(rtol, atol)


def _finish(run, rows, bar, native, param, system, constrained, with_energies=True, grid=None, numeric=None):
    """The blocks (in speeds, the coordinates held by configuration constraints put on them), with
    energies computed in C when there is a compiled model (and they are wanted) and, with implicit
    constraints, the dependent coordinates per row (and, after a failure, what failed); at the end, a warning when an explicit run was held by stiffness, and
    one when a complete run of a model that conserves energy did not keep it."""
    guess = constrained.guess.copy() if constrained is not None else None
    watch = frame_watch(system, param)
    held = held_coordinates(system, {p.symbol: float(v) for p, v in zip(system.parameters, param)})
    first_t = last_t = last_y = None
    energy = None  # (t0, y0, E0, largest T, last E) of the rows, when they have energies
    try:
        for t, y in rows:
            if len(t):
                if held is not None:  # on the configuration constraints, as the right-hand side puts them
                    y = held.rows(t, y)
                dependent = None
                if constrained is not None:
                    from .constrained import dependent_rows

                    dependent = dependent_rows(constrained, np.asarray(y), len(system.coordinates), guess)
                    guess = dependent[-1] if len(dependent) else guess
                energies = None
                if numeric is not None and with_energies:
                    energies = numeric.energies(t, y)
                if native is not None and with_energies:
                    if dependent is None:
                        energies = native.energies(t, y, param)
                    else:  # on each row's own branch, not from the integrator's warm start
                        from .constrained import energies_on_branch

                        energies = energies_on_branch(native, t, y, param, dependent)
                last_y, last_t = np.asarray(y)[-1], float(np.asarray(t)[-1])
                first_t = float(np.asarray(t)[0]) if first_t is None else first_t
                if energies is not None:
                    T, V = energies
                    if energy is None:
                        energy = (float(np.asarray(t)[0]), np.asarray(y)[0].copy(), float(T[0] + V[0]), 0.0, 0.0)
                    energy = (*energy[:3], max(energy[3], float(np.max(np.abs(T)))), float(T[-1] + V[-1]))
                if watch is not None:
                    watch.see(t, y)
                yield Block(grid.snap(t) if grid is not None else np.asarray(t), np.asarray(y), energies, dependent)
    finally:
        bar.close()
    if constrained is not None and not run.complete and last_y is not None:
        from .constrained import diagnose

        run.message = diagnose(system, constrained, run.t_fail, failed_state(run, last_y), guess)
    if held is not None and not run.complete and last_y is not None and run.t_fail is not None:
        from .held import diagnose as held_failure

        run.message = held_failure(system, held, run.t_fail, failed_state(run, last_y)) or run.message
    if native is not None and last_y is not None and is_stiff(run.stats):
        warnings.warn(StiffnessWarning(stiffness_advice(native, param, run.stats, last_t - first_t, last_t, last_y,
                                                         run.method, [q.name for q in system.coordinates],
                                                         charge_coordinates(system))))
    crossed = watch.advice() if watch is not None else ""
    if crossed:
        warnings.warn(SingularSpeedsWarning(crossed))
    if energy is not None and run.complete and constrained is None and not run.switches:
        advice = energy_advice(native, param, len(system.coordinates), run.method, *energy)
        if advice:
            warnings.warn(EnergyWarning(advice))
