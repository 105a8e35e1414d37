"""First-order coordinates (kronsub/core/first_order.py): loops without inductance integrated as a
mixed first/second-order system, checked against the exact solutions of the loop equations
written here from the diagrams (matrix exponentials), the energy balance, the generated C and
numpy against those equations at random states, and the located errors where the velocities
are not determined."""
from __future__ import annotations

import ctypes
import importlib.util
import subprocess

import numpy as np
import pytest
import sympy
from click.testing import CliRunner
from scipy.linalg import expm

import kronsub
from conftest import ROOT
from helpers.circuits import simulated
from kronsub.cli import main
from kronsub.core.first_order import FirstOrderError, first_order
from kronsub.emitters.code import emit_c, emit_python

FOLDER = ROOT / "tests" / "models" / "electrical"
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]


def column(header, rows, name):
    return rows[:, header.index(name)]


def affine_solution(A, b, x0, t):
    """``x(t)`` of ``x' = A x + b`` from ``x0``: the exponential of the augmented matrix."""
    n = len(x0)
    G = np.zeros((n + 1, n + 1))
    G[:n, :n], G[:n, n] = A, b
    return np.array([(expm(G * s) @ np.append(x0, 1.0))[:n] for s in t])


def test_rc_charging_after_a_step_is_the_exponential():
    """``R q' = E H(t - t1) - q/C``: ``q = q0 e^(-t/RC)`` before the step, then
    ``C E + (q(t1) - C E) e^(-(t - t1)/RC)``; the current ``i = q'`` jumps at the step."""
    R, C, E, t1, q0 = 2.0, 0.25, 3.0, 0.3, 0.1
    header, rows = simulated(FOLDER / "rc_step.yaml", "--t", "2", "--dt", "0.05")
    assert header[:3] == ["t", "q", "i"]
    t = column(header, rows, "t")
    q1 = q0 * np.exp(-t1 / (R * C))
    exact = np.where(t < t1, q0 * np.exp(-t / (R * C)), C * E + (q1 - C * E) * np.exp(-(t - t1) / (R * C)))
    current = np.where(t < t1, -exact / (R * C), (E - exact / C) / R)
    assert np.allclose(column(header, rows, "q"), exact, rtol=0, atol=1e-8)
    assert np.allclose(column(header, rows, "i"), current, rtol=0, atol=1e-7)


LADDER = dict(R1=1.0, R2=2.0, R3=0.5, C1=0.5, C2=0.2, C3=1.0, E=2.0)


def ladder_matrices(p=LADDER):
    """The ladder's loop equations from its diagram: ``D q' = e - K q``."""
    D = np.diag([p["R1"], p["R2"], p["R3"]])
    K = np.array([[1 / p["C1"], -1 / p["C1"], 0],
                  [-1 / p["C1"], 1 / p["C1"] + 1 / p["C2"], -1 / p["C2"]],
                  [0, -1 / p["C2"], 1 / p["C2"] + 1 / p["C3"]]])
    e = np.array([p["E"], 0.0, 0.0])
    return np.linalg.solve(D, -K), np.linalg.solve(D, e)


@pytest.mark.parametrize("compiler", ["c", "numpy"])
def test_rc_ladder_is_its_matrix_exponential(compiler, monkeypatch, tmp_path):
    if compiler == "numpy":  # no compiler: the generated numpy module integrates
        monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
        monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    result = CliRunner().invoke(main, ["simulate", str(FOLDER / "rc_ladder.yaml"), "--t", "3", "--dt", "0.1",
                                       "--method", "Radau", "--rtol", "1e-11", "--atol", "1e-12"])
    assert result.exit_code == 0, result.output
    assert ("no C compiler" in result.output) == (compiler == "numpy")
    lines = result.output[result.output.index("t,q1"):].strip().splitlines()
    header, rows = lines[0].split(","), np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    A, b = ladder_matrices()
    t = column(header, rows, "t")
    exact = affine_solution(A, b, np.array([0.2, -0.1, 0.3]), t)
    charges = np.column_stack([column(header, rows, q) for q in ("q1", "q2", "q3")])
    currents = np.column_stack([column(header, rows, i) for i in ("i_1", "i_2", "i_3")])
    assert np.allclose(charges, exact, rtol=0, atol=1e-8)
    assert np.allclose(currents, exact @ A.T + b, rtol=0, atol=1e-7)


