"""Runs of a system with configuration constraints beside velocity constraints (core/held.py,
simulation/held.py, the generated `hold`): tests/models/nonholonomic/rolling_disc_height.yaml,
the rolling disc with its centre's height a coordinate z held by ``z - r cos(lean) = 0``.

- The generated right-hand side (C and numpy) against sympy's KanesMethod with the same
  configuration constraint and the contact's three slip components as velocity constraints, at
  random states; with z put off the constraint, the right-hand side solves it back (Newton's
  method) and gives the rates of the state on it.
- tests/models/nonholonomic/rolling_disc_lean_held.yaml holds the lean instead (z - r cos(lean)
  = 0 is not linear in it: Newton's method iterates): the same motion.
- A run: the energy kept, ``z - r cos(lean)`` zero to Newton's tolerance at every row even with
  a loose integrator tolerance, the velocity constraints (written here as rolling without slip)
  met by the rates at every row, and the same motion as the disc held by its connection
  (models/nonholonomic/rolling_disc.yaml).
"""
from pathlib import Path

import numpy as np
import pytest
import sympy

import kronsub
from kronsub.errors import KronsubError
from kronsub.simulation.fallback import numpy_module
from reference.nonholonomic import kane_rates, rolling_disc_height_kane

ROOT = Path(__file__).resolve().parent.parent
HEIGHT = ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml"
DISC = ROOT / "models" / "nonholonomic" / "rolling_disc.yaml"
LEAN_HELD = ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_lean_held.yaml"
VALUES = {"m": 1.0, "r": 0.3, "g": 9.81}


@pytest.fixture(scope="module")
def system():
    return kronsub.load(HEIGHT).derive(cache=False)


@pytest.fixture(scope="module")
def kane():
    m, g, r = (sympy.Symbol(n, real=True) for n in ("m", "g", "r"))
    q, u, method, dependent = rolling_disc_height_kane(m, g, r)
    values = {m: VALUES["m"], g: VALUES["g"], r: VALUES["r"]}
    return q, u, method, [e.xreplace(values) for e in dependent], values


def _kane_state(kane, yaw, lean, spin, x, y, rates):
    """Kane's q and u (dependent speeds from its velocity constraints) on the constraint."""
    q, u, _, dependent, values = kane
    qv = [yaw, lean, spin, x, y, VALUES["r"] * np.cos(lean)]
    at = {**dict(zip(q, qv)), **dict(zip(u[:3], rates))}
    return qv, [*rates, *(float(e.xreplace(at)) for e in dependent)]


def test_rates_against_kanes_method_at_random_states(system, kane):
    """udot and xdot of the compiled C and of the numpy module equal Kane's; z off the
    constraint is solved back first."""
    q, u, method, _, values = kane
    numeric = system.numeric()
    assert numeric.backend == "C" and numeric.state == ("yaw", "spin", "x", "y", "lean", "z", "yaw_dot", "lean_dot",
                                                        "spin_dot")
    module = numpy_module(system)
    param = [numeric.parameters[p.name] for p in system.parameters]
    rng = np.random.default_rng(37)
    for _ in range(4):
        yaw, lean, spin, x, y = rng.uniform(-1.2, 1.2, 5)
        rates = rng.uniform(-3, 3, 3)
        qv, uv = _kane_state(kane, yaw, lean, spin, x, y, rates)
        expected = kane_rates(method, q, u, qv, uv, values)[:3]
        xdot = [uv[0], uv[2], uv[3], uv[4], uv[1], uv[5]]  # kronsub's order: yaw, spin, x, y, lean, z
        for off in (0.0, 1e-3):
            state = np.array([yaw, spin, x, y, lean, qv[5] + off, *rates])
            for rhs in (numeric.rhs(0.0, state), np.asarray(module["rhs"](0.0, state, param))):
                assert np.allclose(rhs[6:], expected, rtol=1e-11, atol=1e-11)
                assert np.allclose(rhs[:6], xdot, rtol=1e-12, atol=1e-12)


def test_a_run_keeps_energy_and_both_kinds_of_constraint(system):
    r = VALUES["r"]
    for tol in (1e-11, 1e-5):
        run = system.simulate(t=4.0, dt=0.05, rtol=tol, atol=tol, dataframe=False)
        assert run.complete
        yaw, spin, lean, z = (run.y[:, run.columns.index(n)] for n in ("yaw", "spin", "lean", "z"))
        # the configuration constraint at every row, whatever the integrator's tolerance
        assert np.max(np.abs(z - r * np.cos(lean))) < 1e-13
        energy = run.kinetic_energy + run.potential_energy
        drift = np.max(np.abs(energy - energy[0])) / abs(energy[0])
        assert drift < (1e-9 if tol < 1e-8 else 1e-2)
    numeric = system.numeric()
    for row in run.y:
        xdot = numeric.rhs(0.0, row)[:6]
        yaw, lean, spin_dot, lean_dot = row[0], row[4], row[8], row[7]
        rolling = [xdot[2] - r * np.cos(yaw) * spin_dot, xdot[3] - r * np.sin(yaw) * spin_dot,
                   xdot[5] + r * np.sin(lean) * lean_dot]
        assert np.max(np.abs(rolling)) < 1e-12
        assert xdot[1] == spin_dot and xdot[4] == lean_dot


