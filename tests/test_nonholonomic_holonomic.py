"""Configuration constraints beside velocity constraints (model/loader.py, core/nonholonomic.py:
``g(x, t) = 0`` on the listed coordinates, its rate ``G xdot + dg/dt`` joining ``A``, one
dependent coordinate each). tests/models/nonholonomic/rolling_disc_height.yaml is the rolling
disc with the centre's height a coordinate ``z`` held by ``z - r cos(lean) = 0`` instead of the
connection: the same equations in the speeds as models/nonholonomic/rolling_disc.yaml, and
`linearize` on the tangent of ``g = 0`` gives the same closed-form eigenvalues,
``lambda^2 = 4 g / (5 r) - 12 W^2 / 5``."""
import json
import math
from pathlib import Path

import pytest
import sympy
from click.testing import CliRunner

import kronsub
from kronsub.cli import main

ROOT = Path(__file__).resolve().parents[1]
HEIGHT = ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml"
DISC = ROOT / "models" / "nonholonomic" / "rolling_disc.yaml"


@pytest.fixture(scope="module")
def systems():
    return kronsub.load(HEIGHT).derive(cache=False), kronsub.load(DISC).derive(cache=False)


def test_the_equations_in_the_speeds_are_those_of_the_disc_held_by_its_connection(systems):
    ours, theirs = systems
    s, t = ours.speeds, theirs.speeds
    assert s.speeds == t.speeds and s.dependent == (ours.symbol("z"),)
    assert [c.name for c in s.holonomic] == ["touches"] and s.constraint_names == ("roll_x", "roll_y", "touches")
    for a, b in ((s.mass_matrix, t.mass_matrix), (s.velocity_terms, t.velocity_terms), (s.forces, t.forces)):
        assert (sympy.Matrix(a) - sympy.Matrix(b)).applyfunc(sympy.simplify) == sympy.zeros(*a.shape)
    z, lean = ours.symbol("z"), ours.symbol("lean")
    zdot = s.kinematics[list(ours.coordinates).index(z)]
    assert sympy.simplify(zdot + ours.symbol("r") * sympy.sin(lean) * ours.symbol("lean_dot")) == 0


def test_derive_prints_the_configuration_constraint():
    result = CliRunner().invoke(main, ["derive", str(HEIGHT), "--format", "json", "--no-cache"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["configuration_constraints"] == {"touches": "-r*cos(lean) + z"} and data["dependent"] == ["z"]
    text = CliRunner().invoke(main, ["derive", str(HEIGHT), "--no-cache"]).stdout
    assert "| **touches** | `-r*cos(lean) + z` |" in text


@pytest.mark.parametrize("spin", [1.0, 6.0])
def test_linearize_restricts_to_the_constraint_and_gives_the_closed_form(spin):
    r, g = 0.3, 9.81
    # z given off the constraint: moved onto g = 0 (Newton) before linearising
    result = CliRunner().invoke(main, ["linearize", str(HEIGHT), "--format", "json", "--at", "lean=0", "--at", "z=0.25",
                                       "--at", "yaw_dot=0", "--at", f"spin_dot={spin!r}"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["state"] == ["lean", "yaw_dot", "lean_dot", "spin_dot"] and data["equilibrium"] is True
    assert data["dependent"] == {"z": pytest.approx(r, abs=1e-14)}
    square = 4 * g / (5 * r) - 12 * spin ** 2 / 5
    nonzero = sorted(e["re"] if square > 0 else e["im"] for e in data["eigenvalues"]
                     if abs(complex(e["re"], e["im"])) > 1e-6)
    assert nonzero == pytest.approx([-math.sqrt(abs(square)), math.sqrt(abs(square))], rel=1e-10)


@pytest.mark.parametrize("command, extra", [("simulate", ["--t", "0.2", "--reactions"]),
                                            ("codegen", ["--lang", "c", "-o", "out"]),
                                            ("accuracy", ["--t", "0.1", "--quick", "--methods", "dop853"]),
                                            ("animate", ["--t", "0.1", "-o", "disc.gif"])])
def test_the_other_commands_take_it(tmp_path, command, extra):
    """simulate, codegen, accuracy and animate run it (core/held.py: the held coordinate z by
    Newton's method wherever the equations are evaluated); the values are checked in
    tests/test_nonholonomic_held.py."""
    extra = [str(tmp_path / e) if e in ("out", "disc.gif") else e for e in extra]
    result = CliRunner().invoke(main, [command, str(HEIGHT), *extra])
    assert result.exit_code == 0, result.output
    assert "not supported yet" not in result.output


def _write(tmp_path, old, new):
    text = HEIGHT.read_text()
    assert old in text
    path = tmp_path / "model.yaml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path, path.read_text()


def _derive_refuses_at(path, text, written: str, message: str) -> None:
    """``kronsub derive`` of ``path`` exits 1 with ``message`` located at the line ``written``."""
    result = CliRunner().invoke(main, ["derive", str(path), "--no-cache"])
    line = text.splitlines().index(written) + 1
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"Error: {path}:{line}:" in result.output and message in result.output


def test_constraints_that_are_not_independent_are_located(tmp_path):
    path, text = _write(tmp_path, "  touches: disc.z - r*cos(disc.theta)\n",
                        "  touches: disc.z - r*cos(disc.theta)\n  again: 2*disc.z - 2*r*cos(disc.theta)\n")
    _derive_refuses_at(path, text, "constraints:", "configuration constraints are not independent")


def test_auto_coordinates_are_refused_beside_velocity_constraints(tmp_path):
    path, text = _write(tmp_path, "coordinates: [yaw, spin, x, y, lean, z]", "coordinates: auto")
    _derive_refuses_at(path, text, "coordinates: auto", "`coordinates: auto` together with `velocity_constraints:`")


def test_the_multiplier_of_the_configuration_constraint_is_the_normal_force(systems):
    """mu_touches holds the centre at z = r cos(lean): m (g + zddot), zddot the second
    derivative of r cos(lean) (Newton's law along the vertical; the rim's contact is the only
    vertical force besides gravity)."""
    from kronsub.core.nonholonomic import velocity_multipliers

    ours, _ = systems
    mu = dict(velocity_multipliers(ours))["mu_touches"]
    m, r, g, lean = (ours.symbol(n) for n in ("m", "r", "g", "lean"))
    t = sympy.Symbol("t")
    path = sympy.Function("lean")(t)
    zddot = sympy.diff(r * sympy.cos(path), t, 2).subs({sympy.Derivative(path, (t, 2)): ours.symbol("lean_ddot")}) \
        .subs({sympy.Derivative(path, t): ours.symbol("lean_dot")}).subs(path, lean)
    assert sympy.simplify(mu - m * (g + zddot)) == 0