RLC_RC = dict(L=0.5, R1=1.0, C1=0.1, R2=3.0, C2=0.05, E=4.0, w=3.0)


def rlc_rc_exact(t, p=RLC_RC):
    """State ``(q1, q2, i1, s, c)`` with the source ``E s``, ``s = sin(w t)``, ``c = cos(w t)``:
    ``L i1' = E s - R1 i1 - (q1 - q2)/C1``, ``R2 q2' = (q1 - q2)/C1 - q2/C2`` (the RC mesh
    has no inductance), ``s' = w c``, ``c' = -w s``: linear, so a matrix exponential."""
    L, R1, C1, R2, C2, E, w = (p[k] for k in ("L", "R1", "C1", "R2", "C2", "E", "w"))
    A = np.array([[0, 0, 1, 0, 0],
                  [1 / (R2 * C1), -(1 / C1 + 1 / C2) / R2, 0, 0, 0],
                  [-1 / (L * C1), 1 / (L * C1), -R1 / L, E / L, 0],
                  [0, 0, 0, 0, w],
                  [0, 0, 0, -w, 0]])
    x = affine_solution(A, np.zeros(5), np.array([0.1, 0.0, 0.5, 0.0, 1.0]), t)
    return x, np.array([A[1] @ xi for xi in x])


def test_rlc_with_an_rc_branch_is_exact_and_balances_its_energy():
    header, rows = simulated(FOLDER / "rlc_rc.yaml", "--t", "2", "--dt", "0.002")
    t = column(header, rows, "t")
    x, i2 = rlc_rc_exact(t)
    assert np.allclose(column(header, rows, "q1"), x[:, 0], rtol=0, atol=1e-8)
    assert np.allclose(column(header, rows, "q2"), x[:, 1], rtol=0, atol=1e-8)
    assert np.allclose(column(header, rows, "i_1"), x[:, 2], rtol=0, atol=1e-8)
    assert np.allclose(column(header, rows, "i_2"), i2, rtol=0, atol=1e-7)
    # the branch currents carry the energy: d(magnetic + electric)/dt = e i1 - R1 i1^2 - R2 i2^2
    p = RLC_RC
    supplied = p["E"] * np.sin(p["w"] * t) * x[:, 2]
    heat = p["R1"] * x[:, 2] ** 2 + p["R2"] * i2 ** 2
    assert np.allclose(column(header, rows, "dissipated_power"), heat, rtol=1e-7, atol=1e-9)
    stored = column(header, rows, "magnetic_energy") + column(header, rows, "electric_energy")
    net = supplied - heat
    work = np.concatenate([[0.0], np.cumsum(np.diff(t) * (net[1:] + net[:-1]) / 2)])
    assert np.allclose(stored - stored[0], work, rtol=0, atol=1e-5)
    assert np.allclose(column(header, rows, "total_energy"), stored, rtol=1e-12, atol=1e-12)


def test_the_solved_velocities_are_the_loop_equations():
    """``first_order`` of the RLC with an RC branch: q2 is first-order, its current the RC
    mesh's equation solved by hand."""
    system = kronsub.load(FOLDER / "rlc_rc.yaml").derive()
    first = first_order(system)
    names = {s.name: s for s in system.mass_matrix.free_symbols | system.forces.free_symbols}
    q1, q2, C1, C2, R2 = (names[k] for k in ("q1", "q2", "C1", "C2", "R2"))
    assert first.indices == (1,)
    assert sympy.simplify(first.velocities[0] - ((q1 - q2) / C1 - q2 / C2) / R2) == 0
    assert first_order(kronsub.load(ROOT / "models" / "electrical" / "series_rlc.yaml").derive()) is None


