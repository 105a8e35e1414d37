"""User outputs of a sweep: a value per run computed from its rows, written as an aggregate of an
expression of the model's names (coordinates, velocities, parameters, ``t``):
``max(abs(theta))``, ``min(...)``, ``mean(...)`` (over the rows every ``--dt``), ``initial(x)``,
``final(x)``, and ``first_time(phi > pi)`` (the first row's time where the comparison holds; NaN
when none). The inner expression is read by the model's safe reader
(:func:`kronsub.model.expressions.parse_expression`), never evaluated as Python text; a
comparison is split at its operator and each side read so."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import sympy

from ..errors import Location, ModelError, Problem
from ..model.expressions import parse_expression

__all__ = ["AGGREGATES", "UserOutput", "evaluate", "read_outputs"]

AGGREGATES = ("max", "min", "mean", "initial", "final", "first_time")
_CALL = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*\((.*)\)\s*$", re.S)
_COMPARE = re.compile(r"(<=|>=|<|>)")
HINT = ("an output is max(...), min(...), mean(...), initial(...), final(...) of an expression of the model's "
        "coordinates, velocities, parameters and t, or first_time(a > b); e.g. max(abs(theta)), "
        "first_time(phi > pi); name it with NAME=...")


@dataclass(frozen=True)
class UserOutput:
    """One output: its column ``name``, the aggregate, the expression (for ``first_time``: the
    difference of the sides, and the comparison)."""

    name: str
    aggregate: str
    expr: sympy.Expr
    compare: str = ""
    text: str = ""


def _depth0(text: str) -> list[tuple[int, str]]:
    depth, found = 0, []
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0:
            m = _COMPARE.match(text, i)
            if m and (not found or i > found[-1][0] + len(found[-1][1])):
                found.append((i, m.group(1)))
    return found


def read_outputs(items: tuple[str, ...], names: dict[str, sympy.Symbol], option: str = "--summary") -> list[UserOutput]:
    """Every output of ``items`` (``EXPR`` or ``NAME=EXPR``); raises :class:`ModelError` with
    every problem, each at its option."""
    problems, outputs = [], []
    for item in items:
        where = Location(f"{option} {item}")
        name, sep, text = item.partition("=")
        if not sep or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name.strip()) or text.lstrip().startswith("="):
            name, text = item.strip(), item
        name = name.strip()
        call = _CALL.match(text)
        if call is None or call.group(1) not in AGGREGATES:
            problems.append(Problem(where, f"'{text.strip()}' is not an output", HINT))
            continue
        aggregate, body = call.group(1), call.group(2)
        try:
            if aggregate == "first_time":
                ops = _depth0(body)
                if len(ops) != 1:
                    problems.append(Problem(where, "first_time takes one comparison, e.g. first_time(phi > pi)", HINT))
                    continue
                i, op = ops[0]
                left = parse_expression(body[:i], names, where, what="the left side of the comparison")
                right = parse_expression(body[i + len(op):], names, where, what="the right side of the comparison")
                outputs.append(UserOutput(name, aggregate, left - right, op, text.strip()))
            else:
                if _depth0(body):
                    problems.append(Problem(where, f"{aggregate} takes an expression, not a comparison", HINT))
                    continue
                outputs.append(UserOutput(name, aggregate, parse_expression(body, names, where, what="the output"),
                                          "", text.strip()))
        except ModelError as exc:
            problems.extend(exc.problems)
    seen = set()
    for out in outputs:
        if out.name in seen:
            problems.append(Problem(Location(f"{option} {out.text}"), f"two outputs are called {out.name}",
                                    "name them NAME=EXPR"))
        seen.add(out.name)
    if problems:
        raise ModelError(problems)
    return outputs


def evaluator(outputs: list[UserOutput], symbols: list[sympy.Symbol]):
    """A numpy function per output of the arguments ``symbols`` (``t``, the state, the
    parameters): :func:`sympy.lambdify` of the parsed expression tree."""
    return [sympy.lambdify(symbols, out.expr, modules="numpy") for out in outputs]


def evaluate(outputs: list[UserOutput], functions, t: np.ndarray, Y: np.ndarray, param: np.ndarray) -> list[float]:
    """Each output over one run's rows (times ``t``, states ``Y``) at its parameters."""
    values = []
    with np.errstate(all="ignore"):
        for out, f in zip(outputs, functions):
            if not len(t):
                values.append(np.nan)
                continue
            v = np.asarray(f(t, *Y.T, *param), dtype=float)
            if v.shape != t.shape:  # (a constant, or an expression of the parameters alone)
                v = np.broadcast_to(v, t.shape)
            if out.aggregate == "max":
                values.append(float(np.max(v)))
            elif out.aggregate == "min":
                values.append(float(np.min(v)))
            elif out.aggregate == "mean":
                values.append(float(np.mean(v)))
            elif out.aggregate == "initial":
                values.append(float(v[0]))
            elif out.aggregate == "final":
                values.append(float(v[-1]))
            else:
                holds = {">": v > 0, ">=": v >= 0, "<": v < 0, "<=": v <= 0}[out.compare]
                hit = np.flatnonzero(holds)
                values.append(float(t[hit[0]]) if len(hit) else np.nan)
    return values
