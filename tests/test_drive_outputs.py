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


def _run(name, t, dt):
    return kronsub.load(MODELS / name).derive().simulate(t=t, dt=dt, rtol=1e-12, atol=1e-12, dataframe=False)


def _trapezoid(y, t):
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2)


def test_turning_hoop_drive_power_is_the_torque_times_the_rate():
    """The hoop's motor torque is d/dt of the bead's angular momentum about the axis,
    ``d/dt(m R^2 sin^2 th w) = 2 m R^2 w sin th cos th thd``; its power is that times ``w``. The
    primitive's energy is the total_energy column plus the drive's share of T,
    ``1/2 m (R w sin th)^2``, and the power's integral is its change."""
    m, R, w = 0.1, 0.5, 7.0
    run = _run("bead_on_turning_hoop.yaml", 2.0, 1e-3)
    t, th, thd, P = run["t"], run["theta"], run["theta_dot"], run["drive_power"]
    assert np.allclose(P, 2 * m * R**2 * w**2 * np.sin(th) * np.cos(th) * thd, rtol=1e-9, atol=1e-12)
    energy = run["total_energy"] + 0.5 * m * (R * w * np.sin(th))**2
    assert abs(_trapezoid(P, t) - (energy[-1] - energy[0])) < 1e-5 * np.max(np.abs(P)) * t[-1]
    assert np.ptp(energy) > 0.1 and np.ptp(run["total_energy"]) > 0.1  # the drive does put energy in and out


def test_kapitza_drive_power_is_the_pivot_force_times_its_speed():
    """The pivot's force on the bob (vertical, ``m (pyddot + g)`` with ``py = s - l cos th``,
    ``thdd = -(g + sdd) sin th / l``) times the pivot's speed ``sd``:
    ``P = m sd ((g + sdd) cos^2 th + l cos th thd^2)``. The primitive's energy is the total_energy
    column plus the drive's share of T, ``m (sd^2 / 2 + l sin th thd sd)``."""
    m, l, a, w, g = 1.0, 1.0, 0.05, 200.0, 9.81
    run = _run("kapitza_pendulum.yaml", 0.2, 2e-5)
    t, th, thd, P = run["t"], run["theta"], run["theta_dot"], run["drive_power"]
    sd, sdd = -a * w * np.sin(w * t), -a * w**2 * np.cos(w * t)
    hand = m * sd * ((g + sdd) * np.cos(th)**2 + l * np.cos(th) * thd**2)
    assert np.allclose(P, hand, rtol=1e-9, atol=1e-9 * np.max(np.abs(hand)))
    energy = run["total_energy"] + m * (sd**2 / 2 + l * np.sin(th) * thd * sd)
    assert abs(_trapezoid(P, t) - (energy[-1] - energy[0])) < 1e-5 * np.max(np.abs(P)) * t[-1]


@pytest.mark.parametrize("name", ["hoffmann/system1.yaml", "examples/four_bar.yaml"])
def test_undriven_models_have_no_drive_power_column(name):
    path = MODELS.parent / name
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "0.02", "--dt", "0.01"])
    assert result.exit_code == 0, result.output
    header = result.output.splitlines()[0].split(",")
    assert "drive_power" not in header and header[-1] in ("total_energy", *header[-3:])


def test_driven_csv_and_run_table_share_the_column():
    path = MODELS / "bead_on_turning_hoop.yaml"
    result = CliRunner().invoke(main, ["simulate", str(path), "--t", "0.02", "--dt", "0.01"])
    assert result.exit_code == 0, result.output
    header = result.output.splitlines()[0].split(",")
    assert header[-4:] == ["kinetic_energy", "potential_energy", "total_energy", "drive_power"]
    run = _run("bead_on_turning_hoop.yaml", 0.02, 0.01)
    assert "drive_power" in run.table_columns


def test_kapitza_drive_power_is_the_pivot_speed_times_the_printed_reaction():
    """The same power from another route: ``--reactions``' ``R_py`` (core/reactions.py) times the
    pivot's speed ``sd = -a w sin(w t)`` (``s`` has only a ``py`` component)."""
    a, w = 0.05, 200.0
    run = kronsub.load(MODELS / "kapitza_pendulum.yaml").derive().simulate(
        t=0.05, dt=0.001, reactions=True, dataframe=False)
    sd = -a * w * np.sin(w * run["t"])
    assert np.allclose(run["drive_power"], sd * run["R_py"], rtol=1e-9, atol=1e-9 * np.max(np.abs(run["drive_power"])))
