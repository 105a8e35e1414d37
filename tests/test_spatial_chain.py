"""The spatial chain of rods on ball joints (models/chain/generate_spatial.py): one rod is the
compound pendulum on a ball joint (tests/models/sweep/ball_joint_pendulum.yaml) with a rod's
inertia, the same right-hand side at random states; longer chains are valid models."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.simulation.fallback import numpy_module

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "models" / "chain"))
from generate_spatial import spatial_chain_yaml  # noqa: E402


def test_one_rod_is_the_compound_pendulum_on_a_ball_joint():
    rod = kronsub.load("spatial1.yaml", text=spatial_chain_yaml(1)).derive()
    pendulum = kronsub.load(ROOT / "tests/models/sweep/ball_joint_pendulum.yaml").derive()
    assert [q.name for q in rod.coordinates] == ["a1", "b1", "c1"]
    assert [p.name for p in pendulum.parameters] == ["m", "A", "B", "C", "h", "g"]
    rod_rhs, pendulum_rhs = numpy_module(rod)["rhs"], numpy_module(pendulum)["rhs"]
    rng = np.random.default_rng(34)
    for _ in range(4):
        values = dict(g=rng.uniform(5, 10), r=rng.uniform(0.02, 0.2), m1=rng.uniform(0.5, 2), l1=rng.uniform(0.5, 2))
        across = values["m1"] * (3 * values["r"] ** 2 + values["l1"] ** 2) / 12
        same = dict(m=values["m1"], A=across, B=across, C=values["m1"] * values["r"] ** 2 / 2, h=values["l1"] / 2,
                    g=values["g"])
        y = np.concatenate([rng.uniform(-0.5, 0.5, 3), rng.uniform(-1, 1, 3)])
        expected = pendulum_rhs(0.0, y, np.array([same[p.name] for p in pendulum.parameters]))
        got = rod_rhs(0.0, y, np.array([values[p.name] for p in rod.parameters]))
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))


@pytest.mark.parametrize("n", [2, 3])
def test_longer_chains_are_valid_models(n, tmp_path):
    path = tmp_path / f"spatial{n}.yaml"
    path.write_text(spatial_chain_yaml(n))
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 0, result.output
    assert f"{3 * n} generalized coordinates, {n} components" in result.output


def test_a_chain_needs_a_body():
    with pytest.raises(ValueError, match="at least one body"):
        spatial_chain_yaml(0)
