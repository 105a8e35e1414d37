"""Names of a derived system: its symbols by name, values by name, and the linearisation
about an operating point given by name.

Everything a printed equation names is reachable: coordinates, velocities, accelerations,
parameters, ``t`` and, of a closed loop, the dependent coordinates and the named
intermediates (26)-(29).
"""
from __future__ import annotations

import dataclasses
from typing import Mapping, Sequence

import numpy as np
import sympy

from ..core.known_system import KnownSystem
from ..core.linearize import Linearization
from ..core.linearize import linearize as core_linearize
from ..core.nonholonomic import speed_rates
from ..core.nonholonomic_linearize import linearize_speeds
from ..core.rheonomic import depends_on_time
from ..core.symbols import TIME
from ..errors import KronsubError, Location, ModelError, Problem, near_names
from ..model.expressions import parse_expression
from ..model.requirements import parameters_in, unmet

__all__ = ["UnknownName", "linearize", "names", "refuse_driven", "split_assignments", "symbol"]


class UnknownName(KronsubError):
    """A name that is not a coordinate, velocity or parameter of the system."""


def names(system: KnownSystem) -> dict[str, sympy.Symbol]:
    """Every name a printed equation of the system uses: coordinates, velocities,
    accelerations, parameters, ``t``, under velocity constraints the speeds and their rates and,
    for a closed loop, the dependent coordinates and the named intermediates ``lambda_...``,
    ``gamma_...`` (26)-(29) with their printed closed forms; a charge's velocity and acceleration
    also by their printed names, the current ``i_q`` and its rate ``i_q_dot``."""
    out = {"t": TIME}
    groups = [system.coordinates, system.velocities, system.accelerations]
    imp = system.implicit
    if imp is not None:
        groups += [imp.intermediate, imp.intermediates, [name for name, _ in imp.definitions]]
    if system.speeds is not None:  # under velocity constraints: the speeds and their rates
        groups += [system.speeds.speeds, speed_rates(system.speeds.speeds, system.coordinates)]
    for group in groups:
        out.update({s.name: s for s in group})
    out.update({printed: s for s, printed in system.printed_names.items()})  # i_q, i_q_dot beside q_dot, q_ddot
    out.update({p.name: p.symbol for p in system.parameters})
    return out


def symbol(system: KnownSystem, name: str) -> sympy.Symbol:
    """The system's own symbol called ``name`` (they are ``real=True``: a plain
    ``sympy.Symbol(name)`` is a different symbol).

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="pushed")
    >>> theta = system.symbol("theta")
    >>> theta in system.mass_matrix.free_symbols, theta.is_real
    (True, True)
    """
    known = names(system)
    if name not in known:
        near = near_names(name, sorted(known))
        hint = ("did you mean " + ", ".join(f"'{n}'" for n in near) + "?") if near else \
            "names: " + ", ".join(sorted(known))
        raise UnknownName(f"{system.name} has no symbol '{name}'; {hint}")
    return known[name]


def _value(system: KnownSystem, name: str, value, *, constant: bool, option: str | None = None) -> sympy.Expr:
    """A value given as a number or as text read by the whitelisted parser (never sympify
    of raw text); ``constant`` forbids names. ``option`` (``--at``) places problems at ``--at NAME``."""
    if isinstance(value, sympy.Basic):
        return value
    if isinstance(value, bool):
        raise ModelError([Problem(None, f"value of {name}: expected a number, got {value!r}")])
    if isinstance(value, (int, float, np.integer, np.floating)):
        return sympy.Float(float(value)) if isinstance(value, (float, np.floating)) else sympy.Integer(int(value))
    allowed = {} if constant else {p.name: p.symbol for p in system.parameters}
    where = Location(f"{option} {name}") if option else None
    return parse_expression(str(value), allowed, where, what=f"value of {name}")


def split_assignments(system: KnownSystem, at: Mapping[str, object] | None, option: str | None = None):
    """``{name: value}`` into the state/time part and the parameter part, all problems at once
    (placed at ``option NAME`` when the values came from that command-line option)."""
    point, values, problems = {}, {}, []
    params = {p.name: p.symbol for p in system.parameters}
    state = {s.name: s for s in tuple(system.coordinates) + tuple(system.state_velocities)}
    state.update({system.name_of(v): v for v in system.state_velocities})  # a charge's current by its name
    fixed = {v.name for v in system.velocities} - set(state)  # under velocity constraints: not a speed
    for name, raw in (at or {}).items():
        try:
            if name in fixed:
                problems.append(Problem(Location(f"{option} {name}") if option else None,
                                        f"'{name}' is not a speed of {system.name}: the velocity constraints "
                                        "fix it", "give the speeds (" + ", ".join(
                                            u.name for u in system.state_velocities) + "); the other velocities "
                                        "follow from xdot = C u"))
            elif name in state:
                point[state[name]] = _value(system, name, raw, constant=False, option=option)
            elif name in params:
                values[params[name]] = _value(system, name, raw, constant=True, option=option)
            elif name == "t":
                point[TIME] = _value(system, name, raw, constant=False, option=option)
            elif system.implicit is not None and name in {d.name for d in system.implicit.dependent}:
                problems.append(Problem(None, f"'{name}' is a dependent coordinate of {system.name}: the "
                                              "constraints set it", "fix the independent coordinates ("
                                        + ", ".join(q.name for q in system.coordinates) + ") instead"))
            else:
                known = sorted({*params, *state, "t"})
                near = near_names(name, known)
                problems.append(Problem(None, f"'{name}' is not a coordinate, velocity or parameter of "
                                              f"{system.name}",
                                        ("did you mean " + ", ".join(near) + "?") if near else
                                        "names: " + ", ".join(known)))
        except ModelError as exc:
            problems.extend(exc.problems)
    if problems:
        raise ModelError(problems)
    return point, values


