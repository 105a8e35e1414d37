"""Linearisation of a system with implicit constraints: the reduced equations (25)-(29).

The projected equations ``Mbar qddot = r`` (``r = fbar - hbar``) of an implicit system are
written in the independent coordinates ``q`` and the named intermediates ``w``: the
dependent coordinates ``y_d``, ``Lambda = dy_d/dq`` and ``gamma`` (``Cdot qdot = [0; gamma]``).
They depend on ``q`` and ``qdot`` through ``w``, so the derivatives in ``A`` are total ones,
by the implicit-function theorem on ``g(q, y_d) = 0``, ``G_d Lambda = -G_i``,
``G_d gamma = quad(y, qdot, Lambda)``:

    dy_d/dq_j = Lambda[:, j]
    dLambda/dq_j = -G_d^-1 (DG_d,j Lambda + DG_i,j),        D. = d./dq_j + sum_a d./dy_a Lambda[a, j]
    dgamma/dq_j = G_d^-1 (Dquad_j - DG_d,j gamma),   dgamma/dqdot = G_d^-1 dquad/dqdot

and ``dr/dq_j`` (and ``dMbar/dq_j``) add the terms through ``y_d``, ``Lambda`` and ``gamma``.
The state is the reduced one, ``[q; qdot]``; the rest is as in :mod:`.linearize`.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import sympy

from .constraints import ConstraintFailure, Intermediates
from .derivative import matrix_derivative
from .known_system import KnownSystem
from .linearize_numerics import (EQUILIBRIUM_TOLERANCE, Evaluator, Linearization, LinearizationError, at_equilibrium,
                                 checked_inputs, least_squares_equilibrium, numeric_value,
                                 parameter_defaults, parameter_numbers, residual, solve_mass, sorted_eigenvalues,
                                 unevaluable)
from .symbols import TIME
from ..errors import assignment


class _Reduced:
    """The reduced equations and their total derivatives at numeric parameter values."""

    def __init__(self, system: KnownSystem, numbers: dict, inputs: Sequence[sympy.Symbol], guess):
        imp = self.imp = system.implicit
        self.system = system
        self.q, self.qd = list(system.coordinates), list(system.velocities)
        self.n, self.k = len(self.q), len(imp.dependent)
        self.numbers = numbers
        self.evaluator = Intermediates(imp, {s: float(v) for s, v in numbers.items()})
        if guess is not None:
            self.evaluator.guess = np.array(guess, dtype=float)
        yd, lam, gam = list(imp.dependent), list(imp.sensitivities), list(imp.convective)
        self.lam_shape = imp.sensitivities.shape
        r, M = residual(system), system.mass_matrix
        Gd, Gi = imp.jacobian_dependent, imp.jacobian_independent
        quad = sympy.Matrix(imp.quadratic)

        def jac(m, wrt):
            return matrix_derivative(m, list(wrt)) if wrt else sympy.zeros(m.shape[0], 0)

        matrices = {
            "M": M, "r": r, "r_q": jac(r, self.q), "r_qd": jac(r, self.qd), "r_u": jac(r, list(inputs)),
            "r_yd": jac(r, yd), "r_L": jac(r, lam), "r_g": jac(r, gam),
            "Gd": Gd, "Gi": Gi, "quad": quad, "quad_q": jac(quad, self.q), "quad_yd": jac(quad, yd),
            "quad_L": jac(quad, lam), "quad_qd": jac(quad, self.qd),
        }
        for label, symbols in (("q", self.q), ("yd", yd), ("L", lam)):
            for i, s in enumerate(symbols):
                matrices[f"M_{label}{i}"] = matrix_derivative(M, s)
                if label != "L":
                    matrices[f"Gd_{label}{i}"] = matrix_derivative(Gd, s)
                    matrices[f"Gi_{label}{i}"] = matrix_derivative(Gi, s)
        self.names = list(matrices)
        self.symbols = self.q + self.qd + yd + lam + gam + [TIME] + list(numbers)
        self.evaluate = Evaluator([matrices[k] for k in self.names], self.symbols)

    def values(self, q, qd, t: float) -> dict:
        """Every symbol's value at the reduced state ``(q, qdot)`` (the intermediates solved for)."""
        try:
            w = self.evaluator.at(q, qd)
        except ConstraintFailure as exc:
            where = ", ".join(f"{s}={v:.6g}" for s, v in zip(self.q, q))
            raise LinearizationError(f"the constraints cannot be solved at {where}: {exc.message}") from None
        return {**dict(zip(self.q, map(float, q))), **dict(zip(self.qd, map(float, qd))),
                **{s: float(v) for s, v in w.items()}, TIME: t, **self.numbers}

    def at(self, values: dict) -> dict[str, np.ndarray]:
        return dict(zip(self.names, self.evaluate(values)))

    def total(self, values: dict, acceleration=None):
        """``M``, ``r`` and the total ``K = Dr/Dq - [DMbar/Dq_j a]_j``, ``D = Dr/Dqdot``, ``G = dr/du``."""
        e = self.at(values)
        n, k = self.n, self.k
        lam = np.array([values[s] for s in self.imp.sensitivities]).reshape(self.lam_shape)
        gam = np.array([values[s] for s in self.imp.convective])
        Gd = e["Gd"]
        Dr = np.zeros((n, n))
        DM = []
        for j in range(n):
            DGd = e[f"Gd_q{j}"] + sum((e[f"Gd_yd{a}"] * lam[a, j] for a in range(k)), np.zeros((k, k)))
            DGi = e[f"Gi_q{j}"] + sum((e[f"Gi_yd{a}"] * lam[a, j] for a in range(k)), np.zeros((k, n)))
            dlam = -np.linalg.solve(Gd, DGd @ lam + DGi).ravel()
            Dquad = e["quad_q"][:, j] + e["quad_yd"] @ lam[:, j] + e["quad_L"] @ dlam
            dgam = np.linalg.solve(Gd, Dquad - DGd @ gam)
            Dr[:, j] = e["r_q"][:, j] + e["r_yd"] @ lam[:, j] + e["r_L"] @ dlam + e["r_g"] @ dgam
            DM.append(e[f"M_q{j}"] + sum((e[f"M_yd{a}"] * lam[a, j] for a in range(k)), np.zeros((n, n)))
                      + sum((e[f"M_L{b}"] * dlam[b] for b in range(len(dlam))), np.zeros((n, n))))
        D = e["r_qd"] + e["r_g"] @ np.linalg.solve(Gd, e["quad_qd"])
        K = Dr if acceleration is None else Dr - np.column_stack([DMj @ acceleration for DMj in DM])
        return e["M"], e["r"].ravel(), K, D, e["r_u"]


