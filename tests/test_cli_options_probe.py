"""Every command's options under hostile and edge values: the bad-input contract.

Bad input gets exit code 1 (input) or 2 (usage) and an ``Error:`` that names the option
or file and what was expected, never exit 4 ("internal error"), a traceback or a hang;
an output never replaces the model or another output of the same run; edge values that
are valid (a run shorter than its --dt, a --t far below 1e-12) give complete output.
Each case runs in a fresh folder holding ``m.yaml`` (Hoffmann's system I) and the
damaged files it needs.
"""
from __future__ import annotations

import csv
import io
import os
import shutil

import pytest
from click.testing import CliRunner

from conftest import MODELS
from helpers.deadline import within
from kronsub.cli import main

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
FOUR_BAR = MODELS / "examples" / "four_bar.yaml"
LIMIT = 60  # seconds: far above a normal run, far below a hang

POINTS_CSV = "t,a.x,a.y\n0.0,0.0,-1.0\n0.1,0.1,-0.99\n0.2,0.2,-0.98\n"


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """A working folder with the model and the hostile files of the cases."""
    shutil.copy(SYSTEM1, tmp_path / "m.yaml")
    shutil.copy(FOUR_BAR, tmp_path / "loop.yaml")
    (tmp_path / "binary.md").write_bytes(b"ok\n\xff\xfe\x00 not text")
    os.mkfifo(tmp_path / "fifo.md")
    os.mkfifo(tmp_path / "fifo.csv")
    (tmp_path / "dir").mkdir()
    (tmp_path / "points.csv").write_text(POINTS_CSV)
    rows = POINTS_CSV.splitlines()
    (tmp_path / "truncated.csv").write_text("\n".join(rows[:2] + [rows[2][:7]]) + "\n")
    (tmp_path / "nan.csv").write_text(POINTS_CSV.replace("0.1,0.1", "0.1,nan"))
    (tmp_path / "words.csv").write_text(POINTS_CSV.replace("0.1,0.1", "0.1,abc"))
    (tmp_path / "backwards.csv").write_text(POINTS_CSV.replace("0.2,0.2", "0.05,0.2"))
    (tmp_path / "repeated.csv").write_text(POINTS_CSV.replace("0.2,0.2", "0.1,0.2"))
    (tmp_path / "header.csv").write_text(rows[0] + "\n")
    (tmp_path / "empty.csv").write_text("")
    (tmp_path / "binary.csv").write_bytes(b"t,a.x,a.y\n0,\xff,1\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def invoke(*args: str):
    with within(LIMIT, "kronsub " + " ".join(args)):
        return CliRunner().invoke(main, list(args))


def assert_clear(result, code: int, *fragments: str) -> None:
    """Exit ``code``, an ``Error:`` naming every fragment, and no sign of a crash."""
    text = result.output
    assert result.exit_code == code, text
    assert "Traceback" not in text and "internal error" not in text, text
    assert "Error:" in text, text
    for fragment in fragments:
        assert fragment in text, (fragment, text)


BAD = [
    # simulate: times and tolerances
    (["simulate", "m.yaml", "--t", "0"], 2, ["--t", "positive finite"]),
    (["simulate", "m.yaml", "--t", "-1"], 2, ["--t", "positive finite"]),
    (["simulate", "m.yaml", "--t", "nan"], 2, ["--t", "positive finite"]),
    (["simulate", "m.yaml", "--t", "inf"], 2, ["--t", "positive finite"]),
    (["simulate", "m.yaml", "--t", "1e308"], 2, ["--t", "rows"]),
    (["simulate", "m.yaml", "--t", ""], 2, ["--t", "not a valid float"]),
    (["simulate", "m.yaml", "--t", "0.05", "--dt", "0"], 2, ["--dt", "positive finite"]),
    (["simulate", "m.yaml", "--t", "0.05", "--dt", "1e-300"], 2, ["--dt", "rows"]),
    # absurd times and tolerances are usage errors that give the valid range, not failures at t = 0
    (["simulate", "m.yaml", "--t", "5e-324"], 2, ["--t", "at least 2.23e-308", "(got 5e-324)"]),
    (["simulate", "m.yaml", "--t", "1e-310", "--dt", "1e-311"], 2, ["--t", "at least 2.23e-308"]),
    (["simulate", "m.yaml", "--t", "0.05", "--dt", "5e-324"], 2, ["--dt", "at least 2.23e-308"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "1e-300"], 2, ["--rtol", "from 1e-15 to 1", "round-off"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "2"], 2, ["--rtol", "from 1e-15 to 1"]),
    (["simulate", "m.yaml", "--t", "0.05", "--atol", "1e-300"], 2, ["--atol", "0, or at least 1e-30"]),
    (["simulate", "m.yaml", "--t", "0.05", "--atol", "5e-324"], 2, ["--atol", "at least 1e-30"]),
    # --rtol 0 is refused, not raised quietly to SciPy's floor (nor refused by taylor alone)
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "0"], 2, ["--rtol", "from 1e-15 to 1", "(got 0.0)"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "0", "--method", "Radau"], 2, ["--rtol", "from 1e-15 to 1"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "1e-400"], 2, ["--rtol", "(got 0.0)"]),
    (["animate", "m.yaml", "-o", "a.gif", "--t", "5e-324"], 2, ["--t", "at least 2.23e-308"]),
    # a value that is not a finite number, or a name, in --set
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=nan"], 1, ["--set m1", "'nan' is not a finite number"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=-inf"], 1, ["--set m1", "'inf' is not a finite number"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "theta=Infinity"], 1, ["'Infinity' is not a finite number"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=m2"], 1, ["--set m1", "--set takes a constant"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "-1"], 2, ["--rtol", "from 1e-15 to 1", "(got -1.0)"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "nan"], 2, ["--rtol", "finite"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "inf"], 2, ["--rtol", "finite"]),
    (["simulate", "m.yaml", "--t", "0.05", "--atol", "-1e-9"], 2, ["--atol", "at least 0"]),
    (["simulate", "m.yaml", "--t", "0.05", "--rtol", "0", "--atol", "0"], 2, ["--rtol", "from 1e-15 to 1"]),
    (["simulate", "m.yaml", "--t", "0.05", "--method", "RK45", "--rtol", "-1"], 2, ["--rtol"]),
    (["simulate", "m.yaml", "--method", "euler"], 2, ["unknown method 'euler'", "dop853"]),
    (["simulate", "m.yaml", "--method", ""], 2, ["unknown method ''"]),
    (["simulate", "loop.yaml", "--t", "0.05", "--method", "taylor"], 1, ["taylor", "explicit equations"]),
    # --set
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1"], 1, ["--set 'm1'", "name=value"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "=2"], 1, ["--set '=2'", "name=value"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "zz=1"], 1, ["--set zz", "no parameter"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "y=1"], 1, ["--set y", "no parameter"]),  # a primitive coordinate
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=abc"], 1, ["--set m1", "unknown name 'abc'"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=2*a1"], 1, ["--set m1", "unknown name 'a1'"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=nan"], 1, ["--set m1"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=1e999"], 1, ["--set m1", "too large"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=__import__('os')"], 1, ["--set m1", "unknown function"]),
    (["simulate", "m.yaml", "--t", "0.05", "--set", "m1=1", "--set", "m1=2"], 1, ["--set m1", "given twice"]),
    (["simulate", "m.yaml", "--t", "0.05", "--scene", "nope"], 1, ["--scene nope", "free, pushed"]),
    # outputs
    (["simulate", "m.yaml", "--t", "0.05", "-o", "m.yaml"], 2, ["--output m.yaml", "model file itself"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "./m.yaml"], 2, ["--output", "model file itself"]),
    (["simulate", "m.yaml", "--t", "0.05", "--meta", "m.yaml"], 2, ["--meta m.yaml", "model file itself"]),
    (["simulate", "m.yaml", "--t", "0.05", "--plot", "m.yaml"], 2, ["--plot m.yaml", "model file itself"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "o.csv", "--plot", "o.csv"], 2, ["--plot o.csv", "CSV file"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "o.csv", "--meta", "o.csv"], 2, ["--meta o.csv", "CSV file"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "o.csv", "--meta", "p.png", "--plot", "p.png"], 2,
     ["--plot p.png", "metadata file"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "missing/o.csv"], 1, ["missing", "does not exist"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "dir"], 2, ["--output", "is a directory"]),
    (["simulate", "m.yaml", "--t", "0.05", "-o", "/proc/kronsub.csv"], 1, ["/proc/kronsub.csv", "cannot create"]),
    # derive
    (["derive", "m.yaml", "-o", "m.yaml"], 2, ["--output m.yaml", "model file itself"]),
    (["derive", "m.yaml", "--format", "html"], 2, ["--format", "'markdown'"]),
    (["derive", "m.yaml", "--check", "nowhere.md"], 1, ["nowhere.md", "write it first"]),
    (["derive", "m.yaml", "--check", "binary.md"], 1, ["binary.md:2:1", "UTF-8"]),
    (["derive", "m.yaml", "--check", "fifo.md"], 1, ["fifo.md", "named pipe"]),
    (["derive", "m.yaml", "--scene", "nope"], 1, ["--scene nope"]),
    (["derive", "dir"], 2, ["MODEL", "is a directory"]),
    # codegen
    (["codegen", "m.yaml", "--lang", "fortran"], 2, ["--lang", "'c'"]),
    (["codegen", "m.yaml", "--prefix", ""], 2, ["--prefix ''", "C identifier"]),
    (["codegen", "m.yaml", "--prefix", "x;system"], 2, ["--prefix 'x;system'", "C identifier", "x_system"]),
    (["codegen", "m.yaml", "--prefix", "1st"], 2, ["--prefix '1st'", "C identifier"]),
    (["codegen", "m.yaml", "--lang", "python", "--precision", "quad"], 1, ["--precision", "--lang c"]),
    (["codegen", "m.yaml", "-o", "m.yaml"], 2, ["--output", "is a file"]),
    (["codegen", "m.yaml", "-o", "/proc"], 1, ["cannot create a file in /proc"]),
    # accuracy
    (["accuracy", "m.yaml", "--tolerances", "1e-4:"], 1, ["--tolerances '1e-4:'", "1e-4:1e-14"]),
    (["accuracy", "m.yaml", "--tolerances", "a:b"], 1, ["--tolerances 'a:b'"]),
    (["accuracy", "m.yaml", "--tolerances", "1e-4:inf"], 1, ["--tolerances '1e-4:inf'", "below 1"]),
    (["accuracy", "m.yaml", "--tolerances", "1e-300:1e300"], 1, ["--tolerances", "below 1"]),
    (["accuracy", "m.yaml", "--tolerances", "10"], 1, ["--tolerances '10'", "below 1"]),
    (["accuracy", "m.yaml", "--tolerances", ","], 1, ["--tolerances ','"]),
    (["accuracy", "m.yaml", "--tolerances", "1e-4:1e-6:0"], 1, ["--tolerances"]),
    (["accuracy", "m.yaml", "--t", "0"], 2, ["--t", "positive finite"]),
    (["accuracy", "m.yaml", "--t", "nan"], 2, ["--t", "positive finite"]),
    (["accuracy", "m.yaml", "--target", "inf"], 1, ["--target", "positive finite"]),
    (["accuracy", "m.yaml", "--target", "0"], 1, ["--target"]),
    (["accuracy", "m.yaml", "--methods", "rk5"], 1, ["unknown method rk5"]),
    (["accuracy", "m.yaml", "--methods", ","], 1, ["unknown method"]),
    (["accuracy", "m.yaml", "--digits", "5"], 2, ["--digits"]),
    (["accuracy", "m.yaml", "-o", "m.yaml"], 2, ["--output m.yaml", "model file itself"]),
    (["accuracy", "m.yaml", "-o", "w.csv", "--plot", "w.csv"], 2, ["--plot w.csv", "CSV file"]),
    # linearize
    (["linearize", "m.yaml", "--at", "zz=1"], 1, ["'zz'", "not a coordinate"]),
    (["linearize", "m.yaml", "--at", "theta"], 1, ["--at 'theta'", "name=value"]),
    (["linearize", "m.yaml", "--at", "theta=abc"], 1, ["--at theta", "unknown name 'abc'"]),
    (["linearize", "m.yaml", "--at", "theta=1", "--at", "theta=2"], 1, ["--at theta", "given twice"]),
    (["linearize", "m.yaml", "--at", "g=1e308"], 1, ["not finite", "--at"]),
    (["linearize", "m.yaml", "--inputs", "theta"], 1, ["input 'theta'", "not a parameter"]),
    (["linearize", "m.yaml", "--inputs", "F,F"], 2, ["--inputs", "F more than once"]),
    (["linearize", "m.yaml", "-o", "m.yaml"], 2, ["--output m.yaml", "model file itself"]),
    (["linearize", "loop.yaml", "--at", "theta2=5"], 1, ["'theta2' is a dependent coordinate"]),
    # animate
    (["animate", "m.yaml", "-o", "m.yaml"], 2, ["--output m.yaml", "model file itself"]),
    (["animate", "m.yaml", "-o", "a.gif", "--t", "0"], 2, ["--t", "positive finite"]),
    (["animate", "m.yaml", "-o", "a.gif", "--dt", "nan"], 2, ["--dt", "positive finite"]),
    (["animate", "m.yaml", "-o", "a.gif", "--method", "euler"], 2, ["unknown method 'euler'"]),
    (["animate", "m.yaml", "-o", "a.gif", "--t", "1e308"], 2, ["--t", "rows"]),
    (["animate", "points.csv", "-o", "a.gif", "--t", "5", "--set", "m1=3"], 2, ["--t, --set", "MODEL"]),
    (["animate", "truncated.csv", "-o", "a.gif"], 1, ["truncated.csv:3:1", "2 values, the header 3 columns", "truncated"]),
    (["animate", "nan.csv", "-o", "a.gif"], 1, ["nan.csv:3:5", "column 'a.x'", "finite number"]),
    (["animate", "words.csv", "-o", "a.gif"], 1, ["words.csv:3:5", "'abc'"]),
    (["animate", "backwards.csv", "-o", "a.gif"], 1, ["backwards.csv:4:1", "does not increase"]),
    (["animate", "repeated.csv", "-o", "a.gif"], 1, ["repeated.csv:4:1", "does not increase"]),
    (["animate", "header.csv", "-o", "a.gif"], 1, ["header.csv", "no rows"]),
    (["animate", "empty.csv", "-o", "a.gif"], 1, ["empty.csv", "column 't'"]),
    (["animate", "binary.csv", "-o", "a.gif"], 1, ["binary.csv:2:3", "UTF-8"]),
    (["animate", "fifo.csv", "-o", "a.gif"], 1, ["fifo.csv", "named pipe"]),
    (["animate", "nowhere.csv", "-o", "a.gif"], 1, ["nowhere.csv"]),
    (["animate", "points.csv", "-o", "a.txt"], 2, ["--output a.txt", ".gif or .mp4"]),
    # new
    (["new", "m"], 1, ["m.yaml exists", "never overwrites"]),
    (["new", ""], 2, ["NAME", "no usable file name"]),
    (["new", "."], 2, ["NAME", "no usable file name"]),
    (["new", "a\nb"], 2, ["NAME", "\\n"]),
    (["new", "x", "--links", "5"], 2, ["--links", "--from chain"]),
    (["new", "missing/x"], 1, ["missing", "does not exist"]),
    (["new", "/proc/x"], 1, ["/proc/x.yaml", "cannot create"]),
    (["new", "x", "--links", "0", "--from", "chain"], 2, ["--links"]),
    # the rest
    (["components", "zz"], 1, ["no component type, effect type or joint 'zz'"]),
    (["components", "rod", "--format", "xml"], 2, ["--format"]),
    (["check", "nowhere.yaml"], 1, ["nowhere.yaml", "file not found"]),
    (["check", "fifo.md"], 1, ["fifo.md", "named pipe"]),
    (["check", "binary.md"], 1, ["binary.md", "UTF-8"]),
    (["cache", "nuke"], 2, ["No such command 'nuke'"]),
]


