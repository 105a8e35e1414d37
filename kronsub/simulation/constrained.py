"""Runs of systems with implicit constraints: initial conditions, Newton's tolerance, failures.

- Initial conditions are projected onto the constraints: the dependent coordinates by
  Newton's method with the independent ones held (from the values given, else from the
  branch of the derivation), the velocities onto the tangent space ``G ydot = 0``
  (orthogonally, when dependent velocities are given). The corrections are reported; a
  value given with ``--set`` that is off by more than ``TOLERANCE`` is refused.
- Newton's tolerance in the generated code follows the run's: ``min(rtol, atol) / 100``.
- A run that stops at a singular configuration (a toggle position: ``G_d`` singular, or
  Newton's method not converging) is explained: t, the configuration, the constraints.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import sympy

from ..core.constraints import ConstraintFailure, Intermediates
from ..errors import KronsubError, assignment
from ..model.expressions import parse_expression
from .values import RunValues

__all__ = ["TOLERANCE", "ConstraintError", "configure_module", "configure_native", "dependent_names",
           "diagnose", "energies_on_branch", "newton_tolerance", "project_initial", "split_settings"]

TOLERANCE = 1e-2  # largest correction of a given initial value, times (1 + |value|)


class ConstraintError(KronsubError):
    """Initial conditions too far from the constraints, or no solution of them."""


def newton_tolerance(rtol: float, atol: float) -> float:
    return float(min(max(min(rtol, atol) * 1e-2, 1e-14), 1e-8))


def dependent_names(system) -> set[str]:
    imp = system.implicit
    if imp is None:
        return set()
    return {d.name for d in imp.dependent} | {f"{d.name}_dot" for d in imp.dependent}


def split_settings(system, settings: dict) -> tuple[dict, dict]:
    """``--set`` values of the dependent coordinates (and velocities) apart from the others."""
    names = dependent_names(system)
    return ({k: v for k, v in settings.items() if k not in names},
            {k: v for k, v in settings.items() if k in names})


def _param_values(system, values: RunValues) -> dict:
    return {p.symbol: sympy.Float(v, 17) for p, v in zip(system.parameters, values.parameters)}


def project_initial(system, initial: dict, dep_settings: dict, values: RunValues,
                    tol: float) -> tuple[RunValues, list[str], Intermediates]:
    """Consistent ``y0`` and the dependent coordinates there; notes on the corrections."""
    imp = system.implicit
    params = _param_values(system, values)
    evaluator = Intermediates(imp, params, tol)
    n = len(imp.independent)
    q0 = np.array(values.y0[:n])
    qd0 = np.array(values.y0[n:])
    given = {k.name: v for k, v in initial.items()}
    notes: list[str] = []
    guess, strict = [], []
    branch = dict(imp.branch)
    for d in imp.dependent:
        if d.name in dep_settings:
            guess.append(_number(dep_settings[d.name], d.name))
            strict.append(True)
        elif d.name in given:
            guess.append(float(sympy.sympify(given[d.name]).xreplace(params)))
            strict.append(False)
        else:
            guess.append(float(branch.get(d, 0.0)))
            strict.append(None)
    evaluator.guess = np.array(guess, dtype=float)
    try:
        yd = evaluator.dependent(q0)
    except ConstraintFailure as exc:
        raise ConstraintError(f"the initial configuration violates the constraints "
                              f"{_names(imp)} and Newton's method finds none near it ({exc.message})") from None
    for d, g, v, s in zip(imp.dependent, guess, yd, strict):
        if s is None:
            continue
        correction = abs(v - g)
        if s and correction > TOLERANCE * (1 + abs(g)):
            raise ConstraintError(f"{assignment('set', d.name, f'{g:g}')} is {correction:.3g} away from the constraints "
                                  f"{_names(imp)} (the nearest consistent value is {v:.6g}); "
                                  f"corrections above {TOLERANCE:g} (1 + |value|) are refused")
        if correction > 1e-12:
            notes.append(f"{d.name} {g:.6g} -> {v:.12g} (correction {correction:.3g})")
    # velocities: onto the tangent space G ydot = 0
    y = np.concatenate([q0, yd])
    G = evaluator.numeric.jacobian(y)
    dep_dot = [f"{d.name}_dot" for d in imp.dependent]
    vgiven = [(dep_settings.get(k), True) if k in dep_settings else (given.get(sympy.Symbol(k, real=True).name), False)
              for k in dep_dot]
    if any(v is not None for v, _ in vgiven):
        yd_dot = []
        for (v, _), k in zip(vgiven, dep_dot):
            yd_dot.append(_number(v, k) if isinstance(v, str) else
                          (float(sympy.sympify(v).xreplace(params)) if v is not None else 0.0))
        ydot = np.concatenate([qd0, yd_dot])
        fixed = ydot - G.T @ np.linalg.solve(G @ G.T, G @ ydot)
        correction = float(np.max(np.abs(fixed - ydot)))
        if any(s for _, s in vgiven) and correction > TOLERANCE * (1 + float(np.max(np.abs(ydot)))):
            raise ConstraintError(f"the initial velocities are {correction:.3g} away from the tangent space of "
                                  f"the constraints {_names(imp)}; corrections above {TOLERANCE:g} are refused")
        if correction > 1e-12:
            notes.append(f"velocities projected onto the tangent space (correction {correction:.3g})")
        qd0 = fixed[:n]
    y0 = tuple(float(v) for v in np.concatenate([q0, qd0]))
    evaluator.guess = np.array(yd, dtype=float)
    return dataclasses.replace(values, y0=y0), notes, evaluator


def _number(text: str, name: str) -> float:
    return float(parse_expression(text, {}, None, what=f"initial value of {name}"))


def _names(imp) -> str:
    return ", ".join(f"'{c.name}'" for c in imp.constraints)


def configure_native(native, dependent, tol: float) -> None:
    """Warm start and tolerance of the compiled Newton's method (state owned by ``native``)."""
    native.set_newton(dependent, tol)


