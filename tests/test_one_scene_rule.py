"""The rule of the single scene, the same in every command and in the notebook: a model with
exactly one scene uses it unless told otherwise; a run starts from the one route of
starting values (model, scene, overrides; a closed loop's projected onto its constraints).

``tests/models/one_scene.yaml`` has a push whose parameter F has no value: the whole model
cannot be run, its one scene (gravity alone, l = 0.5, q0 = 0.5, t_end 0.2) can."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from conftest import ROOT
from kronsub.cli import main
from kronsub.errors import ModelError

ONE_SCENE = ROOT / "tests" / "models" / "one_scene.yaml"


def cli(*args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result


def both(*args):
    """The command's output without --scene and with --scene swing."""
    return cli(*args).stdout, cli(*args, "--scene", "swing").stdout


def test_derive_uses_the_only_scene():
    plain, named = both("derive", ONE_SCENE, "--format", "json")
    assert plain == named and json.loads(plain)["name"] == "Pendulum with one scene (scene swing)"
    assert set(json.loads(plain)["parameters"]) == {"m", "l", "g"}  # the push (F) is off


def test_codegen_uses_the_only_scene(tmp_path):
    cli("codegen", ONE_SCENE, "--lang", "python", "-o", tmp_path / "a")
    cli("codegen", ONE_SCENE, "--lang", "python", "-o", tmp_path / "b", "--scene", "swing")
    a, b = (tmp_path / "a" / "one_scene.py").read_text(), (tmp_path / "b" / "one_scene.py").read_text()
    assert a == b and "F" not in a.split("PARAMETERS")[1].split("\n")[0]


def test_simulate_uses_the_only_scene():
    plain, named = both("simulate", ONE_SCENE)
    assert plain == named
    rows = plain.splitlines()
    assert rows[0].startswith("t,q,q_dot") and len(rows) == 1 + 5  # t_end 0.2, dt 0.05
    assert float(rows[1].split(",")[1]) == 0.5  # the scene's initial angle


def test_accuracy_uses_the_only_scene(tmp_path):
    meta = tmp_path / "wp.json"
    cli("accuracy", ONE_SCENE, "--t", "0.2", "--methods", "dop853", "--tolerances", "1e-6", "--quick",
        "--meta", meta)
    assert json.loads(meta.read_text())["scene"] == "swing"


def test_animate_model_uses_the_only_scene(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "swing.gif"
    result = cli("animate", ONE_SCENE, "--output", out, "--fps", "20")
    assert out.stat().st_size > 0
    assert "(5 frames)" in result.stderr  # the scene's 0.2 s at 20 frames per second, both ends


def test_linearize_uses_the_only_scene():
    plain, named = both("linearize", ONE_SCENE, "--format", "json")
    assert plain == named
    eigenvalues = json.loads(plain)["eigenvalues"]
    assert max(abs(complex(e["re"], e["im"])) for e in eigenvalues) == pytest.approx(math.sqrt(9.81 / 0.5))


def test_the_notebook_uses_the_only_scene():
    system = kronsub.load(ONE_SCENE).derive()
    run = system.simulate(dataframe=False)
    assert run.t[-1] == 0.2 and run["q"][0] == 0.5 and run.metadata["scene"] == "swing"
    assert system.scene.name == "swing" and system.name.endswith("(scene swing)")
    assert system == kronsub.load(ONE_SCENE).derive(scene="swing")
    assert system.numeric().parameters["l"] == 0.5
    lin = system.linearize()
    assert max(abs(np.linalg.eigvals(np.array(lin.A, dtype=float)))) == pytest.approx(math.sqrt(9.81 / 0.5))


def test_the_notebook_and_the_command_line_run_the_same_rows():
    """``System.simulate()`` gives the numbers of ``kronsub simulate``'s CSV, column by column."""
    text = cli("simulate", ONE_SCENE, "--set", "q=0.3").stdout
    header, *rows = text.splitlines()
    run = kronsub.load(ONE_SCENE).derive().simulate(set={"q": 0.3}, dataframe=False)
    assert run.table_columns == tuple(header.split(","))
    assert np.array_equal(run.table, np.array([[float(x) for x in r.split(",")] for r in rows]))


def test_an_unknown_scene_is_the_command_lines_error():
    with pytest.raises(ModelError) as exc:
        kronsub.load(ONE_SCENE).derive(scene="swnig")
    result = CliRunner().invoke(main, ["derive", str(ONE_SCENE), "--scene", "swnig"])
    assert result.exit_code == 1
    api = exc.value.problems[0].format().splitlines()[0]  # the same problem, each naming the scene as it was given
    assert api.startswith("scene='swnig': ")
    assert result.stderr.splitlines()[0] == "Error: " + api.replace("scene='swnig'", "--scene swnig")
    assert "did you mean 'swing'" in str(exc.value.problems[0].hint)


def test_the_whole_model_is_asked_for_by_name_and_cannot_run():
    """What the rule spares: the whole model (``scene=False``) has the push, whose F has no value."""
    whole = kronsub.load(ONE_SCENE).derive(scene=False)
    assert whole.scene is None and "F" in {p.name for p in whole.parameters}
    with pytest.raises(ModelError, match="no value for parameter F"):
        whole.simulate(t=0.1, dataframe=False)