def _compiled(system, tmp_path):
    for generated in emit_c(system, "model"):
        (tmp_path / generated.name).write_text(generated.text)
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", "libmodel.so", "-lm"],
                   cwd=tmp_path, check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(tmp_path / "libmodel.so"))
    pointer = ctypes.POINTER(ctypes.c_double)
    lib.ks_rhs.argtypes = [ctypes.c_double, pointer, pointer, pointer]
    lib.ks_first_order_velocities.argtypes = [ctypes.c_double, pointer, pointer]

    def rhs(t, y, param):
        y, param, out = (np.ascontiguousarray(a, dtype=float) for a in (y, param, np.zeros(len(y))))
        assert lib.ks_rhs(t, *(a.ctypes.data_as(pointer) for a in (y, param, out))) == 0
        return out

    def velocities(t, y, param):
        y, param = np.array(y, dtype=float), np.ascontiguousarray(param, dtype=float)
        assert lib.ks_first_order_velocities(t, y.ctypes.data_as(pointer), param.ctypes.data_as(pointer)) == 0
        return y

    assert lib.ks_nfirst() == 3
    return rhs, velocities


def test_gauss4_and_the_api_follow_the_ladder():
    """gauss4 (in ``[q; qdot]``: the singular metric has no momentum) at ``dt = 1e-3``, fourth
    order, and the notebook's ``simulate`` with Radau and the exact Jacobian."""
    header, rows = simulated(FOLDER / "rc_ladder.yaml", "--t", "1", "--dt", "0.001", "--method", "gauss4")
    A, b = ladder_matrices()
    t = column(header, rows, "t")
    exact = affine_solution(A, b, np.array([0.2, -0.1, 0.3]), t[::100])
    got = np.column_stack([column(header, rows, q)[::100] for q in ("q1", "q2", "q3")])
    assert np.allclose(got, exact, rtol=0, atol=1e-9)
    run = kronsub.load(FOLDER / "rc_ladder.yaml").derive().simulate(t=1, dt=0.25, method="Radau", dataframe=False,
                                                                   jacobian=True, rtol=1e-11, atol=1e-12)
    times = np.asarray(run["t"])
    exact = affine_solution(A, b, np.array([0.2, -0.1, 0.3]), times)
    assert np.allclose(np.asarray(run["q2"]), exact[:, 1], rtol=0, atol=1e-8)
    assert np.allclose(np.asarray(run["i_2"]), (exact @ A.T + b)[:, 1], rtol=0, atol=1e-7)


