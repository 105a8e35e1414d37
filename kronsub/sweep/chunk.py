"""The chunk task: the runs ``start .. stop-1`` of a sweep, each summarised in a row.

A row holds the run's swept inputs, its status (``complete``, or ``stopped`` with the reason: a
singular metric ``Mbar``, a non-finite state, a toggle position of a closed loop, ...), the time
it got to, its final state, the least and greatest value of each coordinate on the output grid,
the energy drift ``E(t_end) - E(0)`` (24) of a model that conserves energy, and its cost
(steps, rejected steps, evaluations of the right-hand side). The state is ``[q; qdot]``, or
``[q; u]`` in the speeds ``u`` of a model under velocity constraints (``xdot = C(q) u + d``),
whose coordinates held by configuration constraints beside them are put on those constraints
at each run's start and in its rows, as ``simulate`` puts them (:mod:`kronsub.simulation.held`).
A run that fails is a row, never the end of the chunk. Runs wholly in C go through the compiled ensemble (:mod:`.ensemble`), a
block at a time (``taylor`` through its own generated integrator; a closed loop whose coordinates
stay those chosen, each run projected onto its constraints first); the others (scipy's methods,
heyoka, closed loops with ``coordinates: auto``, a closed loop's runs that stop or keep rows, a
worker without a C compiler) run one by one as ``simulate`` runs them
(:func:`kronsub.simulation.run.start`, with the generated numpy module where nothing compiles)."""
from __future__ import annotations

import contextlib
import math
import threading
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core.first_order import zero_rows
from ..core.known_system import KnownSystem
from ..errors import KronsubError
from ..simulation.native import NativeError
from .ensemble import Sources, load, load_taylor, pieces, summary_width
from .plan import Plan
from .trajectories import TrajectoryPart

__all__ = ["ENSEMBLE", "ONE_BY_ONE", "TAYLOR", "Job", "columns", "inputs_of", "run_chunk", "state_names", "state_width",
           "warm"]

ENSEMBLE, TAYLOR, ONE_BY_ONE = "ensemble", "taylor ensemble", "one by one"  # the routes of a sweep's runs


@dataclass(frozen=True)
class Job:
    """Everything a worker needs for any chunk of a sweep (sent to each worker once)."""

    system: KnownSystem
    plan: Plan
    chunk: int
    method: str
    t_end: float
    dt: float
    rtol: float
    atol: float
    base_param: tuple[float, ...]
    base_y0: tuple[float, ...]
    route: str
    sources: Sources | None = None
    outputs: object = None
    initial: dict = field(default_factory=dict)  # the model's and scene's initial values (closed loops)
    dependent_settings: dict = field(default_factory=dict)  # --set of a closed loop's dependent coordinates
    derived_initial: tuple = ()  # (state index, expression of swept parameters) per such initial value
    given: tuple[str, ...] = ()  # the names --set gives (a held coordinate among them is checked, not moved)
    summaries: tuple = ()  # user outputs (:class:`.outputs.UserOutput`), a column each
    taylor_sources: Sources | None = None  # the Taylor integrator's (route TAYLOR)
    trajectories: str | None = None  # the folder each worker writes its chunks' rows in (:mod:`.trajectories`)

    @property
    def chunks(self) -> int:
        return max(1, math.ceil(self.plan.count / self.chunk))

    def span(self, index: int) -> tuple[int, int]:
        """The runs of chunk ``index``."""
        return index * self.chunk, min((index + 1) * self.chunk, self.plan.count)


def state_names(system: KnownSystem) -> list[str]:
    """The names of the state ``[q; qdot]``, or ``[q; u]`` in the speeds."""
    return [q.name for q in system.coordinates] + [system.name_of(v) for v in system.state_velocities]


def state_width(system: KnownSystem) -> int:
    """The entries of the state: ``2 nq``, or ``nq`` and the speeds."""
    return len(system.coordinates) + len(system.state_velocities)