def linearize(system: KnownSystem, at: Mapping[str, object] | None = None, inputs: Sequence[str] = (),
              *, symbolic: bool = False, initial: Mapping | None = None, option: str | None = None,
              drive: Location | None = None) -> Linearization:
    """:func:`kronsub.core.linearize.linearize` with names: ``at={"theta": "pi", "b": 0}``
    fixes coordinates, velocities, ``t`` and parameter values; ``inputs=["u"]`` names the
    parameters that are inputs. ``initial`` (default: the model's initial values carried
    by the system: the model's, a scene's over them) starts the search for an equilibrium.
    ``option`` (``"--at"``) places problems with the values at ``--at NAME``; ``drive`` is where
    the model writes its prescribed motion (:func:`refuse_driven` places its error there).
    Under velocity constraints ``at`` gives coordinates and speeds of a steady motion
    (:func:`~kronsub.core.nonholonomic_linearize.linearize_speeds`).

    >>> import kronsub
    >>> system = kronsub.load("models/hoffmann/system1.yaml").derive(scene="free")
    >>> lin = system.linearize(at={"theta": 0, "phi": 0})
    >>> lin.equilibrium, lin.A.shape
    (True, (4, 4))
    """
    problems = []
    try:
        point, values = split_assignments(system, at, option)
    except ModelError as exc:
        problems.extend(exc.problems)
    params = {p.name: p.symbol for p in system.parameters}
    chosen = []
    for name in inputs:
        if name not in params:
            near = near_names(name, sorted(params))
            problems.append(Problem(None, f"input '{name}' is not a parameter of {system.name}",
                                    ("did you mean " + ", ".join(near) + "?") if near else
                                    "inputs are parameters: " + ", ".join(sorted(params))))
        else:
            chosen.append(params[name])
    if not problems:  # what the components need of the values (model/requirements.py)
        numbers = {p.symbol: p.value for p in system.parameters if p.value is not None}
        numbers.update(values)
        given = {s.name for s in values}
        problems.extend(unmet(system.requirements, numbers, lambda req: next(
            (Location(f"{option} {s.name}") for s in parameters_in(req) if option and s.name in given), None)))
    if problems:
        raise ModelError(problems)
    notes = refuse_driven(system, drive)
    start = dict(system.initial) if initial is None else {symbol(system, k) if isinstance(k, str) else k: v
                                                           for k, v in initial.items()}
    route = linearize_speeds if system.speeds is not None else core_linearize
    lin = route(system, inputs=chosen, point=point, values=values, initial=start, symbolic=symbolic)
    return dataclasses.replace(lin, notes=lin.notes + tuple(notes), printed=system.printed_names)


def refuse_driven(system: KnownSystem, drive: Location | None = None) -> tuple[str, ...]:
    """A prescribed motion ``x = x(xbar, t)`` (:mod:`..core.rheonomic`) and linearisation: when
    ``t`` is left in ``Mbar``, ``hbar`` or ``fbar`` the rest states move with time, so there is
    no equilibrium to linearise about (a :class:`ModelError` placed at ``drive``); when the
    drive drops out of the equations (a hoop turned at a constant rate) the linearisation is
    exact, about a rest state relative to the driven coordinates, and the note returned says so."""
    tr = system.transition
    if tr is None or not depends_on_time(dict(tr.connection)):
        return ()
    equations = [*system.mass_matrix, *system.velocity_terms, *(e for f in system.effect_forces.values() for e in f)]
    if any(TIME in sympy.sympify(e).free_symbols for e in equations):
        raise ModelError([Problem(drive, f"{system.name} has a prescribed motion and its equations name t: "
                                         "its rest states move with time, so there is no equilibrium to "
                                         "linearise about",
                                  "simulate it instead (an averaged stability, such as Kapitza's pendulum "
                                  "upside down, shows in a run); or write the drive so that it leaves the "
                                  "equations (a constant rate in the coordinates it turns)")])
    return ("the connection names t (a prescribed motion) but the equations do not: the operating point is a "
            "rest state relative to the driven coordinates, which move with the drive",)