@pytest.mark.parametrize("args, code, fragments", BAD, ids=[" ".join(a)[:60] for a, _, _ in BAD])
def test_bad_input_is_a_clear_error(folder, args, code, fragments):
    model = (folder / "m.yaml").read_bytes()
    before = sorted(p.name for p in folder.iterdir())
    result = invoke(*args)
    assert_clear(result, code, *fragments)
    assert (folder / "m.yaml").read_bytes() == model  # the model is never replaced
    after = sorted(p.name for p in folder.iterdir())
    assert after == before, "an error left files behind"  # no partial output, no temporary files


def test_codegen_never_writes_over_a_model_of_the_generated_name(folder):
    """A model named like a generated file (system.py with --lang python) is not replaced."""
    shutil.copy(SYSTEM1, folder / "system.py")
    result = invoke("codegen", "system.py", "--lang", "python", "-o", ".")
    assert_clear(result, 2, "system.py", "model file itself")
    assert (folder / "system.py").read_bytes() == SYSTEM1.read_bytes()


def rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))[1:]


@pytest.mark.parametrize("method", ["dop853", "gauss4", "RK45"])
@pytest.mark.parametrize("t_end, dt, times", [
    ("1e-17", "2e-18", ["0.0", "2e-18", "4e-18", "6e-18", "8e-18", "1e-17"]),  # below 1e-12: once only t = 0
    ("1e-300", "0.01", ["0.0", "1e-300"]),
    ("0.05", "1", ["0.0", "0.05"]),  # --dt larger than --t
    ("0.030000001", "0.01", ["0.0", "0.01", "0.02", "0.030000001"]),  # t_end within 1e-7 dt of a row is that row
    ("0.0300001", "0.01", ["0.0", "0.01", "0.02", "0.03", "0.0300001"]),
])
def test_edge_times_give_every_row(folder, method, t_end, dt, times):
    """Rows at every --dt and at --t, each once, labelled with its time: valid edge values
    are complete output (an earlier version kept only t = 0 below 1e-12 and said complete)."""
    result = invoke("simulate", "m.yaml", "--t", t_end, "--dt", dt, "--method", method, "-o", "o.csv")
    assert result.exit_code == 0, result.output
    table = rows((folder / "o.csv").read_text())
    assert [r[0] for r in table] == times
    assert '"complete": true' in (folder / "o.json").read_text()
    # the last row is the state at t_end: as far from the start as the full run says
    reference = invoke("simulate", "m.yaml", "--t", t_end, "--dt", t_end, "--method", "dop853")
    assert reference.exit_code == 0, reference.output
    assert float(table[-1][1]) == pytest.approx(float(rows(reference.stdout)[-1][1]), rel=1e-6)  # gauss4: one fixed step


