"""The README's and the docs' samples of output are what this build prints.

Every fenced block of CSV rows (a header row starting ``t,``) whose paragraph names the command
that prints it (`` `kronsub simulate ...` ``) is run again and compared: the header exactly, the
numbers to 1e-9 relative (their last digits depend on the compiler, instruction set and libm,
as the README says; a wrong sample differs in the leading digits). The way the README reads a
trajectory with numpy keeps every column name.
"""
from __future__ import annotations

import io
import re
import shlex

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import ROOT
from kronsub.cli import main

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", re.M | re.S)
COMMAND = re.compile(r"`kronsub (simulate [^`]+)`")
RELATIVE = 1e-9  # far above the spread between machines (~1e-13), far below any real change


def csv_samples() -> list[tuple[str, str, str]]:
    """(page, command, rows) of every CSV sample; its paragraph names its command and says
    that the last digits depend on the machine."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in FENCE.finditer(text):
            if match.group(1) or not match.group(2).startswith("t,"):
                continue
            paragraph = text[:match.start()].rstrip().rsplit("\n\n", 1)[-1]
            commands = COMMAND.findall(paragraph)
            assert commands, f"{page.name}: the CSV sample at offset {match.start()} names no command"
            assert "depend on the machine" in paragraph, \
                f"{page.name}: the CSV sample of `kronsub {commands[-1]}` does not say its last digits vary"
            found.append((page.name, commands[-1], match.group(2)))
    return found


SAMPLES = csv_samples()


def test_the_readme_has_a_csv_sample():
    assert any(page == "README.md" for page, _, _ in SAMPLES)


@pytest.mark.parametrize("page, command, rows", SAMPLES, ids=[f"{p}: {c}" for p, c, _ in SAMPLES])
def test_csv_sample_is_what_the_command_prints(page, command, rows, monkeypatch):
    monkeypatch.chdir(ROOT)
    result = CliRunner().invoke(main, shlex.split(command))
    assert result.exit_code == 0, result.output
    printed = result.stdout.splitlines()
    shown = rows.splitlines()
    assert printed[0] == shown[0], "the header differs"
    for line in shown[1:]:
        want = [float(v) for v in line.split(",")]
        row = next(r for r in printed[1:] if float(r.split(",")[0]) == want[0])
        got = [float(v) for v in row.split(",")]
        np.testing.assert_allclose(got, want, rtol=RELATIVE, atol=1e-15, err_msg=f"{page}: {command}, t = {want[0]}")


def test_the_readme_numpy_call_keeps_the_point_columns(monkeypatch):
    """``numpy.genfromtxt`` as the README writes it reads a ``--points`` CSV with every column
    named as in its header (numpy's default would turn ``lower.centre.x`` into ``lowercentrex``)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    call = re.search(r"`numpy\.genfromtxt\(f, ([^`]*)\)`", readme)
    assert call, "the README names the numpy call"
    options = dict(re.findall(r"(\w+)=(\"[^\"]*\"|\w+)", call.group(1)))
    kwargs = {k: (v.strip('"') if v.startswith('"') else v == "True") for k, v in options.items()}
    monkeypatch.chdir(ROOT)
    result = CliRunner().invoke(main, ["simulate", "models/hoffmann/system1.yaml", "--t", "0.05", "--points"])
    assert result.exit_code == 0, result.output
    header = result.stdout.splitlines()[0].split(",")
    assert any("." in name for name in header)
    table = np.genfromtxt(io.StringIO(result.stdout), **kwargs)
    assert list(table.dtype.names) == header
    assert table["t"][-1] == 0.05


def test_the_readme_says_where_a_switch_of_coordinates_is_recorded():
    """The CSV has no comment lines (tests/test_constraints_switching.py runs a switch); the
    README sends the reader to the metadata's ``coordinate_switches``."""
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    assert "comment line" not in readme
    assert "`coordinate_switches`" in readme
