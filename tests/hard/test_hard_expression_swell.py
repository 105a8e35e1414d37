"""Hard case 6: expression swell.

What could go wrong: the equations grow far faster than the system (a 30-link chain whose
entries are expanded products of sines), or a connection through inverse trigonometric
functions (a heavy top given in Z-X-Z angles and converted to ``rigid_body3d``'s Z-Y-X ones by
``atan2``/``asin``) leaves square roots of different-looking but equal radicands and quotients
that are never divided out: mass-matrix entries of 10,000-20,000 characters, velocity terms of
250,000, slow derivation and slow, inaccurate generated code.

Criteria: the chain's operation count (joint ``cse`` over ``Mbar``, ``hbar``, ``fbar``, as the
derive benchmark counts it) follows the benchmark's growth law ``5.5 n^2 + 10 n - 9`` (fitted
to its n = 10, 20, 50 rows) within 10 %, and its motion over 1 s agrees with a Kane
(``sympy.physics.mechanics``) reference stored in ``tests/data/``; the top written through
``atan2``/``asin`` has mass-matrix entries no longer than the same top written in its Z-Y-X
angles directly, the very equations of the top written with ``euler: ZXZ``, the equations of a
Lagrangian written by hand, and conserves energy in simulation.
"""
from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
import sympy

import kronsub
from conftest import MODELS, ROOT
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402

HERE = ROOT / "tests" / "hard" / "models"
CHAIN = 30
MEASURED_OPS = {10: 641, 20: 2391, 50: 14241}  # benchmarks/derive_chain.py, joint cse of M, h, f


def growth_law(n: int) -> float:
    """The quadratic through the benchmark's measured rows (exact at n = 10, 20, 50)."""
    return 5.5 * n * n + 10 * n - 9


TOP_PARAMETERS = {"m": 1.0, "l": 0.3, "A": 0.02, "B": 0.025, "C": 0.01, "g": 9.81}


# ---------------------------------------------------------------- the chain
@pytest.fixture(scope="module")
def chain():
    """The derived chain and one joint ``cse`` of its ``Mbar``, ``hbar``, ``fbar`` entries."""
    model = kronsub.load(f"chain{CHAIN}.yaml", text=chain_yaml(CHAIN))
    system = model.derive()
    entries = [*system.mass_matrix, *system.velocity_terms, *system.forces]
    return model, system, entries, sympy.cse(entries)


def test_growth_law_fits_the_benchmark_rows():
    assert all(growth_law(n) == ops for n, ops in MEASURED_OPS.items())


def test_chain_of_30_derives_with_the_operation_count_of_the_growth_law(chain):
    _, _, _, (replacements, reduced) = chain
    ops = sum(sympy.count_ops(e) for _, e in replacements) + sum(sympy.count_ops(e) for e in reduced)
    assert abs(ops - growth_law(CHAIN)) <= 0.1 * growth_law(CHAIN), ops
    print(f"n = {CHAIN}: {ops} operations after cse (growth law {growth_law(CHAIN):.0f})")


def test_chain_of_30_moves_as_kane_says_for_one_second(chain):
    """The derived equations integrated by scipy (lambdified from the cse above: kronsub's own
    code generation for 30 links takes minutes, see the report in docs/numerical-stability.md)."""
    from scipy.integrate import solve_ivp

    model, system, entries, cse = chain
    ref = json.loads((ROOT / "tests/data/chain30_rods.json").read_text(encoding="utf-8"))
    settings = {f"q{i + 1}": repr(q) for i, q in enumerate(ref["initial"]["q"])}
    values = resolve(system, dict(model.initial), settings)
    q, u = list(system.coordinates), list(system.velocities)
    params = [p.symbol for p in system.parameters]
    numeric = sympy.lambdify([q, u, params], entries, modules="numpy", cse=lambda _: cse)
    n = len(q)

    def rhs(_t, y):
        out = np.array(numeric(y[:n], y[n:], values.parameters), dtype=float)
        M, h, f = out[:n * n].reshape(n, n), out[n * n:n * n + n], out[n * n + n:]
        return np.concatenate([y[n:], np.linalg.solve(M, f - h)])

    sol = solve_ivp(rhs, (0, 1.0), np.array(values.y0, dtype=float), method="DOP853", rtol=1e-12, atol=1e-12,
                    t_eval=ref["times"])
    assert sol.success
    for t, row, state in zip(ref["times"], sol.y.T, ref["states"]):
        err = np.max(np.abs(row - np.array(state)))
        assert err <= 1e-8, f"t = {t}: largest difference {err:.3g} (reference error ~{ref['estimated_error']:.1g})"


# ------------------------------------------------------------------ the top
@pytest.fixture(scope="module")
def tops():
    return {name: kronsub.load(HERE / f"top_{name}.yaml").derive() for name in ("zxz_atan2", "zxz_euler", "zyx")}


