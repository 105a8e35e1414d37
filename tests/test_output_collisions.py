"""No output of a command lands on one of its inputs or on another of its outputs: not on a model
file the model uses (``model:``), not on a sweep's table or sweep file, not through a sweep's
metadata file (``runs`` -> ``runs.json``); and ``sweep --force`` removes only what a sweep wrote."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from kronsub.cli import main

ROOT = Path(__file__).resolve().parent.parent
SYSTEM1 = ROOT / "models" / "hoffmann" / "system1.yaml"
ELECTRICAL = ROOT / "models" / "electrical"


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture
def machine(tmp_path):
    """A model that uses another model file (machine.yaml) as a known system, copied to tmp_path."""
    for name in ("synchronous_machine.yaml", "machine.yaml"):
        shutil.copy(ELECTRICAL / name, tmp_path / name)
    return tmp_path / "synchronous_machine.yaml", tmp_path / "machine.yaml"


SIMULATE = ["simulate", "{model}", "--t", "0.01", "-o", "{folder}/run.csv"]


@pytest.mark.parametrize("command", [["derive", "{model}", "-o", "{used}"], ["linearize", "{model}", "-o", "{used}"],
                                     [*SIMULATE, "--meta", "{used}"], [*SIMULATE, "--plot", "{used}"]])
def test_an_output_on_a_model_file_the_model_uses_is_refused(machine, command):
    model, used = machine
    before = used.read_bytes()
    for link in (False, True):  # named as it is, or through a link
        target = used
        if link:
            target = used.parent / "other_name.yaml"
            target.symlink_to(used.name)
        args = [a.format(model=model, used=target, folder=used.parent) for a in command]
        result = invoke(*args)
        assert result.exit_code == 2, result.output
        assert f"is a model file that {model} uses ({used})" in result.output
        assert "hint: choose another" in result.output
        assert used.read_bytes() == before and not (used.parent / "run.csv").exists()


def test_a_model_without_model_files_is_read_once_and_alone(tmp_path):
    from kronsub.model.uses import model_files

    assert model_files(SYSTEM1) == [SYSTEM1]
    loop = tmp_path / "a.yaml"  # a cycle of model files and a missing one: listed, not followed twice
    loop.write_text("components:\n  x: {model: b.yaml}\n  y: {model: missing.yaml}\n")
    (tmp_path / "b.yaml").write_text("components:\n  z: {model: a.yaml}\n")
    assert model_files(loop) == [loop, tmp_path / "b.yaml", tmp_path / "missing.yaml"]


# ------------------------------------------------------------------------------------------
# sweep: its metadata files, its tables, --force
# ------------------------------------------------------------------------------------------

def _sweep(*args):
    pytest.importorskip("distributed")
    pytest.importorskip("pyarrow")
    return invoke("sweep", *args)


def test_a_sweeps_metadata_never_replaces_the_model(tmp_path):
    """``-o runs`` writes ``runs.json`` beside the folder: a JSON model of that name is refused,
    with or without --force, before any run, and is left as it was."""
    import yaml

    model = tmp_path / "runs.json"
    model.write_text(json.dumps(yaml.safe_load(SYSTEM1.read_text())))
    before = model.read_bytes()
    for force in ([], ["--force"]):
        result = _sweep(model, "--grid", "m2=1:2:2", "--t", "0.1", "-o", tmp_path / "runs", *force)
        assert result.exit_code == 2, result.output
        assert f"its metadata {model} is the model file itself" in result.output
        assert "choose another -o" in result.output
    assert model.read_bytes() == before and not (tmp_path / "runs").exists()


@pytest.mark.parametrize("output, trajectories", [("runs", "runs.json"), ("runs.json", "runs")])
def test_a_sweeps_folders_and_metadata_files_are_all_distinct(tmp_path, output, trajectories):
    result = _sweep(SYSTEM1, "--grid", "m2=1:2:2", "--t", "0.1", "-o", tmp_path / output,
                    "--trajectories", tmp_path / trajectories)
    assert result.exit_code == 2 and "metadata" in result.output and "hint: choose another" in result.output, \
        result.output
    assert not any(tmp_path.iterdir())


def test_a_sweeps_table_is_no_output(tmp_path):
    """A Parquet table of runs named runs.json is read, and is no place for -o runs' metadata."""
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    table = tmp_path / "runs.json"
    pq.write_table(pa.table({"m2": [1.0, 2.0]}), table)
    before = table.read_bytes()
    result = _sweep(SYSTEM1, "--table", table, "--t", "0.1", "-o", tmp_path / "runs", "--force")
    assert result.exit_code == 2 and f"its metadata {table} is the --table file itself" in result.output, result.output
    assert table.read_bytes() == before


def _dataset(folder):
    pytest.importorskip("pyarrow")
    from kronsub.sweep.dataset import Dataset

    return Dataset(folder, [("run", "int64")])


@pytest.mark.parametrize("name", [".env", ".git", "notes.txt", ".part-000001.parquet", "part-000002.parquet.bak"])
def test_force_keeps_a_folder_holding_anything_but_a_sweeps_parts(tmp_path, name):
    """--force replaces a sweep's output only: a hidden file, a folder or a near-miss of a part's
    name beside the parts stops it before anything is removed."""
    folder = tmp_path / "runs"
    folder.mkdir()
    (folder / "part-000000.parquet").write_bytes(b"PAR1")
    (folder / name).mkdir() if name == ".git" else (folder / name).write_text("keep me")
    from kronsub.sweep.dataset import DatasetError

    with pytest.raises(DatasetError, match="not a sweep's parts"):
        _dataset(folder).prepare({}, resume=False, force=True)
    assert sorted(p.name for p in folder.iterdir()) == sorted(["part-000000.parquet", name])


def test_force_removes_parts_and_their_temporary_files_through_a_link(tmp_path):
    """A link to a sweep's folder: --force empties the folder it names and keeps the link."""
    real = tmp_path / "real"
    real.mkdir()
    for name in ("part-000000.parquet", "part-000001.parquet", ".part-000002.parquet.abcd_123.tmp"):
        (real / name).write_bytes(b"PAR1")
    link = tmp_path / "runs"
    link.symlink_to(real.name)
    (tmp_path / "runs.json").write_text("{}")
    assert _dataset(link).prepare({}, resume=False, force=True) == set()
    assert link.is_symlink() and real.is_dir() and not any(real.iterdir()) and not (tmp_path / "runs.json").exists()


def test_a_link_to_a_missing_folder_gets_its_folder_made(tmp_path):
    link = tmp_path / "runs"
    link.symlink_to("made/here")
    assert _dataset(link).prepare({}, resume=False, force=False) == set()
    assert link.is_symlink() and (tmp_path / "made" / "here").is_dir()
    assert os.readlink(link) == "made/here"
