"""What the outputs say of a prescribed motion (core/rheonomic.py) beyond the derivation:
``linearize`` refuses a drive that leaves ``t`` in the equations and says what it does when the
drive drops out of them; the LaTeX shows the drive block the Markdown shows."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.errors import ModelError

MODELS = Path(__file__).resolve().parent.parent / "models" / "motion"


def test_linearize_refuses_kapitza_at_the_prescribed_section():
    path = MODELS / "kapitza_pendulum.yaml"
    result = CliRunner().invoke(main, ["linearize", str(path)])
    assert result.exit_code == 1, result.output
    line = next(i for i, text in enumerate(path.read_text().splitlines(), 1) if text.startswith("prescribed:"))
    assert f"Error: {path}:{line}:1: " in result.output and "equations name t" in result.output
    assert "hint: simulate it instead" in result.output
    assert "Traceback" not in result.output


def test_api_linearize_refuses_kapitza_too():
    system = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive()
    with pytest.raises(ModelError) as caught:
        system.linearize(at={"theta": "pi"})
    problem = caught.value.problems[0]
    assert problem.location is not None and problem.location.line > 0
    assert "equations name t" in problem.message


def test_turning_hoop_is_linearised_about_its_relative_rest_and_says_so():
    """The drive leaves the hoop's equations (constant rate): the linearisation is the exact one of
    thdd = (w^2 cos th - g / R) sin th, whose off-centre rest cos th* = g / (w^2 R) oscillates at
    w sin th* (independent closed form), and the note says what the operating point is."""
    system = kronsub.load(MODELS / "bead_on_turning_hoop.yaml").derive()
    R, w, g = 0.5, 7.0, 9.81
    th = float(np.arccos(g / (w**2 * R)))
    lin = system.linearize(at={"theta": th})
    assert lin.equilibrium
    assert any("relative to the driven coordinates" in note for note in lin.notes)
    eig = np.sort_complex(np.asarray(lin.eigenvalues, dtype=complex))
    assert np.allclose(eig.real, 0, atol=1e-9)
    assert np.allclose(np.abs(eig.imag), w * np.sin(th), rtol=1e-9)
    result = CliRunner().invoke(main, ["linearize", str(MODELS / "bead_on_turning_hoop.yaml"),
                                       "--at", f"theta={th!r}"])
    assert result.exit_code == 0, result.output
    assert "Warning: the connection names t (a prescribed motion) but the equations do not" in result.output