def _numeric(system, state):
    """``Mbar``, ``hbar``, ``fbar`` at a state given by symbol names."""
    values = {s: state[s.name] for s in system.mass_matrix.free_symbols | system.velocity_terms.free_symbols
              | system.forces.free_symbols}
    return (np.array(system.mass_matrix.xreplace(values), dtype=float),
            np.array(system.velocity_terms.xreplace(values), dtype=float).ravel(),
            np.array(system.forces.xreplace(values), dtype=float).ravel())


def _states(count=5, seed=3):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = rng.uniform(0.2, 1.3, 3)  # away from beta = 0 (Z-X-Z) and the Z-Y-X lock
        u = rng.uniform(-2, 2, 3)
        yield {**TOP_PARAMETERS, "alpha": q[0], "beta": q[1], "gamma": q[2],
               "alpha_dot": u[0], "beta_dot": u[1], "gamma_dot": u[2]}


def _hand_lagrangian():
    """The top by hand: body angular velocity of the Z-X-Z angles (Goldstein's), the centre at
    ``l R e_z``; ``M = d^2 T / du du``, ``h = dM/dt u - dT/dq``, ``f = -dV/dq``."""
    m, l, A, B, C, g = sympy.symbols("m l A B C g")
    q = sympy.symbols("alpha beta gamma")
    u = sympy.symbols("alpha_dot beta_dot gamma_dot")
    a, b, c = q
    ad, bd, cd = u
    w = (ad * sympy.sin(b) * sympy.sin(c) + bd * sympy.cos(c),
         ad * sympy.sin(b) * sympy.cos(c) - bd * sympy.sin(c),
         ad * sympy.cos(b) + cd)
    centre = sympy.Matrix([l * sympy.sin(a) * sympy.sin(b), -l * sympy.cos(a) * sympy.sin(b), l * sympy.cos(b)])
    v = centre.jacobian(q) * sympy.Matrix(u)
    T = (A * w[0] ** 2 + B * w[1] ** 2 + C * w[2] ** 2 + m * v.dot(v)) / 2
    V = m * g * l * sympy.cos(b)
    M = sympy.hessian(T, u)
    h = sympy.Matrix([sum(sympy.diff(M[i, j], q[k]) * u[k] * u[j] for j in range(3) for k in range(3))
                      - sympy.diff(T, q[i]) for i in range(3)])
    f = sympy.Matrix([-sympy.diff(V, qi) for qi in q])
    return sympy.lambdify([(m, l, A, B, C, g), q, u], (M, h, f))


def test_top_through_atan2_is_no_longer_than_the_top_in_its_own_angles(tops):
    lengths = {name: [len(str(e)) for e in system.mass_matrix] for name, system in tops.items()}
    assert max(lengths["zxz_atan2"]) <= max(lengths["zyx"])
    assert sum(lengths["zxz_atan2"]) <= sum(lengths["zyx"])
    # no square root or inverse function is left in the equations
    for entry in [*tops["zxz_atan2"].mass_matrix, *tops["zxz_atan2"].velocity_terms]:
        assert not entry.has(sympy.atan2, sympy.asin) and not any(
            p.exp.is_Rational and not p.exp.is_Integer for p in entry.atoms(sympy.Pow))


def test_top_through_atan2_has_the_equations_of_the_euler_zxz_top_and_of_the_hand_lagrangian(tops):
    hand = _hand_lagrangian()
    params = tuple(TOP_PARAMETERS[k] for k in ("m", "l", "A", "B", "C", "g"))
    for state in _states():
        M, h, f = _numeric(tops["zxz_atan2"], state)
        M2, h2, f2 = _numeric(tops["zxz_euler"], state)
        Mh, hh, fh = (np.array(x, dtype=float) for x in hand(
            params, [state[k] for k in ("alpha", "beta", "gamma")],
            [state[k] for k in ("alpha_dot", "beta_dot", "gamma_dot")]))
        scale = np.abs(Mh).max()
        for ours in (M, M2):
            assert np.allclose(ours, Mh, rtol=0, atol=1e-13 * scale)
        for ours_h, ours_f in ((h, f), (h2, f2)):
            assert np.allclose(ours_h, hh.ravel(), rtol=1e-12, atol=1e-13 * np.abs(hh).max())
            assert np.allclose(ours_f, fh.ravel(), rtol=1e-12, atol=1e-14)


def test_top_through_atan2_conserves_energy(tops):
    model = kronsub.load(HERE / "top_zxz_atan2.yaml")
    system = tops["zxz_atan2"]
    values = resolve(system, dict(model.initial), {})
    traj = simulate(system, values, 1.0, 0.01, "dop853", progress=False)
    assert traj.complete, traj.message
    T, V = traj.energies
    assert np.ptp(T + V) < 1e-8 * abs(T[0] + V[0])
