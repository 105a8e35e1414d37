"""The ``turned_body`` component (components/spatial.py): a rigid body placed by its centre and
a chain of turns about its own axes. Its kinetic energy against sympy.physics.mechanics' rigid
body oriented by the same successive body-fixed turns; placed through a model file's connection,
its mass matrix against core/rigid_bodies.PlacedBody's ``sum J^T W J``; its bad ``turns:``."""
import random

import pytest
import sympy
from click.testing import CliRunner
from sympy.physics.mechanics import Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

from kronsub.cli import main
from kronsub.components import REGISTRY
from kronsub.components.spatial import SEQUENCES, euler_rates, turn_rates
from kronsub.core.rigid_bodies import PlacedBody, body_metric
from kronsub.core.symbols import symbol, velocity_symbol
from kronsub.model.derive import derive_model
from kronsub.model.loader import load_model

AXES = "ZXYYZY"  # a bicycle's front wheel: yaw, roll, pitch, head angle, steer, the wheel's turn


def test_three_turns_are_the_euler_rates():
    a, b, c = sympy.symbols("a b c")
    for sequence in SEQUENCES:
        assert turn_rates(sequence, (a, b, c)) == euler_rates(sequence, b, c), sequence


def test_kinetic_energy_is_that_of_sympy_rigid_body():
    cls = REGISTRY["turned_body"].chosen({"turns": AXES})
    assert cls.coordinates == ("x", "y", "z", "turn1", "turn2", "turn3", "turn4", "turn5", "turn6")
    names = ("m", "Ixx", "Iyy", "Izz", "Ixy", "Iyz", "Ixz")
    p = dict(zip(("mass", *names[1:]), sympy.symbols(names)))
    body = cls(x={q: symbol(q) for q in cls.coordinates}, p=p, choices={"turns": AXES})
    q = dynamicsymbols("x y z a1:7")
    world = ReferenceFrame("W")
    frame = world
    for axis, angle in zip(AXES, q[3:]):
        frame = frame.orientnew("F", "Axis", (angle, getattr(frame, axis.lower())))
    origin = Point("O")
    centre = origin.locatenew("C", q[0] * world.x + q[1] * world.y + q[2] * world.z)
    centre.set_vel(world, centre.pos_from(origin).dt(world))
    reference = RigidBody("B", centre, frame, p["mass"], (inertia(frame, *[p[k] for k in names[1:]]), centre))
    T_ref = reference.kinetic_energy(world)
    qd = [velocity_symbol(symbol(c)) for c in cls.coordinates]
    ours = (sympy.Matrix(qd).T * body.metric() * sympy.Matrix(qd))[0] / 2
    state_symbols = list(q) + [s.diff() for s in q]
    T_ref = sympy.lambdify([state_symbols, list(p.values())], T_ref)
    ours = sympy.lambdify([[symbol(c) for c in cls.coordinates] + qd, list(p.values())], ours)
    rng = random.Random(3)
    for _ in range(3):
        values = [rng.uniform(-1.5, 1.5) for _ in p]
        state = [rng.uniform(-2, 2) for _ in state_symbols]
        assert ours(state, values) == pytest.approx(T_ref(state, values), rel=1e-12, abs=1e-12)
    R = body.rotation().subs({symbol(c): v for c, v in zip(cls.coordinates, state)})
    R_ref = world.dcm(frame).subs(dict(zip(q, state[:9])))
    assert max(abs(float(e)) for e in R - R_ref) < 1e-12


FORK = """\
parameters:
  m: 3
  lam: 0.3
  d: 0.7
components:
  fork:
    type: turned_body
    turns: ZXYZ
    parameters: {mass: m, Ixx: 0.5, Iyy: 0.7, Izz: 0.3, Ixz: 0.1}
coordinates: [yaw, roll, steer]
connection:
  fork.x: d*cos(yaw)
  fork.y: d*sin(yaw)*cos(roll)
  fork.z: d*sin(roll)
  fork.turn1: yaw
  fork.turn2: roll
  fork.turn3: -lam
  fork.turn4: steer
"""


def test_placed_by_the_connection_is_the_projected_metric(tmp_path):
    """A constant turn (a head angle) and three coordinates: ``Mbar = C^T m C`` of the component
    is ``J^T W J`` of the same body placed by :class:`PlacedBody`."""
    path = tmp_path / "fork.yaml"
    path.write_text(FORK)
    system = derive_model(load_model(path))
    yaw, roll, steer = (symbol(n) for n in ("yaw", "roll", "steer"))
    m, lam, d = 3, sympy.Rational(3, 10), sympy.Rational(7, 10)
    I = sympy.Matrix([[0.5, 0, 0.1], [0, 0.7, 0], [0.1, 0, 0.3]])
    placed = PlacedBody("fork", m, (d * sympy.cos(yaw), d * sympy.sin(yaw) * sympy.cos(roll), d * sympy.sin(roll)),
                        (("Z", yaw), ("X", roll), ("Y", -lam), ("Z", steer)), I)
    reference = body_metric([placed], (yaw, roll, steer))
    rng = random.Random(5)
    for _ in range(4):
        at = {yaw: rng.uniform(-2, 2), roll: rng.uniform(-1, 1), steer: rng.uniform(-2, 2)}
        ours = system.mass_matrix.subs(at).subs({symbol("m"): m, symbol("lam"): lam, symbol("d"): d})
        assert max(abs(float(e)) for e in ours - reference.subs(at)) < 1e-12


@pytest.mark.parametrize("turns, said", [("ZQX", "letters X, Y, Z"), ("ZYXZYXZYX", "1 to 8"), ("[Z, Y]", "a list")])
def test_bad_turns_are_located(tmp_path, turns, said):
    path = tmp_path / "bad.yaml"
    path.write_text(FORK.replace("turns: ZXYZ", f"turns: {turns}"))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1
    assert "bad.yaml:8:12: `turns:` of component 'fork' (turned_body) must be a word of" in result.output
    assert said in result.output and "hint: the axes of the body's turns" in result.output
