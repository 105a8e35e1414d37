"""A charge coordinate's velocity is its current, printed and read as ``i_<name>``
(kronsub/core/currents.py, kronsub/model/currents.py): derive, the CSV, the API, codegen,
linearize, ``--set``, ``--at``, ``initial:`` and the model's expressions; the loop equations
checked against those written by hand from the diagram."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from helpers.circuits import CIRCUITS, simulated
from kronsub.cli import main
from kronsub.core.currents import current_name
from kronsub.core.symbols import symbol, velocity_symbol
from kronsub.model.currents import CurrentNameWarning, subspace_charges
from kronsub.model.expressions import parse_expression
from conftest import MODELS


@pytest.mark.parametrize("charge, current", [
    ("qa", "i_a"), ("q1", "i_1"), ("q_L", "i_L"), ("q_L1", "i_L1"), ("q", "i"), ("armature", "i_armature"),
    ("q_", "i_q_"), ("Q1", "i_Q1"), ("i", "i_i"),
])
def test_the_current_of_a_charge_is_named_by_the_rule(charge, current):
    assert current_name(charge) == current


def test_a_generalized_coordinate_is_a_charge_when_it_writes_only_charges():
    qa, qb, x, s, u = (symbol(n) for n in ("qa", "qb", "x", "s", "u"))
    connection = {qa: s, qb: s - u, x: u}  # s writes two charges; u a charge and a displacement
    assert subspace_charges(connection, [qa, qb], [s, u]) == [s]
    assert subspace_charges({}, [qa], [qa, x]) == [qa]  # no connection: a charge is its own image


def _derive(path, fmt):
    result = CliRunner().invoke(main, ["derive", str(path), "--format", fmt])
    assert result.exit_code == 0, result.output
    return result.stdout


def test_the_ladder_is_printed_in_its_loop_currents_and_the_json_reads_back():
    """Kron's mesh transformation of the ladder: the loop voltages written from the diagram,
    ``E - R1 i1 - (q1 - q2)/C1`` and ``-R2 i2 - q2/C2 + (q1 - q2)/C1``, read back from the JSON
    in the names it prints."""
    data = json.loads(_derive(CIRCUITS / "rlc_ladder.yaml", "json"))
    assert data["velocities"] == ["i_1", "i_2"]
    assert data["currents"]["q1"] == "i_1" and data["currents"]["q_R1"] == "i_R1"
    names = {n: symbol(n) for n in [*data["coordinates"], *data["velocities"], *data["parameters"], "t"]}
    forces = [parse_expression(e, names) for e in data["forces"]]
    L1, L2, R1, R2, C1, C2, E, q1, q2, i1, i2 = (names[n] for n in ("L1", "L2", "R1", "R2", "C1", "C2", "E", "q1",
                                                                   "q2", "i_1", "i_2"))
    hand = [E - R1 * i1 - (q1 - q2) / C1, -R2 * i2 - q2 / C2 + (q1 - q2) / C1]
    assert all(sympy.simplify(f - h) == 0 for f, h in zip(forces, hand))
    assert sympy.simplify(parse_expression(data["kinetic_energy"], names) - (L1 * i1**2 + L2 * i2**2) / 2) == 0
    primitive = {n: symbol(n) for n in [*data["primitive"]["coordinates"], *data["currents"].values(),
                                        *data["parameters"]]}
    r1 = data["primitive"]["forces"]["r1"][data["primitive"]["coordinates"].index("q_R1")]
    assert parse_expression(r1, primitive) == -primitive["R1"] * primitive["i_R1"]  # the branch's own current
    text = json.dumps(data)
    assert "q1_dot" not in text and "q_R1_dot" not in text


def test_markdown_and_latex_print_currents_and_their_rates():
    md = _derive(CIRCUITS / "rlc_ladder.yaml", "markdown")
    assert "`E - R1*i_1 - (q1 - q2)/C1`" in md and "L1*i_1_dot = " in md
    assert "_dot" not in md.replace("i_1_dot", "").replace("i_2_dot", "")
    tex = _derive(CIRCUITS / "rlc_ladder.yaml", "latex")
    assert "R_{1} i_{1}" in tex and r"\dot{q" not in tex and r"\ddot{q" not in tex


def test_mechanical_coordinates_keep_their_velocities():
    """The magnet's ``charges: [q]``: its current is ``i``, the ball's velocity stays ``y_dot``."""
    system = kronsub.load(CIRCUITS / "magnetic_suspension.yaml").derive()
    assert system.currents == {"q": "i"}
    assert [system.name_of(v) for v in system.velocities] == ["y_dot", "i"]
    assert not kronsub.load(MODELS / "examples" / "double_pendulum.yaml").derive().currents
    assert "currents" not in json.loads(_derive(MODELS / "examples" / "double_pendulum.yaml", "json"))


def test_node_equations_name_the_currents_of_their_charges():
    header, _ = simulated(CIRCUITS / "rlc_ladder_nodes.yaml", "--scene", "step", "--t", "0.01")
    assert header[:5] == ["t", "q_L1", "q_L2", "i_L1", "i_L2"]


def test_set_takes_the_current_by_either_name_and_prints_the_current():
    """``--set i=0.5`` and ``--set q_dot=0.5`` start the same run; a wrong name lists ``i``."""
    by_current = simulated(CIRCUITS / "series_rlc.yaml", "--scene", "step", "--t", "0.05", "--set", "i=0.5")
    by_velocity = simulated(CIRCUITS / "series_rlc.yaml", "--scene", "step", "--t", "0.05",
                            "--set", "q_dot=0.5")
    assert by_current[0] == by_velocity[0] and by_current[0][:3] == ["t", "q", "i"]
    np.testing.assert_array_equal(by_current[1], by_velocity[1])
    assert by_current[1][0, 2] == 0.5
    # L di/dt = E - R i - q/C at t = 0: the slope of the current (10 - 0.5)/0.5
    t, i = by_current[1][:3, 0], by_current[1][:3, 2]
    assert abs((i[1] - i[0]) / (t[1] - t[0]) - 19.0) < 0.2
    result = CliRunner().invoke(main, ["simulate", str(CIRCUITS / "series_rlc.yaml"), "--set", "ii=1"])
    assert result.exit_code != 0 and "'ii'" not in result.output and "--set ii" in result.output
    assert "i" in result.output.split("did you mean", 1)[-1]


MODEL = """\
name: named currents
parameters:
  L: {value: 0.5, unit: H}
  R: {value: 2, unit: ohm}
  {extra}
