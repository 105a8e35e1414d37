"""The spatial chain of rods on ball joints (models/chain/generate_spatial.py): one rod is the
compound pendulum on a ball joint (tests/models/sweep/ball_joint_pendulum.yaml, a ``pin``
constraint) with a rod's inertia; two rods with the joints as the connection are the two rods
with the joints as ``pin`` constraints (a closed loop's route): the same right-hand sides at
random states. Longer chains are valid models."""
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


def test_joints_as_the_connection_are_joints_as_pins():
    connected = kronsub.load("spatial2.yaml", text=spatial_chain_yaml(2)).derive()
    pinned = kronsub.load("spatial2_pins.yaml", text=spatial_chain_yaml(2, pins=True)).derive()
    assert connected.implicit is None and pinned.implicit is not None
    assert [p.name for p in connected.parameters] == [p.name for p in pinned.parameters]
    assert connected.coordinates == pinned.coordinates
    rng = np.random.default_rng(34)
    for _ in range(3):  # the joints hold (a mirrored connection would give the same dynamics)
        at = {q: rng.uniform(-1, 1) for q in connected.coordinates}
        at.update({p.symbol: rng.uniform(0.5, 1.5) for p in connected.parameters})

        def point(name):
            return np.array([float(c.xreplace(at)) for c in connected.points[name]])

        assert np.allclose(point("rod1.top"), 0, atol=1e-14)
        assert np.allclose(point("rod2.top"), point("rod1.bottom"), rtol=0, atol=1e-14)
    connected_rhs, pinned_rhs = numpy_module(connected)["rhs"], numpy_module(pinned)["rhs"]
    rng = np.random.default_rng(43)
    for _ in range(4):
        y = np.concatenate([rng.uniform(-0.5, 0.5, 6), rng.uniform(-1, 1, 6)])
        param = rng.uniform(0.5, 1.5, len(connected.parameters))
        expected = pinned_rhs(0.0, y, param)
        assert np.allclose(connected_rhs(0.0, y, param), expected, rtol=1e-11, atol=1e-11 * np.max(np.abs(expected)))


@pytest.mark.parametrize("n, pins", [(3, False), (3, True), (10, False)])
def test_longer_chains_are_valid_models(n, pins, tmp_path):
    path = tmp_path / f"spatial{n}.yaml"
    path.write_text(spatial_chain_yaml(n, pins=pins))
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 0, result.output
    assert f"{3 * n} generalized coordinates, {n} components" in result.output


def test_a_chain_needs_a_body():
    with pytest.raises(ValueError, match="at least one body"):
        spatial_chain_yaml(0)
