"""A constraint times a constant is the same constraint: the rank and redundancy tests, the
regularity of the speeds at the start and Newton's convergence test are relative to each
constraint's own scale, so a closed loop or a knife edge written in other units (here times
1e-12 and 1e12) runs as written plainly: the same rows, where an absolute tolerance used to call
the scaled constraint redundant, the speeds singular, or Newton's method failed."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import MODELS
from kronsub.cli import main


def rows(tmp_path, model, text: str, name: str):
    folder = tmp_path / name  # a copy of the model's folder: the model may name files beside it
    shutil.copytree(model.parent, folder)
    path, out = folder / model.name, tmp_path / f"{name}.csv"
    path.write_text(text)
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    return np.loadtxt(out, delimiter=",", skiprows=1)


@pytest.mark.parametrize("model, written", [
    (MODELS / "hoffmann" / "system2_implicit.yaml", "a1*sin(theta) + a2*sin(phi) - c"),
    (MODELS / "nonholonomic" / "chaplygin_sleigh.yaml", "-sin(theta)*x_dot + cos(theta)*y_dot - a*theta_dot"),
])
@pytest.mark.parametrize("factor", ["1e-12", "1e12"])
def test_a_scaled_constraint_gives_the_same_motion(tmp_path, model, written, factor):
    text = model.read_text()
    assert written in text
    plain = rows(tmp_path, model, text, "plain")
    scaled = rows(tmp_path, model, text.replace(written, f"{factor}*({written})"), "scaled")
    assert plain.shape == scaled.shape
    motion = slice(0, 5)  # t, the coordinates and the velocities or speeds
    assert np.max(np.abs(plain[:, motion] - scaled[:, motion])) <= 1e-9 * (1 + np.max(np.abs(plain[:, motion])))
