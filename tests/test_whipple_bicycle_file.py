"""The Whipple bicycle from its model file, models/benchmarks/whipple_bicycle.yaml (four
``turned_body`` components, the front contact's height under ``constraints:``, both wheels
``rolls_on``), loaded and derived once within the default work budget, through the API's
linearize (what `kronsub linearize` calls, tests/test_nonholonomic_linearize_cli.py; the primitive's
metric and ``C``, compiled once for every speed) about upright straight running at speed v
(rear_dot = v / rR), against Table 2 of Meijaard, Papadopoulos, Ruina & Schwab (2007)
(tests/data/whipple_benchmark.json): the roll and steer eigenvalues for v = 0 .. 10 m/s to
1e-10, the other one 0 (the forward speed); the weave and capsize speeds by a root search are
checked on the bicycle built in Python (tests/test_whipple_bicycle.py)."""
import json
from pathlib import Path

import pytest

import kronsub
from helpers.compare import same_roots
from kronsub.core.deferred import pending

ROOT = Path(__file__).resolve().parents[1]
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"
PUBLISHED = json.loads((ROOT / "tests" / "data" / "whipple_benchmark.json").read_text())
RR = 0.3  # the rear wheel's radius of Table 1, as in the model file


@pytest.fixture(scope="module")
def bicycle():
    return kronsub.load(BICYCLE).derive()  # within the default work budget


@pytest.mark.parametrize("speed", sorted(PUBLISHED["eigenvalues"], key=float))
def test_eigenvalues_of_table_2_from_the_model_file(bicycle, speed):
    lin = bicycle.linearize(at={"rear_dot": float(speed) / RR})
    assert [s.name for s in lin.state] == ["roll", "steer", "roll_dot", "steer_dot", "rear_dot"]
    assert lin.equilibrium and [q.name for q, _ in lin.dependent] == ["pitch"]
    assert abs(lin.dependent[0][1]) < 1e-12  # the paper's reference configuration
    expected = [complex(re, im) for re, im in PUBLISHED["eigenvalues"][speed]]
    assert same_roots(lin.eigenvalues, expected + [0.0], 1e-10), (speed, lin.eigenvalues)
    # from the primitive's metric and C: Mbar and hbar in the coordinates are never formed
    assert pending(bicycle.mass_matrix) and pending(bicycle.velocity_terms)
