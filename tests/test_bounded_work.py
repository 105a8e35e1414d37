"""Small model files finish, or stop at the work budget with a located error (issue 31, section 4).

Each hostile file runs in a subprocess with an address-space limit (2 GiB) and a generous
timeout, so that a regression fails the test rather than hanging or exhausting the machine;
without the fixes each of them runs for minutes, takes all memory or aborts in gmp. The
budget itself (`kronsub.budget`) is tested directly: deterministic counts, placed errors.
"""
from __future__ import annotations

import os
import random
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest
import sympy

from kronsub import budget
from kronsub.core.doubles import complex_value, graph_nodes
from kronsub.core.numeric_jacobian import jacobian
from kronsub.errors import Location

ROOT = Path(__file__).resolve().parents[1]
MEMORY = 2 << 30  # bytes of address space for a run
TIMEOUT = 240  # seconds: far beyond the few seconds the fixed code takes, far below a hang
HEAD = ("name: probe\nparameters: {m: 1, l: 1, a0: 1}\ncomponents:\n"
        "  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}\ncoordinates: [q]\n")


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


def kronsub(*args: str, cwd: Path, cache: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "KRONSUB_CACHE_DIR": str(cache),
           "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-m", "kronsub", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=TIMEOUT, preexec_fn=_limited)


def connected(x: str, y: str = "l*cos(q)", definitions: str = "") -> str:
    return HEAD + definitions + f"connection:\n  x: {x}\n  y: {y}\n"


def nested(template: str, depth: int) -> str:
    text = "q"
    for _ in range(depth):
        text = template.format(text)
    return text


@pytest.fixture
def run(tmp_path):
    def go(text: str, *args: str, name: str = "model.yaml"):
        (tmp_path / name).write_text(text)
        return kronsub(*args, name, cwd=tmp_path, cache=tmp_path / "cache")
    return go


def stopped(result, line: int, column: int | None = None) -> None:
    """A located budget error: exit 1, ``model.yaml:LINE:COL: stopped: ...`` and the hint."""
    assert result.returncode == 1, result.stderr
    where = rf"model\.yaml:{line}:" + (str(column) if column is not None else r"\d+")
    assert re.search(rf"^Error: {where}: stopped: .+ exceeded .*work budget", result.stderr, re.M), result.stderr
    assert "hint: raise the budget with --budget" in result.stderr
    assert "Traceback" not in result.stderr


# -- multiple angles: a connection l*sin(n q) is an ordinary connection -------------------
@pytest.mark.parametrize("n", [20, 1000000])
def test_a_multiple_angle_derives(run, n):
    result = run(connected(f"l*sin({n}*q)"), "derive", "--no-cache")
    assert result.returncode == 0, result.stderr
    assert f"cos({2 * n}*q)" in result.stdout  # kept as a multiple angle, not expanded into powers


def test_a_product_of_powers_of_multiple_angles_derives(run):
    result = run(connected("sin(q)**8*cos(2*q)**8*sin(3*q)**8"), "derive", "--no-cache")
    assert result.returncode == 0, result.stderr


# -- nesting: finishes or stops at the budget, in bounded memory ---------------------------
def test_nested_sines_stop_at_the_budget(run):
    result = run(connected(nested("sin({})", 98)), "derive", "--no-cache", "--budget", "5000000")
    stopped(result, 7)


def test_nested_inverse_tangents_stop_at_the_budget(run):
    result = run(connected(nested("sin(atan2({}, 1))", 12)), "derive", "--no-cache", "--budget", "2000000")
    stopped(result, 7)


def test_check_stops_reading_an_expression_sympy_doubles(run):
    """``check`` does not derive: reading 30 nested ``sin(atan2(...))`` stops at the budget,
    placed at the expression, and nothing after it is read."""
    result = run(connected(nested("sin(atan2({}, 1))", 30)), "check")
    stopped(result, 7, 6)
    assert result.stderr.count("Error:") == 1


