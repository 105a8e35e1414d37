"""The layering of docs/architecture.md, checked by import-linter's contracts in pyproject.toml
([tool.importlinter]): cli -> commands -> api -> simulation -> model -> emitters | effects ->
core -> components, errors and atomic at the ground; no circle among the modules of a package.
grimp records every import, also those inside functions."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_imports_keep_the_layers():
    pytest.importorskip("importlinter", reason="import-linter is not installed (it is in the test extra)")
    command = shutil.which("lint-imports", path=os.pathsep.join([str(Path(sys.executable).parent),
                                                                 os.environ.get("PATH", "")]))
    assert command, "import-linter is installed but its lint-imports command is not on the PATH"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([command, "--no-cache", "--no-logo"], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
