"""Did-you-mean for unknown coordinates, wherever a coordinate name is expected."""
from __future__ import annotations

import pytest
from click.testing import CliRunner

from kronsub.cli import main
from kronsub.errors import near_names

MODEL = """\
name: two links
parameters: {m: 1, l: 1, k: 2}
components:
  link1: {type: pinned_rod, parameters: {mass: m, length: l}, coordinates: {angle: a1}}
  link2: {type: pinned_rod, parameters: {mass: m, length: l}, coordinates: {angle: a2}}
coordinates: [q1, q2]
connection: {a1: q1, a2: q1 + q2}
effects:
  knee: {type: torsional_spring, angle: a2 - a1, stiffness: k}
initial: {q1: 0.1}
scenes:
  swing:
    effects: [knee]
    initial: {q1: 0.2}
    outputs: [coordinates, link1.tip]
"""


def test_near_names_finds_one_edit_where_difflib_does_not():
    assert near_names("q3", ["q1", "q2", "theta"]) == ["q1", "q2"]
    assert near_names("thtea", ["theta", "phi"]) == ["theta"]  # two neighbours swapped
    assert near_names("thet", ["theta", "phi"]) == ["theta"]
    assert near_names("x", ["y", "z"]) == []  # one-letter names: every other one is one edit away
    assert near_names("q1_dott", ["q1_dot", "q2_dot"])[0] == "q1_dot"


@pytest.mark.parametrize("old, new, where, expected", [
    ("initial: {q1: 0.1}", "initial: {q3: 0.1}", "10:11", "'q3' is not a coordinate or velocity of this model"),
    ("connection: {a1: q1,", "connection: {a3: q1,", "7:14", "'a3' is not a coordinate of the primitive system"),
    ("    initial: {q1: 0.2}", "    initial: {q3: 0.2}", "14:15", "'q3' is not a coordinate or velocity"),
    ("angle: a2 - a1,", "angle: a2 - a3,", "9:46", "in angle 'a2 - a3': unknown name 'a3'"),
    ("initial: {q1: 0.1}", "initial: {q1_dott: 0.1}", "10:11", "'q1_dott' is not a coordinate or velocity"),
])
def test_an_unknown_coordinate_gets_the_nearest(tmp_path, old, new, where, expected):
    assert old in MODEL
    path = tmp_path / "m.yaml"
    path.write_text(MODEL.replace(old, new, 1))
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1, result.output
    assert f"m.yaml:{where}: {expected}" in result.output, result.output
    hint = result.output.split("hint: ", 1)[1].splitlines()[0]
    assert hint.startswith("did you mean"), hint
    wanted = "q1_dot" if "dott" in new else ("a1" if "a3" in new else "q1")
    assert f"'{wanted}'" in hint
    assert result.output.count("Error:") == 1


def test_an_unknown_output_point_gets_the_nearest(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(MODEL.replace("link1.tip]", "link1.tipp]"))
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1
    assert "unknown output 'link1.tipp'" in result.output and "did you mean 'link1.tip'" in result.output
