"""Start-up: ``import kronsub`` and ``kronsub --help`` import no SymPy, NumPy, SciPy or Jinja
(the commands that need them import them), and the listing of ``--help``, read from
``kronsub.cli.COMMANDS`` without importing the commands, says what the commands say."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from kronsub.cli import COMMANDS, main

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("sympy", "numpy", "scipy", "jinja2", "mpmath", "yaml")

PROBE = """
import json, sys
{body}
print(json.dumps(sorted(name for name in sys.modules if name.split(".")[0] in {heavy!r})))
"""


def _modules_after(body: str) -> list[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", PROBE.format(body=body, heavy=HEAVY)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_import_kronsub_imports_nothing_heavy():
    assert _modules_after("import kronsub") == []


def test_help_imports_nothing_heavy():
    body = ("from kronsub.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass")
    assert _modules_after(body) == []


def _command_modules_after_help(command: str) -> list[str]:
    body = (f"import json, sys\nfrom kronsub.cli import main\n"
            f"try:\n    main([{command!r}, '--help'])\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(name for name in sys.modules if name.startswith('kronsub.commands.'))))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", body], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_command_module_is_imported_when_its_command_is_used():
    assert _command_modules_after_help("derive") == ["kronsub.commands.common", "kronsub.commands.derive"]
    after_check = _command_modules_after_help("check")
    assert "kronsub.commands.discovery" in after_check
    assert not {"kronsub.commands.derive", "kronsub.commands.simulate"} & set(after_check)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_listing_says_what_the_command_says(name):
    command = main.get_command(None, name)
    assert command is not None and command.name == name
    assert command.get_short_help_str(limit=10**6) == COMMANDS[name][1]


def test_listing_names_every_command():
    result = CliRunner().invoke(main, ["--help"])
    assert result.exit_code == 0
    listed = [line.split()[0] for line in result.output.split("Commands:")[1].splitlines() if line.strip()]
    assert listed == sorted(COMMANDS)


def test_unknown_command_suggests_a_near_one():
    result = CliRunner().invoke(main, ["simulat"])
    assert result.exit_code == 2
    assert "Did you mean 'simulate'?" in result.output


@pytest.mark.parametrize("given", [None, "3"])
def test_a_command_runs_blas_on_one_thread_unless_told(given):
    """The command's module (and NumPy) is imported with OPENBLAS_NUM_THREADS=1 unless the user set it."""
    from kronsub.cli import BLAS_THREADS

    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREADS}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    code = ("import os, sys\n"
            "from kronsub.cli import main\n"
            "try:\n"
            "    main(['check', sys.argv[1]])\n"
            "except SystemExit:\n"
            "    pass\n"
            "print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)\n")
    model = Path(__file__).resolve().parents[1] / "models" / "hoffmann" / "system1.yaml"
    proc = subprocess.run([sys.executable, "-c", code, str(model)], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-2:] == [given or "1", "True"]
