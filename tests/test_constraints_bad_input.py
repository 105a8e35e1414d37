"""Bad `constraints:` get a clear error naming the constraints involved, exit 1, no traceback."""
from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from kronsub.cli import main

TWO_RODS = """name: loop
parameters: {l: 1, d: 1.5, g: 9.81}
components:
  left: {type: pinned_rod, parameters: {mass: 1, length: l}, coordinates: {angle: a}}
  right: {type: pinned_rod, parameters: {mass: 1, length: l, pivot_x: d}, coordinates: {angle: b}}
"""


WHEEL = "  wheel: {type: flywheel, parameters: {inertia: 1}, coordinates: [w]}\n"


def run(tmp_path: Path, text: str):
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["derive", str(path)])
    try:
        err = result.stderr
    except ValueError:
        err = result.output
    assert result.exit_code == 1, (result.exit_code, result.output)
    assert "Traceback" not in err and "internal error" not in err, err
    assert err.startswith(f"Error: {path}:"), err
    return err


def test_inconsistent_constraints(tmp_path):
    # a four-bar whose links (1 + 1 + 1) cannot span the 5 between its fixed pivots
    text = TWO_RODS.replace("d: 1.5", "d: 5") + (
        "  mid: {type: pinned_rod, parameters: {mass: 1, length: l}, coordinates: {angle: c}, pivot: left.tip}\n"
        "coordinates: auto\nconstraints:\n  tips: {pin: [mid.tip, right.tip]}\n")
    err = run(tmp_path, text)
    assert "inconsistent constraints" in err and "'tips.x'" in err and "'tips.y'" in err


def test_redundant_constraints_say_which(tmp_path):
    text = TWO_RODS + (WHEEL + "coordinates: [a]\nconstraints:\n  one: a - b\n  two: 2*a - 2*b\n")
    err = run(tmp_path, text)
    assert "redundant constraints: 'two'" in err and "'one'" in err


def test_too_many_constraints(tmp_path):
    text = TWO_RODS + "coordinates: auto\nconstraints:\n  one: a - 0.1\n  two: b - 0.2\n  three: a + b\n"
    err = run(tmp_path, text)
    assert "too many constraints: 3 ('one', 'two', 'three') on 2 coordinates" in err


def test_more_constraints_than_dependent_coordinates(tmp_path):
    text = TWO_RODS + WHEEL + "coordinates: [a, w]\nconstraints:\n  one: a - b\n  two: a + b - 1\n"
    err = run(tmp_path, text)
    assert "more constraints (2: 'one', 'two') than dependent coordinates (1: b)" in err


def test_unknown_point_in_a_joint(tmp_path):
    text = TWO_RODS + "coordinates: [a]\nconstraints:\n  tips: {pin: [left.tip, right.tpi]}\n"
    err = run(tmp_path, text)
    assert "unknown point 'right.tpi' in constraint 'tips'" in err and "right.tip" in err
    line = text.splitlines().index("  tips: {pin: [left.tip, right.tpi]}") + 1
    assert f":{line}:" in err.splitlines()[0]


def test_independent_coordinates_that_do_not_determine_the_others(tmp_path):
    # three coordinates, one constraint, one listed: two dependent but one equation
    text = TWO_RODS + ("  wheel: {type: flywheel, parameters: {inertia: 1}, coordinates: [w]}\n"
                       "coordinates: [a]\nconstraints:\n  one: a - b\n")
    err = run(tmp_path, text)
    assert "do not determine the others" in err and "'one'" in err


def test_singular_choice_of_independent_coordinates(tmp_path):
    # the constraint does not involve b near b = 0 to first order: dg/db = 0 there
    text = TWO_RODS + "coordinates: [a]\nconstraints:\n  one: a - b**2 - 0.3\ninitial: {a: 0.3, b: 0}\n"
    err = run(tmp_path, text)
    assert "do not determine the others" in err and "singular" in err and "'one'" in err


def test_constraint_without_coordinates(tmp_path):
    err = run(tmp_path, TWO_RODS + "coordinates: [a]\nconstraints:\n  one: l - 1\n")
    assert "constraint 'one' does not involve any coordinate" in err


@pytest.mark.parametrize("joint", ["{hinge: [left.tip, right.tip]}", "{pin: [left.tip]}"])
def test_malformed_joints(tmp_path, joint):
    err = run(tmp_path, TWO_RODS + f"coordinates: [a]\nconstraints:\n  j: {joint}\n")
    assert "'j'" in err


def test_unknown_pivot_point(tmp_path):
    text = ("name: cart\ncomponents:\n  cart: {type: particle1d, parameters: {mass: 1}, coordinates: [x]}\n"
            "  pole: {type: pinned_rod, parameters: {mass: 1, length: 1}, coordinates: {angle: th}, "
            "pivot: cart.centr}\ncoordinates: [x, th]\n")
    err = run(tmp_path, text)
    assert "unknown pivot point 'cart.centr' of 'pole'" in err and "cart.centre" in err


def test_coordinates_auto_is_reported_on_stderr(tmp_path):
    root = Path(__file__).resolve().parent.parent
    result = CliRunner().invoke(main, ["derive", str(root / "models" / "examples" / "slider_crank.yaml")])
    assert result.exit_code == 0, result.output
    try:
        err = result.stderr
    except ValueError:
        err = result.output
    assert "coordinates: auto picked theta" in err


SUB_TIED = """name: bead tied twice
parameters: {m: 1}
components:
  p: {type: particle3d, parameters: {mass: m}, coordinates: [u, v, w]}
coordinates: [u]
constraints:
  x: v - u
  c_x: w - 2*u
initial: {u: 0.1, v: 0.1, w: 0.2}
"""


def test_multipliers_of_two_known_systems_that_share_a_name_point_at_their_components(tmp_path):
    """`arm.c_x` (the known system `arm`'s constraint `c_x`) and `arm_c.x` are both `mu_arm_c_x`:
    neither is written in this file, so the error is at the component entries that bring them
    in (it was at the top of the file, 1:1)."""
    (tmp_path / "sub.yaml").write_text(SUB_TIED, encoding="utf-8")
    text = ("name: two subs\ncomponents:\n"
            "  arm: {model: sub.yaml, coordinates: {u: u1, v: v1, w: w1}}\n"
            "  arm_c: {model: sub.yaml, coordinates: {u: u2, v: v2, w: w2}}\n"
            "coordinates: [u1, u2]\ninitial: {u1: 0.1, v1: 0.1, w1: 0.2, u2: 0.3, v2: 0.3, w2: 0.6}\n")
    err = run(tmp_path, text)
    path = tmp_path / "model.yaml"
    assert err.startswith(f"Error: {path}:4:3: constraints 'arm.c_x' and 'arm_c.x' have the same multiplier "
                          f"name 'mu_arm_c_x' in the reactions: they come from the component 'arm' (at {path}:3:3) "
                          "and this one, 'arm_c'"), err
    assert "hint: rename one of the components" in err
    assert run_ok(tmp_path, text.replace("  arm_c:", "  arm_k:"))


def run_ok(tmp_path: Path, text: str) -> bool:
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 0, result.output
    return True
