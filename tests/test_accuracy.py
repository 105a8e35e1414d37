"""``kronsub accuracy``: each method's error falls with its tolerance against exact solutions;
the CSV, the PNG and --target; a reference too coarse to judge the best point is refused."""
from __future__ import annotations

import csv
import dataclasses
import io

import mpmath
import pytest
from click.testing import CliRunner

import kronsub
from conftest import ROOT
from kronsub.cli import main
from kronsub.simulation import accuracy as A
from kronsub.simulation import accuracy_report as report
from kronsub.simulation.methods import by_engine
from kronsub.simulation.reference import Reference
from kronsub.simulation.values import resolve
from conftest import MODELS
from kronsub.simulation import reference as R
from helpers.systems import closed_loop, loaded
from reference.exact import pendulum_exact, spring_chain_exact

TEST_MODELS = ROOT / "tests" / "models"
TOLERANCES = (1e-3, 1e-6, 1e-9)


def exact_reference(values, t_end, exact) -> Reference:
    return Reference([t_end], exact(values, [t_end]), 1e-25, 30, ("exact solution",))


def available_methods():
    from kronsub.simulation import heyoka_backend

    return A.ALL_METHODS if heyoka_backend.available() else by_engine("c") + by_engine("scipy")


@pytest.mark.parametrize("name, exact, t_end", [("spring_chain", spring_chain_exact, 2.0),
                                                ("pendulum", pendulum_exact, 2.0)])
def test_error_falls_with_tolerance_for_every_method(name, exact, t_end):
    model = kronsub.load(TEST_MODELS / f"{name}.yaml")
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    wp = A.measure(system, values, t_end, available_methods(), TOLERANCES,
                   ref=exact_reference(values, t_end, exact), progress=False, budget=0.0, max_repeats=1)
    assert wp.conservative
    for method in available_methods():
        errors = [p.error for p in wp.points if p.method == method]
        assert len(errors) == len(TOLERANCES), method
        assert all(p.ok for p in wp.points if p.method == method), method
        assert errors[0] > errors[1] > errors[2] or errors[2] < 1e-12, (method, errors)
        assert errors[-1] < 1e-6, (method, errors)
        assert errors[0] > 10 * errors[-1] or errors[0] < 1e-10, (method, errors)
    for p in wp.points:  # energy drift is reported and shrinks with the error
        assert p.energy_drift is not None and p.energy_drift < 1.0


def test_closed_loop_error_falls_with_tolerance_against_the_explicit_twin():
    """System II with the constraint (25), measured against a reference of System II in the
    parametric form (26) (another derivation, no constraints): the error over the independent
    state falls with the tolerance; the residuals of g and of G ydot stay at Newton's level;
    methods without a Newton's method are skipped with the reason."""
    settings = {"theta": "0.55", "theta_dot": "0.5"}  # an oscillation clear of the toggle at theta = 0.2
    system, values, dependent = closed_loop(MODELS / "hoffmann" / "system2_implicit.yaml", settings)
    explicit, twin = loaded(MODELS / "hoffmann" / "system2.yaml", settings)
    t_end = 1.0
    ref = R.reference(explicit, twin.parameters, twin.y0, [t_end], digits=12)
    methods = ("dop853", "rk4", "RK45", "taylor", "heyoka", "gbs-quad")
    wp = A.measure(system, values, t_end, methods, TOLERANCES, ref=ref, dependent=dependent,
                   progress=False, budget=0.0, max_repeats=1)
    assert wp.constraints == ("line",) and wp.conservative
    for method in ("dop853", "rk4", "RK45"):
        points = [p for p in wp.points if p.method == method]
        errors = [p.error for p in points]
        assert all(p.ok for p in points) and len(points) == len(TOLERANCES), method
        assert errors[0] > errors[1] > errors[2] and errors[2] < 1e-7, (method, errors)
        for p in points:
            assert 0 <= p.constraint_residual < 1e-10 and 0 <= p.velocity_residual < 1e-10, p
            assert p.energy_drift is not None and p.energy_drift < 10 * p.error + 1e-12, p
    for method in ("taylor", "heyoka", "gbs-quad"):
        assert "explicit equations only" in wp.skipped[method]
    table = report.markdown(wp)
    assert "max \\|g\\|" in table and "Closed loop (line)" in table


