"""Non-holonomic models from their files (`velocity_constraints:`, `speeds:`; models/nonholonomic):
the rolling disc against sympy's KanesMethod and its contact force against Newton's law, the
Chaplygin sleigh's equations and straight end, the differential-drive robot against its
hand-derived equations, the printed outputs, and the located refusals of bad constraints."""
import json
import os
import subprocess
import sys
from pathlib import Path

import jinja2
import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import kronsub.emitters.text as text_emitters
from helpers.located import line_column, refused
from kronsub.cli import main
from kronsub.core.nonholonomic import speed_rates, velocity_multipliers
from kronsub.core.symbols import symbol
from kronsub.emitters.escape import environment
from kronsub.model.loader import load_model
from reference.nonholonomic import differential_drive_residual, kane_rates, rolling_disc_kane

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "models" / "nonholonomic"


def _derived(name):
    return load_model(MODELS / f"{name}.yaml").derive(cache=False)


def _numbers(system):
    return {p.symbol: float(p.value) for p in system.parameters}


def _rates(s, at):
    M = np.array(s.mass_matrix.xreplace(at).evalf(), dtype=float)
    r = np.array((s.forces - s.velocity_terms).xreplace(at).evalf(), dtype=float)
    return np.linalg.solve(M, r).ravel()


@pytest.fixture(scope="module")
def disc():
    system = _derived("rolling_disc")
    m, g, r = (symbol(n) for n in ("m", "g", "r"))
    return system, rolling_disc_kane(m, g, r)


def test_rolling_disc_against_kanes_method(disc):
    system, (q, u, kane, _) = disc
    s = system.speeds
    x = system.coordinates
    assert [v.name for v in s.speeds] == ["yaw_dot", "lean_dot", "spin_dot"]
    assert (s.constraint_matrix * s.transformation).applyfunc(sympy.simplify) == sympy.zeros(2, 3)
    values = _numbers(system)
    rng = np.random.default_rng(37)
    for _ in range(4):
        qv, uv = rng.uniform(-1.2, 1.2, 5), rng.uniform(-3, 3, 3)
        at = {**dict(zip(x, qv)), **dict(zip(s.speeds, uv)), **values}
        xdot = np.array(s.kinematics.xreplace(at).evalf(), dtype=float).ravel()
        theirs = kane_rates(kane, q, u, qv, xdot, {sympy.Symbol(k.name, real=True): v for k, v in values.items()})
        assert np.allclose(_rates(s, at), theirs[:3], rtol=1e-10, atol=1e-10)


def test_rolling_disc_contact_force_is_the_mass_times_the_centre_acceleration(disc):
    """mu of `roll_x`, `roll_y` = the horizontal contact force = m a of the mass centre (gravity is
    vertical), with the accelerations of every coordinate from KanesMethod."""
    system, (q, u, kane, centre) = disc
    s = system.speeds
    x = system.coordinates
    to_ours = dict(zip(q, x))
    centre = [sympy.sympify(c).xreplace(to_ours) for c in centre]
    values = _numbers(system)
    plain = {sympy.Symbol(k.name, real=True): v for k, v in values.items()}
    multipliers = dict(velocity_multipliers(system))
    rates = speed_rates(s.speeds, x)
    rng = np.random.default_rng(5)
    for _ in range(3):
        qv, uv = rng.uniform(-1.2, 1.2, 5), rng.uniform(-3, 3, 3)
        at = {**dict(zip(x, qv)), **dict(zip(s.speeds, uv)), **values}
        xdot = np.array(s.kinematics.xreplace(at).evalf(), dtype=float).ravel()
        xddot = kane_rates(kane, q, u, qv, xdot, plain)  # u = qdot: udot = qddot, independent then dependent
        at_q = dict(zip(x, qv))
        accel = [sum(float(sympy.diff(c, x[i]).xreplace(at_q).xreplace(values)) * xddot[i] for i in range(5))
                 + sum(float(sympy.diff(c, x[i], x[j]).xreplace(at_q).xreplace(values)) * xdot[i] * xdot[j]
                       for i in range(5) for j in range(5)) for c in centre[:2]]
        at.update(dict(zip(rates, xddot[:3])))
        force = [float(multipliers[f"mu_{n}"].xreplace(at)) for n in ("roll_x", "roll_y")]
        assert np.allclose(force, values[symbol("m")] * np.array(accel), rtol=1e-10, atol=1e-10)