def test_exp_nested_six_deep_is_no_crash(run):
    """gmp aborted the process (exit 134) evaluating ``exp(exp(...))`` at a sample point."""
    result = run(connected(nested("exp({})", 6)), "derive", "--no-cache")
    assert result.returncode in (0, 1), result.stderr
    assert "Traceback" not in result.stderr and "internal error" not in result.stderr


# -- definitions and known systems: shared parts counted once ------------------------------
def chain(n: int, step: str) -> str:
    return "definitions:\n" + "".join(f"  a{i}: {step.format(p=f'a{i - 1}')}\n" for i in range(1, n + 1))


@pytest.mark.parametrize("step", ["{p}*{p} + {p}", "{p}*l + {p}*m"])
def test_check_of_definitions_each_using_the_one_before_twice(run, step):
    result = run(connected("a16*sin(q)", definitions=chain(16, step)), "check")
    assert result.returncode == 0, result.stderr
    assert "OK" in result.stdout


def test_definitions_each_using_the_one_before_twice_derive(run):
    result = run(connected("a24*sin(q)", definitions=chain(24, "{p}*l + {p}*m")), "derive", "--no-cache")
    assert result.returncode == 0, result.stderr


def test_printing_a_definition_that_doubles_stops_at_the_budget(run):
    """``sqrt(a*a + a + 1)`` 16 times over: megabytes of printed equations."""
    result = run(connected("a16*sin(q)", definitions=chain(16, "sqrt({p}*{p} + {p} + 1)")), "derive", "--no-cache",
                 "--budget", "5000000")
    stopped(result, 24)


def test_ten_known_systems_each_using_the_one_below_twice(tmp_path):
    (tmp_path / "f0.yaml").write_text("name: f0\nparameters: {m: 1, l: 1}\ncomponents:\n"
                                      "  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}\n"
                                      "coordinates: [p]\nconnection: {x: l*cos(p), y: l*sin(p)}\n")
    for k in range(1, 10):
        (tmp_path / f"f{k}.yaml").write_text(
            f"name: f{k}\nparameters: {{m: 1, l: 1}}\ncomponents:\n"
            f"  a: {{model: f{k - 1}.yaml, parameters: {{l: l*l + l}}}}\n"
            f"  b: {{model: f{k - 1}.yaml, coordinates: {{p: r}}, parameters: {{m: m*m + m}}}}\n"
            "coordinates: [p]\nconnection: {r: p}\n")
    result = kronsub("derive", "f9.yaml", cwd=tmp_path, cache=tmp_path / "cache")
    assert result.returncode == 0, result.stderr


# -- YAML aliases ----------------------------------------------------------------------------
def test_an_alias_bomb_in_a_scene_is_refused(run):
    bomb = "".join(f"  a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]\n" for i in range(1, 9))
    text = (connected("l*sin(q)") + "effects:\n  gravity: {type: gravity, g: 9.81, direction: [0, -1]}\n"
            "lists:\n  a0: &a0 [gravity, gravity, gravity, gravity, gravity, gravity, gravity, gravity, gravity]\n"
            + bomb + "scenes:\n  s: {effects: *a8}\n")
    result = run(text, "check")
    assert result.returncode == 1, result.stderr
    assert re.search(r"^Error: model\.yaml:\d+:\d+: aliases repeat more than 10,000 values", result.stderr, re.M)


# -- the budget option -----------------------------------------------------------------------
def test_budget_option_stops_a_bundled_model_and_more_lets_it_finish(tmp_path):
    model = ROOT / "models" / "hoffmann" / "system1.yaml"
    small = kronsub("derive", "--no-cache", "--budget", "100", str(model), cwd=tmp_path, cache=tmp_path / "c")
    assert small.returncode == 1
    assert re.search(r"system1\.yaml:\d+:\d+: stopped: .* exceeded the work budget of 100 units", small.stderr)
    assert kronsub("derive", "--no-cache", "--budget", "50000000", str(model), cwd=tmp_path,
                   cache=tmp_path / "c").returncode == 0