def run_cli(*args):
    return CliRunner().invoke(main, ["accuracy", *map(str, args)])


def read_csv_every_way(text: str) -> dict[str, dict]:
    """The accuracy CSV read by each standard reader without options beyond the delimiter:
    reader -> column -> values."""
    import numpy as np

    out = {}
    table = np.genfromtxt(io.StringIO(text), names=True, delimiter=",", dtype=None, encoding="utf-8")
    out["numpy"] = {name: np.atleast_1d(table[name]).tolist() for name in table.dtype.names}
    rows = list(csv.DictReader(io.StringIO(text)))
    out["csv"] = {name: [r[name] for r in rows] for name in rows[0]}
    try:
        import pandas
    except ImportError:
        return out
    frame = pandas.read_csv(io.StringIO(text))
    out["pandas"] = {name: frame[name].tolist() for name in frame.columns}
    return out


def test_cli_writes_table_csv_png_and_names_the_target(tmp_path):
    import json
    import math

    out, png = tmp_path / "wp.csv", tmp_path / "wp.png"
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 2, "--methods", "dop853,rk4,RK45,heyoka",
                     "--tolerances", "1e-3:1e-9:3", "--target", 1e-6, "--quick", "--output", out, "--plot", png)
    assert result.exit_code == 0, result.output
    assert "| dop853 | tol 1e-03 |" in result.output and "| rk4 | h " in result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = out.read_text()
    assert text.startswith("method,tolerance,setting,error,") and "#" not in text  # one header row, then rows
    readers = read_csv_every_way(text)
    for reader, columns in readers.items():
        assert list(columns) == list(report.CSV_COLUMNS), reader
        assert all(float(v) > 0 for v in columns["error"]), reader
        assert all(math.isnan(float(v)) for v in columns["constraint_residual"]), reader  # no constraints here
    rows = list(csv.DictReader(io.StringIO(text)))
    methods = {r["method"] for r in rows}
    assert len(rows) == 3 * len(methods) and methods >= {"dop853", "rk4", "RK45"}  # --quick keeps those given
    line = next(l for l in result.output.splitlines() if l.startswith("Target 1e-06: cheapest is"))
    method, setting = line.split("cheapest is ")[1].split(":")[0].split(" at ")
    chosen = next(r for r in rows if r["method"] == method and r["setting"] == setting)
    assert float(chosen["error"]) <= 1e-6
    def holds(r):  # the target met at this tolerance and at every tighter one of the same method
        return all(float(o["error"]) <= 1e-6 for o in rows if o["method"] == r["method"] and o["status"] == "ok"
                   and float(o["tolerance"]) <= float(r["tolerance"]))
    meeting = [r for r in rows if r["status"] == "ok" and holds(r)]
    assert float(chosen["seconds"]) == min(float(r["seconds"]) for r in meeting)
    # the metadata beside the CSV: the model, the reference and its estimated error, the target
    meta = json.loads((tmp_path / "wp.json").read_text())
    assert meta["format"] == report.METADATA_FORMAT and meta["csv"] == "wp.csv" and meta["t_end"] == 2.0
    assert meta["model"]["name"] == "Simple pendulum" and meta["model"]["file"].endswith("tests/models/pendulum.yaml")
    assert meta["model"]["sha256"] and meta["columns"] == list(report.CSV_COLUMNS)
    reference = meta["reference"]
    assert reference["times"][-1] == 2.0 and reference["sufficient"] is True
    assert 0 <= reference["estimated_error"] < 1e-12 and "Taylor series" in reference["route"]
    model = kronsub.load(TEST_MODELS / "pendulum.yaml")
    exact = pendulum_exact(resolve(model.derive(), dict(model.initial), {}), [2.0])[0]
    with mpmath.workdps(40):
        assert abs(mpmath.mpf(reference["state_at_t_end"]["q"]) - exact[0]) < 1e-20
        assert abs(mpmath.mpf(reference["state_at_t_end"]["q_dot"]) - exact[1]) < 1e-20
    assert meta["target"]["cheapest"] == {"method": method, "setting": setting,
                                          "error": float(chosen["error"]), "seconds": float(chosen["seconds"])}
    if "heyoka" not in methods:
        assert "heyoka" in meta["skipped"]