def test_a_new_model_hint_is_quoted_for_the_shell(folder):
    result = invoke("new", "a;b")
    assert result.exit_code == 0, result.output
    assert "kronsub check 'a;b.yaml'" in result.output
    assert (folder / "a;b.yaml").is_file()


def test_animate_reads_a_good_trajectory_with_points(folder):
    pytest.importorskip("matplotlib")
    result = invoke("animate", "points.csv", "-o", "a.gif", "--fps", "10")
    assert result.exit_code == 0, result.output
    assert (folder / "a.gif").stat().st_size > 0


def test_a_moving_operating_point_says_why_it_is_no_equilibrium(folder):
    """At rest q is an equilibrium, but not with qdot != 0: the warning names the velocity
    (it used to print `qddot = 0, 0` as the reason)."""
    result = invoke("linearize", "m.yaml", "--at", "theta=0", "--at", "phi=0", "--at", "theta_dot=1")
    assert result.exit_code == 0, result.output
    assert "not an equilibrium (qdot is not 0: theta_dot=1)" in result.output


@pytest.mark.parametrize("value", ["nan", "NaN", "inf", "-inf", "oo"])
def test_a_value_that_is_not_finite_is_not_a_name_to_declare(folder, value):
    """``--set m1=nan``: the value must be a finite number; nothing suggests declaring a parameter."""
    result = invoke("simulate", "m.yaml", "--t", "0.05", "--set", f"m1={value}")
    assert_clear(result, 1, "is not a finite number", "finite real number")
    assert "declare" not in result.output


def test_tolerances_and_times_at_the_edges_of_their_ranges_run(folder):
    for args in (["--rtol", "1e-15", "--atol", "1e-10"],
                 ["--rtol", "1", "--atol", "1e-10"], ["--t", "1e-300", "--dt", "1e-300"]):
        result = invoke("simulate", "m.yaml", "--t", "0.05", *args)
        assert result.exit_code == 0, (args, result.output)


def test_animate_runs_a_model_as_long_as_simulate_does(folder, monkeypatch):
    """Without --t, ``animate MODEL`` simulates to the end time ``simulate`` uses (the drawing
    itself is left out: only the run's length is compared)."""
    import json

    import kronsub.simulation.animate as drawing

    drawn = []
    monkeypatch.setattr(drawing, "animate", lambda t, *args, **kwargs: drawn.append(t[-1]) or 1)
    result = invoke("animate", "m.yaml", "--output", "m.gif")
    assert result.exit_code == 0, result.output
    result = invoke("simulate", "m.yaml", "--dt", "0.5", "--output", "run.csv")
    assert result.exit_code == 0, result.output
    assert drawn == [json.loads((folder / "run.json").read_text())["t_end"]]