# -- the budget module -------------------------------------------------------------------------
def test_charges_are_counted_deterministically_and_placed():
    with budget.limited(10) as spent:
        budget.charge(4, "a")
        budget.charge(6, "b")
        assert spent.used == 10
        with pytest.raises(budget.WorkBudgetExceeded) as caught:
            budget.charge(1, "the terms of something")
    error = caught.value
    assert error.what == "the terms of something" and error.location is None
    placed = error.at(Location("m.yaml", 3, 4))
    assert placed.format().startswith("m.yaml:3:4: stopped: the terms of something exceeded the work budget of 10 units")
    assert placed.at(Location("other.yaml", 1, 1)) is placed  # placed once, by the innermost layer
    budget.charge(10 ** 12, "nothing")  # outside a budget nothing is counted


def test_scope_uses_the_active_budget_or_a_default_one():
    with budget.scope() as fresh:
        assert fresh.units == budget.DEFAULT_UNITS
    with budget.limited(5) as outer:
        with budget.scope() as inner:
            assert inner is outer
    assert budget.active() is None


def test_check_refuses_ahead_without_spending():
    with budget.limited(10) as spent:
        budget.check(10, "x")
        with pytest.raises(budget.WorkBudgetExceeded):
            budget.check(11, "x")
        assert spent.used == 0


# -- evaluation in doubles over the graph -----------------------------------------------------
def test_numeric_jacobian_matches_sympy():
    x, y, a = sympy.symbols("x y a", real=True)
    exprs = [x * y ** 3 + sympy.sin(x * y) * a, sympy.atan2(y, x) + sympy.sqrt(x ** 2 + y) + sympy.exp(x) / y,
             sympy.Abs(x - y) * sympy.asin(x / 3) + (x + 1) ** y, sympy.tanh(x) * sympy.log(y) - sympy.cos(x) ** 2]
    rng = random.Random(31)
    for _ in range(5):
        values = {x: rng.uniform(0.1, 0.9), y: rng.uniform(1.1, 1.9), a: rng.uniform(-1, 1)}
        got = jacobian(exprs, [x, y], values)
        for row, e in zip(got, exprs):
            for value, s in zip(row, (x, y)):
                assert value == pytest.approx(complex(e.diff(s).subs(values).evalf()), rel=1e-12, abs=1e-12)


def test_shared_parts_are_evaluated_once():
    q, a = sympy.symbols("q a")
    e = q
    for _ in range(60):  # 2**60 terms when printed; 60 distinct parts
        e = e * a + e * q
    assert len(graph_nodes([e])) < 400
    # e = q (a + q)^60
    assert complex_value(e, {q: 0.5, a: 0.4}) == pytest.approx(0.5 * 0.9 ** 60, rel=1e-12)
    assert jacobian([e], [q], {q: 0.5, a: 0.4})[0][0] == pytest.approx(
        0.9 ** 60 + 60 * 0.5 * 0.9 ** 59, rel=1e-12)


def test_beyond_the_doubles_is_an_overflow_not_an_abort():
    q = sympy.Symbol("q")
    with pytest.raises(OverflowError):
        complex_value(sympy.exp(sympy.exp(sympy.exp(sympy.exp(sympy.exp(q))))), {q: 1.0})


def test_default_budget_grows_with_the_primitive_and_a_given_one_stays():
    with budget.limited() as spent:
        budget.allow_for(budget.GROWS_FROM)  # up to GROWS_FROM coordinates: the default
        assert spent.units == budget.DEFAULT_UNITS
        budget.allow_for(2 * budget.GROWS_FROM)
        assert spent.units == 8 * budget.DEFAULT_UNITS
        budget.allow_for(budget.GROWS_FROM)  # never shrinks
        assert spent.units == 8 * budget.DEFAULT_UNITS
    with budget.limited(1000) as given:
        budget.allow_for(10 * budget.GROWS_FROM)
        assert given.units == 1000


def test_a_large_primitive_widens_the_default_budget_of_the_loader(tmp_path):
    """A chain of 50 rods (150 primitive coordinates) is read under a default budget grown
    for it; the same model under a given budget keeps that budget."""
    from kronsub.model.loader import load_model

    sys.path.insert(0, str(ROOT / "models" / "chain"))
    try:
        from generate import chain_yaml
    finally:
        sys.path.pop(0)
    path = tmp_path / "chain50.yaml"
    path.write_text(chain_yaml(50), encoding="utf-8")
    with budget.limited() as spent:
        load_model(path, cache=False)
        assert spent.units == budget.default_units(150) > budget.DEFAULT_UNITS