def test_target_is_not_named_by_chance():
    """On a chaotic model the error scatters from one tolerance to the next: a point that met the
    target while a tighter tolerance of its method did not is not the cheapest, it is named as
    chance; a failed tighter run does not count against a point."""
    def point(method, tol, error, ms, status=""):
        return A.Point(method, tol, f"tol {tol:.0e}", error, None, ms / 1e3, None, 10, 3, status=status)

    ref = Reference([10.0], [[mpmath.mpf(0)]], 1e-20, 30, ("test",))
    points = [point("taylor", 1e-9, 5e-7, 0.12), point("taylor", 3e-10, 2.5e-6, 0.135),
              point("taylor", 1e-10, 2.7e-7, 0.147), point("taylor", 1e-12, 2.6e-9, 0.19),
              point("dop853", 1e-10, 4e-7, 0.6), point("dop853", 1e-12, float("nan"), 0.9, "step limit"),
              point("rk4", 1e-6, 2e-6, 0.05)]
    wp = A.WorkPrecision("test", 10.0, points, ref, None, True)
    best, chance = wp.cheapest(1e-6), wp.by_chance(1e-6)
    assert (best.method, best.tolerance) == ("taylor", 1e-10) and (chance.method, chance.tolerance) == ("taylor", 1e-9)
    sentence = report.target_sentence(wp, 1e-6)
    assert sentence.startswith("Target 1e-06: cheapest is taylor at tol 1e-10: error 2.7e-07 in 0.147 ms, and at "
                               "every tighter tolerance taylor ran at.")
    assert "taylor at tol 1e-09 met it in 0.120 ms (error 5.0e-07), but a tighter tolerance" in sentence
    assert wp._holds(points[4], 5e-7)  # dop853's failed tighter run aside
    assert wp.by_chance(1e-10) is None and wp.cheapest(1e-10) is None
    wp.points = [point("rk4", 1e-6, 1e-8, 0.05), point("rk4", 1e-8, 1e-5, 0.5)]
    assert wp.cheapest(1e-6) is None and wp.by_chance(1e-6).tolerance == 1e-6
    assert report.target_sentence(wp, 1e-6).startswith("Target 1e-06: no method met it at a tolerance and every tighter "
                                                  "one (best error 1.0e-08). rk4 at tol 1e-06 met it")


def test_cli_closed_loop_csv_and_meta(tmp_path):
    """A closed loop through the command line: the residual columns filled, the metadata names the
    constraints and the dependent coordinates at t = 0; --meta chooses the metadata's file."""
    import json

    out, meta_file = tmp_path / "loop.csv", tmp_path / "info" / "loop-meta.json"
    meta_file.parent.mkdir()
    result = run_cli(MODELS / "hoffmann" / "system2_implicit.yaml", "--set", "theta=0.55", "--set", "theta_dot=0.5",
                     "--t", 0.5, "--methods", "dop853,taylor", "--tolerances", "1e-4,1e-8", "--quick",
                     "--output", out, "--meta", meta_file)
    assert result.exit_code == 0, result.output
    assert "max \\|g\\|" in result.output
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [r["method"] for r in rows] == ["dop853", "dop853"]
    assert all(0 <= float(r["constraint_residual"]) < 1e-10 and r["status"] == "ok" for r in rows)
    assert float(rows[1]["error"]) < float(rows[0]["error"])
    meta = json.loads(meta_file.read_text())
    assert meta["csv"] == str(out) and not (tmp_path / "loop.json").exists()
    assert meta["closed_loop"]["constraints"] == ["line"] and set(meta["closed_loop"]["dependent_at_t0"]) == {"phi"}
    assert "explicit equations only" in meta["skipped"]["taylor"]