def energies_on_branch(native, t, Y, param, dependent) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy per row, each row's Newton's method started from its own
    dependent coordinates (``dependent_rows``): the compiled warm start is the integrator's,
    left wherever the run stopped (at a toggle, next to the other branch), so it is kept aside
    and put back."""
    saved = native.dependent
    T, V = np.empty(len(t)), np.empty(len(t))
    try:
        for i, row in enumerate(dependent):
            native.set_newton(row)
            T[i:i + 1], V[i:i + 1] = native.energies(np.asarray(t)[i:i + 1], np.asarray(Y)[i:i + 1], param)
    finally:
        native.set_newton(saved)
    return T, V


def configure_module(module: dict, dependent, tol: float) -> None:
    module["set_dependent"](dependent)
    module["NEWTON"]["tolerance"] = tol


def diagnose(system, evaluator: Intermediates, t: float, y, guess) -> str:
    """Why the run failed at ``(t, y)``: the equations without a finite value there (an overflow,
    a function outside its domain: :mod:`..core.finite`, as for a system without constraints),
    a toggle position, or no solution of the constraints near."""
    imp = system.implicit
    n = len(imp.independent)
    where = ", ".join(f"{q.name}={v:.6g}" for q, v in zip(imp.independent, y[:n]))
    where += ", " + ", ".join(f"{d.name}~{v:.6g}" for d, v in zip(imp.dependent, guess))
    evaluator.guess = np.array(guess, dtype=float)
    try:
        intermediates = evaluator.at(y[:n], y[n:])
    except ConstraintFailure as exc:
        if exc.kind == "singular":
            kind = "a singular configuration (toggle position): "
        elif evaluator.closed:  # reached from a configuration where it had a value: the end of this choice's range
            kind = _toggle(evaluator, imp, y, guess) or (
                f"the independent coordinates chosen ({_independent(imp)}) are singular here: the dependent "
                "ones reach the end of their closed form's range (a toggle position of this choice, which "
                "other independent coordinates may pass): ")
        else:
            kind = _toggle(evaluator, imp, y, guess) or "no solution of the constraints near the last one: "
        return f"{kind}{exc.message}; constraints {_names(imp)} at t = {t:.6g}, {where}"
    cause = _not_finite(system, evaluator, t, y, intermediates)
    if cause is not None:  # where, with the dependent coordinates solved there
        solved = ", ".join(f"{q.name}={v:.6g}" for q, v in zip(imp.independent + imp.dependent,
                                                             [*y[:n], *(intermediates[d] for d in imp.dependent)]))
        return cause + f" at t = {t:.6g}, {solved}"
    return (f"{_toggle(evaluator, imp, y, guess)}the constraints {_names(imp)} could not be solved in the "
            f"generated code at t = {t:.6g}, in a step from {where}, where they still have a solution: the "
            f"step went where the independent coordinates chosen ({_independent(imp)}) do not determine the "
            "dependent ones")


def _independent(imp) -> str:
    return ", ".join(q.name for q in imp.independent)


def _not_finite(system, evaluator: Intermediates, t: float, y, intermediates: dict) -> str | None:
    """Why ``Mbar``, ``fbar``, ``hbar`` or the energies have no finite value at ``(t, y)`` with the
    intermediates solved there, in the words of :func:`..core.finite.at_state`; None when they do."""
    from ..core.finite import at_state

    values = evaluator.numeric_parameters
    param = [float(values.get(p.symbol, np.nan)) for p in system.parameters]
    if not np.all(np.isfinite(np.asarray(y, dtype=float))):
        return None
    cause = at_state(system, t, y, param, intermediates)
    return None if cause is None else cause.stated()


def _toggle(evaluator: Intermediates, imp, y, guess) -> str:
    """The start of the message when the last configuration is next to a toggle position: the
    dependent block of the Jacobian nearly loses rank against the whole (else empty)."""
    n = len(imp.independent)
    last = np.concatenate([np.asarray(y[:n], dtype=float), np.asarray(guess, dtype=float)])
    G = evaluator.numeric.jacobian(last)
    if not np.all(np.isfinite(G)):
        return ""
    ratio = np.linalg.svd(G[:, n:], compute_uv=False)[-1] / max(np.linalg.norm(G, 2), 1e-300)
    if ratio >= 0.1:
        return ""
    return (f"a singular configuration (toggle position) of the independent coordinates chosen ({_independent(imp)}) "
            "is reached: dg/d(" + ", ".join(d.name for d in imp.dependent) + f") is nearly singular (relative size "
            f"{ratio:.2g}) at the last configuration, and ")


def dependent_rows(evaluator: Intermediates, Y: np.ndarray, n: int, start) -> np.ndarray:
    """The dependent coordinates at every row (Newton from the previous row's)."""
    evaluator.guess = np.array(start, dtype=float)
    out = []
    for y in Y:
        try:
            out.append(evaluator.dependent(y[:n]))
        except ConstraintFailure:
            out.append(np.full(len(start), np.nan))
    return np.array(out).reshape(len(Y), len(start))
