"""The trajectory CSV is plain (standard readers take it without options) and its numbers
round-trip exactly; the run's metadata is a JSON sidecar."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main
from kronsub.simulation.grid import Grid
from kronsub.simulation.run import simulate
from kronsub.simulation.table import format_rows, sidecar_path, trajectory_csv
from kronsub.simulation.values import resolve

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
# doubles whose short and 17-digit forms differ, extremes, signed zero, non-finite
AWKWARD = [0.1 + 0.2, 1 / 3, 2 / 3, 1e-300, 5e-324, -0.0, 1.7976931348623157e308, 123456789.12345679,
           -2.5e-17, 0.03]


def _trajectory(t_end=0.5):
    model = kronsub.load(SYSTEM1)
    system = model.derive()
    values = resolve(system, dict(model.initial), {"F": "0.3"})
    traj = simulate(system, values, t_end, 0.01, "dop853", progress=False)
    return system, values, traj


def _readers(text: str) -> dict[str, dict[str, np.ndarray]]:
    """The CSV read by each standard reader (no options beyond the delimiter numpy needs)."""
    out = {}
    table = np.genfromtxt(io.StringIO(text), names=True, delimiter=",", deletechars="", dtype=float)
    out["numpy"] = {name: np.atleast_1d(table[name]) for name in table.dtype.names}
    rows = list(csv.DictReader(io.StringIO(text)))
    out["csv"] = {name: np.array([float(row[name]) for row in rows]) for name in rows[0]}
    try:
        import pandas
    except ImportError:  # pandas is in the test extra; a bare install still runs the other two
        pass
    else:
        # pandas 3 parses round-trip by default; older ones need the option (deprecated in 3)
        options = {} if int(pandas.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
        frame = pandas.read_csv(io.StringIO(text), **options)
        out["pandas"] = {name: frame[name].to_numpy(dtype=float) for name in frame.columns}
    return out


def test_every_reader_gets_back_the_exact_doubles():
    system, values, traj = _trajectory()
    text = trajectory_csv(system, "system1.yaml", traj, values, 1e-10, 1e-10)[0]
    assert not any(line.startswith("#") for line in text.splitlines())
    names = ["t"] + [q.name for q in system.coordinates] + [v.name for v in system.velocities]
    readers = _readers(text)
    assert set(readers) >= {"numpy", "csv"}
    for reader, columns in readers.items():
        assert list(columns)[: len(names)] == names, reader
        assert np.array_equal(columns["t"], traj.t), reader
        got = np.column_stack([columns[n] for n in names[1:]])
        assert np.array_equal(got, traj.y), reader  # bit for bit, not approximately


def test_pandas_reads_it_without_options():
    pandas = pytest.importorskip("pandas")
    system, values, traj = _trajectory()
    frame = pandas.read_csv(io.StringIO(trajectory_csv(system, "m.yaml", traj, values, 1e-10, 1e-10)[0]))
    assert list(frame.columns[:5]) == ["t", "theta", "phi", "theta_dot", "phi_dot"]
    assert frame.shape[0] == len(traj.t) and frame.dtypes.map(lambda d: d.kind == "f").all()
    # pandas before 3 parses to within an ulp by default (exactly with float_precision="round_trip")
    np.testing.assert_allclose(frame["t"].to_numpy(), traj.t, rtol=1e-15, atol=0)


def test_numbers_are_written_in_shortest_round_trip_form():
    data = np.array([AWKWARD, [float("nan"), float("inf"), -float("inf")] + AWKWARD[3:]])
    text = format_rows(data)
    back = np.array([[float(v) for v in line.split(",")] for line in text.splitlines()])
    assert np.array_equal(back, data, equal_nan=True)
    assert np.array_equal(np.signbit(back), np.signbit(data))
    cells = text.splitlines()[0].split(",")
    assert cells[0] == "0.30000000000000004" and cells[-1] == "0.03" and cells[5] == "-0.0"
    for cell in cells:  # no shorter decimal gives the same double: the shortest form
        digits = cell.lstrip("-").split("e")[0].replace(".", "").strip("0")
        if len(digits) > 1:
            shorter = float(f"{float(cell):.{len(digits) - 2}e}")
            assert shorter != float(cell), cell


@pytest.mark.parametrize("dt, t_end", [(0.01, 1.0), (0.1, 3.0), (0.001, 0.05), (0.25, 2.0), (0.03, 0.5)])
def test_output_times_are_the_decimals_of_the_grid(dt, t_end):
    from decimal import Decimal

    grid = Grid(t_end, dt)
    times = grid[0:len(grid)]
    for k, t in enumerate(times[:-1]):
        assert t == float(Decimal(repr(dt)) * k)  # the double nearest the decimal k dt
    assert times[-1] == t_end
    assert np.array_equal(Grid(np.float64(t_end), np.float64(dt))[0:len(grid)], times)  # numpy scalars too
    assert np.array_equal(grid.snap(times + 1e-9 * dt * np.sign(np.arange(len(times)) % 2 - 0.5)), times)


def test_the_command_writes_plain_csv_and_a_sidecar(tmp_path):
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.1", "--dt", "0.01", "-o", str(out),
                                       "--set", "F=0.3"])
    assert result.exit_code == 0, result.output
    text = out.read_text()
    lines = text.splitlines()
    assert lines[0].startswith("t,theta,phi,") and [line.split(",")[0] for line in lines[1:5]] == \
        ["0.0", "0.01", "0.02", "0.03"]
    system, values, traj = _trajectory(0.1)
    cli = _readers(text)["csv"]
    assert np.array_equal(cli["theta"], traj.y[:, 0])  # the same doubles as the API's run
    meta = json.loads(sidecar_path(out).read_text())
    assert meta["csv"] == "run.csv" and meta["status"] == "complete" and meta["complete"] is True
    assert meta["model"]["sha256"] and len(meta["model"]["sha256"]) == 64
    assert meta["method"] == "dop853" and meta["rtol"] == 1e-10 and meta["dt"] == 0.01 and meta["t_end"] == 0.1
    assert meta["parameters"]["F"] == 0.3 and meta["initial_state"] == {"theta": 0.5, "phi": -0.2, "theta_dot": 0.0,
                                                                       "phi_dot": 0.0}
    assert meta["cost"]["steps"] > 0 and meta["rows"] == 11 and meta["last_t"] == 0.1
    assert meta["columns"] == lines[0].split(",")


def test_standard_output_is_only_the_csv_and_meta_is_asked_for(tmp_path):
    meta = tmp_path / "m.json"
    result = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.02", "--dt", "0.01",
                                       "--meta", str(meta)])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines()[0].startswith("t,") and len(result.stdout.splitlines()) == 4
    assert json.loads(meta.read_text())["csv"] is None
    same = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.02", "-o", str(tmp_path / "a.csv"),
                                     "--meta", str(tmp_path / "a.csv")])
    assert same.exit_code == 2 and "the CSV file itself" in same.output


def test_sidecar_names():
    from pathlib import Path

    assert sidecar_path(Path("d/out.csv")) == Path("d/out.json")
    assert sidecar_path(Path("d/out.CSV")) == Path("d/out.json")
    assert sidecar_path(Path("out.txt")) == Path("out.txt.json")
    assert sidecar_path(Path("out.json")) == Path("out.json.json")


def test_the_sidecar_hashes_the_model_files_a_model_uses(tmp_path):
    """A model built on a known system: the run depends on both files, so both are hashed."""
    import hashlib
    import shutil

    shutil.copy(SYSTEM1, tmp_path / "system1.yaml")
    (tmp_path / "outer.yaml").write_text(
        "name: outer\ncomponents:\n  sys1: {model: system1.yaml}\ncoordinates: [theta, phi]\n")
    (tmp_path / "outer2.yaml").write_text(
        "name: outer2\ncomponents:\n  o: {model: outer.yaml}\ncoordinates: [theta, phi]\n")
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(tmp_path / "outer2.yaml"), "--t", "0.02", "-o", str(out)])
    assert result.exit_code == 0, result.output
    meta = json.loads(sidecar_path(out).read_text())
    uses = meta["model"]["uses"]
    assert [Path(u["file"]).name for u in uses] == ["outer.yaml", "system1.yaml"]
    for u in uses:
        assert u["sha256"] == hashlib.sha256(Path(u["file"]).read_bytes()).hexdigest()

