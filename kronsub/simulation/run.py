"""Integrating the equations of motion: the method table and the run driver.

The right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]`` is the generated
C, compiled once and cached by content hash; without a C compiler, or when
the compilation fails, the generated numpy module stands in (with a one-line
warning). A run is split
into chunks so long runs can show progress and stream their rows (:func:`start`
yields blocks of at most :data:`BLOCK_ROWS` rows, so memory does not grow with
the run); a non-finite state or a mass matrix that is not positive definite
stops it, keeping the rows so far.
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core.known_system import KnownSystem
from ..emitters.code import emit_python
from ..emitters.escape import python_string
from ..errors import KronsubError
from .compiled import native_model
from .methods import METHODS as REGISTRY, SIMULATE, unknown_method
from .native import CompileError, CompilerNotFound
from .values import RunValues


METHODS = {name: REGISTRY[name] for name in SIMULATE}  # the methods of ``simulate``, by name
FIXED_STEP = tuple(name for name, m in METHODS.items() if m.fixed_step)  # the methods that step --dt at a time


class StiffnessWarning(UserWarning):
    """An explicit method found the problem stiff (Hairer's test): an implicit one would be cheaper."""


class EnergyWarning(UserWarning):
    """A run did not keep the energy of a model that conserves it: its rows are not accurate."""


class SimulationError(KronsubError):
    """A run that could not start."""


@dataclass
class Trajectory:
    """Rows of a run: times, states ``[q; qdot]``, and how the run ended."""

    t: np.ndarray
    y: np.ndarray
    method: str
    complete: bool = True
    message: str = ""
    t_fail: float | None = None
    stats: dict = field(default_factory=dict)
    backend: str = ""
    energies: tuple[np.ndarray, np.ndarray] | None = None  # (T, V) per row, when computed in C
    y_fail: np.ndarray | None = None  # the state at which the right-hand side failed, when known
    dependent: np.ndarray | None = None  # implicit constraints: the dependent coordinates per row
    switches: list = field(default_factory=list)  # coordinates: auto: (t, what) per switch
    # coordinates: auto: (first row, end row, split, its own rows [q; qdot] in its own layout) per
    # stretch of rows computed with one choice of independent coordinates (switching.Split)
    segments: list | None = None


def _numpy_module(system: KnownSystem, outputs=None):
    """The generated numpy module, loaded from its text (our own generated code)."""
    namespace: dict = {}
    (generated,) = emit_python(system, "model", outputs=outputs)
    exec(compile(generated.text, f"<kronsub model {python_string(system.name)}>", "exec"), namespace)
    return namespace


class _Progress:
    """A progress bar on stderr for runs longer than a second, only on a terminal."""

    def __init__(self, total: float, enabled: bool | None = None):
        self.total = total
        self.start = time.perf_counter()
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False

    def update(self, t: float) -> None:
        if not self.enabled or time.perf_counter() - self.start < 1.0:
            return
        frac = min(1.0, t / self.total) if self.total > 0 else 1.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r[{bar:<30}] t = {t:.4g} / {self.total:.4g}")
        sys.stderr.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")


MAX_ROWS = 10**8  # a run asking for more rows is a mistake (--dt far too small), not a plan
BLOCK_ROWS = 100_000  # rows per block of a streamed run (bounds the memory of long runs)


MIN_TIME = sys.float_info.min  # the smallest normal double: a subnormal one has too few bits to step by
RTOL_RANGE = (1e-15, 1.0)  # tighter is below the round-off of doubles; looser asks for no accuracy
MIN_ATOL = 1e-30  # tighter than any state of a mechanical model in SI units needs, and not met at t = 0


def time_problem(flag: str, value: float) -> str | None:
    """Why ``--t`` or ``--dt`` cannot be ``value`` (None: it can): a positive finite normal double."""
    if math.isfinite(value) and value >= MIN_TIME:
        return None
    what = "time" if flag == "--t" else "interval"
    return f"{flag} must be a positive finite {what} of at least {MIN_TIME:.3g} (got {value!r})"


def row_count(t_end: float, dt: float) -> int:
    """The number of output rows of a run from 0 to ``t_end`` every ``dt``; raises
    :class:`SimulationError` when ``t_end`` or ``dt`` is not a positive finite normal number
    (:func:`time_problem`) or the run would have more than :data:`MAX_ROWS` rows."""
    for flag, value in (("--t", t_end), ("--dt", dt)):
        why = time_problem(flag, value)
        if why is not None:
            raise SimulationError(why)
    ratio = t_end / dt
    if not ratio < MAX_ROWS:
        raise SimulationError(f"--t {t_end:g} with --dt {dt:g} asks for {ratio:.3g} rows, more than "
                              f"{MAX_ROWS:.0e}; raise --dt or shorten --t")
    return len(_Grid(t_end, dt))


def check_tolerances(rtol: float, atol: float) -> None:
    """Raise :class:`SimulationError` unless ``rtol`` is 0 or in :data:`RTOL_RANGE`, ``atol`` 0 or
    finite and at least :data:`MIN_ATOL`, and not both are zero (an adaptive method's error test
    ``|err| <= atol + rtol |y|``: a tighter one is below round-off, and the run stops at t = 0)."""
    low, high = RTOL_RANGE
    if not (rtol == 0 or low <= rtol <= high):
        raise SimulationError(f"--rtol must be a finite tolerance of at least 0: 0, or from {low:g} to {high:g} "
                              f"(got {rtol!r})\n"
                              f"  hint: a relative tolerance below {low:g} is under the round-off of doubles; "
                              "e.g. --rtol 1e-10 --atol 1e-10")
    if not (atol == 0 or MIN_ATOL <= atol < math.inf):
        raise SimulationError(f"--atol must be a finite tolerance of at least 0: 0, or at least {MIN_ATOL:g} "
                              f"(got {atol!r})\n"
                              "  hint: it is in the units of the state; e.g. --rtol 1e-10 --atol 1e-10")
    if rtol == 0 and atol == 0:
        raise SimulationError("--rtol and --atol are both 0: no step would pass the error test\n"
                              "  hint: give one of them a positive value, e.g. --rtol 1e-10")


@dataclass
class Block:
    """Consecutive rows of a run: times, states ``[q; qdot]`` and, when computed in C, ``(T, V)``."""

    t: np.ndarray
    y: np.ndarray
    energies: tuple[np.ndarray, np.ndarray] | None = None
    dependent: np.ndarray | None = None  # implicit constraints: the dependent coordinates per row
    split: object | None = None  # coordinates: auto: the choice (switching.Split) that computed these rows
    own: np.ndarray | None = None  # ... and the rows in its own layout (the first choice's are in ``y``)


@dataclass
class Run:
    """A run in progress: iterate over it for its :class:`Block` s of rows, as they are
    computed; once the iteration ends, ``complete``, ``message``, ``t_fail`` and ``stats``
    say how the run ended."""

    method: str
    backend: str
    blocks: object = None
    complete: bool = True
    message: str = ""
    t_fail: float | None = None
    stats: dict = field(default_factory=dict)
    y_fail: np.ndarray | None = None  # the state at which the right-hand side failed, when known
    switches: list = field(default_factory=list)  # coordinates: auto: (t, old, new) independent coordinates
    pending: tuple | None = None  # (t, y) where scipy's toggle event stopped a segment

    def __iter__(self):
        yield from self.blocks

    def stop(self, message: str, t_fail: float | None, stats: dict | None = None, y_fail=None) -> None:
        self.complete, self.message, self.t_fail = False, message, t_fail
        if y_fail is not None:
            self.y_fail = np.asarray(y_fail)
        if stats is not None:
            self.stats = stats


def simulate(system: KnownSystem, values: RunValues, t_end: float, dt: float, method: str = "dop853",
             rtol: float = 1e-10, atol: float = 1e-10, chunks: int = 20, progress: bool | None = None,
             outputs=None, constrained=None) -> Trajectory:
    """Integrate from t = 0 to ``t_end`` with rows every ``dt`` (all rows in memory); the
    arguments as for :func:`start`."""
    run = start(system, values, t_end, dt, method, rtol, atol, chunks, progress, outputs, constrained)
    return collect(run, list(run), len(system.coordinates))


def collect(run: Run, blocks: list[Block], nq: int) -> Trajectory:
    """The trajectory of ``blocks`` of ``run`` (all of them, or those before an interrupt)."""
    n = 2 * nq
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
    ``system`` has implicit constraints."""
    if system.implicit is not None and method in METHODS and not METHODS[method].closed_loops:
        raise SimulationError(f"method '{method}' needs explicit equations (its Taylor series), which a system "
                              "with implicit constraints does not have; use dop853 (default), gauss4, Radau or LSODA")


def start(system: KnownSystem, values: RunValues, t_end: float, dt: float, method: str = "dop853",
          rtol: float = 1e-10, atol: float = 1e-10, chunks: int = 20, progress: bool | None = None,
          outputs=None, constrained=None) -> Run:
    """A run from t = 0 to ``t_end`` with rows every ``dt``, streamed: the model is compiled
    now, the rows are computed in blocks (at most :data:`BLOCK_ROWS` each) while the
    :class:`Run` is iterated.

    ``outputs`` (a scene's; None: everything) decides whether the energies are computed. With
    implicit constraints, ``constrained`` is the :class:`~kronsub.core.constraints.Intermediates`
    of the projected initial conditions (:func:`.constrained.project_initial`)."""
    if method not in METHODS:
        raise SimulationError(unknown_method(method))
    explicit_only(system, method)
    row_count(t_end, dt)
    check_tolerances(rtol, atol)
    if system.implicit is not None and constrained is None:
        from .constrained import project_initial

        values, _, constrained = project_initial(system, {}, {}, values, _newton_tol(rtol, atol))
    param = np.array(values.parameters, dtype=float)
    y0 = np.array(values.y0, dtype=float)
    grid = _Grid(t_end, dt)
    if METHODS[method].engine in ("heyoka", "taylor"):  # the compiled model for the energies and their check
        heyoka = METHODS[method].engine == "heyoka"
        run = Run("heyoka", "heyoka") if heyoka else Run("taylor", "C")
        rows = ((b.t, b.y) for b in (_heyoka_blocks if heyoka else _taylor_blocks)(run, system, param, y0, grid, rtol))
        with_energies = outputs is None or outputs.energies
        native = _compiled_quietly(system, outputs) if with_energies else None
        run.blocks = _finish(run, rows, _Progress(t_end, False), native, param, system, None, with_energies)
        return run
    native = _compiled(system, outputs)
    if constrained is not None and native is not None:
        from .constrained import configure_native

        configure_native(native, constrained.guess, _newton_tol(rtol, atol))
    spec = METHODS[method]
    if native is None and spec.engine == "c":
        fallback = "DOP853"
        warnings.warn(f"method '{method}' runs in compiled C; using scipy's {fallback} instead")
        spec = METHODS[fallback]
    run = Run(spec.name, "C" if native is not None else "numpy")
    bar = _Progress(t_end, progress)
    if not bar.enabled:
        chunks = 1  # one call: no restarts of the step-size control
    chunks = max(chunks, math.ceil(len(grid) / BLOCK_ROWS))
    with_energies = outputs is None or outputs.energies
    if system.implicit is not None and system.implicit.choice == "auto":  # may switch coordinates
        run.blocks = _auto_blocks(run, system, spec, native, constrained, grid, y0, param, rtol, atol, dt, chunks, bar,
                                  outputs, with_energies)
        return run
    if spec.engine == "c":
        rows = _native_blocks(run, native, spec.name, grid, y0, param, rtol, atol, dt, chunks, bar, system)
    else:
        rhs = (_native_rhs(native, param) if native is not None else
               _numpy_rhs(system, param, outputs, constrained, _newton_tol(rtol, atol)))
        rows = _scipy_blocks(run, rhs, spec.name, grid, y0, rtol, atol, chunks, bar, system, param=param)
    run.blocks = _finish(run, rows, bar, native, param, system, constrained, with_energies, grid)
    return run


def _compiled(system, outputs):
    """The model compiled from its generated C, or None (with a warning) to use the numpy module."""
    try:
        return native_model(system, outputs)
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
        return native_model(system, outputs)
    except (CompilerNotFound, CompileError):
        return None


class _Tail:
    """The output grid from row ``offset`` on (a run going on after a switch of coordinates),
    after a first time ``start`` between two rows when given."""

    def __init__(self, grid, offset: int, start: float | None = None):
        self.grid, self.offset, self.start = grid, offset, start
        self.shift = offset - (1 if start is not None else 0)  # tail index -> grid index
        self.t_end, self.dt = grid.t_end, grid.dt
        self.spacing = grid.spacing if start is None else min(grid.spacing, grid[offset] - start)

    def __len__(self) -> int:
        return len(self.grid) - self.shift

    def __getitem__(self, index):
        if isinstance(index, slice):
            a, b, _ = index.indices(len(self))
            if self.start is not None and a == 0 and b > 0:
                return np.concatenate([[self.start], self.grid[self.offset:b + self.shift]])
            return self.grid[a + self.shift:b + self.shift]
        i = index + len(self) if index < 0 else index
        return self.start if (self.start is not None and i == 0) else self.grid[i + self.shift]


def _auto_blocks(run, system, spec, native, constrained, grid, y0, param, rtol, atol, dt, chunks, bar, outputs,
                 with_energies):
    """The blocks of a run with ``coordinates: auto``, switching the independent coordinates where
    ``G_d`` nears singular (:mod:`.switching`); rows in the layout of the first choice."""
    from ..core.constraints import ConstraintFailure
    from . import switching as sw
    from .constrained import configure_module, configure_native, diagnose

    tol = _newton_tol(rtol, atol)
    first = split = sw.Split(system, constrained)
    offset, start, total = 0, None, {}
    last = None  # (t, y, ydot) of the last row written
    watched = False  # this stretch again in scipy, whose event watches G_d between the rows
    try:
        while True:
            if offset:
                native = _compiled(split.system, outputs)
                if native is None and spec.engine == "c":
                    spec = METHODS["DOP853"]
            module = None
            if native is not None:
                configure_native(native, split.evaluator.guess, tol)
            else:
                module = _numpy_module(split.system, outputs)
                configure_module(module, split.evaluator.guess, tol)
            if spec.engine == "c" and not watched:  # (start() made it a scipy method when nothing compiled)
                rows = _native_blocks(run, native, spec.name, _Tail(grid, offset, start), y0, param, rtol, atol, dt,
                                      chunks, bar, split.system)
            else:
                rhs = _native_rhs(native, param) if native is not None else _numpy_rhs_of(module, param)
                rows = _scipy_blocks(run, rhs, "DOP853" if watched else spec.name, _Tail(grid, offset, start), y0,
                                     rtol, atol, chunks, bar, split.system, events=_toggle_event(split))
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
                                _module_energies(module, t[:cut], Y[:cut], param))
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
                elif spec.engine == "c" and not watched and len(run.switches) < sw.MAX_SWITCHES:
                    again = True  # C watched only the rows: from the last one again, watched between rows
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
        run.message = diagnose(split.system, split.evaluator, run.t_fail, _failed_state(run, split.row(*last[1:])),
                               guess)


def _failed_state(run, last_row: np.ndarray) -> np.ndarray:
    """The state to explain a failure at: where the right-hand side failed when that is near the
    last row written (an integrator's trial stage can be far off: phi = -1e31), else that row."""
    y, last = run.y_fail, np.asarray(last_row, dtype=float)
    if y is None or y.shape != last.shape or not np.all(np.isfinite(y)):
        return last
    n = len(last) // 2
    return y if np.max(np.abs(y[:n] - last[:n])) <= 0.5 * (1.0 + np.max(np.abs(last[:n]))) else last


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


def _numpy_rhs_of(module, param):
    rhs = module["rhs"]

    def f(t, y):
        try:
            return rhs(t, y, param)
        except np.linalg.LinAlgError as exc:
            raise _Singular(t, y) from exc

    return f


def _module_energies(module, t, Y, param):
    T = np.array([module["kinetic_energy"](y, param) for y in Y])
    V = np.array([module["potential_energy"](ti, y, param) for ti, y in zip(t, Y)])
    return T, V


def _newton_tol(rtol: float, atol: float) -> float:
    from .constrained import newton_tolerance

    return newton_tolerance(rtol, atol)


def _finish(run, rows, bar, native, param, system, constrained, with_energies=True, grid=None):
    """The blocks, with energies computed in C when there is a compiled model (and they are
    wanted) and, with implicit constraints, the dependent coordinates per row (and, after a
    failure, what failed); at the end, a warning when an explicit run was held by stiffness, and
    one when a complete run of a model that conserves energy did not keep it."""
    guess = constrained.guess.copy() if constrained is not None else None
    first_t = last_t = last_y = None
    energy = None  # (t0, y0, E0, largest T, last E) of the rows, when they have energies
    try:
        for t, y in rows:
            if len(t):
                dependent = None
                if constrained is not None:
                    from .constrained import dependent_rows

                    dependent = dependent_rows(constrained, np.asarray(y), len(system.coordinates), guess)
                    guess = dependent[-1] if len(dependent) else guess
                energies = None
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
                yield Block(grid.snap(t) if grid is not None else np.asarray(t), np.asarray(y), energies, dependent)
    finally:
        bar.close()
    if constrained is not None and not run.complete and last_y is not None:
        from .constrained import diagnose

        run.message = diagnose(system, constrained, run.t_fail, _failed_state(run, last_y), guess)
    if native is not None and last_y is not None and _stiffness(run.stats):
        warnings.warn(StiffnessWarning(_stiffness_advice(native, param, run.stats, last_t - first_t, last_t, last_y,
                                                         run.method)))
    if energy is not None and run.complete and constrained is None and not run.switches:
        advice = _energy_advice(native, param, len(system.coordinates), run.method, *energy)
        if advice:
            warnings.warn(EnergyWarning(advice))


ENERGY_DRIFT_SHARE = 1e-2  # of the largest kinetic energy: no run accurate to any tolerance drifts this far
ENERGY_FLOOR_SHARE = 1e-6  # of |E|: the scale of a run that hardly moves (the rounding of V is not a drift)


def _energy_advice(native, param, nq: int, method: str, t0: float, y0, E0: float, T_max: float, E1: float) -> str:
    """A warning when the energy changed by more than ``ENERGY_DRIFT_SHARE`` of its scale over a
    run of a model that conserves it (else ""): a run that went wrong without failing, such as
    heyoka's step fooled by a Taylor series with gaps (a motion from rest at a symmetric
    position, benchmarks/README.md). The scale is the energy the motion exchanges, its largest
    kinetic energy, not ``|E|``, which an offset of the potential can make as large as it likes;
    ``ENERGY_FLOOR_SHARE |E|`` below it."""
    scale = max(T_max, ENERGY_FLOOR_SHARE * abs(E0))
    if not (np.isfinite(E1) and scale > 0) or abs(E1 - E0) <= ENERGY_DRIFT_SHARE * scale:
        return ""
    try:
        if not _conserves_energy(native, param, nq, t0, y0):
            return ""
    except Exception:  # noqa: BLE001 - the check is a courtesy; a failed evaluation must not stop the run
        return ""
    hint = ("heyoka reads its step size off its last two Taylor orders, which a motion from rest at a symmetric "
            "position can fool: use --method taylor or dop853" if method == "heyoka" else
            "tighten --rtol (adaptive methods) or --dt (fixed-step methods), or try another --method")
    return (f"the energy of this conservative model went from {E0:.6g} to {E1:.6g} over the run, "
            f"{abs(E1 - E0) / scale:.2g} of its largest kinetic energy ({scale:.3g}): "
            f"{method}'s rows are not accurate; {hint}")


def _conserves_energy(native, param, nq: int, t0: float, y0) -> bool:
    """Whether ``dE/dt = 0`` along the equations (``E = T + V``, ``V`` of the conservative
    effects): at three states with random velocities (seeded) about the first row, the rate,
    by central differences, is below 1e-6 of the sum of its terms' magnitudes. Damping, driving,
    loads or connections that depend on time all give a rate of the order of its terms."""
    rng = np.random.default_rng(20261124)
    y0 = np.asarray(y0, dtype=float)

    def energy(t, y):
        return native.kinetic_energy(y, param) + native.potential_energy(t, y, param)

    for _ in range(3):
        y = y0.copy()
        y[nq:] += rng.standard_normal(nq) * max(1.0, float(np.max(np.abs(y0[nq:]), initial=0.0)))
        ydot = native.rhs(t0, y, param)
        dt = 1e-5 * max(1.0, abs(t0))
        terms = [(energy(t0 + dt, y) - energy(t0 - dt, y)) / (2 * dt)]
        for i in range(len(y)):
            e = np.zeros_like(y)
            e[i] = 1e-5 * max(1.0, abs(y[i]))
            terms.append((energy(t0, y + e) - energy(t0, y - e)) / (2 * e[i]) * ydot[i])
        if not abs(sum(terms)) <= 1e-6 * sum(map(abs, terms)):
            return False
    return True


def _stiffness(stats: dict) -> bool:
    """Whether an explicit adaptive run's step size was held by stability: Hairer's test fired, or
    the step size bounced on the stability boundary (a large share of rejected steps over many)."""
    steps, rejected = stats.get("steps", 0), stats.get("rejected", 0)
    return "stiff_from" in stats or (steps + rejected >= STIFF_MIN_STEPS
                                     and rejected >= STIFF_REJECTED_SHARE * (steps + rejected))


def _fastest_mode(native, param, t: float, y: np.ndarray) -> complex:
    """The eigenvalue of largest modulus of the Jacobian of the right-hand side at ``y``
    (central differences)."""
    n = len(y)
    J = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1e-6 * max(1.0, abs(y[j]))
        J[:, j] = (native.rhs(t, y + e, param) - native.rhs(t, y - e, param)) / (2 * e[j])
    lam = np.linalg.eigvals(J)
    return complex(lam[np.argmax(np.abs(lam))])


def _stiffness_advice(native, param, stats: dict, span: float, t: float, y, method: str) -> str:
    """What to do about a stiff run: an implicit method when its fastest mode (at the last state
    ``y`` at time ``t``) is damped; when it is an undamped oscillation, every method has to
    follow it, so say that instead."""
    steps, rejected = stats["steps"], stats["rejected"]
    cost = f"{steps} steps, {rejected} rejected, mean step {span / max(steps, 1):.3g}"
    try:
        lam = _fastest_mode(native, param, t, np.asarray(y, dtype=float))
    except Exception:  # noqa: BLE001 - the advice is a courtesy; a failed evaluation must not stop the run
        lam = complex("nan")
    mode = f"fastest mode lambda = {lam.real:.3g}{lam.imag:+.3g}i"
    if np.isfinite(lam.real) and -lam.real >= STIFF_DAMPED_SHARE * abs(lam):
        return (f"the problem is stiff: {method}'s step size is held by stability, not accuracy ({cost}; {mode}); "
                "an implicit method is far cheaper here: use --method Radau")
    return (f"a fast oscillation holds {method}'s step size ({cost}; {mode}, period "
            f"{2 * np.pi / max(abs(lam.imag), 1e-300):.3g}): it is undamped, so every method must follow it; "
            "an implicit method (--method Radau) pays off only where the fast mode is damped")


STIFF_MIN_STEPS = 5000        # fewer steps are cheap whatever the cause
STIFF_REJECTED_SHARE = 0.25   # accuracy-limited smooth runs reject a few per cent
STIFF_DAMPED_SHARE = 0.05     # a fast mode that decays by e within 20 radians counts as damped


MERGE = 1e-7
"""A multiple of ``dt`` within ``MERGE dt`` of ``t_end`` is ``t_end`` itself (as in the C integrators'
``output_time``): no two rows are closer than that."""


class _Grid:
    """Output times 0, dt, 2 dt, ... and exactly t_end, made a slice at a time.

    When ``dt`` is a short decimal ``m / 10**k`` (as ``repr`` writes it), the k-th time is the
    double nearest to the decimal ``k m / 10**k`` (``0.03``, not ``3 * 0.01 = 0.030000000000000002``),
    so times print in their short form; :meth:`snap` puts an integrator's own times on the grid."""

    def __init__(self, t_end: float, dt: float):
        self.t_end, self.dt = t_end, dt
        # every multiple of dt before t_end (one within MERGE dt of it is t_end), then t_end: the
        # rows the C integrators' dense output writes, whatever the remainder
        n = math.ceil(t_end / dt - MERGE) + 1
        self.n = max(n, 2)  # a run always starts at 0 (also when dt > t_end)
        self.decimal = _decimal(dt, self.n)
        # the closest two rows: dt, or less from the last multiple of dt to t_end
        self.spacing = min(dt, t_end - float(self._times(np.array([self.n - 2.0]))[0]))

    def __len__(self) -> int:
        return self.n

    def _times(self, index: np.ndarray) -> np.ndarray:
        if self.decimal is None:
            return index * self.dt
        m, scale = self.decimal  # index * m < 2**53: exact; the division rounds once
        return (index * float(m)) / scale

    def __getitem__(self, index):
        if isinstance(index, slice):
            a, b, _ = index.indices(self.n)
            times = self._times(np.arange(a, b, dtype=float))
            if b == self.n and b > a:
                times[-1] = self.t_end
            return times
        i = index + self.n if index < 0 else index
        return self.t_end if i == self.n - 1 else float(self._times(np.array([float(i)]))[0])

    def snap(self, t: np.ndarray) -> np.ndarray:
        """Times within a millionth of the rows' spacing of a grid time replaced by that grid time
        (the last rows may be closer than ``dt``: ``t_end`` is not a multiple of ``dt``, or below it)."""
        t = np.asarray(t, dtype=float)
        last = self.n - 1
        k = np.clip(np.rint(t / self.dt), 0, last)
        grid = self._times(k)
        grid[k == last] = self.t_end
        end = np.abs(t - self.t_end) < np.abs(t - grid)
        k, grid = np.where(end, last, k), np.where(end, self.t_end, grid)
        spacing = np.where(k >= last - 1, self.spacing, self.dt)
        return np.where(np.abs(t - grid) <= 1e-6 * spacing, grid, t)


def _decimal(dt: float, n: int) -> tuple[int, float] | None:
    """``(m, 10.0**k)`` with ``repr(dt)`` the decimal ``m / 10**k``, when ``n m < 2**53`` (the
    grid times are then correctly rounded decimals); else None."""
    from decimal import Decimal

    sign, digits, exponent = Decimal(repr(float(dt))).as_tuple()
    if not isinstance(exponent, int) or exponent > 0 or -exponent > 22:
        return None
    m = int("".join(map(str, digits)))
    return (m, float(10 ** -exponent)) if n * m < 2**53 else None


def _heyoka_blocks(run, system, param, y0, grid, tol):
    try:
        from . import heyoka_backend
    except ImportError:
        heyoka_backend = None
    if heyoka_backend is None or not heyoka_backend.available():
        raise SimulationError("method 'heyoka' needs heyoka: pip install 'kronsub[heyoka]'")
    integrator = heyoka_backend.HeyokaIntegrator(system, tol)
    y, first = y0, True
    for a, b in _chunks(grid, math.ceil(len(grid) / BLOCK_ROWS)) if len(grid) > 1 else [(0, 0)]:
        times = grid[a:b + 1]
        t, Y, complete, message = integrator.run(param, y, times)
        start = 0 if first else 1  # a chunk starts on the last row of the one before
        if len(t) > start:
            yield Block(t[start:], Y[start:])
        if not complete:
            run.stop(message, float(t[-1]) if len(t) else float(times[0]))
            return
        y, first = Y[-1], False


def _taylor_blocks(run, system, param, y0, grid, tol):
    from .native import NativeError
    from .taylor_c import TaylorC, TaylorUnavailable, order_for

    try:
        integrator = TaylorC(system)
        integrator.build(order_for(tol))
    except (TaylorUnavailable, NativeError) as exc:
        raise SimulationError(str(exc)) from None
    except ValueError as exc:
        raise SimulationError(f"--rtol: {exc}") from None
    stats = run.stats = {"steps": 0, "order": order_for(tol)}
    y, first = y0, True
    for a, b in _chunks(grid, math.ceil(len(grid) / BLOCK_ROWS)) if len(grid) > 1 else [(0, 0)]:
        times = grid[a:b + 1]
        t, Y, complete, message = integrator.solve(param, y, times, tol)
        stats["steps"] += integrator.last_steps
        start = 0 if first else 1  # a chunk starts on the last row of the one before
        if len(t) > start:
            yield Block(t[start:], Y[start:])
        if not complete:
            last = Y[-1] if len(Y) else y
            if np.all(np.isfinite(last)):  # from the last row: an overflow, or a function outside its domain
                message = _not_finite(system, t[-1] if len(t) else times[0], last, param, message)
            run.stop(message + _where(system, Y[-1] if len(Y) else None), float(t[-1]) if len(t) else float(times[0]),
                     y_fail=last)
            return
        y, first = Y[-1], False


def _native_rhs(native, param):
    from .native import SingularMassMatrix

    rhs = native.scipy_rhs(param)

    def f(t, y):
        try:
            return rhs(t, y)
        except SingularMassMatrix as exc:
            raise _Singular(t, y) from exc

    return f


def _numpy_rhs(system, param, outputs=None, constrained=None, tol=1e-12):
    module = _numpy_module(system, outputs)
    if constrained is not None:
        from .constrained import configure_module

        configure_module(module, constrained.guess, tol)
    return _numpy_rhs_of(module, param)


class _Singular(Exception):
    def __init__(self, t, y):
        super().__init__(t)
        self.t, self.y = t, y


def _chunks(grid, count: int):
    """Index ranges of the output grid, one per chunk."""
    edges = np.unique(np.linspace(0, len(grid) - 1, min(count, len(grid) - 1) + 1).astype(int))
    return list(zip(edges[:-1], edges[1:]))


def _rank_loss(system, t, y, param) -> str:
    """``; <why Mbar is singular at y>`` (:func:`..core.finite.rank_loss`), or nothing."""
    from ..core.finite import rank_loss

    if param is None or t is None or y is None or not np.all(np.isfinite(y)):
        return ""
    why = rank_loss(system, t, y, param)
    return f"; {why}" if why else ""


def _where(system, y) -> str:
    """The configuration at a failure, for the message."""
    if y is None:
        return ""
    return " at " + ", ".join(f"{q.name}={v:.6g}" for q, v in zip(system.coordinates, y))


def _fixed_pieces(t0: float, t1: float, dt: float) -> list[tuple[float, float]]:
    """``t0 .. t1`` cut at multiples of ``dt`` (counted from t = 0) for a fixed-step method: whole
    steps of ``dt`` between them, a shorter step only up to the first multiple (a run going on
    after a switch of coordinates) and from the last one to ``t1`` (a ``t_end`` that is not a
    multiple), so its rows fall on the ``--dt`` grid as every other method's do."""
    tiny = MERGE * dt
    first = math.ceil(t0 / dt - MERGE) * dt
    # past a multiple (not one itself, to rounding): cut at the last row before t1, as _Grid counts them
    past = t1 / dt - math.floor(t1 / dt + 1e-9) > 1e-9
    last = (math.ceil(t1 / dt - MERGE) - 1) * dt if past else t1
    cuts = [t0] + [first] * (t0 + tiny < first < t1 - tiny) + [last] * (t0 + tiny < last < t1) + [t1]
    cuts = sorted(set(cuts))
    return list(zip(cuts[:-1], cuts[1:]))


def _aligned_pieces(t0: float, t1: float, dt: float) -> list[tuple[float, float]]:
    """``t0 .. t1`` for an adaptive method, cut at the first multiple of ``dt`` after a ``t0``
    between two rows (a run going on after a switch of coordinates there): C writes its rows
    every ``dt`` from the start of a piece, so each piece must start on the grid."""
    tiny = MERGE * dt
    first = math.ceil(t0 / dt - MERGE) * dt
    return [(t0, first), (first, t1)] if t0 + tiny < first < t1 - tiny else [(t0, t1)]


def _native_blocks(run, native, method, grid, y0, param, rtol, atol, dt, chunks, bar, system):
    """Blocks ``(t, Y)`` of a run wholly in C, one per chunk of the grid."""
    last = grid[0]
    yield np.array([last]), np.array([y0])
    stats = run.stats = {"steps": 0, "rejected": 0, "evaluations": 0}
    y = y0
    fixed = method in FIXED_STEP
    pieces = [p for a, b in _chunks(grid, chunks)
              for p in (_fixed_pieces(grid[a], grid[b], dt) if fixed else _aligned_pieces(grid[a], grid[b], dt))]
    for t0, t1 in pieces:
        t, Y, result = native.integrate(method, t0, y, t1, dt, param, rtol=rtol, atol=atol,
                                        h=dt if fixed else None)
        stats["steps"] += result.n_steps
        stats["rejected"] += result.n_rejected
        stats["evaluations"] += result.n_evals
        if result.t_stiff is not None and "stiff_from" not in stats:
            stats["stiff_from"] = result.t_stiff
        keep = t > last + 1e-6 * grid.spacing  # a piece's first row repeats the last one
        if np.any(keep):
            last = t[keep][-1]
            yield t[keep], Y[keep]
        if result.status != 0:
            message = result.message
            at_finite = result.status in (1, 2) and result.y_fail is not None and np.all(np.isfinite(result.y_fail))
            if result.status in (1, 2) and not _real_at(native, t0, y, param):  # not finite at the start
                message = _not_finite(system, t0, y, param)
            elif at_finite:
                # NaN forces at a finite state (a spring whose ends meet): which effect, if any; Mbar
                # without a real value where the run got to is the edge of the coordinates' range, where
                # it is singular (System II's lower rod on the line): said so, the cause beside it
                cause = _cause(system, result.t_fail, result.y_fail, param, mass_only=result.status == 1)
                if cause is not None and result.status == 1 and not cause.overflow and cause.label.startswith("Mbar"):
                    message = f"{message}: {cause}"
                elif cause is not None:
                    message = cause.stated()
            message += _where(system, result.y_fail) if result.status in (1, 2) else ""
            if at_finite:
                message += _rank_loss(system, result.t_fail, result.y_fail, param)
            run.stop(message, result.t_fail, y_fail=result.y_fail)
            return
        y = Y[-1]
        bar.update(t1)


STALL_STEPS = 1000
"""A scipy run whose last this many steps advanced time by less than `STALL_SPAN` of ``max(1, |t|)``
has stalled (an implicit method creeping towards a singular configuration takes steps of 1e-12)."""
STALL_SPAN = 1e-8


class _Cursor:
    """The output times not yet written, read from the grid a block at a time."""

    BLOCK = 4096

    def __init__(self, grid):
        self.grid, self.i, self.start = grid, 1, 1
        self.block = grid[1:min(1 + self.BLOCK, len(grid))]

    def done(self) -> bool:
        return self.i >= len(self.grid)

    def upto(self, t: float) -> np.ndarray:
        """The times ``<= t`` not yet taken, now taken."""
        out = []
        while self.i < len(self.grid):
            k = self.i - self.start
            if k >= len(self.block):
                self.start = self.i
                self.block = self.grid[self.i:min(self.i + self.BLOCK, len(self.grid))]
                continue
            j = int(np.searchsorted(self.block, t, side="right"))
            if j > k:
                out.append(self.block[k:j])
                self.i += j - k
            if j < len(self.block):
                break
        return np.concatenate(out) if out else np.empty(0)


def _real_at(native, t: float, y, param) -> bool:
    """Whether the energies have a finite real value at ``(t, y)`` (a connection through sqrt, asin
    or acos has none outside its domain, where the mass matrix is NaN, not singular; huge values
    overflow)."""
    try:
        with np.errstate(all="ignore"):
            values = [native.kinetic_energy(y, param), native.potential_energy(t, y, param)]
    except Exception:  # noqa: BLE001 - a model without energies, or one that fails otherwise: no verdict
        return True
    return bool(np.all(np.isfinite(values)))


def _cause(system, t: float, y, param, mass_only: bool = False):
    """The :class:`..core.finite.Cause` of :func:`_not_finite`, or None."""
    from ..core.finite import at_state

    cause = at_state(system, t, y, param)
    if cause is not None and mass_only and not (cause.overflow or cause.label.startswith("Mbar")):
        return None
    return cause


def _not_finite(system, t: float, y, param, otherwise: str | None = None, mass_only: bool = False) -> str:
    """Why the equations are NaN or infinite at ``(t, y)``, where the state is finite: a value
    beyond the range of doubles, or a function outside its domain (:mod:`..core.finite`); else
    ``otherwise`` (None: that the double values are not finite, though the exact ones are, or
    with implicit constraints, whose dependent coordinates are not known here, just that).
    ``mass_only``: only an overflow or a problem in ``Mbar`` (a singular one, as at a coordinate
    singularity, keeps ``otherwise``)."""
    cause = _cause(system, t, y, param, mass_only)
    if cause is not None:
        return cause.stated()
    if otherwise is not None:
        return otherwise
    if system.implicit is not None:
        return "the equations have no finite value at this state"
    return ("the equations are NaN or infinite at this state in double precision, though finite when evaluated "
            "exactly (an intermediate value overflows or cancels: check for huge or tiny parameters and initial "
            "values)")


def _scipy_blocks(run, rhs, method, grid, y0, rtol, atol, chunks, bar, system, events=None, param=None):
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
    cursor = _Cursor(grid)
    recent: deque = deque(maxlen=STALL_STEPS)
    solver = None
    with np.errstate(all="ignore"):
        try:
            # NaN at the start makes scipy's first step size NaN, and its step loop never ends
            if not np.all(np.isfinite(rhs(grid[0], np.array(y0, dtype=float)))):
                message = "the derivative of the state is NaN or infinite at the initial state"
                run.stop(message if param is None else _not_finite(system, grid[0], y0, param, message), grid[0],
                         y_fail=y0)
                return
            solver = getattr(integrate, method)(rhs, grid[0], np.array(y0, dtype=float), grid[len(grid) - 1],
                                                rtol=rtol, atol=atol)
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
                        message = _not_finite(system, solver.t, solver.y, param, otherwise=message)
                    run.stop(message, solver.t, y_fail=solver.y)
                    return
                if not np.all(np.isfinite(solver.y)):
                    message = "the state became NaN or infinite"
                    run.stop(message if param is None else _not_finite(system, t_old, y_old, param, message), t_old,
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
                             + _where(system, solver.y), t_new, y_fail=solver.y)
                    return
        except _Singular as exc:
            message = "the mass matrix is singular or not positive definite" + _where(system, exc.y)
            if param is not None:  # NaN entries, not a singular matrix: an overflow, or outside the domain
                t, y = (exc.t, exc.y) if np.all(np.isfinite(exc.y)) else (t_old, y_old)  # (a stage overflowed)
                found = _not_finite(system, t, y, param, otherwise="", mass_only=True)
                message = found + _where(system, y) if found else message + _rank_loss(system, exc.t, exc.y, param)
            run.stop(message, exc.t, y_fail=exc.y)
            return
        except (ValueError, RuntimeError, ArithmeticError, np.linalg.LinAlgError) as exc:
            t, y = (solver.t, solver.y) if solver is not None else (grid[0], y0)
            message = str(exc)
            if param is not None and np.all(np.isfinite(y)):  # scipy's "array must not contain infs or NaNs"
                message = _not_finite(system, t, y, param, otherwise=message)
            run.stop(message, t, y_fail=y)
            return