def test_cli_refuses_to_plot_against_a_coarse_reference(tmp_path, monkeypatch):
    def coarse(system, param, y0, times, digits, dependent=None):
        with mpmath.workdps(30):
            states = pendulum_exact(resolve(system, {}, {"q": "2.5"}), times)
        return Reference(list(times), states, 1e-3, digits, ("a deliberately coarse reference",))

    monkeypatch.setattr(A, "compute_reference", coarse)
    png = tmp_path / "wp.png"
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 1, "--methods", "dop853", "--tolerances", "1e-8",
                     "--plot", png)
    assert result.exit_code == 1
    assert "not 100x below the best point" in result.output
    assert not png.exists()


def test_cli_fails_when_every_point_failed(tmp_path, monkeypatch):
    """A table of failures only is not a measurement: exit 1, the first failure named, the CSV kept."""
    measure = A.measure

    def failing(*args, **kwargs):
        wp = measure(*args, **kwargs)
        wp.points = [dataclasses.replace(p, status="step size too small at t = 0.5") for p in wp.points]
        return wp

    monkeypatch.setattr(A, "measure", failing)
    csv, png = tmp_path / "wp.csv", tmp_path / "wp.png"
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 1, "--methods", "dop853,rk4", "--tolerances", "1e-6,1e-8",
                     "--output", csv, "--plot", png)
    assert result.exit_code == 1, result.output
    assert "every point failed (4 of 4)" in result.output
    assert "dop853 at tol 1e-06: step size too small at t = 0.5" in result.output
    assert csv.read_text().count("failed") == 4 and not png.exists()


def test_a_failed_point_shows_no_measurement(tmp_path, monkeypatch):
    """A point whose run stopped is shown as failed: no error, energy drift or time in the
    table, ``nan`` error and drift in the CSV; the other points keep their numbers."""
    measure = A.measure

    def one_failing(*args, **kwargs):
        wp = measure(*args, **kwargs)
        wp.points[0] = dataclasses.replace(wp.points[0], status="stopped at t = 0.25: step size too small")
        return wp

    monkeypatch.setattr(A, "measure", one_failing)
    csv_path = tmp_path / "wp.csv"
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 1, "--methods", "rk4", "--tolerances", "1e-6,1e-8",
                     "--output", csv_path)
    assert result.exit_code == 0, result.output
    rows = [line for line in result.output.splitlines() if line.startswith("| rk4 |")]
    cells = [[c.strip() for c in row.strip("|").split("|")] for row in rows]
    assert cells[0][2:] == ["failed", "", "", "", "", "stopped at t = 0.25: step size too small"], rows[0]
    assert all(c for c in cells[1][2:7]), rows[1]  # error, drift, time, evaluations, steps measured
    first, second = list(csv.DictReader(io.StringIO(csv_path.read_text())))
    assert first["status"] == "failed" and first["error"] == first["energy_drift"] == "nan"
    assert second["status"] == "ok" and float(second["error"]) < 1e-3


def test_quick_keeps_the_tolerances_given(monkeypatch):
    """``--quick`` thins the default range only: tolerances written out are all run."""
    grids = []
    measure = A.measure

    def spy(system, values, t_end, methods, tolerances, **kwargs):
        grids.append(tuple(tolerances))
        return measure(system, values, t_end, methods, tolerances, **kwargs)

    monkeypatch.setattr(A, "measure", spy)
    given = ["--tolerances", "1e-5,1e-6,1e-7,1e-8"]
    for extra in (given, []):
        result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 0.5, "--methods", "rk4", "--quick", *extra)
        assert result.exit_code == 0, result.output
    assert grids[0] == (1e-5, 1e-6, 1e-7, 1e-8)
    assert grids[1] == A.quick_tolerances(A.parse_tolerances("1e-4:1e-14")) != A.parse_tolerances("1e-4:1e-14")