def test_chaplygin_sleigh_equations_and_straight_end():
    system = _derived("chaplygin_sleigh")
    s = system.speeds
    m, I, a = (symbol(n) for n in ("m", "I", "a"))
    v, w = s.speeds
    assert [u.name for u in s.speeds] == ["v", "w"]
    # Bloch's sleigh: m v' = m a w^2, (I + m a^2) w' = -m a v w
    assert (s.mass_matrix - sympy.diag(m, I + m * a**2)).applyfunc(sympy.simplify) == sympy.zeros(2, 2)
    assert (s.forces - s.velocity_terms - sympy.Matrix([m * a * w**2, -m * a * v * w])).applyfunc(
        sympy.simplify) == sympy.zeros(2, 1)
    assert sympy.simplify(s.kinetic_energy - (m * v**2 + (I + m * a**2) * w**2) / 2) == 0
    # the knife edge's sideways force: its moment about the mass centre turns the sleigh, I w' = -a F
    (name, mu), = velocity_multipliers(system)
    assert name == "mu_knife_edge" and sympy.simplify(mu + I * speed_rates(s.speeds, system.coordinates)[1] / a) == 0
    values = _numbers(system)
    args = (*system.coordinates, v, w)
    field = sympy.lambdify(args, s.kinematics.col_join(s.mass_matrix.LUsolve(s.forces - s.velocity_terms)).xreplace(
        values), "numpy")
    v0, w0 = -0.5, 2.0  # backwards and turning: it turns round and ends going forwards, straight
    run = solve_ivp(lambda t, z: np.ravel(field(*z)), (0.0, 80.0), [0, 0, 0, v0, w0], rtol=1e-10, atol=1e-12)
    energy = values[m] * v0**2 / 2 + (values[I] + values[m] * values[a]**2) * w0**2 / 2
    assert abs(run.y[4, -1]) < 1e-3
    assert run.y[3, -1] == pytest.approx(np.sqrt(2 * energy / values[m]), rel=1e-6)
    heading, motion = run.y[2, -1], np.ravel(field(*run.y[:, -1]))[:2]
    assert abs(-np.sin(heading) * motion[0] + np.cos(heading) * motion[1]) < 1e-3 * np.hypot(*motion)


def test_differential_drive_against_its_hand_derived_equations():
    system = _derived("differential_drive")
    s = system.speeds
    names = ("m", "Ic", "J", "R", "b", "d", "tau_l", "tau_r")
    m, Ic, J, R, b, d, tau_l, tau_r = (symbol(n) for n in names)
    speeds = s.speeds
    rates = speed_rates(speeds, system.coordinates)
    assert [r.name for r in rates] == ["phi_l_ddot", "phi_r_ddot"]
    ours = s.mass_matrix * sympy.Matrix(rates) + s.velocity_terms - s.forces
    theirs = differential_drive_residual(m, Ic, J, R, b, d, tau_l, tau_r, *speeds, *rates)
    assert (ours - theirs).applyfunc(sympy.simplify) == sympy.zeros(2, 1)
    theta = symbol("theta")
    v = R * (speeds[0] + speeds[1]) / 2
    assert sympy.simplify(s.kinematics[0] - v * sympy.cos(theta)) == 0
    assert sympy.simplify(s.kinematics[2] - R * (speeds[1] - speeds[0]) / (2 * b)) == 0


def _worktree_templates(monkeypatch):
    """The templates of this checkout (an editable install may map kronsub.templates elsewhere)."""
    monkeypatch.setattr(text_emitters, "template_environment",
                        lambda: environment(jinja2.FileSystemLoader(str(ROOT / "templates"))))


