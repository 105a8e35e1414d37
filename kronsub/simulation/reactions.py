"""``simulate --reactions``: the reactions of viewpoint (alpha) at every row of a run.

From the reaction expressions (:mod:`kronsub.core.reactions`) and the accelerations of the
generated right-hand side; for a system whose projection onto the speeds is made in numbers
(:func:`~kronsub.core.projection_work.projected_in_numbers`), from the pieces of the rates at each
row (:mod:`kronsub.core.numeric_reactions`), the same multipliers under the same names."""
from __future__ import annotations

import numpy as np
import sympy

from ..core.constraints import ConstraintFailure
from ..core.linearize_numerics import LinearizationError
from ..core.nonholonomic import speed_rates
from ..core.numeric_reactions import multipliers, multiplier_names
from ..core.projection_work import projected_in_numbers
from ..core.reactions import MultiplierSystem, reactions
from ..core.symbols import acceleration_symbol
from .fallback import numpy_module
from .numeric_speeds import NumericSpeeds


def reaction_columns(system, traj, param, module=None, constrained=None) -> tuple[list[str], np.ndarray]:
    """Names and values: the accelerations from the generated right-hand side at each row
    (``module``, the generated numpy module: made here when None), then the reaction expressions
    (with the intermediates from Newton's method on implicit systems); for a system projected
    onto its speeds in numbers, the multipliers from the pieces of its rates (:func:`_projected_rows`).

    A run of ``coordinates: auto`` is evaluated stretch by stretch with the choice of
    independent coordinates that computed it (``traj.segments``): the multipliers do not depend
    on the choice, but the first choice's expressions are singular at its toggle position."""
    if traj.segments:
        return _switched_columns(traj, param)
    if projected_in_numbers(system):
        return multiplier_names(system), _projected_rows(system, traj.t, traj.y, param)
    names, fn = _reaction_function(system, param)
    if module is None:
        module = numpy_module(system)
    if constrained is not None and traj.dependent is not None and len(traj.dependent):
        constrained.guess = np.array(traj.dependent[0], dtype=float)
    return names, _rows(system, fn, len(names), traj.t, traj.y, param, module, constrained)


def _reaction_function(system, param):
    """The reactions' names and one function of (state, accelerations, intermediates, t)."""
    items = reactions(system)
    values = {p.symbol: float(v) for p, v in zip(system.parameters, param)}
    inter = list(system.implicit.intermediates) if system.implicit is not None else []
    rates = (speed_rates(system.speeds.speeds, system.coordinates) if system.speeds is not None else
             [acceleration_symbol(q) for q in system.coordinates])  # what ydot's second part holds
    args = (list(system.coordinates) + list(system.state_velocities) + rates + inter + [sympy.Symbol("t", real=True)])
    if isinstance(items, MultiplierSystem):  # G_d^T mu = r, solved at each row
        k = len(items.names)
        parts = sympy.lambdify(args, [sympy.sympify(e).xreplace(values) for e in [*items.matrix, *items.rows]],
                               "math")

        def fn(*a):
            flat = parts(*a)
            return np.linalg.solve(np.array(flat[:k * k], dtype=float).reshape(k, k), np.array(flat[k * k:], dtype=float))

        return list(items.names), fn
    return [name for name, _ in items], sympy.lambdify(args, [sympy.sympify(e).xreplace(values) for _, e in items],
                                                       "math")


def _rows(system, fn, k, times, states, param, module, constrained) -> np.ndarray:
    """The reactions at each ``(t, [q; qdot])`` (``[q; u]`` under velocity constraints); a row that
    fails stays NaN."""
    n = len(system.coordinates)
    inter = list(system.implicit.intermediates) if system.implicit is not None else []
    rows = []
    for t, y in zip(times, states):
        try:
            if constrained is not None:
                module["set_dependent"](constrained.guess)
            ydot = module["rhs"](t, y, param)
            w = constrained.at(y[:n], y[n:]) if constrained is not None else {}
            rows.append(fn(*y[:n], *y[n:], *ydot[n:], *[w[s] for s in inter], t))
        except Exception:  # noqa: BLE001 - a failed row stays NaN, whatever failed in it
            rows.append([float("nan")] * k)
    return np.array(rows, dtype=float).reshape(len(times), k)


def _projected_rows(system, times, states, param) -> np.ndarray:
    """The multipliers at each ``(t, [x; u])`` from ``S``, ``C``, ``Cdot u + ddot``, ``M``, ``h``, ``f``
    in numbers, ``udot`` the numpy route's right-hand side there (:class:`.numeric_speeds.NumericSpeeds`,
    the held coordinates on their constraints first); a row that fails stays NaN."""
    numeric = NumericSpeeds(system, param)
    n, k = len(system.coordinates), len(system.speeds.constraint_names)
    out = np.full((len(times), k), np.nan)
    for i, (t, y) in enumerate(zip(times, states)):
        try:
            parts = numeric.rates.parts(numeric.on_constraints(float(t), y[:n]), y[n:], float(t))
            out[i] = multipliers(parts, parts.speed_rates().real, numeric.rates.l)
        except (ConstraintFailure, LinearizationError, np.linalg.LinAlgError, ArithmeticError, ValueError):
            continue  # held coordinates off their constraints, S or Mbar singular: the row stays NaN
    return out


def _switched_columns(traj, param) -> tuple[list[str], np.ndarray]:
    """The rows of each stretch with its own choice's system, module and Newton's method, started
    from the configuration the run recorded at the stretch's first row."""
    first = traj.segments[0][2]
    n1 = len(first.independent_idx)
    done: dict[int, tuple] = {}
    names, out = None, np.full((len(traj.t), 0), np.nan)
    for start, stop, split, own in traj.segments:
        if id(split) not in done:
            done[id(split)] = (*_reaction_function(split.system, param), numpy_module(split.system))
        split_names, fn, module = done[id(split)]
        if names is None:
            names, out = split_names, np.full((len(traj.t), len(split_names)), np.nan)
        if stop == start:
            continue
        y = np.empty(len(first.y))
        y[first.independent_idx] = traj.y[start, :n1]
        y[first.dependent_idx] = traj.dependent[start]
        split.evaluator.guess = np.array(y[split.dependent_idx], dtype=float)
        out[start:stop] = _rows(split.system, fn, len(names), traj.t[start:stop], own, param, module, split.evaluator)
    return names or [], out


__all__ = ["reaction_columns"]
