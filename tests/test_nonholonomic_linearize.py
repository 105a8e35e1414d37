"""Linearisation about a steady motion with dependent speeds (core/nonholonomic_linearize.py) on
the rolling disc built from a placed rigid body (core/rigid_bodies.py): its upright rolling
against the closed form of the linearised disc (stable exactly above the critical spin
``sqrt(g/(3 r))``), its Jacobian at random states against sympy's ``KanesMethod.linearize``, and
the refusals."""
import dataclasses

import numpy as np
import pytest
import sympy

from helpers.compare import same_roots
from kronsub.core.linearize_numerics import LinearizationError
from kronsub.core.nonholonomic_linearize import (ConstrainedMotion, ProjectedMetric, SteadyMotionRates,
                                                 linearize_steady_motion)
from kronsub.core.primitive import christoffel_terms
from kronsub.core.rigid_bodies import PlacedBody, body_metric, centre_height, point_velocity
from kronsub.core.symbols import symbol, velocity_symbol
from reference.rolling import NAMES, KaneDisc

m, g, r = (symbol(n) for n in ("m", "g", "r"))
VALUES = {m: 1.3, g: 9.81, r: 0.3}


def _disc(projected: bool = True) -> ConstrainedMotion:
    """The disc from its body: centre above the contact ``(x, y)``, turned by yaw, lean, spin;
    the contact point's material velocity zero along the plane."""
    q = tuple(symbol(n) for n in NAMES)
    yaw, lean, spin, x, y = q
    tilt = PlacedBody("frame", m, (0, 0, 0), (("Z", yaw), ("X", lean)), sympy.eye(3)).rotation()
    centre = sympy.Matrix([x, y, 0]) + tilt * sympy.Matrix([0, 0, r])
    disc = PlacedBody("disc", m, tuple(centre), (("Z", yaw), ("X", lean), ("Y", spin)),
                      sympy.diag(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4))
    slip = point_velocity(disc, (x, y, 0), q) * sympy.Matrix([velocity_symbol(s) for s in q])
    assert sympy.simplify(slip[2]) == 0  # the lowest point does not leave the plane
    force = sympy.Matrix([-sympy.diff(g * centre_height([disc]), s) for s in q])
    metric = ProjectedMetric(disc.weights(), disc.projection(q)) if projected else body_metric([disc], q)
    return ConstrainedMotion(q, metric, force, {velocity_symbol(s): velocity_symbol(s) for s in q[:3]},
                             (slip[0], slip[1]))


def test_upright_rolling_against_the_closed_form_and_the_critical_spin():
    """Linearised upright rolling at spin ``W``: ``(I + m r^2) lean'' + (J + m r^2) W yaw' - m g r lean = 0``,
    ``I yaw'' = J W lean'`` with ``I = m r^2/4``, ``J = m r^2/2``: eigenvalues ``0, 0`` and
    ``+-sqrt(4/5 (g/r - 3 W^2))``, so stable (no root in the right half plane) exactly for
    ``W > sqrt(g/(3 r))``."""
    motion = _disc()
    lean, spin_rate = motion.coordinates[1], velocity_symbol(motion.coordinates[2])
    rates = SteadyMotionRates(motion, VALUES)
    gr = float(VALUES[g] / VALUES[r])
    critical = np.sqrt(gr / 3)
    for spin in (0.0, 0.5 * critical, 0.99 * critical, 1.01 * critical, 2 * critical, 25.0):
        lin = rates.linearize({spin_rate: spin}, keep=(lean,))
        assert lin.equilibrium and lin.state == (lean, *motion.speeds)
        root = np.sqrt(complex(0.8 * (gr - 3 * spin**2)))
        assert same_roots(lin.eigenvalues, [0, 0, root, -root], 1e-10)
        unstable = max(e.real for e in lin.eigenvalues) > 1e-8
        assert unstable == (spin < critical)
        assert rates.linearize({spin_rate: spin}).state == lin.state  # yaw, spin, x, y found ignorable
    # the same with the metric formed symbolically (M = J^T W J expanded) instead of numerically,
    # and with its velocity terms (A) given (core/primitive.py) rather than formed numerically
    plain = _disc(projected=False)
    given = dataclasses.replace(plain, velocity_terms=christoffel_terms(
        plain.metric, plain.coordinates, [velocity_symbol(s) for s in plain.coordinates]))
    for motion in (plain, given):
        lin = SteadyMotionRates(motion, VALUES).linearize({spin_rate: 3.0}, keep=(lean,))
        assert np.allclose(lin.A, rates.linearize({spin_rate: 3.0}, keep=(lean,)).A, atol=1e-12)


