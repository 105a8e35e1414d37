"""Kept outputs (kronsub/model/kept.py): ``derive`` and ``codegen`` run again with the same
command import no SymPy and write the very bytes the derived run wrote; ``--no-cache``, other
options, other templates or a changed model file derive again."""
from __future__ import annotations

import pytest

from conftest import MODELS
from helpers.fresh import cli, kronsub
from kronsub.model import kept

HEAVY = ("sympy", "mpmath", "scipy")
SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


@pytest.fixture
def loaded(monkeypatch):
    """The model files read by the model loader in this test (a derived output reads them)."""
    from kronsub.model import loader

    calls = []
    real = loader.load_model

    def load_model(*args, **kwargs):
        calls.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(loader, "load_model", load_model)
    return calls


def test_derive_again_imports_no_sympy_and_prints_the_same(tmp_path):
    cache = tmp_path / "cache"
    first = cli("derive", SYSTEM1, "--format", "json", "--scene", "free", cache=cache)
    assert first.exit_code == 0
    code, again, heavy = kronsub(["derive", str(SYSTEM1), "--format", "json", "--scene", "free"], cache, tmp_path,
                                 HEAVY)
    assert code in (0, None) and heavy == [] and again.decode() == first.stdout


def test_codegen_again_imports_no_sympy_and_writes_the_same_files(tmp_path):
    cache = tmp_path / "cache"
    first = cli("codegen", SYSTEM1, "--output", tmp_path / "first", "--prefix", "s1", cache=cache)
    assert first.exit_code == 0, first.output
    code, _, heavy = kronsub(["codegen", str(SYSTEM1), "--output", "again", "--prefix", "s1"], cache, tmp_path, HEAVY)
    assert code in (0, None) and heavy == []
    names = sorted(p.name for p in (tmp_path / "first").iterdir())
    assert names == ["system1.c", "system1.h"] == sorted(p.name for p in (tmp_path / "again").iterdir())
    for name in names:
        assert (tmp_path / "again" / name).read_bytes() == (tmp_path / "first" / name).read_bytes()


def test_what_the_output_depends_on_derives_again(tmp_path, monkeypatch, loaded):
    cache = tmp_path / "cache"
    model = tmp_path / "system1.yaml"
    model.write_text(SYSTEM1.read_text())
    args = ("derive", model, "--format", "json")
    first = cli(*args, cache=cache)
    assert first.exit_code == 0 and len(loaded) == 1
    assert cli(*args, cache=cache).stdout == first.stdout and len(loaded) == 1  # kept
    assert cli(*args, "--no-cache", cache=cache).stdout == first.stdout and len(loaded) == 2
    assert cli("derive", model, "--format", "markdown", cache=cache).exit_code == 0 and len(loaded) == 3
    model.write_text(SYSTEM1.read_text().replace("value: 9.81", "value: 9.80"))
    changed = cli(*args, cache=cache)
    assert changed.exit_code == 0 and len(loaded) == 4 and changed.stdout != first.stdout
    real = kept.code_fingerprint  # kronsub's source, its templates with it
    monkeypatch.setattr(kept, "code_fingerprint", lambda: "other" + real())
    assert cli(*args, cache=cache).stdout == changed.stdout and len(loaded) == 5


def test_a_check_against_a_kept_output(tmp_path, loaded):
    """``derive --check`` compares with the kept text as with a derived one."""
    cache = tmp_path / "cache"
    out = tmp_path / "s1.json"
    assert cli("derive", SYSTEM1, "--output", out, cache=cache).exit_code == 0  # markdown text in a .json file
    assert cli("derive", SYSTEM1, "--format", "json", "--output", out, cache=cache).exit_code == 0
    assert len(loaded) == 2
    checked = cli("derive", SYSTEM1, "--check", out, cache=cache)
    assert checked.exit_code == 0 and "up to date" in checked.output and len(loaded) == 2
    out.write_text(out.read_text() + "\n")
    checked = cli("derive", SYSTEM1, "--check", out, cache=cache)
    assert checked.exit_code == 1 and "differs" in checked.output and len(loaded) == 2


@pytest.mark.parametrize("command", [["derive"], ["codegen", "--output"], ["simulate", "--t", "0.01"]])
def test_a_command_that_warned_warns_again(command, tmp_path):
    """A derived run that said a warning (here a voltage added to a force) is not kept: the same
    command again derives again and says it again."""
    text = (MODELS / "electrical" / "series_rlc.yaml").read_text()
    text = text.replace("E: {value: 10, unit: V, description: source voltage switched on at t = 0}",
                        "E: {value: 10, unit: V}\n  F: {value: 1, unit: N}")
    model = tmp_path / "warned.yaml"
    model.write_text(text.replace("voltage: E}", "voltage: E - F}"))
    cache = tmp_path / "cache"
    for _ in range(2):
        result = cli(command[0], model, *command[1:], *([tmp_path / "code"] if command[0] == "codegen" else []),
                     cache=cache)
        assert result.exit_code == 0, result.output
        assert "Warning: " in result.output and "the units do not match" in result.output