components:
  coil: {type: inductor, parameters: {inductance: L}, coordinates: [qa]}
coordinates: [qa]
effects:
  drag: {type: generalized_force, coordinate: qa, value: -R*{velocity}}
initial: {{{initial}: 3}}
"""


def _write(tmp_path, name, **fields):
    path = tmp_path / name
    text = MODEL.replace("{extra}", fields.get("extra", "")).replace("{velocity}", fields["velocity"])
    path.write_text(text.replace("{{{initial}: 3}}", "{" + fields["initial"] + ": 3}"))
    return path


@pytest.mark.parametrize("velocity, initial", [("i_a", "i_a"), ("qa_dot", "qa_dot")])
def test_the_model_reads_the_current_by_either_name(tmp_path, velocity, initial):
    """``L di/dt = -R i``: ``i = 3 exp(-R t/L)``, whichever name the model uses."""
    path = _write(tmp_path, "m.yaml", velocity=velocity, initial=initial)
    system = kronsub.load(path, cache=False).derive(cache=False)
    qa = system.coordinates[0]
    assert system.forces[0] == -system.symbol("R") * velocity_symbol(qa)
    assert system.initial[velocity_symbol(qa)] == 3
    assert system.symbol("i_a") is velocity_symbol(qa) and system.symbol("i_a_dot") == system.symbol("qa_ddot")
    run = system.simulate(t=0.5, dt=0.25)
    i = np.asarray(run["i_a"])
    np.testing.assert_allclose(i, 3 * np.exp(-2 / 0.5 * np.asarray(run.index)), rtol=1e-6)


def test_a_current_whose_name_is_taken_keeps_its_velocity_name_with_a_located_warning(tmp_path):
    path = _write(tmp_path, "clash.yaml", velocity="qa_dot", initial="qa_dot", extra="i_a: {value: 1}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        system = kronsub.load(path, cache=False).derive(cache=False)
    messages = [str(w.message) for w in caught if issubclass(w.category, CurrentNameWarning)]
    assert len(messages) == 1 and str(path) in messages[0] and "'i_a'" in messages[0]
    assert ":8:" in messages[0]  # at `coordinates: [qa]`, line 8
    assert [system.name_of(v) for v in system.velocities] == ["qa_dot"]
    assert json.loads(_derive(path, "json"))["velocities"] == ["qa_dot"]


def test_codegen_and_linearize_name_the_currents(tmp_path):
    code = CliRunner().invoke(main, ["codegen", str(CIRCUITS / "series_rlc.yaml"), "--lang", "python",
                                     "-o", str(tmp_path)])
    assert code.exit_code == 0, code.output
    assert 'STATE = ["q", "i"]' in (tmp_path / "series_rlc.py").read_text()
    lin = CliRunner().invoke(main, ["linearize", str(CIRCUITS / "series_rlc.yaml"), "--format", "json"])
    data = json.loads(lin.output)
    assert data["state"] == ["q", "i"]
    # L q'' + R q' + q/C = 0: A = [[0, 1], [-1/(L C), -R/L]] = [[0, 1], [-100, -2]]
    np.testing.assert_allclose(data["A"], [[0, 1], [-100, -2]], rtol=1e-12)


TEXTBOOK = """\
name: textbook coil
parameters:
  L: {value: 0.5}
  R: {value: 2}
