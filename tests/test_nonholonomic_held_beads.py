"""Two configuration constraints beside a velocity constraint, not linear in the coordinates they
hold and pivoted in Newton's method (core/held.py, the generated `hold`):
tests/models/nonholonomic/sleigh_and_beads.yaml, the Chaplygin sleigh beside two beads held on
wires written as a sum and a difference, against sympy's KanesMethod with each wire on its own
and the knife edge (the same motion), at random states and along a run: the kinetic energy kept,
each wire and the knife edge met at every row."""
from pathlib import Path

import numpy as np
import pytest
import sympy

import kronsub
from kronsub.simulation.fallback import numpy_module
from reference.nonholonomic import kane_rates, sleigh_and_beads_kane

ROOT = Path(__file__).resolve().parent.parent
BEADS = ROOT / "tests" / "models" / "nonholonomic" / "sleigh_and_beads.yaml"
VALUES = {"m": 1.0, "I": 0.05, "a": 0.2, "mp": 0.5, "mq": 0.3, "L": 0.4, "c": 2.0}


@pytest.fixture(scope="module")
def system():
    return kronsub.load(BEADS).derive()


def _height(level: float) -> float:
    """The real root y of ``y + c y^3 = level`` (one: the left side increases)."""
    roots = np.roots([VALUES["c"], 0.0, 1.0, -level])
    return float(roots[np.argmin(np.abs(roots.imag))].real)


def test_rates_against_kanes_method_at_random_states(system):
    assert [d.name for d in system.speeds.dependent] == ["py", "qy"]
    symbols = {n: sympy.Symbol(n, real=True) for n in VALUES}
    q, u, kane, dependent = sleigh_and_beads_kane(*(symbols[n] for n in ("m", "I", "a", "mp", "mq", "L", "c")))
    values = {symbols[n]: v for n, v in VALUES.items()}
    dependent = [e.xreplace(values) for e in dependent]
    numeric = system.numeric()
    assert numeric.state == ("x", "y", "theta", "px", "qx", "py", "qy", "v", "w", "up", "uq")
    module = numpy_module(system)
    param = [numeric.parameters[p.name] for p in system.parameters]
    L, rng = VALUES["L"], np.random.default_rng(37)
    for _ in range(4):
        x, y, theta, px, qx = rng.uniform(-1.0, 1.0, 5)
        py, qy = _height(L * np.sin(px / L)), _height(L * np.cos(qx / L))
        x_dot, theta_dot, px_dot, qx_dot = rng.uniform(-2, 2, 4)
        qv = [x, y, theta, px, qx, py, qy]
        at = {**dict(zip(q, qv)), **dict(zip(u[:4], (x_dot, theta_dot, px_dot, qx_dot)))}
        y_dot, py_dot, qy_dot = (float(e.xreplace(at)) for e in dependent)
        uv = [x_dot, theta_dot, px_dot, qx_dot, y_dot, py_dot, qy_dot]
        x_dd, theta_dd, px_dd, qx_dd, y_dd = kane_rates(kane, q, u, qv, uv, values)[:5]
        v = np.cos(theta) * x_dot + np.sin(theta) * y_dot
        turning = theta_dot * (np.cos(theta) * y_dot - np.sin(theta) * x_dot)
        v_dot = np.cos(theta) * x_dd + np.sin(theta) * y_dd + turning
        expected = [x_dot, y_dot, theta_dot, px_dot, qx_dot, py_dot, qy_dot, v_dot, theta_dd, px_dd, qx_dd]
        for off in (0.0, 0.05):  # the heights put off the wires are solved back first
            state = np.array([x, y, theta, px, qx, py + off, qy - off, v, theta_dot, px_dot, qx_dot])
            for rhs in (numeric.rhs(0.0, state), np.asarray(module["rhs"](0.0, state, param))):
                assert np.allclose(rhs, expected, rtol=1e-11, atol=1e-11)


def test_a_run_keeps_the_energy_the_wires_and_the_knife_edge(system):
    L, c, a = VALUES["L"], VALUES["c"], VALUES["a"]
    run = system.simulate(t=3.0, dt=0.05, rtol=1e-10, atol=1e-10, dataframe=False)
    assert run.complete and any(note.startswith("py 0.04 -> ") for note in run.notes)
    energy = run.kinetic_energy
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * energy[0]
    column = {name: run.y[:, run.columns.index(name)] for name in run.columns}
    wires = [column["py"] + c * column["py"] ** 3 - L * np.sin(column["px"] / L),
             column["qy"] + c * column["qy"] ** 3 - L * np.cos(column["qx"] / L)]
    assert max(np.max(np.abs(w)) for w in wires) < 1e-13
    numeric = system.numeric()
    for row in run.y:
        x_dot, y_dot, theta_dot = numeric.rhs(0.0, row)[:3]
        theta = row[2]
        assert abs(-np.sin(theta) * x_dot + np.cos(theta) * y_dot - a * theta_dot) < 1e-12
    assert np.ptp(column["py"]) > 0.3 and np.ptp(column["qy"]) > 0.3  # the beads travel along their wires