def test_derive_prints_the_equations_in_the_speeds(monkeypatch):
    _worktree_templates(monkeypatch)
    system = _derived("chaplygin_sleigh")
    data = json.loads(text_emitters.emit_json(system))
    assert data["speeds"] == ["v", "w"] and data["speed_rates"] == ["v_dot", "w_dot"]
    assert data["mass_matrix"] == [["m", "0"], ["0", "I + a**2*m"]]
    assert data["kinematics"] == {"x_dot": "-a*w*sin(theta) + v*cos(theta)", "y_dot": "a*w*cos(theta) + v*sin(theta)",
                                  "theta_dot": "w"}
    assert data["velocity_constraints"] == {"knife_edge": "-a*theta_dot - x_dot*sin(theta) + y_dot*cos(theta)"}
    assert len(data["unconstrained"]["mass_matrix"]) == 3
    markdown = text_emitters.emit_markdown(system)
    for heading in ("## Velocity constraints", "## Equations in the speeds", "## Equations of motion"):
        assert heading in markdown
    assert "- `x_dot = -a*w*sin(theta) + v*cos(theta)`" in markdown
    latex = text_emitters.emit_latex(system)
    assert r"\section*{Equations in the speeds}" in latex and r"\dot{w}" in latex


def test_derive_json_is_deterministic():
    outputs = set()
    for seed in ("0", "12345"):
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": str(ROOT)}
        run = subprocess.run([sys.executable, "-m", "kronsub", "derive", str(MODELS / "chaplygin_sleigh.yaml"),
                              "--format", "json", "--no-cache", "--reactions"],
                             capture_output=True, text=True, env=env, timeout=120, check=True)
        outputs.add(run.stdout)
    assert len(outputs) == 1


HEAD = """name: bad
parameters:
  m: {value: 1}
  a: {value: 0.2}
components:
  body: {type: planar_body, parameters: {mass: m, inertia: 1}}
coordinates: [x, y, theta]
connection: {body.x: x, body.y: y, body.angle: theta}
"""

