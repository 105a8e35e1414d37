"""Shared by the circuit tests: a run as a user makes it, and a system's names to symbols."""
from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from conftest import MODELS
from kronsub.cli import main

CIRCUITS = MODELS / "electrical"


def simulated(path, *args):
    """``kronsub simulate`` as a user runs it (tight tolerances): the CSV header and rows."""
    result = CliRunner().invoke(main, ["simulate", str(path), "--rtol", "1e-11", "--atol", "1e-12", *args])
    assert result.exit_code == 0, result.output
    lines = result.output.strip().splitlines()
    return lines[0].split(","), np.array([[float(v) for v in line.split(",")] for line in lines[1:]])


def symbols(system):
    """The system's parameters, coordinates and velocities by name."""
    return {p.name: p.symbol for p in system.parameters} | {q.name: q for q in system.coordinates} | \
        {v.name: v for v in system.velocities}
