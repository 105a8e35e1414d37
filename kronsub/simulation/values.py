"""Numbers for a run: parameter values and the initial state.

They come from the model (parameter defaults, ``initial:``) and are
overridden by ``--set name=value``; values are constant expressions read by
the whitelisted parser. Unset coordinates and velocities start at zero; a
parameter without a value is an error that names it.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import sympy

from ..core.known_system import KnownSystem
from ..errors import Location, ModelError, Problem, assignment, near_names
from ..errors import option as spelled
from ..model.expressions import constant_value, parse_expression
from ..model.requirements import parameters_in, unmet

__all__ = ["CONSTANT_HINT", "RunValues", "parse_assignments", "resolve"]


_UNKNOWN_NAME = re.compile(r"unknown name '([^']*)'")
CONSTANT_HINT = ("{option} takes a constant: a number or a formula of numbers, e.g. 2.5 or 2*pi/3 (no parameter, "
                 "coordinate or other name)")


@dataclass(frozen=True)
class RunValues:
    """Parameter values in the order of ``system.parameters`` and ``y0 = [q0; qdot0]``."""

    parameters: tuple[float, ...]
    y0: tuple[float, ...]


def parse_assignments(items: tuple[str, ...], option: str = "--set") -> dict[str, str]:
    """``name=value`` strings given with ``option`` on the command line; a name given twice is
    an error (which value was meant is not for kronsub to guess)."""
    out: dict[str, str] = {}
    problems = []
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name or not value.strip():
            problems.append(Problem(None, f"{option} '{item}' is not of the form name=value", f"e.g. {option} m1=2.5"))
        elif name in out:
            problems.append(Problem(None, f"{option} {name} is given twice ({name}={out[name]}, {name}={value.strip()})",
                                    "give each name once"))
        else:
            out[name] = value.strip()
    if problems:
        raise ModelError(problems)
    return out


def resolve(system: KnownSystem, initial: dict, settings: dict[str, str]) -> RunValues:
    """Parameter values and initial state, with every problem reported at once. A charge's
    current is set by its name ``i_q`` or as ``q_dot`` (:mod:`kronsub.core.currents`)."""
    problems: list[Problem] = []
    known = {p.name for p in system.parameters}
    state = [q.name for q in system.coordinates] + [v.name for v in system.state_velocities]
    printed = [q.name for q in system.coordinates] + [system.name_of(v) for v in system.state_velocities]
    settings = {system.symbol_name(name): text for name, text in settings.items()}
    for name in settings:
        if name not in known and name not in state:
            near = near_names(name, known | set(printed))
            hint = ("did you mean " + ", ".join(near) + "?") if near else \
                "parameters: " + ", ".join(sorted(known)) + "; state: " + ", ".join(printed)
            problems.append(Problem(None, f"{spelled('set', name)}: no parameter, coordinate or velocity of that name",
                                    hint))

    def number(text: str, what: str, name: str) -> float | None:
        name = system.printed_name(name)
        where = Location(spelled("set", name))
        try:
            return constant_value(parse_expression(text, {}, where, what=what), where, what=what)
        except ModelError as exc:
            problems.extend(dataclasses.replace(p, hint=CONSTANT_HINT.format(option=spelled("set"))) if _UNKNOWN_NAME.search(p.message) else p
                            for p in exc.problems)
            return None

    def value_of(expr, what: str) -> float | None:
        try:
            return constant_value(sympy.sympify(expr), None, what=what)
        except ModelError as exc:
            problems.extend(exc.problems)
            return None

    params: list[float] = []
    missing = []
    for p in system.parameters:
        if p.name in settings:
            params.append(number(settings[p.name], f"value of {p.name}", p.name))
        elif p.value is not None and sympy.sympify(p.value).is_number:
            params.append(value_of(p.value, f"value of parameter {p.name}"))
        else:
            missing.append(p.name)
    if missing:
        problems.append(Problem(None, "no value for parameter" + ("s " if len(missing) > 1 else " ")
                                + ", ".join(missing), "give them a `value:` in the model or "
                                + ", ".join(assignment("set", m, "...") for m in missing)))
    values = dict(zip([p.symbol for p in system.parameters], params))
    if not missing and None not in params:  # what the components need of the values (model/requirements.py)
        problems.extend(unmet(system.requirements, values, lambda req: next(
            (Location(spelled("set", s.name)) for s in parameters_in(req) if s.name in settings), None)))
    y0: list[float] = []
    initial_by_name = {k.name: v for k, v in initial.items()}
    for name in state:
        if name in settings:
            y0.append(number(settings[name], f"initial value of {system.printed_name(name)}", name))
        elif name in initial_by_name:
            y0.append(value_of(sympy.sympify(initial_by_name[name]).xreplace(values),
                               f"initial value of {system.printed_name(name)}")
                      if not missing and None not in params else 0.0)
        else:
            y0.append(0.0)
    if problems:
        raise ModelError(problems)
    return RunValues(tuple(params), tuple(y0))