BAD = [
    ("velocity_constraints:\n  c: x_dot**2 + y_dot\n", None,
     "velocity constraint 'c' is not linear in the velocities", "A(x) xdot + b(x, t) = 0", "c:"),
    ("velocity_constraints:\n  c: y*x_dot + x*y_dot\n", None, "velocity constraint 'c' is integrable",
     "configuration constraint", "c:"),
    ("velocity_constraints:\n  c: x - y\n", None, "velocity constraint 'c' has no velocity in it",
     "configuration constraint", "c:"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\n"
     "speeds: {u1: -2*sin(theta)*x_dot + 2*cos(theta)*y_dot, u2: theta_dot}\n", None,
     "the speeds do not span the null space of the velocity constraints", "choose speeds", "{u1"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: [theta_dot]\n", None,
     "1 speed(s) for 2 degree(s) of freedom", "name 2 speeds", "[theta_dot]"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot - v(t)\n", None,
     "in velocity constraint 'c' '-sin(theta)*x_dot + cos(theta)*y_dot - v(t)': unknown function 'v'",
     "allowed functions", "v(t)"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: [z_dot, theta_dot]\n", None,
     "speed 'z_dot' is not the velocity of a listed coordinate", "x_dot", "z_dot"),
    ("speeds: [theta_dot]\n", None, "`speeds:` without `velocity_constraints:`", "", "speeds:"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\ninitial: {x: 1, y_dot: 2}\n", None,
     "'y_dot' is not a speed: the velocity constraints fix it", "x_dot, theta_dot", "y_dot: 2"),
    # in a scene's initial values too (it was ignored there: the run started at rest)
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nscenes:\n  s: {initial: {y_dot: 2}}\n", None,
     "'y_dot' is not a speed: the velocity constraints fix it", "x_dot, theta_dot", "y_dot: 2"),
    # as many constraints as velocities: no speed left (no internal ShapeError)
    ("velocity_constraints:\n  c1: x_dot - sin(y)*theta_dot\n  c2: y_dot - cos(x)*theta_dot\n  c3: theta_dot - x*y_dot\n",
     None, "the 3 constraints fix all 3 velocities: no speed is left", "remove a constraint", "c1:"),
    # infinite at the parameters' values, complex at the start (no internal TypeError of a rank)
    ("velocity_constraints:\n  c: x_dot/(a - 1/5) - y_dot + x*theta_dot\n", None,
     "the coefficients of the velocities are infinite or undefined at every configuration tried", "divisions", "c:"),
    ("velocity_constraints:\n  c: sqrt(a - 1)*x_dot - y_dot + x*theta_dot\n", None,
     "the velocity constraints or the speeds have no real value at the initial configuration (x = 0)", "sqrt",
     "velocity_constraints:"),
    # speeds chosen by kronsub, or named, singular where the run starts (y_dot = -x_dot/tan(theta))
    ("velocity_constraints:\n  c: cos(theta)*x_dot + sin(theta)*y_dot\n", None,
     "the speeds are singular at the initial configuration (theta = 0)", "`speeds: [y_dot, theta_dot]`",
     "velocity_constraints:"),
    ("velocity_constraints:\n  c: cos(theta)*x_dot + sin(theta)*y_dot\nspeeds: [x_dot, theta_dot]\n", None,
     "the speeds are singular at the initial configuration (theta = 0)", "start the coordinates elsewhere",
     "speeds:"),
    # a knife edge's direction or offset zero or complex at the parameters' values
    ("velocity_constraints:\n  c: {knife_edge: body, direction: [1, sqrt(-a)]}\n", None,
     "direction of 'c' [1, sqrt(-a)] is not a real vector at the parameters' values", "finite real", "[1, sqrt"),
    ("velocity_constraints:\n  c: {knife_edge: body, direction: [a - 1/5, 0]}\n", None,
     "direction of 'c' is the zero vector", "nonzero entry", "[a - 1/5"),
    ("velocity_constraints:\n  c: {knife_edge: body, at: [sqrt(-a), 0]}\n", None,
     "at of 'c' [sqrt(-a), 0] is not a real vector at the parameters' values", "finite real", "[sqrt"),
    # a speed named as kronsub names something else (the run's lambdify saw `v_dot` twice), or as a
    # coordinate's velocity that it is not
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: {v_dot: theta_dot, v: x_dot}\n", None,
     "speed 'v_dot' is the name kronsub gives the rate of speed 'v'", "a name of its own", "v_dot:"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: {mu_c: theta_dot, v: x_dot}\n", None,
     "speed 'mu_c' is the name kronsub gives the multiplier of velocity constraint 'c'", "a name of its own",
     "mu_c:"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: {v: theta_dot, x_ddot: x_dot}\n",
     None, "speed 'x_ddot' is the name kronsub gives the acceleration of coordinate 'x'", "a name of its own",
     "x_ddot:"),
    ("velocity_constraints:\n  c: -sin(theta)*x_dot + cos(theta)*y_dot\nspeeds: {x_dot: theta_dot, theta_dot: x_dot}\n",
     None, "speed 'x_dot' is the velocity of coordinate 'x', defined as something else", "`x_dot: x_dot`",
     "x_dot:"),
]


@pytest.mark.parametrize("extra, _, message, hint, at", BAD)
def test_bad_velocity_constraints_are_located(tmp_path, extra, _, message, hint, at):
    text = HEAD + extra
    path, out = refused(tmp_path, text)
    index = len(HEAD) + extra.index(at)  # the first place `at` is written in the section
    line, column = line_column(text, index)
    assert f"Error: {path}:{line}:{column}: {message}" in out
    hint_line = out.split(f"{message}", 1)[1].split("\n")[1]
    assert hint_line.startswith("  hint: ") and hint in hint_line


@pytest.mark.parametrize("joint, written", [("rolling_disc_joint", "rolling_disc"),
                                            ("chaplygin_sleigh_joint", "chaplygin_sleigh")])
def test_contact_joints_give_the_constraints_written_by_hand(joint, written):
    """`rolls_on` (the rim's lowest point at rest) and `knife_edge` (no velocity across the edge)
    against the same constraints written as expressions: the same A, C and equations."""
    system = load_model(ROOT / "tests" / "models" / "nonholonomic" / f"{joint}.yaml").derive(cache=False)
    ours, theirs = system.speeds, _derived(written).speeds
    assert ours.speeds == theirs.speeds
    symbols = sorted(set().union(*(m.free_symbols for m in (theirs.mass_matrix, theirs.velocity_terms,
                                                             theirs.kinematics, theirs.constraint_matrix))), key=str)
    rng = np.random.default_rng(2)
    for _ in range(3):  # equal as functions: at random points of the state and the parameters
        at = {v: float(x) for v, x in zip(symbols, rng.uniform(-1.3, 1.3, len(symbols)))}
        for a, b in ((ours.constraint_matrix, theirs.constraint_matrix), (ours.kinematics, theirs.kinematics),
                     (ours.mass_matrix, theirs.mass_matrix), (ours.velocity_terms, theirs.velocity_terms),
                     (ours.forces, theirs.forces)):
            assert np.allclose(np.array((a - b).xreplace(at).evalf(), dtype=float), 0, atol=1e-12)