def test_a_derivation_in_a_budget_of_its_own_grows_it_as_the_loader_does(tmp_path, monkeypatch):
    """``load(path).derive()`` derives in a fresh default budget (the command reads and derives
    in one): that budget grows with the primitive as the loader's did, so the API and the CLI
    agree on which models they derive. Made small here: a default of half the derivation's
    work, growing from 1 coordinate."""
    import kronsub

    path = tmp_path / "double.yaml"
    path.write_text((ROOT / "models" / "hoffmann" / "system1.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    model = kronsub.load(path, cache=False)
    with budget.limited(10 ** 12) as spent:
        model.derive(scene=False, cache=False)
    work = spent.used
    monkeypatch.setattr(budget, "DEFAULT_UNITS", work // 2)
    with pytest.raises(budget.WorkBudgetExceeded):  # the default, not grown (GROWS_FROM beyond it)
        model.derive(scene=False, cache=False)
    monkeypatch.setattr(budget, "GROWS_FROM", 1)  # grown to (coordinates)^3 times the default
    system = model.derive(scene=False, cache=False)
    assert system.mass_matrix.shape == (2, 2)
    with budget.limited() as grown:
        model.derive(scene=False, cache=False)
    assert grown.units == budget.default_units(len(model.primitive.coordinates)) > budget.DEFAULT_UNITS


def test_a_scenes_derivation_in_the_api_is_bounded_as_the_whole_models(tmp_path, monkeypatch):
    """``load(path).derive(scene=...)`` outside any command derives in a default work budget, as
    ``derive(scene=False)`` does: a scene's derivation (``derive_scene``) is no way around it.
    Made small here: a default of half the scene's derivation's work."""
    import kronsub

    path = tmp_path / "rlc.yaml"
    path.write_text((ROOT / "models" / "electrical" / "series_rlc.yaml").read_text(encoding="utf-8"),
                    encoding="utf-8")
    model = kronsub.load(path, cache=False)
    with budget.limited(10 ** 12) as spent:
        model.derive(scene="discharge", cache=False)
    assert budget.active() is None  # outside any command from here on
    monkeypatch.setattr(budget, "DEFAULT_UNITS", spent.used // 2)
    with pytest.raises(budget.WorkBudgetExceeded):
        model.derive(scene="discharge", cache=False)
    with pytest.raises(budget.WorkBudgetExceeded):
        model.derive(scene=False, cache=False)
    monkeypatch.setattr(budget, "DEFAULT_UNITS", spent.used * 4)
    assert model.derive(scene="discharge", cache=False).mass_matrix.shape == (1, 1)


def test_printing_a_drive_is_under_the_commands_cpu_backstop(tmp_path, monkeypatch):
    """``derive`` prints a prescribed motion's drive terms, which it projects again (``hbar``
    with ``t`` held) and simplifies: work no count sees, so the CPU-time backstop covers the
    printing with the reading and the derivation (a pivot moved as cosines nested 60 deep in ``t``
    ran for many minutes in the printing). Made short here: a backstop of 2 s."""
    from click.testing import CliRunner

    from kronsub.cli import main

    text = (ROOT / "models" / "motion" / "kapitza_pendulum.yaml").read_text(encoding="utf-8")
    path = tmp_path / "deep.yaml"
    path.write_text(text.replace("s: a*cos(w*t)", "s: " + nested("cos({})", 60).replace("q", "t")), encoding="utf-8")
    monkeypatch.setattr(budget, "MIN_SECONDS", 2.0)
    monkeypatch.setattr(budget, "SECONDS_PER_MILLION", 0.0)
    result = CliRunner().invoke(main, ["derive", str(path), "--format", "json", "--no-cache"])
    assert result.exit_code == 1, result.output
    assert f"Error: {path}: stopped: " in result.output and "the 2 s of CPU time of the work budget" in result.output
    assert "Traceback" not in result.output
