"""A run in the speeds that crosses a configuration where its speeds are singular is reported
(kronsub/simulation/frame_crossing.py): the integrator steps over ``det [A; Y] = 0`` without
failing, so the warning is all that says the rows after it are not accurate. The rolling disc
with its contact's x-row written times ``lean`` (``lean*x_dot = r cos(yaw) spin_dot``) has
``det [A; Y] = lean`` with the speeds ``yaw_dot, lean_dot, spin_dot``; a run that falls through
upright crosses it. The speeds the warning suggests carry the same motion through, its energy
kept; the bundled models' runs say nothing."""
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from kronsub.cli import main

ROOT = Path(__file__).resolve().parent.parent
DISC = (ROOT / "models" / "nonholonomic" / "rolling_disc.yaml").read_text()
TIMES_LEAN = DISC.replace("roll_x: x_dot - r*cos(yaw)*spin_dot", "roll_x: lean*x_dot - r*cos(yaw)*spin_dot")


def _run(tmp_path, text, *args):
    model = tmp_path / "model.yaml"
    model.write_text(text)
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(model), "--t", "0.5", "--dt", "0.01", "-o", str(out), *args])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    return result.output, header, np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)


def test_a_run_through_singular_speeds_is_reported_where_it_crossed(tmp_path):
    assert TIMES_LEAN != DISC
    start = "initial: {lean: 0.3, lean_dot: -3, yaw_dot: 0.5, spin_dot: 8}"
    output, header, data = _run(tmp_path, re.sub(r"^initial: .*$", start, TIMES_LEAN, flags=re.M))
    warned = re.search(r"Warning: the run crossed a configuration where the speeds are singular, between "
                       r"t = ([-\d.e]+) and t = ([-\d.e]+) .*e\.g\. `speeds: \[([^\]]*)\]`", output.replace("\n", " "))
    assert warned, output
    t0, t1 = float(warned[1]), float(warned[2])
    t, lean = data[:, 0], data[:, header.index("lean")]
    i = int(np.argmin(np.abs(t - t0)))
    assert abs(t[i] - t0) < 1e-9 and abs(t[i + 1] - t1) < 1e-9
    assert lean[i] > 0 > lean[i + 1]  # det [A; Y] = lean changed its sign between the two rows
    assert np.all(lean[:i + 1] > 0)  # and not before
    suggested = [s.strip() for s in warned[3].split(",")]
    assert len(suggested) == 3 and "spin_dot" not in suggested  # spin_dot with lean*x_dot is the singular pair

    # the suggested speeds carry the motion through upright: no warning, energy kept
    given = {"yaw_dot": 0.5, "lean_dot": -3.0}
    given.update({s: 0.1 for s in suggested if s not in given})
    other = re.sub(r"^initial: .*$", "initial: {lean: 0.3, " + ", ".join(f"{k}: {v}" for k, v in given.items())
                   + "}\nspeeds: [" + ", ".join(suggested) + "]", TIMES_LEAN, flags=re.M)
    output, header, data = _run(tmp_path, other, "--rtol", "1e-11", "--atol", "1e-12")
    assert "Warning" not in output, output
    lean, energy = data[:, header.index("lean")], data[:, header.index("total_energy")]
    assert lean[0] > 0 > lean.min()  # it went through upright
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * max(1.0, abs(energy[0]))


@pytest.mark.parametrize("name", ["rolling_disc", "chaplygin_sleigh", "differential_drive"])
def test_runs_on_regular_speeds_say_nothing(tmp_path, name):
    output, _, data = _run(tmp_path, (ROOT / "models" / "nonholonomic" / f"{name}.yaml").read_text())
    assert "Warning" not in output and len(data) == 51, output
