#!/usr/bin/env python
"""Recompute ``chain30_rods.json``: the 30-link rod chain after 0.5 s and 1 s, by Kane's method.

Independent of kronsub: the equations are ``sympy.physics.mechanics``'s (``KanesMethod`` on the
chain of ``tests/reference/mechanics.py``: 30 uniform rods, mass 1, length 1, pinned end to end
from the origin, absolute angles q1..q30 from the downward vertical, g = 9.81), integrated by
scipy's DOP853 from q_i = 0.3 sin(i), at rest, at two tolerances (1e-12 and 1e-13); their
largest difference is recorded as the estimated error. Deriving takes about a minute.

Usage: python tests/data/chain30_reference.py
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import sympy
from scipy.integrate import solve_ivp

HERE = Path(__file__).resolve().parent
OUT = HERE / "chain30_rods.json"
N = 30
TIMES = (0.5, 1.0)


def initial_angles(n: int = N) -> list[float]:
    return [0.3 * math.sin(i) for i in range(1, n + 1)]


def main() -> int:
    sys.path.insert(0, str(HERE.parent))
    from reference import mechanics as ref

    start = time.perf_counter()
    raw = ref.rod_chain_raw(N, "kane")
    M, forcing = raw.plain()
    q = [sympy.Symbol(f"q{i}") for i in range(1, N + 1)]
    u = [sympy.Symbol(f"q{i}_dot") for i in range(1, N + 1)]
    params = {sympy.Symbol("g"): 9.81}
    params.update({sympy.Symbol(f"m{i}"): 1 for i in range(1, N + 1)})
    params.update({sympy.Symbol(f"l{i}"): 1 for i in range(1, N + 1)})
    M, forcing = M.xreplace(params), forcing.xreplace(params)
    mass = sympy.lambdify([q], M, modules="numpy", cse=True)
    force = sympy.lambdify([q, u], forcing, modules="numpy", cse=True)
    print(f"derived and lambdified in {time.perf_counter() - start:.1f} s", flush=True)

    def rhs(_t, y):
        qq, uu = y[:N], y[N:]
        acc = np.linalg.solve(np.array(mass(qq), dtype=float), np.array(force(qq, uu), dtype=float).ravel())
        return np.concatenate([uu, acc])

    y0 = np.array(initial_angles() + [0.0] * N)
    runs = []
    for tol in (1e-12, 1e-13):
        sol = solve_ivp(rhs, (0, TIMES[-1]), y0, method="DOP853", rtol=tol, atol=tol, t_eval=TIMES)
        runs.append(sol.y.T)
        print(f"tol {tol:g}: {sol.nfev} evaluations", flush=True)
    error = float(np.abs(runs[0] - runs[1]).max())
    OUT.write_text(json.dumps({
        "model": "models/chain/generate.py chain_yaml(30): m = l = 1, g = 9.81",
        "initial": {"q": initial_angles(), "q_dot": [0.0] * N},
        "times": list(TIMES),
        "states": [row.tolist() for row in runs[1]],
        "estimated_error": error,
        "method": "sympy.physics.mechanics KanesMethod; scipy DOP853 at rtol = atol = 1e-13",
    }, indent=1) + "\n")
    print(f"wrote {OUT.name}; estimated error {error:.2g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
