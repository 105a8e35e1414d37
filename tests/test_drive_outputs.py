"""What the outputs say of a prescribed motion (core/rheonomic.py) beyond the derivation:
``linearize`` refuses a drive that leaves ``t`` in the equations and says what it does when the
drive drops out of them; the LaTeX shows the drive block the Markdown shows."""
import re
from pathlib import Path

import jinja2
import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.core.symbols import TIME
from kronsub.emitters import text
from kronsub.emitters.escape import environment
from kronsub.emitters.latex_layout import WIDTH, measure
from kronsub.emitters.report import latex_printer
from kronsub.errors import ModelError
from kronsub.model.expressions import parse_expression

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


@pytest.fixture
def worktree_templates(monkeypatch):
    """The templates beside this package (an editable install may map ``kronsub.templates`` to
    another checkout)."""
    root = Path(kronsub.__file__).resolve().parent.parent / "templates"
    if root.is_dir():
        monkeypatch.setattr(text, "template_environment",
                            lambda: environment(jinja2.FunctionLoader(lambda n: (root / n).read_text("utf-8"))))


def _markdown_drive(doc: str) -> list[str]:
    """The cells of the two drive tables of the Markdown (velocity of the drive, its terms in hbar)."""
    start = doc.index("Velocity of the drive")
    block = doc[start:doc.index("\n## ", start)]
    return re.findall(r"^\| \*\*[^*]+\*\* \| `([^`]*)` \|$", block, re.M)


def _latex_drive(doc: str) -> list[str]:
    """The right-hand sides of the two drive displays of the LaTeX, their line breaks removed."""
    start = doc.index("Velocity of the drive")
    block = doc[start:doc.index("\\section*", start)]
    cells = []
    for align in re.findall(r"\\begin\{align\*\}\n(.*?)\\end\{align\*\}", block, re.S):
        for row in re.split(r" \\\\\n(?!&\\quad)", align.strip()):
            cells.append(row.split("&= ", 1)[1].replace(" \\\\\n&\\quad ", " "))
    return cells


@pytest.mark.parametrize("name", ["bead_on_turning_hoop.yaml", "kapitza_pendulum.yaml"])
def test_latex_shows_the_drive_terms_the_markdown_shows(name, worktree_templates):
    system = kronsub.load(MODELS / name).derive()
    plain = _markdown_drive(text.emit_markdown(system))
    shown = _latex_drive(text.emit_latex(system))
    tr = system.transition
    # as many entries: dx/dt per primitive coordinate, then hbar's drive terms per coordinate
    assert len(plain) == len(shown) == len(tr.primitive_coordinates) + len(system.coordinates)
    names = {s.name: s for s in (*system.coordinates, *system.velocities, *tr.primitive_coordinates, TIME)}
    names.update({p.name: p.symbol for p in system.parameters})
    show = latex_printer(tuple(system.coordinates) + tuple(tr.primitive_coordinates))
    for cell, latex in zip(plain, shown):
        expr = parse_expression(cell, names)
        assert " ".join(show(expr).split()) == " ".join(latex.split()), (cell, latex)
    assert any(TIME in parse_expression(c, names).free_symbols for c in plain)  # the drive's own terms


@pytest.mark.parametrize("name", ["bead_on_turning_hoop.yaml", "kapitza_pendulum.yaml"])
def test_latex_drive_block_fits_the_page(name, worktree_templates):
    doc = text.emit_latex(kronsub.load(MODELS / name).derive())
    start = doc.index("Velocity of the drive")
    for line in doc[start:doc.index("\\section*", start)].splitlines():
        if line.startswith(("\\begin", "\\end")) or "$" in line:
            continue
        assert measure(line) <= WIDTH + 8, line