def _moves_as_the_disc_held_by_its_connection(system):
    """``system``'s run from its initial values is the rolling disc's (models/nonholonomic) from the same start."""
    ours = system.simulate(t=3.0, dt=0.5, rtol=1e-12, atol=1e-12, dataframe=False)
    theirs = kronsub.load(DISC).derive().simulate(t=3.0, dt=0.5, rtol=1e-12, atol=1e-12, dataframe=False,
                                                   set={"lean": 0.1, "yaw_dot": 0.5, "spin_dot": 8, "lean_dot": 0})
    for name in ("yaw", "lean", "spin", "x", "y", "yaw_dot", "lean_dot", "spin_dot"):
        a, b = ours.y[:, ours.columns.index(name)], theirs.y[:, theirs.columns.index(name)]
        assert np.allclose(a, b, rtol=1e-8, atol=1e-8), name


def test_the_same_motion_as_the_disc_held_by_its_connection(system):
    _moves_as_the_disc_held_by_its_connection(system)


def test_the_start_is_put_on_the_constraint(system):
    """The held z moved onto the constraint from the lean given (reported); a z given with
    --set more than 1% off is refused, as a closed loop's dependent coordinate is."""
    run = system.simulate(t=0.1, dt=0.1, set={"lean": 0.3}, dataframe=False)
    z = run.y[0, run.columns.index("z")]
    assert z == pytest.approx(VALUES["r"] * np.cos(0.3), abs=1e-15)
    assert any(note.startswith("z 0.298501 -> 0.28660") for note in run.notes)
    close = system.simulate(t=0.1, dt=0.1, set={"lean": 0.3, "z": 0.287}, dataframe=False)
    assert close.y[0, close.columns.index("z")] == pytest.approx(z, abs=1e-15)
    with pytest.raises(KronsubError, match=r"set=\{'z': 0.25\} is 0.0366 away from the configuration constraints "
                                           r"'touches' \(the nearest consistent value is 0.28660"):
        system.simulate(t=0.1, dt=0.1, set={"z": 0.25, "lean": 0.3}, dataframe=False)


def test_reactions_along_a_run(system):
    """--reactions: the rolling multipliers are those of the disc held by its connection, and
    mu_touches is the normal force m (g + zddot), zddot = d^2 (r cos lean)/dt^2 with lean_ddot
    from the right-hand side."""
    m, g, r = VALUES["m"], VALUES["g"], VALUES["r"]
    ours = system.simulate(t=1.0, dt=0.25, reactions=True, dataframe=False)
    theirs = kronsub.load(DISC).derive().simulate(t=1.0, dt=0.25, reactions=True, dataframe=False,
                                                  set={"lean": 0.1, "yaw_dot": 0.5, "spin_dot": 8, "lean_dot": 0})
    columns, table = list(ours.table_columns), ours.table
    for name in ("mu_roll_x", "mu_roll_y"):
        assert np.allclose(table[:, columns.index(name)], theirs.table[:, list(theirs.table_columns).index(name)],
                           rtol=1e-8, atol=1e-10)
    numeric = system.numeric()
    for row, normal in zip(ours.y, table[:, columns.index("mu_touches")]):
        lean, lean_dot = row[4], row[7]
        lean_ddot = numeric.rhs(0.0, row)[7]
        zddot = -r * np.cos(lean) * lean_dot ** 2 - r * np.sin(lean) * lean_ddot
        assert normal == pytest.approx(m * (g + zddot), rel=1e-10)


def test_a_held_coordinate_the_constraint_is_not_linear_in():
    """The lean held: the generated right-hand side (C and numpy) solves it back from a value off
    the constraint by Newton's method, and the run is the disc held by its connection."""
    system = kronsub.load(LEAN_HELD).derive()
    assert system.speeds.dependent == (system.symbol("lean"),)
    numeric = system.numeric()
    module = numpy_module(system)
    param = [numeric.parameters[p.name] for p in system.parameters]
    r, lean = VALUES["r"], 0.4
    on = np.array([0.3, 1.0, 0.2, -0.1, r * np.cos(lean), lean, 0.7, -0.4, 5.0])
    off = on.copy()
    off[5] += 0.05
    for rhs in (numeric.rhs, lambda t, y: np.asarray(module["rhs"](t, y, param))):
        assert np.allclose(rhs(0.0, off), rhs(0.0, on), rtol=1e-13, atol=1e-13)
    assert np.allclose(module["hold"](0.0, off, param), on[:6], rtol=0, atol=1e-15)
    _moves_as_the_disc_held_by_its_connection(system)


def test_a_run_through_a_configuration_the_held_coordinate_is_not_fixed_at(tmp_path):
    """The lean held: upright (lean = 0) the rim's height does not fix it (dg/dlean = r sin(lean));
    a run that falls through there stops, and says so."""
    from click.testing import CliRunner

    from kronsub.cli import main

    result = CliRunner().invoke(main, ["simulate", str(LEAN_HELD), "--t", "1", "--set", "lean_dot=-2",
                                       "--set", "spin_dot=1", "-o", str(tmp_path / "run.csv")])
    assert result.exit_code == 3 and "Traceback" not in result.output  # a numerical failure
    assert "dg/d(lean) is nearly singular" in result.output
    assert "the configuration constraints 'touches' do not fix lean there" in result.output
    assert "order `coordinates:`" in result.output
