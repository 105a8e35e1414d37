"""``kronsub accuracy``: each method's error falls with its tolerance against exact solutions;
the CSV, the PNG and --target; a reference too coarse to judge the best point is refused."""
from __future__ import annotations

import csv
import io

import mpmath
import pytest
from click.testing import CliRunner

import kronsub
from conftest import ROOT
from kronsub.cli import main
from kronsub.simulation import accuracy as A
from kronsub.simulation.reference import Reference
from kronsub.simulation.values import resolve
from conftest import MODELS
from kronsub.simulation import reference as R
from test_reference import closed_loop, loaded, pendulum_exact, spring_chain_exact

TEST_MODELS = ROOT / "tests" / "models"
TOLERANCES = (1e-3, 1e-6, 1e-9)


def exact_reference(values, t_end, exact) -> Reference:
    return Reference([t_end], exact(values, [t_end]), 1e-25, 30, ("exact solution",))


def available_methods():
    from kronsub.simulation import heyoka_backend

    return A.ALL_METHODS if heyoka_backend.available() else A.NATIVE + A.SCIPY


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
    table = A.markdown(wp)
    assert "max \\|g\\|" in table and "Closed loop (line)" in table


def run_cli(*args):
    return CliRunner().invoke(main, ["accuracy", *map(str, args)])


def test_cli_writes_table_csv_png_and_names_the_target(tmp_path):
    out, png = tmp_path / "wp.csv", tmp_path / "wp.png"
    result = run_cli(TEST_MODELS / "pendulum.yaml", "--t", 2, "--methods", "dop853,rk4,RK45",
                     "--tolerances", "1e-3:1e-9:3", "--target", 1e-6, "--quick", "--output", out, "--plot", png)
    assert result.exit_code == 0, result.output
    assert "| dop853 | tol 1e-03 |" in result.output and "| rk4 | h " in result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader(io.StringIO("".join(l for l in out.read_text().splitlines(True)
                                                   if not l.startswith("#")))))
    assert len(rows) == 6  # --quick: the first and the last of the three tolerances
    line = next(l for l in result.output.splitlines() if l.startswith("Target 1e-06: cheapest is"))
    method, setting = line.split("cheapest is ")[1].split(":")[0].split(" at ")
    chosen = next(r for r in rows if r["method"] == method and r["setting"] == setting)
    assert float(chosen["error"]) <= 1e-6
    meeting = [r for r in rows if float(r["error"]) <= 1e-6 and not r["status"]]
    assert float(chosen["seconds"]) == min(float(r["seconds"]) for r in meeting)


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