DISC = """name: bad
parameters: {m: 1, r: 0.3}
components:
  disc: {type: rigid_body3d, euler: ZXY, parameters: {mass: m, Ixx: 1, Iyy: 2, Izz: 1}}
  bead: {type: particle3d, parameters: {mass: m}, coordinates: [bx, by, bz]}
coordinates: [yaw, lean, spin, x, y, bx, by, bz]
connection:
  disc.x: x + r*sin(yaw)*sin(lean)
  disc.y: y - r*cos(yaw)*sin(lean)
  disc.z: HEIGHT
  disc.psi: yaw
  disc.theta: lean
  disc.phi: spin
velocity_constraints:
"""

BAD_JOINTS = [
    ("r*cos(lean)", "  c: {rolls_on: plane, body: bead, radius: r}\n", "bead",
     "rolling joint 'c': component 'bead' has no contact point: it is not a rigid body", "rigid_body3d"),
    ("r*cos(lean)", "  c: {rolls_on: plane, body: disc}\n", "disc}",
     "rolling joint 'c': component 'disc' has no contact point without a rim", "radius:"),
    ("r", "  c: {rolls_on: plane, body: disc, radius: r}\n", "disc,",
     "rolling joint 'c': the rim of 'disc' is at height", "keep it on the ground"),
    ("r*cos(lean)", "  c: {rolls_on: ice, body: disc, radius: r}\n", "ice",
     "velocity constraint 'c' rolls on 'ice'", "plane"),
    ("r*cos(lean)", "  c: {knife_edge: disc}\n", "disc}",
     "knife edge 'c' on a body in space is not supported yet", "planar body"),
    ("r*cos(lean)", "  c: {rolls_on: plane, body: disc, radius: r, axle: [0, r - 3/10, 0]}\n", "[0, r",
     "axle of 'c' is the zero vector", "nonzero entry"),
]


@pytest.mark.parametrize("height, extra, at, message, hint", BAD_JOINTS)
def test_bad_contact_joints_are_located(tmp_path, height, extra, at, message, hint):
    head = DISC.replace("HEIGHT", height)
    text = head + extra
    path, out = refused(tmp_path, text)
    index = len(head) + extra.index(at)
    line, column = line_column(text, index)
    assert f"Error: {path}:{line}:{column}: {message}" in out
    assert hint in out.split(message, 1)[1].split("\n")[1]


def test_a_model_with_velocity_constraints_as_a_known_system_is_refused(tmp_path):
    (tmp_path / "sleigh.yaml").write_text((MODELS / "chaplygin_sleigh.yaml").read_text())
    text = "name: outer\ncomponents:\n  s: {model: sleigh.yaml}\ncoordinates: [x, y, theta]\n"
    path = tmp_path / "outer.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["derive", str(path), "--no-cache"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert (f"Error: {path}:3:14: model file 'sleigh.yaml' has velocity constraints: as a known system it is not "
            "supported yet") in result.output


def test_a_broken_constraint_is_reported_once_not_again_at_the_speeds_initial_values(tmp_path):
    """The speeds named under `speeds:` are names of the model even when a constraint beside them
    fails: `initial:` (and a scene's) giving them values is no second error ("'v' is not a
    coordinate or velocity of this model")."""
    text = HEAD + ("velocity_constraints:\n  c: x_dot**2 - y_dot\nspeeds: {v: x_dot, w: theta_dot}\n"
                   "initial: {v: 1, w: 2}\nscenes:\n  s: {initial: {v: 3}}\n")
    _, out = refused(tmp_path, text)
    assert out.count("Error:") == 1 and "velocity constraint 'c' is not linear in the velocities" in out
