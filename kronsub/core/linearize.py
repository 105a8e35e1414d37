"""Linearisation of the equations of motion about an operating point.

With ``r(q, qdot, t, u) = fbar - hbar`` the equations (10') read ``Mbar qddot = r``;
as a first-order system in ``y = [q; qdot]``, ``ydot = [qdot; a]`` with
``a = Mbar^-1 r``. Differentiating ``Mbar a = r`` at the point ``(q*, qdot*, u*)``:

    Mbar da/dq_k = dr/dq_k - (dMbar/dq_k) a*,    Mbar da/dqdot = dr/dqdot,    Mbar da/du = dr/du,

so ``ydot ~ A (y - y*) + B (u - u*)`` with

    A = [[0, I], [Mbar^-1 K, Mbar^-1 D]],   B = [[0], [Mbar^-1 G]],
    K = dr/dq - [(dMbar/dq_k) a*]_k,   D = dr/dqdot,   G = dr/du.

At an equilibrium (``qdot* = 0``, ``a* = 0``) the ``dMbar/dq`` term vanishes, and so does
``hbar``'s contribution to ``D`` (``hbar`` is quadratic in the velocities, the bracket
of (E)): only ``fbar``'s dependence on the velocities (dampers) is left in ``D``.

The operating point is an equilibrium by default: ``r(q, 0, t, u) = 0`` (``Mbar`` is
positive definite, so ``a = 0`` exactly when ``r = 0``) is solved numerically for the
coordinates not given, from the model's initial values.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import sympy

from .derivative import matrix_derivative
from .finite import describe_rank_loss
from .known_system import KnownSystem
from .first_order import first_order
from .linearize_first_order import linearize_first_order
from .linearize_implicit import linearize_implicit
from .linearize_numerics import (EQUILIBRIUM_TOLERANCE, Evaluator, Linearization, LinearizationError, at_equilibrium,
                                 checked_inputs, least_squares_equilibrium, numeric_value,
                                 parameter_defaults, parameter_numbers, residual, solve_mass, sorted_eigenvalues,
                                 unevaluable)
from .seeded import seeded, sympy_seeded
from .symbols import TIME, free_symbols_of, velocity_symbol
from ..errors import assignment


def linearize(system: KnownSystem, *, inputs: Sequence[sympy.Symbol] = (),
              point: Mapping[sympy.Symbol, sympy.Expr] | None = None,
              values: Mapping[sympy.Symbol, sympy.Expr] | None = None,
              initial: Mapping[sympy.Symbol, sympy.Expr] | None = None,
              symbolic: bool = False) -> Linearization:
    """``A``, ``B`` of the first-order system about an operating point.

    ``point`` fixes coordinates, velocities and ``t`` (default 0); the coordinates
    it leaves out are solved for an equilibrium starting from ``initial`` (else 0),
    velocities left out are 0. With no ``point`` at all, failing to find an
    equilibrium is an error; a given point that is not one is linearised about
    anyway and reported (``equilibrium`` false, ``acceleration`` there).
    ``values`` overrides the parameters' defaults (an input's value is its operating
    value ``u*``). ``symbolic`` keeps the parameters not in ``values`` as symbols in
    ``A`` and ``B``.
    """
    if getattr(system, "implicit", None) is not None:  # the reduced equations (linearize_implicit.py)
        return linearize_implicit(system, inputs=inputs, point=point, values=values, initial=initial,
                                  symbolic=symbolic)
    first = first_order(system)
    if first is not None:  # the mixed first/second-order state (linearize_first_order.py)
        return linearize_first_order(system, first, inputs=inputs, point=point, values=values, initial=initial,
                                     symbolic=symbolic)
    point = dict(point or {})
    values = dict(values or {})
    initial = dict(initial or {})
    q = list(system.coordinates)
    qd = list(system.velocities)
    n = len(q)
    inputs = checked_inputs(system, inputs)
    t0 = sympy.sympify(point.pop(TIME, 0))
    numbers, missing = parameter_numbers(system, values)
    defaults = parameter_defaults(system)
    if missing and not symbolic:
        raise LinearizationError("no value for parameter" + ("s " if len(missing) > 1 else " ")
                                 + ", ".join(missing) + "; give it with " + assignment("at") + " "
                                 "(or linearise symbolically)")

    r = residual(system)
    M = system.mass_matrix
    x_q = sympy.Matrix(q)
    K0 = matrix_derivative(r, x_q)
    D0 = matrix_derivative(r, list(qd)) if n else sympy.zeros(n, 0)
    G0 = matrix_derivative(r, list(inputs)) if inputs else sympy.zeros(n, 0)
    dM = [matrix_derivative(M, qk) for qk in q]

    # the operating point, numerically
    start = {qk: numeric_value(initial.get(qk, 0), numbers) for qk in q}
    fixed = {}
    for s, v in point.items():
        if s not in q and s not in qd:
            raise LinearizationError(f"'{s}' is not a coordinate or velocity of {system.name}")
        fixed[s] = v
    free = [qk for qk in q if qk not in fixed]
    state_values = {**{v: 0.0 for v in qd}, **start}
    for s, v in fixed.items():
        state_values[s] = numeric_value(v, numbers)
        if not np.isfinite(state_values[s]):
            raise LinearizationError(f"the operating value of '{s}' is not a real number")
    symbols = q + qd + [TIME] + [p.symbol for p in system.parameters]
    numeric_values = {**state_values, TIME: numeric_value(t0, numbers), **numbers}
    if missing:  # symbolic without values: the point must be given, it cannot be solved for
        if free:
            raise LinearizationError("cannot find an equilibrium without values for " + ", ".join(missing)
                                     + "; give them, or every coordinate, with " + assignment("at"))
        acceleration = (float("nan"),) * n
    else:
        evaluate = Evaluator([M, r, K0], symbols)
        if free:
            numeric_values = _solve_equilibrium(evaluate, numeric_values, q, free, r)
        Mn, rn, _ = evaluate(numeric_values)
        if not (np.all(np.isfinite(Mn)) and np.all(np.isfinite(rn))):
            raise LinearizationError(unevaluable(r, q, numeric_values, M, "at the operating point"))
        acceleration = tuple(float(a) for a in solve_mass(Mn, rn.ravel(), numeric_values, q))
    velocities_zero = all(numeric_value(fixed.get(v, 0), numbers) == 0 for v in qd)
    if missing:  # no numbers to check with: check exactly
        equilibrium = velocities_zero and _exact_equilibrium(r, q, qd, fixed, t0, values)
    else:
        equilibrium = velocities_zero and max((abs(a) for a in acceleration), default=0.0) <= EQUILIBRIUM_TOLERANCE
    steady = ()
    if free and not fixed and not equilibrium and not missing:
        steady, numeric_values, acceleration = _steady_motion(system, numeric_values, q, qd, free, r, D0, symbols,
                                                              acceleration)
        equilibrium = bool(steady)
    if free and not fixed and not equilibrium:
        worst = max(abs(a) for a in acceleration)
        where = ", ".join(f"{s}={numeric_values[s]:.6g}" for s in q)
        raise LinearizationError(f"no equilibrium found near the initial values (at {where} the largest "
                                 f"acceleration is {worst:.3g}); give the operating point with " + assignment("at") + " "
                                 "NAME=VALUE for every coordinate")

    op_state = {}
    for s in q + qd:
        if s in fixed and (symbolic or sympy.sympify(fixed[s]).is_number):
            op_state[s] = sympy.sympify(fixed[s])
        elif s in fixed:
            op_state[s] = sympy.Float(state_values[s], 17)
        else:
            op_state[s] = _exact(numeric_values[s]) if symbolic else sympy.Float(numeric_values[s], 17)
    op_inputs = {u: sympy.sympify(values.get(u, defaults.get(u, u))) for u in inputs}

    notes = []
    if steady:
        notes.append("a steady motion: the cyclic coordinates " + ", ".join(s.name for s in steady)
                     + " (in none of Mbar, hbar, fbar) move at the constant velocities "
                     + ", ".join(f"{velocity_symbol(s).name} = {numeric_values[velocity_symbol(s)]:.6g}"
                                 for s in steady) + ", found with the other coordinates")
    if symbolic:
        subs = {**op_state, TIME: t0, **{p: sympy.sympify(v) for p, v in values.items()}, **op_inputs}
        A, B = _symbolic_matrices(M, r, K0, D0, G0, dM, subs, n, len(inputs))
        with sympy_seeded():
            left = [sympy.simplify(e.xreplace(subs)) for e in r] if free and equilibrium else []
        depends = sorted({s.name for e in left if e != 0 for s in e.free_symbols})
        if depends:
            notes.append(f"the equilibrium was found with the values of {', '.join(depends)} and depends on "
                         "them: A and B hold at those values only")
        eig = None
        if not missing:
            An = np.array(A.xreplace({s: sympy.Float(v) for s, v in numbers.items()}).evalf(), dtype=float)
            eig = sorted_eigenvalues(An)
        substituted = tuple((p.symbol, sympy.sympify(values[p.symbol])) for p in system.parameters
                            if p.symbol in values)
    else:
        evaluate = Evaluator([M, r, K0, D0, G0] + dM, symbols)
        Mn, rn, Kn, Dn, Gn, *dMn = evaluate(numeric_values)
        a = np.array(acceleration)
        if n:
            Kn = Kn - np.column_stack([dMk @ a for dMk in dMn])
        lower = solve_mass(Mn, np.hstack([Kn, Dn, Gn]), numeric_values, q)
        if n:  # singular to round-off, which Cholesky lets through (a spherical pole: sin(pi)**2 = 1.5e-32)
            why = describe_rank_loss(Mn, [s.name for s in q])
            if why:
                notes.append(f"{why}: A is not to be trusted along it")
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :] = lower[:, :2 * n]
        B = np.zeros((2 * n, len(inputs)))
        B[n:, :] = lower[:, 2 * n:]
        eig = sorted_eigenvalues(A)
        substituted = tuple((p.symbol, sympy.sympify(values.get(p.symbol, defaults.get(p.symbol))))
                            for p in system.parameters)
    return Linearization(
        state=tuple(q + qd), inputs=inputs,
        point=tuple(list(op_state.items()) + list(op_inputs.items())), time=t0,
        parameters=substituted, A=A, B=B, eigenvalues=eig, acceleration=acceleration,
        equilibrium=equilibrium, found=tuple(free), symbolic=symbolic, notes=tuple(notes),
    )


def _solve_equilibrium(evaluate: Evaluator, values: dict, q, free, r) -> dict:
    """Solve ``r(q, 0) = 0`` for the free coordinates (:func:`least_squares_equilibrium`:
    Levenberg-Marquardt, which copes with coordinates the equilibrium does not fix, such as a
    cart's position, then the trust-region reflective method where it stalls)."""

    columns = [q.index(s) for s in free]
    values = dict(values)

    def at(x):
        current = dict(values)
        current.update(zip(free, (float(v) for v in x)))
        return current

    def fun(x):
        _, r, _ = evaluate(at(x))
        return r.ravel()

    def jac(x):
        _, _, K = evaluate(at(x))
        return K[:, columns]

    x0 = np.array([values[s] for s in free], dtype=float)
    if not np.all(np.isfinite(fun(x0))):
        raise LinearizationError(unevaluable(r, q, values, evaluate.matrices[0]))

    def settled(x):
        Mn, rn, _ = evaluate(at(x))
        return at_equilibrium(Mn, rn.ravel())

    return at(least_squares_equilibrium(fun, jac, x0, settled))


def _steady_motion(system, values, q, qd, free, r, D0, symbols, acceleration):
    """Where no equilibrium has ``qdot = 0``: a steady motion, ``r(q, qdot) = 0`` with the
    velocities of the cyclic coordinates (those in none of ``Mbar``, ``r``: a DC motor's shaft
    angle and armature charge, a magnet's coil charge) unknown beside the free coordinates,
    which then move at constant speed (a spinning shaft, a steady current) while nothing else
    moves. ``((), values, acceleration)`` unchanged when there is none."""
    appear = free_symbols_of([system.mass_matrix, r])
    cyclic = [s for s in q if s not in appear]
    if not cyclic:
        return (), values, acceleration
    unknowns = [s for s in free if s not in cyclic] + [velocity_symbol(s) for s in cyclic]
    steady_evaluate = Evaluator([system.mass_matrix, r, matrix_derivative(r, sympy.Matrix(q)), D0], symbols)
    columns = [(2, q.index(s)) if s in q else (3, qd.index(s)) for s in unknowns]

    def at(x):
        return {**values, **dict(zip(unknowns, (float(v) for v in x)))}

    def fun(x):
        return steady_evaluate(at(x))[1].ravel()

    def jac(x):
        blocks = steady_evaluate(at(x))
        return np.column_stack([blocks[b][:, c] for b, c in columns])

    def settled(x):
        Mn, rn, _, _ = steady_evaluate(at(x))
        return at_equilibrium(Mn, rn.ravel())

    x0 = np.array([values[s] for s in unknowns], dtype=float)
    try:
        found = at(least_squares_equilibrium(fun, jac, x0, settled))
    except (ValueError, np.linalg.LinAlgError):
        return (), values, acceleration
    Mn, rn, _, _ = steady_evaluate(found)
    if not at_equilibrium(Mn, rn.ravel()):
        return (), values, acceleration
    return (tuple(cyclic), found,
            tuple(float(a) for a in solve_mass(Mn, rn.ravel(), found, q)))


def _exact(value: float) -> sympy.Expr:
    """A found coordinate as an exact number when it is a simple multiple of pi or a
    rational (``3.14159...`` -> ``pi``), else a Float."""
    guess = sympy.nsimplify(value, [sympy.pi], tolerance=1e-10, rational=False)
    if abs(float(guess) - value) <= 1e-10 * max(1.0, abs(value)) and sympy.count_ops(guess) <= 6:
        return guess
    return sympy.Float(value, 17)


@seeded
def _exact_equilibrium(r, q, qd, fixed, t0, values) -> bool:
    subs = {**{v: 0 for v in qd}, **{s: sympy.sympify(v) for s, v in fixed.items()}, TIME: t0,
            **{p: sympy.sympify(v) for p, v in values.items()}}
    return all(sympy.simplify(e.xreplace(subs)) == 0 for e in r)


@seeded
def _symbolic_matrices(M, r, K0, D0, G0, dM, subs, n, m):
    Ms = M.xreplace(subs)
    a = Ms.LUsolve(r.xreplace(subs)).applyfunc(sympy.simplify)
    K = K0.xreplace(subs)
    if n and any(e != 0 for e in a):
        K = K - sympy.Matrix.hstack(*[dMk.xreplace(subs) * a for dMk in dM])
    rhs = sympy.Matrix.hstack(K, D0.xreplace(subs), G0.xreplace(subs))
    lower = Ms.LUsolve(rhs).applyfunc(lambda e: sympy.factor(sympy.simplify(e)))
    A = sympy.zeros(2 * n, 2 * n)
    A[:n, n:] = sympy.eye(n)
    A[n:, :] = lower[:, :2 * n]
    B = sympy.zeros(2 * n, m)
    if m:
        B[n:, :] = lower[:, 2 * n:]
    return A, B


__all__ = ["EQUILIBRIUM_TOLERANCE", "Linearization", "LinearizationError", "linearize"]
