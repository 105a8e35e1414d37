"""A sweep set up from a derived model: the swept names checked against the system's
parameters, coordinates and velocities (its speeds, under velocity constraints), the values the
runs share resolved as ``simulate`` resolves them (the model's, the scene's, ``--set``:
:func:`kronsub.simulation.start.starting_values`), and the route of its runs chosen."""
from __future__ import annotations

from ..errors import Location, ModelError, Problem, assignment, near_names, on_command_line, option
from ..simulation.methods import METHODS, SIMULATE, unknown_method
from ..simulation.run import SimulationError, check_tolerances, explicit_only, row_count
from .axes import GridAxis, SampleAxis
from ..core.symbols import TIME
from ..simulation.rows import BLOCK_ROWS
from .chunk import ENSEMBLE, ONE_BY_ONE, TAYLOR, Job, columns, state_names
from .ensemble import BATCH_METHODS, ensemble_sources, taylor_sources
from .outputs import read_outputs
from .plan import MAX_RUNS, Plan

__all__ = ["DEFAULT_CHUNK", "SweepError", "make_job", "make_plan"]

DEFAULT_CHUNK = 1000  # runs per task: ~0.1 s of a small model in C, enough to hide a task's overhead


class SweepError(SimulationError):
    """A sweep that cannot start: too many runs, a method or time it cannot use."""


def make_plan(grids: list[GridAxis], samples: list[SampleAxis], runs: int | None, seed: int,
              latin: bool = False) -> Plan:
    """The runs of the axes; ``runs`` draws per grid point when there are sample axes."""
    sample, draws = option("sample"), option("runs")
    count = f"{draws} N" if on_command_line() else f"{draws}=N"
    if samples and runs is None:
        raise SweepError(f"{sample} needs {count}, the number of draws")
    if not samples and runs is not None and runs != 1:
        raise SweepError(f"{draws} is the number of draws of {sample} axes; a grid alone has as many runs as points\n"
                         f"  hint: add {assignment('sample', 'NAME', '...', text=True)}, or leave out {draws}")
    if latin and not samples:
        raise SweepError(f"{option('latin')} stratifies {sample} axes; there are none")
    if runs is not None and runs < 1:
        raise SweepError(f"{draws} must be at least 1 (got {runs})")
    if not grids and not samples:
        raise SweepError(f"nothing to sweep\n  hint: add {assignment('grid', 'NAME', 'a:b:n', text=True)} or "
                         f"{assignment('sample', 'NAME', 'uniform(a, b)', text=True)}"
                         f"{' ' if on_command_line() else ', '}{count}")
    plan = Plan(tuple(grids), tuple(samples), runs or 1, seed, latin)
    if plan.count > MAX_RUNS:
        raise SweepError(f"the sweep has {plan.count:,} runs, more than {MAX_RUNS:,}\n"
                         "  hint: coarsen the grid or draw fewer samples; split a larger study into sweeps")
    return plan


