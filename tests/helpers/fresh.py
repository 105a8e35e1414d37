"""The command line in a fresh process, with the heavy modules it imported: what a second run of
the same command (kept outputs, prepared runs) must do without SymPy."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from kronsub.cli import main

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("sympy", "mpmath", "scipy", "yaml")

PROBE = """
import json, sys
from kronsub.cli import main
code = None
try:
    main({args!r})
except SystemExit as exc:
    code = exc.code
with open({modules!r}, "w") as fh:
    json.dump([code, sorted({{n.split(".")[0] for n in sys.modules}} & set({heavy!r}))], fh)
"""


def kronsub(args: list[str], cache: Path, cwd: Path, heavy=HEAVY) -> tuple[int, bytes, list[str]]:
    """Run the command line in a fresh process: exit code, standard output, heavy modules imported
    (those of ``heavy``)."""
    modules = cwd / "modules.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "KRONSUB_CACHE_DIR": str(cache)}
    done = subprocess.run([sys.executable, "-c", PROBE.format(args=args, modules=str(modules), heavy=tuple(heavy))],
                          cwd=cwd, env=env, capture_output=True, timeout=300)
    assert modules.exists(), done.stderr.decode()
    code, imported = json.loads(modules.read_text())
    modules.unlink()
    return code, done.stdout, imported


def cli(*args, cache: Path):
    """The command line in this process with its own cache folder."""
    return CliRunner().invoke(main, [str(a) for a in args], env={"KRONSUB_CACHE_DIR": str(cache)})


__all__ = ["HEAVY", "cli", "kronsub"]