def linearize_implicit(system: KnownSystem, *, inputs: Sequence[sympy.Symbol] = (),
                       point: Mapping | None = None, values: Mapping | None = None,
                       initial: Mapping | None = None, symbolic: bool = False) -> Linearization:
    """:func:`.linearize.linearize` for a system with implicit constraints (numeric only)."""
    imp = system.implicit
    if symbolic:
        raise LinearizationError(f"{system.name} has implicit constraints: its A and B are numeric only (the "
                                 "dependent coordinates are found by Newton's method)\n  hint: leave out "
                                 "--symbolic, or write the subspace in parametric form (eq. 26)")
    point, values, initial = dict(point or {}), dict(values or {}), dict(initial or {})
    inputs = checked_inputs(system, inputs)
    q, qd = list(system.coordinates), list(system.velocities)
    n = len(q)
    t0 = sympy.sympify(point.pop(TIME, 0))
    numbers, missing = parameter_numbers(system, values)
    defaults = parameter_defaults(system)
    if missing:
        raise LinearizationError("no value for parameter" + ("s " if len(missing) > 1 else " ")
                                 + ", ".join(missing) + "; give it with " + assignment("at"))
    for s in point:
        if s not in q and s not in qd:
            raise LinearizationError(f"'{s}' is not an independent coordinate or velocity of {system.name}")
    state = {s: numeric_value(point.get(s, initial.get(s, 0)), numbers) for s in q + qd}
    for s, v in state.items():
        if not np.isfinite(v):
            raise LinearizationError(f"the operating value of '{s}' is not a real number")
    for s in qd:
        state[s] = state[s] if s in point else 0.0
    guess = [numeric_value(initial[d], numbers) for d in imp.dependent] if all(d in initial for d in imp.dependent) \
        else None
    reduced = _Reduced(system, numbers, inputs, guess if guess and all(np.isfinite(guess)) else None)
    t = numeric_value(t0, numbers)
    free = [s for s in q if s not in point]
    qv = np.array([state[s] for s in q])
    qdv = np.array([state[s] for s in qd])
    if free:
        qv = _equilibrium(reduced, qv, qdv, t, [q.index(s) for s in free])
    at = reduced.values(qv, qdv, t)
    Mn, rn, *_ = reduced.total(at)
    acceleration = solve_mass(Mn, rn, at, q)
    velocities_zero = not np.any(qdv)
    equilibrium = velocities_zero and float(np.max(np.abs(acceleration), initial=0.0)) <= EQUILIBRIUM_TOLERANCE
    if free and not [s for s in point if s in q] and not equilibrium:
        where = ", ".join(f"{s}={v:.6g}" for s, v in zip(q, qv))
        raise LinearizationError(f"no equilibrium found near the initial values (at {where} the largest "
                                 f"acceleration is {np.max(np.abs(acceleration)):.3g}); give the operating "
                                 "point with " + assignment("at") + " for every independent coordinate")
    Mn, rn, K, D, G = reduced.total(at, acceleration)
    lower = solve_mass(Mn, np.hstack([K, D, G]), at, q)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :] = lower[:, :2 * n]
    B = np.zeros((2 * n, len(inputs)))
    B[n:, :] = lower[:, 2 * n:]
    op_state = {s: (sympy.sympify(point[s]) if s in point and sympy.sympify(point[s]).is_number
                    else sympy.Float(v, 17)) for s, v in zip(q + qd, list(qv) + list(qdv))}
    op_inputs = {u: sympy.sympify(values.get(u, defaults.get(u, u))) for u in inputs}
    return Linearization(
        state=tuple(q + qd), inputs=inputs,
        point=tuple(list(op_state.items()) + list(op_inputs.items())), time=t0,
        parameters=tuple((p.symbol, sympy.sympify(values.get(p.symbol, defaults.get(p.symbol))))
                         for p in system.parameters),
        A=A, B=B, eigenvalues=sorted_eigenvalues(A), acceleration=tuple(float(a) for a in acceleration),
        equilibrium=equilibrium, found=tuple(free), symbolic=False,
        dependent=tuple((d, float(at[d])) for d in imp.dependent),
    )