def test_generated_c_and_numpy_give_the_ladder_equations(tmp_path):
    """``ydot = [D^-1 (e - K q); 0]``: the charges' rates solved, the velocity slots not
    integrated, at random states and parameters; C built with warnings as errors."""
    system = kronsub.load(FOLDER / "rc_ladder.yaml").derive()
    order = [p.name for p in system.parameters]
    rhs_c, velocities = _compiled(system, tmp_path)
    (python,) = emit_python(system, "model_py")
    (tmp_path / python.name).write_text(python.text)
    spec = importlib.util.spec_from_file_location("model_py", tmp_path / python.name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rng = np.random.default_rng(3)
    for _ in range(20):
        p = {k: rng.uniform(0.5, 2.0) for k in LADDER}
        param = [p[k] for k in order]
        A, b = ladder_matrices(p)
        y = rng.uniform(-1, 1, 6)
        expected = np.concatenate([A @ y[:3] + b, np.zeros(3)])
        for got in (rhs_c(0.7, y, param), module.rhs(0.7, y, np.array(param))):
            assert np.allclose(got, expected, rtol=1e-12, atol=1e-12)
        assert np.allclose(velocities(0.7, y, param)[3:], A @ y[:3] + b, rtol=1e-12, atol=1e-12)


def test_methods_that_take_their_own_series_are_refused():
    result = CliRunner().invoke(main, ["simulate", str(FOLDER / "rc_ladder.yaml"), "--t", "1", "--method", "taylor"])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert "q1, q2, q3 are first-order coordinates" in result.output and "Radau" in result.output


SHARED = """name: shared
parameters: {L: 1, R: 2, C: 1, E: 1}
components:
  coil: {type: inductor, parameters: {inductance: L}, coordinates: [q_L]}
  res: {type: branch, coordinates: [q_R]}
  cap: {type: branch, coordinates: [q_C]}
coordinates: [q1, q2]
connection: {q_L: q1 - q2, q_R: q1, q_C: q2}
effects:
  res: {type: resistor, charge: q_R, resistance: R}
  cap: {type: capacitor, charge: q_C, capacitance: C}
  src: {type: voltage_source, charge: q_R, voltage: E}
"""

TWO_CAPACITORS = """name: unresisted
parameters: {R: 2, C1: 1, C2: 2}
components:
  res: {type: branch, coordinates: [q_R]}
  c1: {type: branch, coordinates: [q_C1]}
  c2: {type: branch, coordinates: [q_C2]}
coordinates: [q1, q2]
connection: {q_R: q1 - q2, q_C1: q1, q_C2: q2}
effects:
  res: {type: resistor, charge: q_R, resistance: R}
  c1: {type: capacitor, charge: q_C1, capacitance: C1}
  c2: {type: capacitor, charge: q_C2, capacitance: C2}
"""


@pytest.mark.parametrize("text, message", [
    (SHARED, "shared.yaml:7:15: the loop (q1 + q2) has resistance but no inductance, and no loop charge runs "
             "through it alone"),
    (TWO_CAPACITORS, "shared.yaml:7:15: the loop (q1 + q2) has no inductance and no resistance"),
])
def test_a_loop_whose_velocity_is_not_determined_is_a_located_error(tmp_path, text, message):
    path = tmp_path / "shared.yaml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1, result.output
    assert message in result.output and "Traceback" not in result.output


def test_zero_rows_without_dissipation_are_refused_naming_the_coordinates():
    """Past the model's check (a textbook component with a zero metric row and no dissipation):
    the derived system's first-order solve names the coordinate."""
    system = kronsub.load(FOLDER / "rc_ladder.yaml").derive()
    bare = type(system)(name="bare", coordinates=system.coordinates, mass_matrix=system.mass_matrix,
                        velocity_terms=system.velocity_terms,
                        effect_forces={k: v for k, v in system.effect_forces.items() if k.startswith("c")})
    with pytest.raises(FirstOrderError, match="coordinates q1, q2, q3 have no inertia and no dissipation"):
        first_order(bare)


def test_linearize_gives_the_loop_equations_in_the_mixed_state():
    """``y = [q1, q2, q1_dot]``: the RLC with an RC branch is linear, so ``A`` is the matrix of
    the hand-written equations (the source's ``E sin(w t)`` is zero at t = 0)."""
    from kronsub.core.linearize import linearize

    system = kronsub.load(FOLDER / "rlc_rc.yaml").derive()
    lin = linearize(system)
    p = RLC_RC
    expected = np.array([[0, 0, 1],
                         [1 / (p["R2"] * p["C1"]), -(1 / p["C1"] + 1 / p["C2"]) / p["R2"], 0],
                         [-1 / (p["L"] * p["C1"]), 1 / (p["L"] * p["C1"]), -p["R1"] / p["L"]]])
    assert [s.name for s in lin.state] == ["q1", "q2", "q1_dot"]
    assert lin.equilibrium and np.allclose(np.asarray(lin.A, dtype=float), expected, rtol=1e-12, atol=1e-12)


def test_linearize_of_a_circuit_without_inductance_is_its_loop_equation():
    """Every loop first-order (the RC circuit): no inductance, so ``y = [q]`` alone, ``A =
    -1/(R C)`` from ``R q_dot = E - q/C`` (the source off at t = 0); it failed inside the
    Jacobian of the empty second-order block."""
    from kronsub.core.linearize import linearize

    system = kronsub.load(FOLDER / "rc_step.yaml").derive()
    lin = linearize(system)
    values = {p.name: float(p.value) for p in system.parameters}
    assert [s.name for s in lin.state] == ["q"]
    assert np.allclose(np.asarray(lin.A, dtype=float), [[-1 / (values["R"] * values["C"])]], rtol=1e-12)


def test_the_accuracy_reference_follows_the_exact_solution():
    """The mpmath reference of ``accuracy`` (its Taylor route through the solved velocities)
    against the matrix exponential."""
    from kronsub.simulation.reference import reference

    system = kronsub.load(FOLDER / "rlc_rc.yaml").derive()
    param = [RLC_RC[p.name] for p in system.parameters]
    times = [0.25, 0.5]
    ref = reference(system, param, [0.1, 0.0, 0.5, 0.0], times, digits=16)
    x, _ = rlc_rc_exact(np.array(times))
    for i in range(len(times)):
        state = ref.at(i)
        assert np.allclose([state[0], state[1], state[2]], x[i, :3], rtol=0, atol=1e-13)


NODE = """name: massless node
parameters: {m: 1, k: 2, c: 0.5}
components:
  node:
    coordinates: [x, y]
    metric: [[m, 0], [0, 0]]
    potential: k*(x - y)**2/2 + k*y**2/2
    dissipation: c*y_dot**2/2
coordinates: [x, y]
initial: {x: 1}
"""


def test_a_massless_node_between_springs_and_a_damper(tmp_path):
    """The same mechanism in mechanics: a mass on a spring to a massless node, held by a second
    spring and a damper, ``m x'' = -k (x - y)``, ``c y' = k (x - y) - k y``; a matrix exponential."""
    path = tmp_path / "node.yaml"
    path.write_text(NODE, encoding="utf-8")
    header, rows = simulated(path, "--t", "2", "--dt", "0.25")
    m, k, c = 1.0, 2.0, 0.5
    A = np.array([[0, 0, 1], [k / c, -2 * k / c, 0], [-k / m, k / m, 0]])
    t = column(header, rows, "t")
    exact = affine_solution(A, np.zeros(3), np.array([1.0, 0.0, 0.0]), t)
    assert np.allclose(column(header, rows, "x"), exact[:, 0], rtol=0, atol=1e-9)
    assert np.allclose(column(header, rows, "y"), exact[:, 1], rtol=0, atol=1e-9)
    assert np.allclose(column(header, rows, "y_dot"), exact @ A[1], rtol=0, atol=1e-8)
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "1", "--set", "c=0"])
    assert result.exit_code != 0 and "Traceback" not in result.output


def test_a_sweep_reports_the_final_currents(tmp_path):
    """The sweep's final velocities of first-order coordinates are solved from each run's final
    state (the state does not integrate them): the ladder's currents at t = 1 for two R1."""
    pd = pytest.importorskip("pandas")
    out = tmp_path / "sweep.parquet"
    result = CliRunner().invoke(main, ["sweep", str(FOLDER / "rc_ladder.yaml"), "--grid", "R1=1:2:2", "--t", "1",
                                       "--rtol", "1e-11", "--atol", "1e-12", "--workers", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = pd.read_parquet(out).sort_values("R1")
    for _, run in table.iterrows():
        A, b = ladder_matrices(LADDER | {"R1": float(run["R1"])})
        exact = affine_solution(A, b, np.array([0.2, -0.1, 0.3]), np.array([1.0]))[0]
        got = [run[f"final_{i}"] for i in ("i_1", "i_2", "i_3")]
        assert np.allclose(got, A @ exact + b, rtol=0, atol=1e-7)