def _held(system: KnownSystem) -> bool:
    """Whether configuration constraints stand beside ``system``'s velocity constraints."""
    return system.speeds is not None and bool(system.speeds.holonomic)


def columns(job: Job) -> list[tuple[str, str]]:
    """The columns of a row ``(name, type)``: ``int64``, ``float64`` or ``string``."""
    q = [c.name for c in job.system.coordinates]
    return ([("run", "int64")] + [(name, "float64") for name in job.plan.names] +
            [("status", "string"), ("reason", "string"), ("t_final", "float64")] +
            [(f"final_{name}", "float64") for name in state_names(job.system)] +
            [(f"min_{name}", "float64") for name in q] + [(f"max_{name}", "float64") for name in q] +
            [("energy_drift", "float64"), ("steps", "int64"), ("rejected", "int64"), ("evaluations", "int64")] +
            [(out.name, "float64") for out in job.summaries])


def inputs_of(job: Job, start: int, stop: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """The swept inputs, and each run's parameters and initial state."""
    import sympy

    system = job.system
    inputs = job.plan.inputs(start, stop)
    n = stop - start
    param = np.tile(np.asarray(job.base_param, dtype=float), (n, 1)).reshape(n, len(job.base_param))
    y0 = np.tile(np.asarray(job.base_y0, dtype=float), (n, 1))
    p_index = {p.name: i for i, p in enumerate(system.parameters)}
    s_index = {name: i for i, name in enumerate(state_names(system))}
    for name, values in inputs.items():
        if name in p_index:
            param[:, p_index[name]] = values
        else:
            y0[:, s_index[name]] = values
    symbols = [p.symbol for p in system.parameters]
    for index, expr in job.derived_initial:  # initial values written with swept parameters
        for r in range(n):
            y0[r, index] = float(sympy.sympify(expr).xreplace(dict(zip(symbols, param[r]))).evalf(17))
    return inputs, param, y0


_CONSERVES: dict[str, bool] = {}
_ASKING = threading.Lock()  # the model's library (its parameter buffer) asked by one thread at a time


def _conserves(job: Job, native) -> bool:
    """Whether the model conserves energy (:func:`kronsub.simulation.advice.conserves_energy` at the
    base values: a property of the equations, the same for every chunk)."""
    from ..simulation.advice import conserves_energy

    if job.sources is not None:
        key = job.sources.sha256
    else:
        from ..simulation.compiled import fingerprint

        key = fingerprint(job.system, job.outputs) or repr(job.system)
    key = f"{key} {job.base_param} {job.base_y0}"
    with _ASKING:
        if key not in _CONSERVES:
            try:
                _CONSERVES[key] = bool(conserves_energy(native, np.asarray(job.base_param),
                                                        len(job.system.coordinates), 0.0, np.asarray(job.base_y0)))
            except Exception:  # noqa: BLE001 - a model whose energy cannot be evaluated reports no drift
                _CONSERVES[key] = False
        return _CONSERVES[key]


def warm(job: Job) -> None:
    """Build and load what this process's chunks of ``job`` call (its libraries, whether the model
    conserves energy), as the first chunk would: for a process that starts its workers meanwhile.
    What fails here fails again in the chunk, which says so."""
    if job.route not in (ENSEMBLE, TAYLOR):
        return
    try:
        ensemble = load(job.sources)
        if job.route == TAYLOR:
            load_taylor(job.taylor_sources)
        if job.system.implicit is None:
            _conserves(job, ensemble.native)
    except Exception:  # noqa: BLE001 - the chunk meets it again and says so (or runs one by one)
        pass


def run_chunk(job: Job, index: int) -> dict[str, object]:
    """The rows of chunk ``index``, as columns (:func:`columns`); with ``job.trajectories``, the
    runs' rows written as the chunk's trajectory part first."""
    start, stop = job.span(index)
    inputs, param, y0 = inputs_of(job, start, stop)
    n, nq, ny = stop - start, len(job.system.coordinates), state_width(job.system)
    part = contextlib.nullcontext() if job.trajectories is None else \
        TrajectoryPart(job.trajectories, index, job.system, job.outputs)
    with part as sink:
        compiled = None
        try:  # (the libraries are loaded before any row goes to the part)
            if job.route in (ENSEMBLE, TAYLOR):
                with np.errstate(all="ignore"):  # (per thread: chunks may run side by side in one process)
                    compiled = _ensemble(job, param, y0, start, sink)
        except NativeError:  # no C compiler on this worker: the generated numpy module, run by run
            compiled = None
        if compiled is not None:
            summary, reasons, users = compiled
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                summary, reasons, users = _one_by_one(job, param, y0, start, sink)
    first = zero_rows(job.system)
    if first:
        _first_order_finals(job, summary, param, first)
    status = summary[:, 0]
    out: dict[str, object] = {"run": np.arange(start, stop, dtype=np.int64), **inputs}
    out["status"] = np.where(status == 0, "complete", "stopped").tolist()
    out["reason"] = reasons
    out["t_final"] = summary[:, 1]
    for k, name in enumerate(state_names(job.system)):
        out[f"final_{name}"] = summary[:, 5 + k]
    for k, q in enumerate(job.system.coordinates):
        out[f"min_{q.name}"] = summary[:, 5 + ny + k]
    for k, q in enumerate(job.system.coordinates):
        out[f"max_{q.name}"] = summary[:, 5 + ny + nq + k]
    out["energy_drift"] = summary[:, 6 + ny + 2 * nq] - summary[:, 5 + ny + 2 * nq]
    for k, name in ((2, "steps"), (3, "rejected"), (4, "evaluations")):
        out[name] = summary[:, k].astype(np.int64)
    for k, user in enumerate(job.summaries):
        out[user.name] = users[:, k]
    assert all(len(v) == n for v in out.values())
    return out


def _first_order_finals(job: Job, summary: np.ndarray, param: np.ndarray, indices) -> None:
    """The final velocities of the first-order coordinates (:mod:`kronsub.core.first_order`),
    which the state carries but does not integrate: solved from each run's final state by the
    generated right-hand side, in place in ``summary``."""
    from ..simulation.fallback import numpy_module  # heavy (the code emitters): only for first-order coordinates

    rhs = numpy_module(job.system, job.outputs)["rhs"]
    nq, ny = len(job.system.coordinates), state_width(job.system)
    columns = [5 + nq + j for j in indices]
    for r in range(len(summary)):
        y = summary[r, 5:5 + ny].copy()
        try:
            with np.errstate(all="ignore"):
                rates = rhs(float(summary[r, 1]), y, param[r])
        except (ArithmeticError, ValueError, np.linalg.LinAlgError):
            rates = np.full(ny, np.nan)
        summary[r, columns] = np.asarray(rates)[list(indices)]


ROWS_BYTES = 1 << 26  # the rows of the runs of one call to the ensemble, when user outputs need them


def _functions(job: Job):
    """The user outputs as numpy functions of ``(t, state..., parameters...)``."""
    from ..core.symbols import TIME
    from .outputs import evaluator

    system = job.system
    return evaluator(list(job.summaries), [TIME, *system.coordinates, *system.state_velocities,
                                           *(p.symbol for p in system.parameters)])


def _ensemble(job: Job, param: np.ndarray, y0: np.ndarray, run0: int = 0,
              sink: TrajectoryPart | None = None) -> tuple[np.ndarray, list[str], np.ndarray]:
    from ..simulation.grid import Grid

    ensemble = load(job.sources)
    if job.system.implicit is not None:
        return _closed_loops(job, ensemble, param, y0, run0, sink)
    if _held(job.system):
        return _held_runs(job, ensemble, param, y0, run0, sink)
    energies = _conserves(job, ensemble.native)
    cuts = pieces(job.t_end, job.dt, "dop853" if job.route == TAYLOR else job.method)
    grid = Grid(job.t_end, job.dt)
    if job.route == TAYLOR:
        from ..simulation.taylor_c import STATUS

        taylor, times = load_taylor(job.taylor_sources), grid[0:len(grid)]

        def block_of(a, b, with_rows=False):
            return taylor.run(times, job.rtol, param[a:b], y0[a:b], ensemble if energies else None, with_rows)
    else:
        def block_of(a, b, with_rows=False):
            return ensemble.run(job.method, cuts, job.dt, job.rtol, job.atol, param[a:b], y0[a:b], energies,
                                with_rows=with_rows)
    users = np.full((len(y0), len(job.summaries)), np.nan)
    if not job.summaries and sink is None:
        summary = block_of(0, len(y0))
    else:
        from .outputs import evaluate

        functions = _functions(job) if job.summaries else None
        per_run = (len(grid) + 3 * len(cuts)) * (y0.shape[1] + 1) * 8
        block = max(1, ROWS_BYTES // per_run)
        parts = []
        for a in range(0, len(y0), block):
            b = min(a + block, len(y0))
            part, rows, written = block_of(a, b, with_rows=True)
            parts.append(part)
            for r in range(b - a):
                kept = rows[r, :written[r]]
                times = grid.snap(kept[:, 0])
                if sink is not None:
                    sink.add(run0 + a + r, times, kept[:, 1:])
                if functions is not None:
                    users[a + r] = evaluate(list(job.summaries), functions, times, kept[:, 1:],
                                            param[a + r, :len(job.system.parameters)])
        summary = np.concatenate(parts)
    messages: dict[int, str] = {}
    reasons = [""] * len(summary)
    for r in np.flatnonzero(summary[:, 0] != 0):  # (a complete run has no reason: most rows)
        status = int(summary[r, 0])
        if status not in messages:
            messages[status] = STATUS.get(status, f"status {status}") if job.route == TAYLOR else \
                ensemble.message(status)
        reasons[r] = f"{messages[status]} at t = {summary[r, 1]:.6g}"
    return summary, reasons, users


def _closed_loops(job: Job, ensemble, param: np.ndarray, y0: np.ndarray, run0: int = 0,
                  sink: TrajectoryPart | None = None) -> tuple[np.ndarray, list[str], np.ndarray] | None:
    """The runs of a closed loop through the ensemble, each from its initial values projected onto
    the constraints and its own Newton state ``[y_d; tolerance]`` after its parameters, as
    ``simulate`` starts it; a run that stops (a toggle position, Newton's method not converging)
    and every run that keeps rows (the dependent coordinates are computed by ``simulate``'s
    route) go one by one. None: the whole chunk one by one."""
    from ..simulation.constrained import newton_tolerance, project_initial
    from ..simulation.values import RunValues

    if sink is not None or job.summaries:
        return None
    native, system = ensemble.native, job.system
    tol = newton_tolerance(job.rtol, job.atol)
    nparam, ny = len(system.parameters), y0.shape[1]
    full = np.zeros((len(y0), nparam + native.nstate))
    start = np.array(y0, dtype=float)
    failed = []
    for r in range(len(y0)):
        values = RunValues(tuple(float(v) for v in param[r]), tuple(float(v) for v in y0[r]))
        try:
            values, _, constrained = project_initial(system, job.initial, job.dependent_settings, values, tol)
        except KronsubError:
            failed.append(r)
            continue
        start[r] = values.y0
        full[r, :nparam] = param[r]
        full[r, nparam:nparam + native.nstate - 1] = np.asarray(constrained.guess, dtype=float).ravel()
        full[r, -1] = tol
    cuts = pieces(job.t_end, job.dt, job.method)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        summary = ensemble.run(job.method, cuts, job.dt, job.rtol, job.atol, full, start, False)
    redo = sorted(set(failed) | {r for r in range(len(y0)) if summary[r, 0] != 0})
    reasons = [""] * len(y0)
    if redo:
        again, told, _ = _one_by_one(job, param[redo], y0[redo], run0, None)
        for k, r in enumerate(redo):
            summary[r], reasons[r] = again[k], told[k]
    summary[:, 5 + ny + ny] = summary[:, 6 + ny + ny] = np.nan  # as one by one: no energy drift of a closed loop
    return summary, reasons, np.full((len(y0), 0), np.nan)


def _held_runs(job: Job, ensemble, param: np.ndarray, y0: np.ndarray, run0: int = 0,
               sink: TrajectoryPart | None = None) -> tuple[np.ndarray, list[str], np.ndarray]:
    """The runs of a system in its speeds with configuration constraints beside its velocity
    constraints through the ensemble, as ``simulate`` makes them: each from its start put on the
    constraints (:func:`kronsub.simulation.held.hold_start`), its rows put on them as the
    right-hand side puts the states it evaluates (:meth:`kronsub.core.held.HeldCoordinates.rows`),
    its final state, least and greatest coordinates and energies taken from those rows. A run
    whose start is not put there, or that stops, goes one by one (``simulate``'s message)."""
    from ..core.held import held_coordinates
    from ..simulation.grid import Grid
    from ..simulation.held import hold_start
    from ..simulation.values import RunValues
    from .outputs import evaluate

    system, native = job.system, ensemble.native
    nq, ny, nparam = len(system.coordinates), state_width(system), len(system.parameters)
    held: dict[tuple, object] = {}  # per parameter values

    def held_at(r: int):
        values = tuple(float(v) for v in param[r, :nparam])
        if values not in held:
            held[values] = held_coordinates(system, {p.symbol: v for p, v in zip(system.parameters, values)})
        return held[values]

    start = np.array(y0, dtype=float)
    redo = set()
    for r in range(len(y0)):
        try:
            values, _ = hold_start(system, RunValues(tuple(map(float, param[r])), tuple(map(float, y0[r]))),
                                   job.given, held_at(r))
            start[r] = values.y0
        except KronsubError:
            redo.add(r)
    energies = _conserves(job, native)
    cuts, grid = pieces(job.t_end, job.dt, job.method), Grid(job.t_end, job.dt)
    summary = np.full((len(y0), summary_width(nq, ny)), np.nan)
    reasons = [""] * len(y0)
    users = np.full((len(y0), len(job.summaries)), np.nan)
    functions = _functions(job) if job.summaries else None
    block = max(1, ROWS_BYTES // ((len(grid) + 3 * len(cuts)) * (ny + 1) * 8))
    for a in range(0, len(y0), block):
        b = min(a + block, len(y0))
        part, rows, written = ensemble.run(job.method, cuts, job.dt, job.rtol, job.atol, param[a:b], start[a:b],
                                           False, with_rows=True)
        for k in range(b - a):
            r = a + k
            if r in redo or part[k, 0] != 0:  # simulate's start, or its message and the rows it kept
                again, told, mine = _one_by_one(job, param[r:r + 1], y0[r:r + 1], run0 + r, sink)
                summary[r], reasons[r], users[r] = again[0], told[0], mine[0]
                continue
            kept = rows[k, :written[k]]
            Y = held_at(r).rows(kept[:, 0], kept[:, 1:])
            times = grid.snap(kept[:, 0])
            summary[r, :5] = part[k, :5]
            summary[r, 5:5 + ny] = Y[-1]
            summary[r, 5 + ny:5 + ny + nq] = Y[:, :nq].min(axis=0)
            summary[r, 5 + ny + nq:5 + ny + 2 * nq] = Y[:, :nq].max(axis=0)
            if energies:
                T, V = native.energies(kept[[0, -1], 0], Y[[0, -1]], param[r, :nparam])
                summary[r, 5 + ny + 2 * nq], summary[r, 6 + ny + 2 * nq] = T[0] + V[0], T[1] + V[1]
            if sink is not None:
                sink.add(run0 + r, times, Y)
            if functions is not None:
                users[r] = evaluate(list(job.summaries), functions, times, Y, param[r, :nparam])
    return summary, reasons, users


def _one_by_one(job: Job, param: np.ndarray, y0: np.ndarray, run0: int = 0,
                sink: TrajectoryPart | None = None) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Each run as ``simulate`` runs it (closed loops projected onto their constraints first)."""
    from ..simulation.run import start
    from ..simulation.values import RunValues

    system = job.system
    nq, ny = len(system.coordinates), state_width(system)
    summary = np.full((len(y0), summary_width(nq, ny)), np.nan)
    reasons = []
    native = None
    if system.implicit is None:
        try:
            from ..simulation.compiled import native_model

            native = native_model(system, job.outputs)
        except KronsubError:
            native = None
    energies = native is not None and _conserves(job, native)
    users = np.full((len(y0), len(job.summaries)), np.nan)
    functions = _functions(job) if job.summaries else None
    for r in range(len(y0)):
        row = summary[r]
        row[5:5 + ny] = y0[r]
        row[5 + ny:5 + ny + nq] = row[5 + ny + nq:5 + ny + 2 * nq] = y0[r, :nq]
        row[1:5] = (0.0, 0, 0, 0)
        values = RunValues(tuple(float(v) for v in param[r]), tuple(float(v) for v in y0[r]))
        try:
            constrained = None
            if system.implicit is not None:
                from ..simulation.constrained import newton_tolerance, project_initial

                values, _, constrained = project_initial(system, job.initial, job.dependent_settings, values,
                                                         newton_tolerance(job.rtol, job.atol))
                row[5:5 + ny] = values.y0
            elif _held(system):  # on the configuration constraints beside the velocity constraints
                from ..simulation.held import hold_start

                values, _ = hold_start(system, values, job.given)
                row[5:5 + ny] = values.y0
                row[5 + ny:5 + ny + nq] = row[5 + ny + nq:5 + ny + 2 * nq] = values.y0[:nq]
            run = start(system, values, job.t_end, job.dt, job.method, job.rtol, job.atol, progress=False,
                        outputs=job.outputs, constrained=constrained)
            first = last = None
            kept = [] if functions is not None else None
            for block in run:
                Y = np.asarray(block.y).reshape(len(block.t), -1)
                if not len(Y):
                    continue
                if kept is not None:
                    kept.append((np.asarray(block.t, dtype=float), Y))
                if sink is not None:
                    sink.add(run0 + r, np.asarray(block.t, dtype=float), Y, block.dependent)
                row[5 + ny:5 + ny + nq] = np.minimum(row[5 + ny:5 + ny + nq], Y[:, :nq].min(axis=0))
                row[5 + ny + nq:5 + ny + 2 * nq] = np.maximum(row[5 + ny + nq:5 + ny + 2 * nq], Y[:, :nq].max(axis=0))
                row[5:5 + ny] = Y[-1]
                row[1] = float(block.t[-1])
                if block.energies is not None:
                    T, V = block.energies
                    first = float(T[0] + V[0]) if first is None else first
                    last = float(T[-1] + V[-1])
            if kept:
                from .outputs import evaluate

                users[r] = evaluate(list(job.summaries), functions, np.concatenate([k[0] for k in kept]),
                                    np.concatenate([k[1] for k in kept]), param[r])
            stats = run.stats
            row[2:5] = (stats.get("steps", 0), stats.get("rejected", 0), stats.get("evaluations", 0))
            if run.complete:
                row[0] = 0
                reasons.append("")
                if energies and first is not None:
                    row[5 + ny + 2 * nq], row[6 + ny + 2 * nq] = first, last
            else:
                row[0] = 1
                row[1] = run.t_fail if run.t_fail is not None else row[1]
                reasons.append(f"{run.message} at t = {row[1]:.6g}")
        except KronsubError as exc:
            row[0] = 1
            reasons.append(str(exc).splitlines()[0])
    return summary, reasons, users
