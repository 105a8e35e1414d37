"""Prepared runs (kronsub/simulation/prepared.py): ``simulate`` run again with the same command
imports no SymPy and writes the very bytes the derived run wrote (CSV and metadata); a record
or a library changed since, not private, or a model file it uses changed is not used, and a run
that would not complete as recorded is left to the derived run; an interrupt keeps the rows as
a derived run's does."""
from __future__ import annotations

import json
import shutil
import stat
from pathlib import Path

import pytest

from conftest import MODELS, ROOT
from helpers.fresh import cli, kronsub
from kronsub.simulation import prepared as prepared_module
from kronsub.simulation.native import NativeModel

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def outputs(folder: Path) -> tuple[bytes, bytes]:
    return (folder / "out.csv").read_bytes(), (folder / "out.json").read_bytes()


def derived(args, cache: Path, folder: Path) -> tuple[bytes, bytes]:
    """The outputs of a run of ``args`` to ``folder/out.csv`` (a derived run the first time,
    recorded in ``cache`` as a prepared run)."""
    folder.mkdir(parents=True)
    result = cli(*args, "--output", folder / "out.csv", cache=cache)
    assert result.exit_code == 0, result.output
    return outputs(folder)


ARGS = ("simulate", SYSTEM1, "--t", "2")


@pytest.fixture(scope="module")
def shared(tmp_path_factory):
    """A cache for the module holding the prepared run of :data:`ARGS`, and its outputs."""
    base = tmp_path_factory.mktemp("prepared")
    reference = derived(ARGS, base / "cache", base / "reference")
    shutil.copytree(base / "cache", base / "pristine")  # as it was then, for the tests that change it
    return base / "cache", reference, base / "pristine"


CASES = {
    "model": ["--t", "10"],
    "scene, --set, gauss4": ["--scene", "free", "--set", "theta=0.3", "--set", "m2=2", "--method", "gauss4",
                             "--t", "3", "--dt", "0.02"],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_same_command_again_imports_no_sympy_and_writes_the_same_bytes(shared, tmp_path, case):
    cache = shared[0]
    args = ["simulate", str(SYSTEM1), *CASES[case]]
    reference = derived(args, cache, tmp_path / "derived")
    (tmp_path / "prepared").mkdir()
    code, _, heavy = kronsub([*args, "--output", "out.csv"], cache, tmp_path / "prepared")
    assert code in (0, None) and heavy == []
    assert outputs(tmp_path / "prepared") == reference
    code, stdout, heavy = kronsub(args, cache, tmp_path)
    assert code in (0, None) and heavy == [] and stdout == reference[0]


@pytest.fixture
def served(monkeypatch):
    """The prepared runs run in this test (a list, one entry per run computed from a record)."""
    calls = []
    real = prepared_module.runs

    def runs(found, progress=None):
        calls.append(found)
        return real(found, progress)

    monkeypatch.setattr(prepared_module, "runs", runs)
    return calls


@pytest.fixture
def own(shared, tmp_path):
    """A copy of the module's cache holding the prepared run of :data:`ARGS` alone (for a test
    that changes it), and the outputs of that run."""
    _, reference, pristine = shared
    shutil.copytree(pristine, tmp_path / "cache")
    return tmp_path / "cache", reference


def test_a_changed_record_is_not_used_and_is_written_again(own, tmp_path, served):
    cache, reference = own
    [record] = (cache / "kept").iterdir()
    assert stat.S_IMODE(record.stat().st_mode) == 0o600 and stat.S_IMODE(record.parent.stat().st_mode) == 0o700
    text = record.read_bytes()
    record.write_bytes(text.replace(b'"rtol": 1e-10', b'"rtol": 1e-09'))  # its seal no longer matches
    assert derived(ARGS, cache, tmp_path / "changed") == reference and served == []
    assert record.read_bytes() == text  # the derived run recorded it anew
    assert derived(ARGS, cache, tmp_path / "again") == reference and len(served) == 1


def test_a_record_others_may_read_is_not_used(own, tmp_path, served):
    cache, reference = own
    [record] = (cache / "kept").iterdir()
    record.chmod(0o644)
    assert derived(ARGS, cache, tmp_path / "open") == reference and served == []


def test_a_changed_library_is_not_used(own, tmp_path, served):
    cache, reference = own
    [library] = (cache / "native").glob("*/lib*.so")
    with open(library, "ab") as fh:
        fh.write(b"\0")
    assert derived(ARGS, cache, tmp_path / "changed") == reference and served == []


def test_a_changed_known_system_file_is_not_served(tmp_path, monkeypatch, served):
    """The model takes spring_pendulum.yaml twice as a known system: a change there (the model
    file itself unchanged) is read, derived and run again."""
    cache = tmp_path / "cache"
    for name in ("coupled_spring_pendulums.yaml", "spring_pendulum.yaml"):
        shutil.copy(ROOT / "tests" / "models" / "sweep" / name, tmp_path / name)
    args = ["simulate", "coupled_spring_pendulums.yaml", "--t", "1"]
    monkeypatch.chdir(tmp_path)
    first = cli(*args, cache=cache)
    assert first.exit_code == 0 and not served
    code, again, heavy = kronsub(args, cache, tmp_path)
    assert code in (0, None) and heavy == [] and again.decode() == first.stdout
    sub = tmp_path / "spring_pendulum.yaml"
    sub.write_text(sub.read_text().replace("m: {value: 0.7,", "m: {value: 0.8,"))
    changed = cli(*args, cache=cache)
    assert changed.exit_code == 0 and not served and changed.stdout != first.stdout
    code, again, heavy = kronsub(args, cache, tmp_path)
    assert code in (0, None) and heavy == [] and again.decode() == changed.stdout


def test_an_interrupt_keeps_the_rows_as_a_derived_run_does(own, tmp_path, monkeypatch, served):
    cache, _ = own

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(NativeModel, "integrate", interrupted)
    runs = {}
    for name in ("prepared", "derived"):
        if name == "derived":
            monkeypatch.setattr(prepared_module, "load", lambda key: None)
        out = tmp_path / name / "out.csv"
        out.parent.mkdir()
        result = cli(*ARGS, "--output", out, cache=cache)
        assert result.exit_code == 130 and len(served) == 1, result.output
        runs[name] = result.output.replace(str(out.parent), "FOLDER"), outputs(out.parent)
    assert "Interrupted after t = 0.0: the 1 row computed so far is kept" in runs["prepared"][0]
    meta = json.loads(runs["prepared"][1][1])
    assert meta["status"] == "interrupted" and meta["rows"] == 1
    assert runs["prepared"] == runs["derived"]


def test_a_run_that_would_warn_is_left_to_the_derived_run(own, tmp_path, monkeypatch, served):
    """The energy check of the prepared run (a conservative model's drift) finds a problem: the
    derived run runs instead and writes what it writes (here, no warning: the check was forced)."""
    cache, reference = own
    monkeypatch.setattr(prepared_module, "energy_advice", lambda *args: "drifted")
    out = tmp_path / "warned" / "out.csv"
    out.parent.mkdir()
    result = cli(*ARGS, "--output", out, cache=cache)
    assert result.exit_code == 0 and len(served) == 1 and outputs(out.parent) == reference
    assert "Warning" not in result.output


def test_cache_info_and_clear_count_the_prepared_runs(own):
    cache, _ = own
    assert "kept outputs: 1 " in cli("cache", "info", cache=cache).output
    assert "kept outputs: 1 " in cli("cache", "clear", cache=cache).output
    assert not (cache / "kept").exists()