def _equilibrium(reduced: _Reduced, qv, qdv, t: float, columns: list[int]) -> np.ndarray:
    """Solve ``r(q, 0) = 0`` for the free independent coordinates
    (:func:`.linearize_numerics.least_squares_equilibrium`, the total derivative as its Jacobian; the
    dependent ones follow by Newton at every step)."""

    def full(x):
        out = np.array(qv, dtype=float)
        out[columns] = x
        return out

    def fun(x):
        return reduced.total(reduced.values(full(x), qdv, t))[1]

    def jac(x):
        return reduced.total(reduced.values(full(x), qdv, t))[2][:, columns]

    x0 = np.array(qv, dtype=float)[columns]
    if not np.all(np.isfinite(fun(x0))):  # why, with the intermediates solved there (core/finite.py)
        system = reduced.system
        raise LinearizationError(unevaluable(residual(system), list(system.coordinates),
                                              reduced.values(full(x0), qdv, t), system.mass_matrix))

    def settled(x):
        Mn, rn, *_ = reduced.total(reduced.values(full(x), qdv, t))
        return at_equilibrium(Mn, rn)

    def get():
        return np.array(reduced.evaluator.guess, dtype=float)  # y_d, Newton's warm start

    def put(guess):
        reduced.evaluator.guess = np.array(guess, dtype=float)

    return full(least_squares_equilibrium(fun, jac, x0, settled, (get, put)))


__all__ = ["linearize_implicit"]
