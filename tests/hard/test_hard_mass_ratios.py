"""Hard case 4: mass ratios of 1e-6 and 1e6 in a chain.

What could go wrong: ``Mbar`` becomes badly conditioned, and the ``L D L^T`` solve in the
generated right-hand side (no pivoting) loses far more digits than the conditioning forces; or
the trajectory drifts from the true one. Criteria: the condition number of ``Mbar`` is reported;
the generated right-hand side's accelerations agree with a 50-digit solve of an independent
``sympy.physics.mechanics`` (Kane) derivation to the accuracy the conditioning permits
(within ``100 eps cond(Mbar)``, and 1e-10 relative: the conditioning comes from the
scales of the masses, which ``L D L^T`` does not feel); the trajectory over 1 s agrees with the Kane
equations integrated by scipy at tight tolerance.
"""
from __future__ import annotations

import sys

import mpmath
import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp

import kronsub
from reference import mechanics as ref
from conftest import MODELS
from kronsub.emitters.code import emit_c
from kronsub.simulation.native import NativeModel, compile_library
from kronsub.simulation.run import simulate
from kronsub.simulation.values import resolve

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402

N = 3
MASSES = {"heavy tip": [1.0, 1e-6, 1e6], "light tip": [1e6, 1.0, 1e-6], "alternating": [1e-6, 1e6, 1e-6]}


@pytest.fixture(scope="module")
def chain():
    model = kronsub.load("chain3.yaml", text=chain_yaml(N))
    system = model.derive()
    native = NativeModel(compile_library([(g.name, g.text) for g in emit_c(system, "model")], "model"),
                         N, len(system.parameters))
    return model, system, native, ref.rod_chain(N)


def _settings(masses):
    return {f"m{i + 1}": repr(m) for i, m in enumerate(masses)}


@pytest.mark.parametrize("case", sorted(MASSES))
def test_right_hand_side_is_as_accurate_as_the_conditioning_allows(chain, case):
    model, system, native, kane = chain
    values = resolve(system, dict(model.initial), _settings(MASSES[case]))
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    rng = np.random.default_rng(7)
    mpmath.mp.dps = 50
    syms = sorted(kane.mass_matrix.free_symbols | kane.forces.free_symbols | kane.velocity_terms.free_symbols,
                  key=lambda s: s.name)
    worst = 0.0
    for _ in range(5):
        y = rng.uniform(-3, 3, 2 * N)
        vals = dict(params, **{f"q{i + 1}": y[i] for i in range(N)}, **{f"q{i + 1}_dot": y[N + i] for i in range(N)})
        subs = {s: sympy.Float(vals[s.name], 50) for s in syms}
        M = mpmath.matrix(kane.mass_matrix.xreplace(subs).evalf(50).tolist())
        r = mpmath.matrix((kane.forces - kane.velocity_terms).xreplace(subs).evalf(50).tolist())
        exact = np.array([float(v) for v in mpmath.lu_solve(M, r)])
        cond = float(mpmath.mnorm(M, 1) * mpmath.mnorm(mpmath.inverse(M), 1))
        got = native.rhs(0.0, y, values.parameters)[N:]
        err = np.max(np.abs(got - exact)) / np.max(np.abs(exact))
        worst = max(worst, err / (cond * np.finfo(float).eps))
        # the conditioning here comes from the scales of the masses, which L D L^T does not feel:
        # far better than the eps cond(Mbar) bound of a backward-stable solve
        assert err <= min(1e-10, 100 * np.finfo(float).eps * cond), f"{case}: error {err:.3g}, cond(Mbar) {cond:.3g}"
    print(f"{case}: cond(Mbar) up to {cond:.3g}; error / (eps cond) at most {worst:.3g}")


@pytest.mark.parametrize("case", sorted(MASSES))
def test_trajectory_agrees_with_kane(chain, case):
    model, system, native, kane = chain
    values = resolve(system, dict(model.initial), dict(_settings(MASSES[case]), q1="0.4", q2="-0.3", q3="0.2"))
    traj = simulate(system, values, 1.0, 0.25, "dop853", rtol=1e-12, atol=1e-12, progress=False)
    assert traj.complete
    params = {p.name: v for p, v in zip(system.parameters, values.parameters)}

    def f(t, y):
        vals = dict(params, t=t, **{f"q{i + 1}": y[i] for i in range(N)},
                    **{f"q{i + 1}_dot": y[N + i] for i in range(N)})
        M, h, fo = ref.numeric(kane, vals)
        return np.concatenate([y[N:], np.linalg.solve(M, fo - h)])

    sol = solve_ivp(f, (0, 1.0), values.y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=traj.t)
    assert np.allclose(traj.y, sol.y.T, rtol=1e-7, atol=1e-7), np.abs(traj.y - sol.y.T).max()