def make_job(system, plan: Plan, initial: dict, settings: dict[str, str], *, method: str, t_end: float, dt: float,
             rtol: float, atol: float, outputs=None, chunk: int = DEFAULT_CHUNK,
             axes_text: dict[str, str] | None = None, compiled: bool = True, summaries: tuple[str, ...] = (),
             summary_option: str = "--summary") -> Job:
    """The :class:`Job` of ``plan`` over ``system``; ``settings`` the fixed ``--set`` values. Raises
    :class:`ModelError` (unknown or doubly given names, bad values) or :class:`SweepError`."""
    from ..simulation.start import starting_values
    from ..simulation.values import resolve

    if method not in SIMULATE:
        raise SweepError(unknown_method(method))
    explicit_only(system, method)
    row_count(t_end, dt)
    check_tolerances(rtol, atol)
    params = [p.name for p in system.parameters]
    states = state_names(system)
    known = set(params) | set(states)
    where = axes_text or {}
    problems = []
    for name in plan.names:
        at = Location(where.get(name, name))
        if name not in known:
            near = near_names(name, known)
            current = system.printed_name(name)
            problems.append(Problem(at, f"{name}: no parameter, coordinate or velocity of that name",
                                    f"it is the current {current}: sweep it by that name" if current in known else
                                    ("did you mean " + ", ".join(near) + "?") if near else
                                    "parameters: " + ", ".join(params) + "; state: " + ", ".join(states)))
        elif name in settings:
            problems.append(Problem(at, f"{name} is swept and also given by {option('set')}", "give it one or the other"))
    own = [name for name, _ in columns(Job(system=system, plan=Plan((), (), 1, 0), chunk=1, method=method, t_end=t_end,
                                           dt=dt, rtol=rtol, atol=atol, base_param=(), base_y0=(), route=""))]
    for name in plan.names:  # a row's own columns (those of a sweep of nothing) cannot also be an input's
        if name in own:
            problems.append(Problem(Location(where.get(name, name)), f"{name}: a sweep's row has a column {name} of "
                                    "its own, which a swept input of that name would clash with",
                                    "rename it in the model file; a row's own columns: " + ", ".join(own)))
    dependent = set()
    if system.implicit is not None:
        from ..simulation.constrained import dependent_names

        dependent = dependent_names(system)
        for name in plan.names:
            if name in dependent:
                problems.append(Problem(Location(where.get(name, name)), f"{name} is a dependent coordinate of the "
                                        "closed loop: it follows from the independent ones",
                                        "sweep the independent coordinates: " + ", ".join(states)))
    if system.speeds is not None and system.speeds.dependent:
        held = {d.name for d in system.speeds.dependent}
        constraints = ", ".join(f"'{c.name}'" for c in system.speeds.holonomic)
        for name in plan.names:
            if name in held:
                problems.append(Problem(Location(where.get(name, name)), f"{name} is held by the configuration "
                                        f"constraints {constraints}: it follows from the other coordinates",
                                        "sweep the other coordinates: " + ", ".join(
                                            q.name for q in system.coordinates if q.name not in held)))
    names = {"t": TIME, **{q.name: q for q in system.coordinates},
             **{v.name: v for v in system.state_velocities}, **{system.name_of(v): v for v in system.state_velocities},
             **{p.name: p.symbol for p in system.parameters}}
    user = []
    try:
        user = read_outputs(summaries, names, summary_option)
    except ModelError as exc:
        problems.extend(exc.problems)
    taken = {name for name, _ in columns(Job(system=system, plan=plan, chunk=1, method=method, t_end=t_end, dt=dt,
                                                 rtol=rtol, atol=atol, base_param=(), base_y0=(), route=""))}
    for out in user:
        if out.name in taken:
            problems.append(Problem(Location(f"{summary_option} {out.text}"), f"the output name {out.name} is a column "
                                    "of every row already", f"name it: {summary_option} NAME={out.text}"))
    if problems:
        raise ModelError(problems)
    fixed = {k: v for k, v in settings.items() if k not in dependent}
    dependent_settings = {k: v for k, v in settings.items() if k in dependent}
    # the values every run shares, as simulate starts (in speeds, held coordinates put on their constraints)
    values = resolve(system, initial, fixed) if system.implicit is not None else \
        starting_values(system, fixed, initial=initial).values
    swept = {p.symbol for p in system.parameters if p.name in plan.names}
    _meets_requirements(system, plan, values.parameters, where)
    derived = []
    if swept:
        by_name = {k.name: v for k, v in initial.items()}
        import sympy

        for index, name in enumerate(states):
            if name in plan.names or name in fixed or name not in by_name:
                continue
            expr = sympy.sympify(by_name[name])
            if expr.free_symbols & swept:
                derived.append((index, expr))
    route = ONE_BY_ONE
    # a closed loop in the ensemble too, when its coordinates stay those chosen (not `auto`, which
    # may switch them between rows)
    steady = system.implicit is None or system.implicit.choice != "auto"
    if compiled and steady and method in BATCH_METHODS and METHODS[method].engine == "c":
        route = ENSEMBLE
    elif compiled and system.implicit is None and method == "taylor" and row_count(t_end, dt) <= BLOCK_ROWS:
        route = TAYLOR  # one call of the Taylor integrator per run, as simulate makes it
    sources = ensemble_sources(system, outputs) if route in (ENSEMBLE, TAYLOR) else None
    taylor = None
    if route == TAYLOR:
        from ..simulation.taylor_c import TaylorUnavailable

        try:
            taylor = taylor_sources(system, rtol)
        except (TaylorUnavailable, ValueError):
            route, sources = ONE_BY_ONE, None
    return Job(system=system, plan=plan, chunk=chunk, method=method, t_end=t_end, dt=dt, rtol=rtol, atol=atol,
               base_param=values.parameters, base_y0=values.y0, route=route, sources=sources, outputs=outputs,
               initial=dict(initial), dependent_settings=dependent_settings, derived_initial=tuple(derived),
               given=tuple(fixed),
               summaries=tuple(user), taylor_sources=taylor)


REQUIREMENT_BLOCK = 1 << 18  # runs whose swept values are checked at once


def _meets_requirements(system, plan: Plan, base: tuple[float, ...], where: dict[str, str]) -> None:
    """Every run's parameters meet what the components need of them (a mass not below zero, a
    length above it: :mod:`kronsub.model.requirements`), as ``simulate --set`` checks them; the
    first run that breaks one is a :class:`ModelError` at its axis, before anything runs."""
    from ..model.requirements import first_unmet, parameters_in

    names = set(plan.names)
    concerned = [r for r in system.requirements if {s.name for s in parameters_in(r)} & names]
    if not concerned:
        return
    symbols = [p.symbol for p in system.parameters]
    for start in range(0, plan.count, REQUIREMENT_BLOCK):
        stop = min(start + REQUIREMENT_BLOCK, plan.count)
        inputs = plan.inputs(start, stop)
        columns = [inputs.get(p.name, value) for p, value in zip(system.parameters, base)]
        found = first_unmet(concerned, symbols, columns)
        if found is not None:
            row, req, problem = found
            run = start + row
            axes = [s.name for s in parameters_in(req) if s.name in names]
            given = ", ".join(f"{name} = {float(inputs[name][row]):.6g}" for name in plan.names
                              if name in inputs and any(p.name == name for p in system.parameters))
            raise ModelError([Problem(Location(where.get(axes[0], axes[0])),
                                      f"run {run} ({given}): {problem.message}",
                                      f"{problem.hint}; keep the swept values within that range "
                                      "(a sample: uniform(a, b) or loguniform(a, b) bounded there)")])
