"""The ``kronsub derive`` command: formats, files, --check, determinism."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from click.testing import CliRunner

from conftest import MODELS, ROOT
from kronsub.cli import main

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def derive(*args):
    result = CliRunner().invoke(main, ["derive", *map(str, args)])
    return result


def test_markdown_is_the_default_and_shows_every_step():
    result = derive(SYSTEM1)
    assert result.exit_code == 0, result.output
    out = result.output
    for heading in ("# System I", "## Primitive system", "## Interconnection", "## Projected system",
                    "## Equations of motion"):
        assert heading in out
    assert "2*a1*a2*m2*cos(phi - theta)" in out  # eq. (22)


def test_json_is_the_machine_contract():
    result = derive(SYSTEM1, "--format", "json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["coordinates"] == ["theta", "phi"]
    assert data["velocities"] == ["theta_dot", "phi_dot"]
    assert data["mass_matrix"][0][1] == "2*a1*a2*m2*cos(phi - theta)"
    assert len(data["forces"]) == len(data["velocity_terms"]) == 2
    assert set(data["effects"]) == {"gravity", "push"}
    assert "primitive" in data and "transformation" in data["primitive"]


def test_latex_is_a_document():
    result = derive(SYSTEM1, "--format", "latex")
    assert result.exit_code == 0, result.output
    assert result.output.startswith("\\documentclass")
    assert "\\end{document}" in result.output
    assert "\\dot{\\theta}" in result.output


def test_output_file_and_check(tmp_path):
    out = tmp_path / "system1.json"
    assert derive(SYSTEM1, "--format", "json", "--output", out).exit_code == 0
    same = derive(SYSTEM1, "--format", "json", "--check", out)
    assert same.exit_code == 0, same.output
    out.write_text(out.read_text().replace("m2", "m3", 1))
    changed = derive(SYSTEM1, "--format", "json", "--check", out)
    assert changed.exit_code == 1
    assert "---" in changed.output and "+++" in changed.output


@pytest.mark.parametrize("fmt, name", [("json", "expected.json"), ("latex", "expected.tex"),
                                       ("markdown", "expected.md"), ("json", "expected.txt"),
                                       ("latex", "expected")])
def test_check_reads_the_format_of_its_file(tmp_path, fmt, name):
    """``derive --check FILE`` without --format compares in FILE's format (its extension, else
    its text), so an up-to-date file is up to date and a changed one is a diff in that format."""
    out = tmp_path / name
    assert derive(SYSTEM1, "--format", fmt, "--output", out).exit_code == 0
    same = derive(SYSTEM1, "--check", out)
    assert same.exit_code == 0 and "up to date" in same.output, same.output
    out.write_text(out.read_text() + "a line of my own\n")
    changed = derive(SYSTEM1, "--check", out)
    assert changed.exit_code == 1
    diff = [line for line in changed.output.splitlines() if line[:1] in "+-" and line[:3] not in ("---", "+++")]
    assert diff == ["-a line of my own"], changed.output


def test_check_refuses_a_format_other_than_its_file(tmp_path):
    out = tmp_path / "expected.json"
    assert derive(SYSTEM1, "--format", "json", "--output", out).exit_code == 0
    result = derive(SYSTEM1, "--format", "markdown", "--check", out)
    assert result.exit_code == 2
    assert f"Error: --check {out} holds JSON, but --format is markdown" in result.output
    assert "give --format json" in result.output


def test_python_dash_m_runs_the_cli():
    result = subprocess.run([sys.executable, "-m", "kronsub", "--help"], capture_output=True, text=True)
    assert result.returncode == 0 and "derive" in result.stdout


_EVERY_FORMAT = """
import sys
from kronsub.cli import main
for fmt in ("markdown", "latex", "json"):
    sys.stdout.write("=== " + fmt + "\\n")
    sys.stdout.flush()
    try:
        main(["derive", sys.argv[1], "--format", fmt, "--no-cache"], standalone_mode=False)
    finally:
        sys.stdout.flush()
"""


def test_output_is_byte_identical_under_different_hash_seeds(tmp_path):
    """`kronsub derive` in every format, twice, under two PYTHONHASHSEED values and no cache:
    the same bytes (one process per seed runs the three formats)."""
    outputs = []
    for seed in ("0", "4242"):
        env = dict(os.environ, PYTHONHASHSEED=seed, KRONSUB_CACHE_DIR="off")
        proc = subprocess.run([sys.executable, "-c", _EVERY_FORMAT, str(MODELS / "hoffmann" / "system2.yaml")],
                              capture_output=True, env=env, cwd=ROOT)
        assert proc.returncode == 0, proc.stderr.decode()
        outputs.append(proc.stdout)
    assert [ln for ln in outputs[0].splitlines() if ln.startswith(b"=== ")] == [b"=== markdown", b"=== latex",
                                                                                b"=== json"]
    assert len(outputs[0]) > 3000 and outputs[0] == outputs[1]


def test_cached_and_fresh_derivations_print_the_same(tmp_path, monkeypatch):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    first = derive(MODELS / "hoffmann" / "system2.yaml", "--format", "json").output
    second = derive(MODELS / "hoffmann" / "system2.yaml", "--format", "json").output
    fresh = derive(MODELS / "hoffmann" / "system2.yaml", "--format", "json", "--no-cache").output
    assert first == second == fresh
    assert any((tmp_path / "cache").iterdir())
