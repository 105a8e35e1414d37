"""Linearisation of a system with first-order coordinates (:mod:`.first_order`).

The state is ``y = [q; qdot_I]``: every coordinate, and the velocities of the coordinates
with inertia. The first-order coordinates ``J`` move with ``qdot_J = v_J(t, q, qdot_I, u)``,
solved from their equations, and the others by the regular block ``Mbar_II qddot_I = r_I``
(``r = fbar - hbar`` with ``qdot_J = v_J``), so

    A = [[dv/dq, dv/dqdot_I], [Mbar_II^-1 K, Mbar_II^-1 D]],
    K = dr_I/dq - [(dMbar_II/dq_k) a*]_k,   D = dr_I/dqdot_I,   G = dr_I/du,

with ``v = qdot`` (``v_J`` in rows ``J``, ``qdot_I`` in the others) and the total derivatives
through ``v_J``. An equilibrium is ``r(q, 0) = 0`` as in :mod:`.linearize` (``D_JJ`` regular:
``v_J = 0`` exactly where ``r_J = 0``). Numeric only.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import sympy

from .derivative import matrix_derivative
from .first_order import FirstOrder
from .known_system import KnownSystem
from .linearize_numerics import (EQUILIBRIUM_TOLERANCE, Evaluator, Linearization, LinearizationError,
                                 checked_inputs, least_squares_equilibrium, numeric_value, parameter_defaults,
                                 parameter_numbers, residual, sorted_eigenvalues, unevaluable)
from .symbols import TIME
from ..errors import assignment


def linearize_first_order(system: KnownSystem, first: FirstOrder, *, inputs: Sequence[sympy.Symbol] = (),
                          point: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                          values: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                          initial: Mapping[sympy.Symbol, sympy.Expr] | None = None,
                          symbolic: bool = False) -> Linearization:
    """``A``, ``B`` in ``y = [q; qdot_I]`` (the arguments as for :func:`.linearize.linearize`)."""
    q, qd = list(system.coordinates), list(system.velocities)
    n = len(q)
    J = list(first.indices)
    I = [i for i in range(n) if i not in J]  # noqa: E741 - the paper's letters for the blocks
    names = ", ".join(q[j].name for j in J)
    if symbolic:
        raise LinearizationError(f"a symbolic linearisation of first-order coordinates ({names}) is not "
                                 "available; linearise numerically")
    point, values, initial = dict(point or {}), dict(values or {}), dict(initial or {})
    inputs = checked_inputs(system, inputs)
    t0 = sympy.sympify(point.pop(TIME, 0))
    numbers, missing = parameter_numbers(system, values)
    if missing:
        raise LinearizationError("no value for parameter" + ("s " if len(missing) > 1 else " ")
                                 + ", ".join(missing) + "; give it with " + assignment("at"))
    for s in point:
        if s in [qd[j] for j in J]:
            raise LinearizationError(f"'{s}' is no state: {q[qd.index(s)]} is a first-order coordinate, its "
                                     "velocity follows from the state")
        if s not in q and s not in qd:
            raise LinearizationError(f"'{s}' is not a coordinate or velocity of {system.name}")
    state = q + [qd[i] for i in I]
    r = residual(system)
    solved = first.substitution(system)
    r_I = sympy.Matrix([r[i] for i in I]).xreplace(solved)
    v = sympy.Matrix([first.velocities[J.index(i)] if i in J else qd[i] for i in range(n)])
    M_II = sympy.Matrix([[system.mass_matrix[i, k] for k in I] for i in I])
    symbols = q + qd + [TIME] + [p.symbol for p in system.parameters]
    evaluate = Evaluator([M_II, r_I, v, matrix_derivative(r_I, state), matrix_derivative(v, state),
                          matrix_derivative(r_I, list(inputs)) if inputs else sympy.zeros(len(I), 0),
                          matrix_derivative(v, list(inputs)) if inputs else sympy.zeros(n, 0),
                          r, matrix_derivative(r, q)]
                         + [matrix_derivative(M_II, qk) for qk in q], symbols)

    numeric_values = {**{s: 0.0 for s in qd}, **{s: numeric_value(initial.get(s, 0), numbers) for s in q},
                      TIME: numeric_value(t0, numbers), **numbers}
    numeric_values.update({s: numeric_value(v_, numbers) for s, v_ in point.items()})
    free = [s for s in q if s not in point]
    if free:
        numeric_values = _equilibrium(evaluate, numeric_values, q, free, r)
    Mn, rn, vn, dr, dv, gr, gv, _, _, *dM = evaluate(numeric_values)
    try:
        np.linalg.cholesky(Mn)
        a = np.linalg.solve(Mn, rn.ravel())
    except np.linalg.LinAlgError:
        where = ", ".join(f"{s}={numeric_values[s]:.6g}" for s in q)
        raise LinearizationError(f"the mass matrix of the coordinates with inertia is not positive definite at "
                                 f"{where}") from None
    rates = np.zeros(n)
    rates[I], rates[J] = a, vn.ravel()[J]
    velocities_zero = all(numeric_values[s] == 0 for s in qd if s in point)
    equilibrium = velocities_zero and float(np.max(np.abs(rates), initial=0.0)) <= EQUILIBRIUM_TOLERANCE
    if free and not point and not equilibrium:
        where = ", ".join(f"{s}={numeric_values[s]:.6g}" for s in q)
        raise LinearizationError(f"no equilibrium found near the initial values (at {where} the largest rate is "
                                 f"{np.max(np.abs(rates)):.3g}); give the operating point with " + assignment("at") + " "
                                 "for every coordinate")
    K = dr.copy()
    K[:, :n] -= np.column_stack([dMk @ a for dMk in dM]) if n else 0
    lower = np.linalg.solve(Mn, np.hstack([K, gr]))
    A = np.vstack([dv, lower[:, :len(state)]])
    B = np.vstack([gv, lower[:, len(state):]])
    defaults = parameter_defaults(system)
    op_state = tuple((s, sympy.Float(numeric_values[s], 17)) for s in state)
    op_inputs = tuple((u, sympy.sympify(values.get(u, defaults.get(u, u)))) for u in inputs)
    return Linearization(
        state=tuple(state), inputs=inputs, point=op_state + op_inputs, time=t0,
        parameters=tuple((p.symbol, sympy.sympify(values.get(p.symbol, defaults.get(p.symbol))))
                         for p in system.parameters),
        A=A, B=B, eigenvalues=sorted_eigenvalues(A), acceleration=tuple(float(x) for x in rates),
        equilibrium=equilibrium, found=tuple(free),
        notes=(f"{names} {'is a first-order coordinate' if len(J) == 1 else 'are first-order coordinates'} "
               "(no inertia): the state holds no velocity of "
               f"{'it' if len(J) == 1 else 'them'}, and the rates at the point are their velocities",))


def _equilibrium(evaluate: Evaluator, values: dict, q, free, r) -> dict:
    """``r(q, 0) = 0`` for the free coordinates (:func:`least_squares_equilibrium`)."""
    columns = [q.index(s) for s in free]

    def at(x):
        return {**values, **dict(zip(free, (float(v) for v in x)))}

    def fun(x):
        return evaluate(at(x))[7].ravel()

    def jac(x):
        return evaluate(at(x))[8][:, columns]

    x0 = np.array([values[s] for s in free], dtype=float)
    if not np.all(np.isfinite(fun(x0))):
        raise LinearizationError(unevaluable(r, q, values, evaluate.matrices[0]))
    scale = max(1.0, float(np.max(np.abs(fun(x0)), initial=0.0)))
    return at(least_squares_equilibrium(fun, jac, x0, lambda x: np.max(np.abs(fun(x)), initial=0.0) <= 1e-12 * scale))


__all__ = ["linearize_first_order"]
