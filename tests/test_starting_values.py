"""The one route of a run's starting values (kronsub/simulation/start.py): the model's initial
values, a scene's over them, settings over both, a closed loop's projected onto its constraints."""
from __future__ import annotations

import math

import pytest

import kronsub
from conftest import MODELS, ROOT
from kronsub.errors import ModelError
from kronsub.simulation.start import starting_values

ONE_SCENE = ROOT / "tests" / "models" / "one_scene.yaml"


def test_the_scene_over_the_model_and_the_settings_over_both():
    system = kronsub.load(ONE_SCENE).derive(scene="swing")
    start = starting_values(system)
    assert start.values.y0 == (0.5, 0.0) and start.constrained is None and not start.notes
    assert dict(zip((p.name for p in system.parameters), start.values.parameters))["l"] == 0.5
    moved = starting_values(system, {"q": "pi/4", "q_dot": "1", "g": "2"}).values
    assert moved.y0 == (pytest.approx(math.pi / 4), 1.0)
    assert dict(zip((p.name for p in system.parameters), moved.parameters))["g"] == 2.0
    with pytest.raises(ModelError, match="no value for parameter F"):
        starting_values(kronsub.load(ONE_SCENE).derive(scene=False))


def test_a_closed_loop_starts_on_its_constraints():
    """The four-bar's dependent coordinates at the start make every constraint vanish (26)-(29),
    with the independent coordinate as given."""
    system = kronsub.load(MODELS / "examples" / "four_bar.yaml").derive()
    start = starting_values(system, {"theta1": "2.1", "theta1_dot": "0.7"})
    imp = system.implicit
    q = dict(zip(system.coordinates, start.values.y0[:1]))
    q.update(zip(imp.dependent, start.constrained.guess))
    params = {p.symbol: v for p, v in zip(system.parameters, start.values.parameters)}
    residuals = [float(c.expression.xreplace({**q, **params})) for c in imp.constraints]
    assert q[system.coordinates[0]] == 2.1 and max(map(abs, residuals)) < 1e-12
    assert start.notes  # the model's guesses for theta2, theta3 were corrected
