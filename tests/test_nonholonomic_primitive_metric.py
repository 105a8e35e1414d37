"""A system under velocity constraints from its model file: ``Mbar``, ``hbar`` in the coordinates
built only when read (core/deferred.py), and its linearisation taken from the primitive's metric
and ``C`` (``primitive_metric``, the route of the Python-built bicycle; ``h`` the Christoffel terms
of the projected metric, or the primitive's own carried by ``C``) rather than from ``Mbar`` and
``hbar``: the routes give the same Jacobian at random states that are not steady."""
import dataclasses

import numpy as np
import pytest
import sympy

from conftest import ROOT
from kronsub.core.deferred import DeferredMatrix, pending
from kronsub.core.linearize_numerics import parameter_numbers
from kronsub.core.nonholonomic_linearize import SteadyMotionRates, constrained_motion, primitive_metric
from kronsub.core.symbols import velocity_symbol
from kronsub.model.loader import load_model

MODELS = [ROOT / "models" / "nonholonomic" / "rolling_disc.yaml",
          ROOT / "models" / "nonholonomic" / "chaplygin_sleigh.yaml",
          ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml"]


def test_a_deferred_matrix_is_built_once_when_first_read():
    x = sympy.Symbol("x")
    calls = []

    def build():
        calls.append(1)
        return sympy.Matrix([[x, 1], [2, x ** 2]])

    m = DeferredMatrix(2, 2, build)
    assert m.shape == (2, 2) and pending(m) and not calls
    assert m[1, 1] == x ** 2 and not pending(m)
    assert (m * m)[0, 0] == x ** 2 + 2 and type(m.T) is sympy.MutableDenseMatrix and m == build()
    assert len(calls) == 2  # once for m, once for the comparison's own matrix
    with pytest.raises(ValueError, match="built 2 x 2"):
        DeferredMatrix(3, 1, build)[0]


@pytest.mark.parametrize("path", MODELS, ids=lambda p: p.stem)
def test_the_primitive_route_linearises_as_mbar_and_hbar(path):
    system = load_model(path, cache=False).derive(cache=False)
    assert pending(system.mass_matrix) and pending(system.velocity_terms)
    motion = constrained_motion(system)
    assert motion.metric == primitive_metric(system) and motion.velocity_terms is None
    assert pending(system.mass_matrix)  # the linearisation's route does not build them
    assert motion.metric.velocity_terms is None  # library components: h of the primitive is (A) of its metric
    t = system.transition
    placement = {x: image for x, image in t.connection if x != image}
    # the primitive's own h (as a known system placed as a component would bring it)
    own = dataclasses.replace(motion, metric=dataclasses.replace(
        motion.metric, velocity_terms=sympy.Matrix(t.primitive_velocity_terms).xreplace(placement),
        velocities=tuple(velocity_symbol(x) for x in t.primitive_coordinates)))
    formed = dataclasses.replace(motion, metric=sympy.Matrix(system.mass_matrix),
                                 velocity_terms=sympy.Matrix(system.velocity_terms))
    numbers, _ = parameter_numbers(system, {})
    rng = np.random.default_rng(37)
    routes = [SteadyMotionRates(m, numbers) for m in (motion, own, formed)]
    for _ in range(2):
        x = rng.uniform(-0.6, 0.6, len(system.coordinates))
        u = rng.uniform(-2, 2, len(system.speeds.speeds))
        point = {**dict(zip(system.coordinates, x)), **dict(zip(system.speeds.speeds, u))}
        dependent = tuple(system.speeds.dependent)
        keep = tuple(q for q in system.coordinates if q not in dependent)
        a, b, c = (rates.linearize(point, keep, dependent).A for rates in routes)
        for other in (a, b):
            assert np.allclose(other, c, rtol=1e-10, atol=1e-10 * np.max(np.abs(c))), path.stem
