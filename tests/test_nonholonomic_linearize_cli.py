"""`kronsub linearize` of a model with velocity constraints (core/nonholonomic_linearize.py through
api/naming.py): the rolling disc of models/nonholonomic/rolling_disc.yaml about upright rolling at
spin rate W, against the closed form of a thin disc (I_axle = m r^2/2, I_diameter = m r^2/4):

    (I_d + m r^2) lean'' + (I_a (I_a + m r^2) / I_d W^2 - m g r) lean = 0,
    i.e. lambda^2 = 4 g / (5 r) - 12 W^2 / 5,

so that upright rolling is unstable below the critical spin sqrt(g / (3 r)) and not above it; the
other eigenvalues are 0 (the steady turning motions nearby, the spin rate)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from helpers.compare import same_roots
from kronsub.cli import main

ROOT = Path(__file__).resolve().parents[1]
DISC = ROOT / "models" / "nonholonomic" / "rolling_disc.yaml"


def _linearize(*at, fmt="json"):
    args = ["linearize", str(DISC), "--format", fmt]
    for a in at:
        args += ["--at", a]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    return result


def _upright(spin, r=0.3, g=9.81):
    out = _linearize("lean=0", "yaw_dot=0", "lean_dot=0", f"spin_dot={spin!r}", f"r={r!r}", f"g={g!r}")
    return json.loads(out.stdout)


def _closed_form(spin, r, g):
    square = 4 * g / (5 * r) - 12 * spin ** 2 / 5
    root = complex(math.sqrt(square), 0) if square >= 0 else complex(0, math.sqrt(-square))
    return [root, -root, 0, 0]


@pytest.mark.parametrize("spin, r, g", [(1.0, 0.3, 9.81), (3.0, 0.3, 9.81), (6.0, 0.3, 9.81), (4.0, 0.5, 1.62)])
def test_upright_rolling_disc_eigenvalues_are_the_closed_form(spin, r, g):
    data = _upright(spin, r, g)
    assert data["state"] == ["lean", "yaw_dot", "lean_dot", "spin_dot"]  # yaw, spin, x, y ignorable
    assert data["equilibrium"] is True and data["notes"] == []
    assert data["form"].startswith("d/dt [x; w]")
    ours = [complex(e["re"], e["im"]) for e in data["eigenvalues"]]
    assert same_roots(ours, _closed_form(spin, r, g), 1e-9 * (1 + spin ** 2))
    A = np.array(data["A"])
    assert A[0].tolist() == [0, 0, 1, 0]  # d/dt lean = lean_dot: the kinematic row


def test_stability_switches_at_the_critical_spin():
    r, g = 0.3, 9.81
    critical = math.sqrt(g / (3 * r))
    below = _upright(0.98 * critical, r, g)
    above = _upright(1.02 * critical, r, g)
    assert max(e["re"] for e in below["eigenvalues"]) > 0.1
    assert max(abs(e["re"]) for e in above["eigenvalues"]) < 1e-6
    assert min(abs(e["im"]) for e in above["eigenvalues"] if abs(e["im"]) > 1e-9) > 0.1


def test_markdown_has_the_shape_of_linearize():
    text = _linearize("lean=0", "yaw_dot=0", "lean_dot=0", "spin_dot=6", fmt="markdown").stdout
    for heading in ("# Linearisation of Rolling disc", "## Operating point", "## State and inputs", "## A",
                    "## B", "## Eigenvalues of A"):
        assert heading + "\n" in text
    assert "The point is a steady motion." in text
    assert "State `y = [lean, yaw_dot, lean_dot, spin_dot]`" in text


def test_the_api_gives_the_same_and_a_moving_point_is_reported():
    system = kronsub.load(DISC).derive()
    lin = system.linearize(at={"lean": 0, "yaw_dot": 0, "lean_dot": 0, "spin_dot": 6})
    assert lin.equilibrium and lin.in_speeds and lin.A.shape == (4, 4)
    leaning = system.linearize(at={"lean": 0.2, "yaw_dot": 0, "spin_dot": 6})  # falls: not steady
    assert not leaning.equilibrium and leaning.notes


def test_a_velocity_the_constraints_fix_is_refused_at_the_option():
    result = CliRunner().invoke(main, ["linearize", str(DISC), "--at", "x_dot=1"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "Error: --at x_dot: 'x_dot' is not a speed of Rolling disc: the velocity constraints fix it" \
        in result.output
    assert "  hint: give the speeds (yaw_dot, lean_dot, spin_dot)" in result.output


def test_symbolic_is_refused():
    result = CliRunner().invoke(main, ["linearize", str(DISC), "--symbolic"])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "--symbolic is not supported for a model with velocity constraints" in result.output


def _symbolic_jacobian(system, kept, point, inputs=()):
    """The Jacobian of ``[xdot_kept; Mbar^-1 (fbar - hbar)]`` from the equations `derive` prints
    in the speeds (symbolic, ``C`` a function of ``x``): another route to ``A`` and ``B``."""
    import sympy

    s = system.speeds
    values = {p.symbol: p.value for p in system.parameters}
    rows = [s.kinematics[list(system.coordinates).index(q)] for q in kept]
    udot = s.mass_matrix.LUsolve(s.forces - s.velocity_terms)
    F = sympy.Matrix(rows).col_join(udot)
    state = list(kept) + list(s.speeds)
    at = {**values, **point}
    A = np.array(F.jacobian(state).xreplace(at).evalf(), dtype=float)
    B = np.array(F.jacobian(list(inputs)).xreplace(at).evalf(), dtype=float) if inputs else None
    return A, B


def test_a_at_a_moving_point_is_the_jacobian_of_the_printed_equations():
    """Away from any steady motion (leaning, turning, falling) the kept rows and the speeds'
    rates still linearise to the Jacobian of the printed equations in the speeds."""
    system = kronsub.load(DISC).derive()
    at = {"lean": 0.3, "yaw": 0.7, "yaw_dot": 0.5, "lean_dot": 0.2, "spin_dot": 4.0}
    lin = system.linearize(at=at)
    assert not lin.equilibrium and lin.state[0] == system.symbol("lean")
    point = {system.symbol(k): v for k, v in at.items()}
    A, _ = _symbolic_jacobian(system, [system.symbol("lean")], point)
    assert np.allclose(lin.A, A, rtol=1e-10, atol=1e-10)


def test_inputs_of_the_differential_drive():
    """B of the wheels' torques about straight running, against the printed equations; the
    heading, position and wheel angles are ignorable there."""
    system = kronsub.load(ROOT / "models" / "nonholonomic" / "differential_drive.yaml").derive()
    at = {"phi_l_dot": 10.0, "phi_r_dot": 10.0, "tau_l": 0, "tau_r": 0}
    lin = system.linearize(at=at, inputs=["tau_l", "tau_r"])
    assert lin.equilibrium and [s.name for s in lin.state] == ["phi_l_dot", "phi_r_dot"]
    point = {system.symbol(k): v for k, v in at.items()}
    A, B = _symbolic_jacobian(system, [], point, [system.symbol("tau_l"), system.symbol("tau_r")])
    assert np.allclose(lin.A, A, atol=1e-12) and np.allclose(lin.B, B, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(lin.B)) > 1  # the torques do act


def test_a_steady_motion_at_a_huge_speed_is_linearised():
    """The sleigh running straight at v = 1e200: w decays at the rate m a v/(I + m a^2) (its
    steadiness test squared the speed and raised an internal OverflowError)."""
    path = ROOT / "models" / "nonholonomic" / "chaplygin_sleigh.yaml"
    result = CliRunner().invoke(main, ["linearize", str(path), "--at", "v=1e200", "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    rates = sorted(e["re"] for e in data["eigenvalues"])
    assert rates[0] == pytest.approx(-1.0 * 0.2 * 1e200 / (0.05 + 1.0 * 0.2 ** 2), rel=1e-9)
    assert all(e["im"] == 0 for e in data["eigenvalues"])


@pytest.mark.parametrize("model, at", [("chaplygin_sleigh", "w=1e200"), ("rolling_disc", "spin_dot=1e308")])
def test_a_steady_motion_beyond_the_doubles_is_refused_in_words(model, at):
    """Speeds so large that the rates overflow a double: ``A`` is not finite there, said as the
    linearisation without speeds says it (no internal OverflowError of the steadiness test, no
    LinAlgError of the eigenvalues, no numpy warnings on the way)."""
    path = ROOT / "models" / "nonholonomic" / f"{model}.yaml"
    result = CliRunner().invoke(main, ["linearize", str(path), "--at", at])
    assert result.exit_code == 1, result.output
    assert "Error: A is not finite at the operating point: the equations overflow a double there" in result.output
    assert "internal error" not in result.output and "Warning: overflow" not in result.output