components:
  coil:
    coordinates: [q]
    charges: [q]
    metric: [[L]]
    dissipation: R*i**2/2
coordinates: [q]
initial: {i: 3}
"""


def test_a_textbook_dissipation_names_its_charges_current(tmp_path):
    """Rayleigh's ``R i^2/2`` of the coil's own ``charges: [q]``: ``L di/dt = -R i``."""
    path = tmp_path / "coil.yaml"
    path.write_text(TEXTBOOK)
    system = kronsub.load(path, cache=False).derive(cache=False)
    i = system.symbol("i")
    assert i is system.symbol("q_dot") and system.forces[0] == -system.symbol("R") * i
    md = _derive(path, "markdown")
    assert "`L*i_dot = -R*i`" in md


def test_a_sweep_takes_the_current_by_its_name(tmp_path):
    """The series RLC from ``q = 0`` and two starting currents: ``y' = A y + b`` with
    ``A = [[0, 1], [-1/(L C), -R/L]]``, ``b = [0, E/L]``, at ``t = 0.1``; the velocity's
    other name is refused with the current's."""
    pd = pytest.importorskip("pandas")
    from scipy.linalg import expm

    out = tmp_path / "sweep.parquet"
    args = ["sweep", str(CIRCUITS / "series_rlc.yaml"), "--t", "0.1", "--rtol", "1e-11", "--atol", "1e-12",
            "--workers", "1", "-o", str(out)]
    result = CliRunner().invoke(main, [*args, "--grid", "i=0:1:2", "--summary", "final(R*i**2)"])
    assert result.exit_code == 0, result.output
    L, R, C, E = 0.5, 1.0, 0.02, 10.0
    M = np.zeros((3, 3))
    M[0, 1], M[1, 0], M[1, 1], M[1, 2] = 1, -1 / (L * C), -R / L, E / L  # [q, i, 1]
    for _, run in pd.read_parquet(out).sort_values("i").iterrows():
        q, i, _ = expm(M * 0.1) @ np.array([0.0, float(run["i"]), 1.0])
        assert np.allclose([run["final_q"], run["final_i"]], [q, i], rtol=0, atol=1e-8)
        assert np.isclose(run["final(R*i**2)"], R * i**2, rtol=1e-8)
    refused = CliRunner().invoke(main, [*args[:-1], str(tmp_path / "refused.parquet"), "--grid", "q_dot=0:1:2"])
    assert refused.exit_code != 0 and "it is the current i" in refused.output


def test_a_sweep_plot_labels_charges_in_coulombs_and_currents_in_amperes():
    from kronsub.sweep.plot import label

    system = kronsub.load(CIRCUITS / "dc_motor.yaml").derive()
    assert [label(system, n) for n in ("q", "i", "R")] == ["q [C]", "i [A]", "R [ohm]"]


def test_two_charges_with_one_current_name_keep_them_apart(tmp_path):
    """``qa`` and ``q_a`` would both be ``i_a``: the first takes it, the second keeps ``q_a_dot``."""
    path = tmp_path / "two.yaml"
    path.write_text("""\
name: two coils
parameters:
  L: {value: 0.5}
components:
  one: {type: inductor, parameters: {inductance: L}, coordinates: [qa]}
  two: {type: inductor, parameters: {inductance: L}, coordinates: [q_a]}
coordinates: [qa, q_a]
""")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        system = kronsub.load(path, cache=False).derive(cache=False)
    assert [system.name_of(v) for v in system.velocities] == ["i_a", "q_a_dot"]
    assert sum(issubclass(w.category, CurrentNameWarning) for w in caught) == 1
