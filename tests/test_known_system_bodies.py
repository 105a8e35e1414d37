"""A body inside a known system, named from the model that uses it (``s.lower``, and a level
further down ``pair.left.lower``): a torque and a slider act on that body, and a known
system of several bodies is not taken to mean its first one (it was, silently)."""
from pathlib import Path

import pytest
import sympy

import kronsub
from kronsub.errors import ModelError

HERE = Path(__file__).parent / "models" / "known_bodies"


def test_torques_on_bodies_one_and_two_levels_down():
    """Absolute angles: a torque on a rod is the row of its angle (virtual work tau dangle)."""
    system = kronsub.load(HERE / "torques.yaml").derive(cache=False)
    tau, nu = sympy.symbols("tau nu", real=True)
    assert list(system.effect_forces["on_left_lower"]) == [0, tau, 0, 0]
    assert list(system.effect_forces["on_right_upper"]) == [0, 0, nu, 0]


@pytest.mark.parametrize("name, count", [("pair", 4), ("pair.left", 2)])
def test_a_known_system_of_several_bodies_must_say_which(tmp_path, name, count):
    model = (HERE / "torques.yaml").read_text().replace("component: pair.left.lower", f"component: {name}")
    path = tmp_path / "torques.yaml"
    path.write_text(model)
    for file in ("pair.yaml", "arm.yaml"):
        (tmp_path / file).write_text((HERE / file).read_text())
    with pytest.raises(ModelError) as caught:
        kronsub.load(path)
    text = str(caught.value)
    assert f"component '{name}' is a known system of {count} bodies" in text
    assert "`pair.left.lower`" in text and (count == 2 or "`pair.right.upper`" in text)


def test_an_unknown_inner_body_is_named_with_the_valid_ones(tmp_path):
    model = (HERE / "torques.yaml").read_text().replace("pair.left.lower", "pair.left.lowr")
    path = tmp_path / "torques.yaml"
    path.write_text(model)
    for file in ("pair.yaml", "arm.yaml"):
        (tmp_path / file).write_text((HERE / file).read_text())
    with pytest.raises(ModelError, match=r"unknown component 'pair\.left\.lowr'[\s\S]*pair\.left\.lower"):
        kronsub.load(path)


def test_a_slider_on_a_known_systems_body_is_the_slider_on_the_body_written_out():
    """The group property (13): through the known arm or with the arm written out, the same
    system on y = (p, q, xb, yb) and the same constraint."""
    known = kronsub.load(HERE / "bead_on_known.yaml").derive(cache=False).implicit
    inline = kronsub.load(HERE / "bead_inline.yaml").derive(cache=False).implicit
    order = [[q.name for q in known.intermediate].index(q.name) for q in inline.intermediate]
    assert sorted(order) == [0, 1, 2, 3]
    metric = known.metric.extract(order, order)
    assert sympy.simplify(metric - inline.metric) == sympy.zeros(4, 4)
    for ours, theirs in ((known.velocity_terms, inline.velocity_terms), (known.forces, inline.forces)):
        assert sympy.simplify(ours.extract(order, [0]) - theirs) == sympy.zeros(4, 1)
    (c_known,), (c_inline,) = known.constraints, inline.constraints
    assert sympy.simplify(c_known.expression - c_inline.expression) == 0
