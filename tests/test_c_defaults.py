"""The generated C header gives the parameters' values in the model, as the numpy module's
``DEFAULTS`` does: ``<PREFIX>_DEFAULT_<name>`` for each, and ``<PREFIX>_DEFAULTS``, an
initializer of ``param[]`` in its order, when every parameter has one. A program using them is
built with ``gcc -std=c99 -Wall -Wextra -Werror`` and prints the very doubles of the model."""
from __future__ import annotations

import importlib.util
import shutil
import subprocess
from importlib import resources
from pathlib import Path

import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS, ROOT
from kronsub.cli import main

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]

NEGATIVE = """\
name: pushed back
parameters:
  m: {value: 2, unit: kg}
  F: {value: -2.5, unit: N}
  x0: {value: -1e-300, unit: m}
components:
  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}
coordinates: [x]
effects:
  push: {type: generalized_force, coordinate: x, value: F + x0}
"""


@pytest.fixture(autouse=True)
def _templates_of_this_tree(monkeypatch):
    """Render this tree's templates/ (an editable install may map them elsewhere)."""
    files = resources.files
    monkeypatch.setattr(resources, "files", lambda package: ROOT / "templates" if package == "kronsub.templates"
                        else files(package))


def _generate(model: Path, out: Path, lang: str) -> None:
    result = CliRunner().invoke(main, ["codegen", str(model), "--lang", lang, "--prefix", "abc", "--name", "m",
                                       "--output", str(out)])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("model", [MODELS / "hoffmann" / "system1.yaml", MODELS / "examples" / "cart_pole.yaml",
                                   "negative"])
def test_c_defaults_are_the_models_values(model, tmp_path):
    if model == "negative":
        model = tmp_path / "negative.yaml"
        model.write_text(NEGATIVE)
    out = tmp_path / "build"
    _generate(model, out, "c")
    _generate(model, out, "python")
    spec = importlib.util.spec_from_file_location("m_numpy", out / "m.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    names = [p.name for p in kronsub.load(model).derive().parameters]
    assert list(module.DEFAULTS) == names
    program = ['#include <stdio.h>', '#include "m.h"', "int main(void) {",
               "    const double param[ABC_NPARAM] = ABC_DEFAULTS;",
               "    int i;",
               "    for (i = 0; i < ABC_NPARAM; i++) printf(\"%.17g\\n\", param[i]);"]
    program += [f'    printf("%.17g\\n", ABC_DEFAULT_{name} * 1.0);' for name in names]
    program += [f'    printf("%.17g\\n", -ABC_DEFAULT_{name});' for name in names]  # a negative one parenthesized
    program += ["    return 0;", "}"]
    (out / "main.c").write_text("\n".join(program) + "\n")
    subprocess.run(["gcc", *CFLAGS, "main.c", "-o", "main"], cwd=out, check=True, capture_output=True, text=True)
    printed = [float(v) for v in subprocess.run([str(out / "main")], check=True, capture_output=True,
                                                text=True).stdout.split()]
    want = [float(module.DEFAULTS[name]) for name in names]
    assert printed == want + want + [-v for v in want]


def test_no_defaults_initializer_when_a_parameter_has_no_value(tmp_path):
    """A parameter without a value has no macro, and there is no initializer to leave it out of."""
    model = tmp_path / "partial.yaml"
    model.write_text(NEGATIVE.replace("m: {value: 2, unit: kg}", "m: {unit: kg}"))
    out = tmp_path / "build"
    _generate(model, out, "c")
    header = (out / "m.h").read_text()
    assert "#define ABC_DEFAULT_F (-2.5)" in header
    assert "ABC_DEFAULT_m " not in header and "ABC_DEFAULTS" not in header
