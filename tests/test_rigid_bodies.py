"""Rigid bodies placed by turns about their own axes (core/rigid_bodies.py): the angular
velocity of a chain of turns against ``R^T Rdot``, a material point's velocity against the
derivative of its world position, and the metric against the kinetic energy of
``sympy.physics.mechanics.RigidBody`` of the same placement."""
import numpy as np
import sympy
from sympy.physics import mechanics as me

from kronsub.core.rigid_bodies import PlacedBody, angular_velocity, body_metric, point_velocity
from kronsub.core.symbols import symbol, velocity_symbol

q = tuple(symbol(n) for n in ("a", "b", "c", "d"))
tilt = symbol("tilt")
TURNS = (("Z", q[0]), ("X", q[1] + q[2]), ("Y", -tilt), ("Z", q[2]), ("Y", q[3]))


def _compiled(expr, symbols):
    """``expr`` (a matrix or expression) as a function of ``symbols`` (subs is slow on these)."""
    fn = sympy.lambdify(symbols, expr, "numpy")
    return lambda at: np.array(fn(*[at[s] for s in symbols]), dtype=float)


def _at(rng):
    return {**dict(zip(q, rng.uniform(-2, 2, 4))), tilt: 0.3,
            **{velocity_symbol(s): v for s, v in zip(q, rng.uniform(-2, 2, 4))}}


def test_angular_velocity_is_that_of_the_rotation():
    body = PlacedBody("b", 1, (0, 0, 0), TURNS, sympy.eye(3))
    R = body.rotation()
    qd = sympy.Matrix([velocity_symbol(s) for s in q])
    Rdot = sum((R.diff(s) * v for s, v in zip(q, qd)), sympy.zeros(3, 3))
    skew = R.T * Rdot  # [omega]_x in body axes
    symbols = [*q, tilt, *qd]
    theirs, ours_of = _compiled(skew, symbols), _compiled(angular_velocity(TURNS, q) * qd, symbols)
    rng = np.random.default_rng(1)
    for _ in range(3):
        at = _at(rng)
        W = theirs(at)
        ours = ours_of(at).ravel()
        assert np.allclose(ours, [W[2, 1], W[0, 2], W[1, 0]], atol=1e-12)
        assert np.allclose(W, -W.T, atol=1e-12)


def test_point_velocity_and_metric_against_a_rigid_body():
    m, L = symbol("m"), symbol("L")
    frame = PlacedBody("f", 0, (0, 0, 0), TURNS[:3], sympy.eye(3)).rotation()
    centre = frame * sympy.Matrix([L, 0, q[3] * L])
    inertia = sympy.Matrix([[2, 0, 0.3], [0, 3, 0], [0.3, 0, 1.5]])
    body = PlacedBody("b", m, tuple(centre), TURNS, inertia)
    qd = sympy.Matrix([velocity_symbol(s) for s in q])
    # a material point: fixed in the body, at body coordinates (0.2, -0.1, 0.4) from the centre
    point = centre + body.rotation() * sympy.Matrix([0.2, -0.1, 0.4])
    rate = point.jacobian(list(q)) * qd
    # sympy.physics.mechanics: the same rotation by body-fixed turns, its kinetic energy
    t = me.dynamicsymbols._t
    f = [sympy.Function(s.name)(t) for s in q]
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Body", [f[0], f[1] + f[2], -tilt], "ZXY").orientnew("C", "Body", [f[2], f[3], 0], "ZYX")
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", sum((c * e for c, e in zip(centre.xreplace(dict(zip(q, f))), (N.x, N.y, N.z))), 0 * N.x))
    G.set_vel(N, G.pos_from(O).dt(N))
    rigid = me.RigidBody("b", G, B, m, (me.inertia(B, 2, 3, 1.5, 0, 0, 0.3), G))
    T = rigid.kinetic_energy(N).xreplace({fi.diff(t): velocity_symbol(s) for fi, s in zip(f, q)}).xreplace(
        dict(zip(f, q)))
    M = body_metric([body], q)
    symbols = [*q, tilt, *qd, m, L]
    ours, theirs = _compiled(point_velocity(body, tuple(point), q) * qd, symbols), _compiled(rate, symbols)
    energy, kinetic = _compiled((qd.T * M * qd)[0] / 2, symbols), _compiled(T, symbols)
    rng = np.random.default_rng(2)
    for _ in range(3):
        at = {**_at(rng), m: 1.7, L: 0.8}
        assert np.allclose(ours(at).ravel(), theirs(at).ravel(), atol=1e-12)
        assert np.isclose(float(energy(at)), float(kinetic(at)), rtol=1e-12)
