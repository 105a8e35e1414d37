"""Every bundled model against an independent sympy.physics.mechanics derivation.

Mass matrix, velocity terms and forces must agree numerically at 20 random
states to 1e-12 relative; the energies too (kinetic exactly, potential up to a
constant).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import kronsub
from reference import mechanics as ref
from conftest import MODELS

CASES = {
    "hoffmann/three_particles.yaml": (ref.three_particles, {}),
    "hoffmann/system1.yaml": (ref.system1, {}),
    # |c - a1 sin(theta)| < a2 keeps the subspace (26) real
    "hoffmann/system2.yaml": (ref.system2, {"c": (0.1, 0.3), "theta": (-0.3, 0.3), "a1": (0.3, 0.6),
                                              "a2": (0.9, 1.2)}),
    "examples/double_pendulum.yaml": (ref.double_pendulum, {}),
    "examples/cart_pole.yaml": (ref.cart_pole, {}),
    "examples/particle_on_sphere.yaml": (ref.particle_on_sphere, {"theta": (0.2, 2.9)}),
    "examples/watt_governor.yaml": (ref.watt_governor, {}),
    "chain/chain5.yaml": (lambda: ref.rod_chain(5), {}),
}


def _numeric(system):
    exprs = [system.mass_matrix, system.velocity_terms, system.forces]
    syms = sorted(set().union(*(e.free_symbols for e in exprs)), key=lambda s: s.name)
    fn = sympy.lambdify(syms, exprs, modules="numpy")
    n = len(system.coordinates)

    def at(values):
        M, h, f = fn(*[values[s.name] for s in syms])
        return (np.array(M, dtype=float).reshape(n, n), np.array(h, dtype=float).reshape(n),
                np.array(f, dtype=float).reshape(n))

    return at


def _close(a, b, what, values):
    scale = max(np.max(np.abs(b)), 1.0)
    assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * scale), f"{what} differs at {values}:\n{a}\n{b}"


@pytest.mark.parametrize("path", sorted(CASES))
def test_equations_match_mechanics(path):
    make_reference, ranges = CASES[path]
    reference = make_reference()
    system = kronsub.load(MODELS / path).derive()
    assert tuple(q.name for q in system.coordinates) == reference.coordinates
    names = set()
    for m in (system.mass_matrix, system.velocity_terms, system.forces,
              reference.mass_matrix, reference.velocity_terms, reference.forces):
        names |= {s.name for s in m.free_symbols}
    ours = _numeric(system)
    rng = np.random.default_rng(1944)
    for _ in range(20):
        values = {n: rng.uniform(*_range(n, reference, ranges)) for n in sorted(names)}
        M, h, f = ours(values)
        Mr, hr, fr = ref.numeric(reference, values)
        _close(M, Mr, "mass matrix", values)
        _close(h, hr, "velocity terms", values)
        _close(f, fr, "forces", values)


@pytest.mark.parametrize("path", sorted(CASES))
def test_energies_match_mechanics(path):
    make_reference, ranges = CASES[path]
    reference = make_reference()
    system = kronsub.load(MODELS / path).derive()
    plain = lambda e: e.xreplace({s: sympy.Symbol(s.name) for s in e.free_symbols})  # noqa: E731
    T, Tr = plain(system.kinetic_energy), reference.kinetic_energy
    V, Vr = plain(system.potential_energy), reference.potential_energy
    rng = np.random.default_rng(24)
    syms = sorted((T.free_symbols | Tr.free_symbols | V.free_symbols | Vr.free_symbols), key=lambda s: s.name)
    for _ in range(5):
        vals = {s: rng.uniform(*_range(s.name, reference, ranges)) for s in syms}
        for ours, theirs in ((T, Tr), (V, Vr)):
            a, b = float(ours.xreplace(vals)), float(theirs.xreplace(vals))
            assert abs(a - b) <= 1e-12 * max(1.0, abs(b)), (ours, theirs)


def _range(name, reference, ranges):
    """Parameters are positive; coordinates and velocities take either sign."""
    if name in ranges:
        return ranges[name]
    if name in reference.coordinates or name in reference.velocities:
        return (-1.5, 1.5)
    return (0.3, 1.7)