@pytest.mark.parametrize("args, message", [
    (["--methods", "dop853,rk5"], "unknown method rk5"),
    (["--tolerances", "1e-4:x"], "--tolerances '1e-4:x'"),
    (["--tolerances", "-1"], "positive"),
    (["--set", "nope=1"], "--set nope"),
])
def test_cli_bad_options_are_clear_errors(args, message):
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--quick", *args)
    assert result.exit_code == 1
    assert message in result.output and "Traceback" not in result.output


def test_tolerance_grid():
    assert A.parse_tolerances("1e-4:1e-14") == tuple(10.0 ** -k for k in range(4, 15))
    assert A.parse_tolerances("1e-4:1e-10:3") == (1e-4, 1e-7, 1e-10)
    assert A.parse_tolerances("1e-6,1e-9") == (1e-6, 1e-9)
    assert A.quick_tolerances(A.parse_tolerances("1e-4:1e-14")) == (1e-4, 1e-7, 1e-10, 1e-13, 1e-14)


def test_accuracy_uses_the_library_simulate_built(tmp_path, monkeypatch):
    """The compiled model is looked up by its equations' fingerprint (simulation/compiled.py):
    after a first build, accuracy's runners emit no C at all."""
    import numpy as np

    import kronsub.emitters.code as code
    from kronsub.simulation.compiled import compiled_library

    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    system, values = loaded(MODELS / "examples" / "double_pendulum.yaml")
    compiled_library(system)

    def refuse(*args, **kwargs):
        raise AssertionError("emit_c called again")

    monkeypatch.setattr(code, "emit_c", refuse)
    bench = A.Bench(system, np.array(values.parameters), np.array(values.y0), 0.5)
    assert bench.native is not None and bench.compile_seconds < 5
    y = bench.prepare("dop853", 1e-10).run()[0]
    assert np.all(np.isfinite(y)) and len(y) == len(values.y0)


def test_a_held_coordinate_s_integrated_value_is_no_error(monkeypatch):
    """Under velocity constraints with a configuration constraint beside them (the rolling disc
    whose lean is held by its rim touching the plane), the integrated held coordinate is only
    the starting guess of Newton's method, as in a run's rows: a drift of it changes neither the
    error nor the energy drift `accuracy` reports. The integrator's final lean is pushed off by
    0.05 (far beyond any error here): the figures stay those of the run as it was."""
    model = kronsub.load(TEST_MODELS / "nonholonomic" / "rolling_disc_lean_held.yaml")
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    lean = [q.name for q in system.coordinates].index("lean")
    t_end = 0.5
    ref = R.reference(system, values.parameters, values.y0, [t_end], digits=20)

    def figures():
        wp = A.measure(system, values, t_end, ("dop853",), (1e-6, 1e-10), ref=ref, progress=False, budget=0.0,
                       max_repeats=1)
        return [(p.error, p.energy_drift) for p in wp.points]

    plain = figures()
    prepare = A.Bench.prepare

    def drifted(bench, method, tol):
        timed = prepare(bench, method, tol)

        def run():
            y_end, *rest = timed.run()
            y_end = [float(v) for v in y_end]
            y_end[lean] += 0.05
            return (y_end, *rest)

        return dataclasses.replace(timed, run=run)

    monkeypatch.setattr(A.Bench, "prepare", drifted)
    pushed = figures()
    assert all(e < 1e-4 for e, _ in plain) and plain[1][0] < plain[0][0]
    for (e0, d0), (e1, d1) in zip(plain, pushed):
        assert abs(e1 - e0) <= 1e-9 * max(e0, 1e-12) + 1e-15 and abs(d1 - d0) <= 1e-6 * max(d0, 1e-15) + 1e-15
