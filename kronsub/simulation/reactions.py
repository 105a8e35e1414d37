"""``simulate --reactions``: the reactions of viewpoint (alpha) at every row of a run."""
from __future__ import annotations

import numpy as np
import sympy

from ..core.reactions import MultiplierSystem, reactions
from ..core.symbols import acceleration_symbol


def reaction_columns(system, traj, param, module, constrained=None) -> tuple[list[str], np.ndarray]:
    """Names and values: the accelerations from the generated right-hand side at each row, then
    the reaction expressions (with the intermediates from Newton's method on implicit systems)."""
    items = reactions(system)
    values = {p.symbol: float(v) for p, v in zip(system.parameters, param)}
    n = len(system.coordinates)
    inter = list(system.implicit.intermediates) if system.implicit is not None else []
    args = (list(system.coordinates) + list(system.velocities) + [acceleration_symbol(q) for q in system.coordinates]
            + inter + [sympy.Symbol("t", real=True)])
    if isinstance(items, MultiplierSystem):  # G_d^T mu = r, solved at each row
        k = len(items.names)
        parts = sympy.lambdify(args, [sympy.sympify(e).xreplace(values) for e in [*items.matrix, *items.rows]],
                               "math")

        def fn(*a):
            flat = parts(*a)
            return np.linalg.solve(np.array(flat[:k * k], dtype=float).reshape(k, k), np.array(flat[k * k:], dtype=float))

        items = [(name, None) for name in items.names]
    else:
        fn = sympy.lambdify(args, [sympy.sympify(e).xreplace(values) for _, e in items], "math")
    rows = []
    if constrained is not None and traj.dependent is not None and len(traj.dependent):
        constrained.guess = np.array(traj.dependent[0], dtype=float)
    for t, y in zip(traj.t, traj.y):
        try:
            if constrained is not None:
                module["set_dependent"](constrained.guess)
            ydot = module["rhs"](t, y, param)
            w = constrained.at(y[:n], y[n:]) if constrained is not None else {}
            rows.append(fn(*y[:n], *y[n:], *ydot[n:], *[w[s] for s in inter], t))
        except (ArithmeticError, ValueError, np.linalg.LinAlgError, Exception):  # a failed row stays NaN
            rows.append([float("nan")] * len(items))
    return [name for name, _ in items], np.array(rows, dtype=float).reshape(len(traj.t), len(items))
