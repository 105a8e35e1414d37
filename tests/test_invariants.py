"""Invariants of the derived equations on models that use every component and effect type.

Independent of any reference derivation: along ``Mbar qddot + hbar = fbar``
- the velocity terms do no work: ``qdot . hbar = 1/2 qdot^T Mdot qdot`` (Lagrange's (A));
- the conservative effects are the gradient of the potential: ``f_cons = -dV/dq``;
- dampers only dissipate: ``qdot . f_damper <= 0``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy

import kronsub
from conftest import MODELS, explicit_model_paths
from kronsub.core.rheonomic import depends_on_time, project_frozen

HERE = Path(__file__).resolve().parent / "models"
# (model, its conservative effects, its dissipative effects)
CASES = {
    "polar_spring.yaml": ({"gravity", "spring"}, {"damper"}),
    "geared_pendulum.yaml": ({"gravity", "twist"}, {"drag"}),
    "body_on_springs.yaml": ({"gravity", "left", "right"}, set()),
    "top_3d.yaml": ({"gravity", "tip"}, set()),
    "disc_and_slider.yaml": ({"gravity", "well"}, set()),
}


def _evaluator(system, exprs):
    syms = sorted(set().union(*(sympy.sympify(e).free_symbols for e in exprs)), key=lambda s: s.name)
    f = sympy.lambdify(syms, exprs, modules="numpy")
    return lambda vals: [np.array(v, dtype=float) for v in f(*[vals[s.name] for s in syms])]


def _states(system, rng, count=15):
    names = {s.name for s in system.mass_matrix.free_symbols | system.forces.free_symbols
             | system.velocity_terms.free_symbols | system.potential_energy.free_symbols}
    names |= {q.name for q in system.coordinates} | {v.name for v in system.velocities} | {"t"}
    values = {p.name: float(p.value) for p in system.parameters if p.value is not None}
    for _ in range(count):
        vals = {n: rng.uniform(-1.2, 1.2) for n in names}
        vals.update(values)
        if "r" in vals:
            vals["r"] = rng.uniform(0.3, 1.5)
        yield vals


def _paths():
    return sorted(CASES) + explicit_model_paths()


def _load(name):
    return kronsub.load(HERE / name if name in CASES else MODELS / name).derive()


@pytest.mark.parametrize("name", _paths())
def test_velocity_terms_do_no_work(name):
    """``qdot . hbar = qdot . Mdot qdot / 2``; for a connection in t, of ``hbar`` with t held fixed
    (the drive's own terms do work: tests/test_prescribed_models.py checks them)."""
    system = _load(name)
    q, qd = list(system.coordinates), sympy.Matrix(system.velocities)
    M = system.mass_matrix
    Mdot = sum((sympy.diff(M, qk) * v for qk, v in zip(q, qd)), sympy.zeros(*M.shape))
    h = system.velocity_terms
    tr = system.transition
    if tr is not None and depends_on_time(dict(tr.connection)):
        h = project_frozen(tr.primitive_coordinates, tr.primitive_metric, tr.primitive_velocity_terms,
                           dict(tr.connection), system.coordinates)
    work = (qd.T * h)[0, 0]
    half = (qd.T * Mdot * qd)[0, 0] / 2
    f = _evaluator(system, [work, half])
    for vals in _states(system, np.random.default_rng(5)):
        if "c" in vals and name.endswith("system2.yaml"):
            vals.update(c=0.1, a1=0.4, a2=1.0, theta=0.2)
        w, h = f(vals)
        assert abs(w - h) <= 1e-9 * (1 + abs(h)), (name, w, h)


@pytest.mark.parametrize("name", sorted(CASES))
def test_conservative_effects_are_the_gradient_of_the_potential(name):
    conservative, dissipative = CASES[name]
    system = _load(name)
    assert set(system.effect_forces) >= conservative | dissipative
    f_cons = sum((system.effect_forces[e] for e in conservative), sympy.zeros(len(system.coordinates), 1))
    grad = sympy.Matrix([sympy.diff(system.potential_energy, qk) for qk in system.coordinates])
    qd = sympy.Matrix(system.velocities)
    power = [(qd.T * system.effect_forces[e])[0, 0] for e in sorted(dissipative)]
    f = _evaluator(system, [f_cons + grad, *power] if power else [f_cons + grad])
    for vals in _states(system, np.random.default_rng(6)):
        out = f(vals)
        assert np.allclose(out[0], 0.0, atol=1e-9), (name, out[0])
        for p in out[1:]:
            assert p <= 1e-12, (name, p)


def test_a_stiff_conservative_model_keeps_its_energy_in_simulation():
    from kronsub.simulation.run import simulate
    from kronsub.simulation.table import energies
    from kronsub.simulation.values import resolve

    model = kronsub.load(HERE / "body_on_springs.yaml")
    system = model.derive()
    values = resolve(system, {}, {"tau": "0", "y": "-0.2", "a": "0.3"})
    traj = simulate(system, values, 5.0, 0.05, "dop853", rtol=1e-12, atol=1e-12, progress=False)
    T, V = energies(system, traj, np.array(values.parameters))
    E = T + V
    assert traj.complete and np.max(np.abs(E - E[0])) <= 1e-9 * max(1.0, np.max(np.abs(T)))