def test_jacobian_at_random_states_against_kanes_method():
    """At states that are not steady (every coordinate kept), ``A`` is the Jacobian of the rates;
    sympy's ``KanesMethod.linearize`` (the same speeds, the contact's dependent) gives it too."""
    motion = _disc()
    rates = SteadyMotionRates(motion, VALUES)
    kane = KaneDisc()
    rng = np.random.default_rng(37)
    for _ in range(2):
        qs, us = rng.uniform(-1.2, 1.2, 5), rng.uniform(-3, 3, 3)
        lin = rates.linearize({**dict(zip(motion.coordinates, qs)), **dict(zip(motion.speeds, us))},
                              keep=motion.coordinates)
        assert not lin.equilibrium
        theirs = kane.linearized(qs, us, {"m": 1.3, "g": 9.81, "r": 0.3})
        assert np.allclose(lin.A, theirs, rtol=1e-10, atol=1e-10 * np.max(np.abs(theirs)))


def test_refusals():
    motion = _disc()
    yaw, lean = motion.coordinates[:2]
    spin_rate = velocity_symbol(motion.coordinates[2])
    with pytest.raises(LinearizationError, match="no value for parameter g"):
        SteadyMotionRates(motion, {m: 1.0, r: 0.3})
    rates = SteadyMotionRates(motion, VALUES)
    # x moves along the heading: leaving out the yaw while keeping x is refused
    with pytest.raises(LinearizationError, match="'yaw', which is neither kept nor dependent"):
        rates.linearize({spin_rate: 3.0, yaw: 0.4}, keep=(lean, motion.coordinates[3]))
    with pytest.raises(LinearizationError, match="not a coordinate"):
        rates.linearize({}, keep=(symbol("nope"),))
    with pytest.raises(LinearizationError, match="speed"):
        linearize_steady_motion(ConstrainedMotion(motion.coordinates, motion.metric, motion.force,
                                                  dict(list(motion.speeds.items())[:2]), motion.velocity_constraints),
                                {}, keep=(lean,), values=VALUES)


def test_a_dependent_coordinate_follows_its_constraint():
    """The disc again with its centre's height ``z`` a coordinate of its own, held by the
    configuration constraint ``z = r cos(lean)``, and its potential written
    ``m g (z + (z - r cos(lean)) sin(lean))`` (``m g z`` on the constraint, another function off
    it): linearised with ``z`` dependent, ``A``
    is the plain disc's at every state; the Jacobian that moves the lean with ``z`` held is not."""
    plain = _disc()
    q = plain.coordinates
    yaw, lean, spin, x, y = q
    z = symbol("z")
    coordinates = (*q, z)
    tilt = PlacedBody("frame", m, (0, 0, 0), (("Z", yaw), ("X", lean)), sympy.eye(3)).rotation()
    centre = sympy.Matrix([x, y, 0]) + tilt * sympy.Matrix([0, 0, r])
    centre[2] = z
    disc = PlacedBody("disc", m, tuple(centre), (("Z", yaw), ("X", lean), ("Y", spin)),
                      sympy.diag(m * r**2 / 4, m * r**2 / 2, m * r**2 / 4))
    contact = centre - tilt * sympy.Matrix([0, 0, r])
    slip = point_velocity(disc, tuple(contact), coordinates) * sympy.Matrix([velocity_symbol(s) for s in coordinates])
    potential = g * m * (z + (z - r * sympy.cos(lean)) * sympy.sin(lean))
    force = sympy.Matrix([-sympy.diff(potential, s) for s in coordinates])
    lifted = ConstrainedMotion(coordinates, ProjectedMetric(disc.weights(), disc.projection(coordinates)), force,
                               plain.speeds, (slip[0], slip[1]), (z - r * sympy.cos(lean),))
    ours, theirs = SteadyMotionRates(lifted, VALUES), SteadyMotionRates(plain, VALUES)
    rng = np.random.default_rng(7)
    for _ in range(2):
        qs, us = rng.uniform(-1.2, 1.2, 5), rng.uniform(-3, 3, 3)
        point = {**dict(zip(q, qs)), **dict(zip(plain.speeds, us))}
        lin = ours.linearize({**point, z: 0.1}, keep=q, dependent=(z,))  # z starts off the constraint
        assert lin.dependent[0][1] == pytest.approx(float(VALUES[r]) * np.cos(qs[1]), abs=1e-14)
        expected = theirs.linearize(point, keep=q).A
        assert np.allclose(lin.A, expected, rtol=1e-10, atol=1e-10 * np.max(np.abs(expected)))
        x0 = [v for _, v in lin.point[:6]]
        _, Jz, _ = ours.jacobian(x0, us)
        naive = Jz[np.ix_([0, 1, 2, 3, 4, 6, 7, 8], [0, 1, 2, 3, 4, 6, 7, 8])]
        assert np.max(np.abs(naive - expected)) > 0.1
