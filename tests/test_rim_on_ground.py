"""A rolling joint (`rolls_on`, model/contacts.py) whose rim is held on the ground by a
configuration constraint beside it (`constraints:`) rather than by the connection: accepted when
a constraint is the rim's height (tests/models/nonholonomic/rolling_disc_height.yaml, the joint
in place of the hand-written rows, gives the same constraint rows), refused at the body when
none is."""
from pathlib import Path

import sympy
from click.testing import CliRunner

from kronsub.cli import main
from kronsub.model.loader import load_model

ROOT = Path(__file__).resolve().parents[1]
HAND = (ROOT / "tests" / "models" / "nonholonomic" / "rolling_disc_height.yaml").read_text()
JOINT = HAND.replace("""  roll_x: x_dot - r*cos(yaw)*spin_dot
  roll_y: y_dot - r*sin(yaw)*spin_dot""", "  contact: {rolls_on: plane, body: disc, radius: r}")


def test_rim_held_by_a_configuration_constraint(tmp_path):
    assert JOINT != HAND
    (tmp_path / "hand.yaml").write_text(HAND)
    (tmp_path / "joint.yaml").write_text(JOINT)
    hand, joint = (load_model(tmp_path / n).velocity.transformation for n in ("hand.yaml", "joint.yaml"))
    A_hand, A_joint = hand.constraint_matrix, joint.constraint_matrix
    assert A_hand.shape == A_joint.shape == (3, 6)
    assert (A_hand - A_joint).applyfunc(sympy.simplify) == sympy.zeros(3, 6)


def test_rim_off_the_ground_is_located(tmp_path):
    path = tmp_path / "off.yaml"
    path.write_text(JOINT.replace("touches: disc.z - r*cos(disc.theta)", "touches: disc.z - 2*r*cos(disc.theta)"))
    result = CliRunner().invoke(main, ["derive", str(path)])
    assert result.exit_code == 1
    assert "off.yaml:25:36: rolling joint 'contact': the rim of 'disc' is at height" in result.output
    assert "above the ground, not on it" in result.output and "under `constraints:`" in result.output
