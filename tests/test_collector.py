"""kronsub.collector: the cyclic garbage collector paused around loading, deriving and
emitting, and always given back as it was."""
from __future__ import annotations

import gc
import os
import subprocess
import sys

import pytest

import kronsub
from conftest import MODELS
from kronsub.collector import collector_paused, preparation, released
from kronsub.errors import ModelError


@pytest.fixture
def collector_on():
    was = gc.isenabled()
    gc.enable()
    yield
    if not was:
        gc.disable()


def test_pauses_nest_and_restore(collector_on):
    with collector_paused():
        assert not gc.isenabled()
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the inner pause does not turn it on inside the outer one
    assert gc.isenabled()
    gc.disable()
    with collector_paused():
        pass
    assert not gc.isenabled()  # off before: left off
    gc.enable()


def test_the_collector_comes_back_after_an_error_and_after_work(collector_on, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\ncomponents: {a: {type: no_such_type}}\n", encoding="utf-8")
    with pytest.raises(ModelError):
        kronsub.load(bad)
    assert gc.isenabled()
    with pytest.raises(ZeroDivisionError):
        with collector_paused():
            1 / 0
    assert gc.isenabled()
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive(cache=False)
    assert gc.isenabled()
    from kronsub.emitters.code import emit_c
    from kronsub.emitters.text import emit_markdown

    assert emit_markdown(system) and emit_c(system, "s1")
    assert gc.isenabled()


def test_a_command_freezes_what_is_left_at_exit_and_its_outputs_are_whole(tmp_path):
    """The shutdown's collections skip what a command leaves (kronsub.collector.frozen_at_exit):
    frozen once the command's process exits, after its outputs were written and closed."""
    out = tmp_path / "run.csv"
    probe = ("import atexit, gc\n"
             "atexit.register(lambda: print('frozen' if gc.get_freeze_count() else 'not frozen'))\n"
             "from kronsub.cli import main\n"
             f"main(['simulate', {str(MODELS / 'hoffmann' / 'system1.yaml')!r}, '--t', '0.5', '--output', "
             f"{str(out)!r}], standalone_mode=False)\n"
             "print('ran', gc.get_freeze_count() == 0)\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "KRONSUB_CACHE_DIR": str(tmp_path / "cache")})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["ran", "True", "frozen"]  # not during the command: at its exit
    rows = out.read_text().splitlines()
    assert len(rows) == 52 and rows[-1].startswith("0.5,")  # a header and t = 0, 0.01, ..., 0.5


def test_a_preparation_sets_aside_what_it_leaves_until_released(collector_on):
    """kronsub.collector.preparation: paused inside; afterwards the collector is on again and the
    objects then alive are frozen, a collection walks none of them; released() gives them back."""
    assert gc.get_freeze_count() == 0
    with preparation():
        assert not gc.isenabled()
        made = [[i] for i in range(1000)]
    assert gc.isenabled() and gc.get_freeze_count() > 0
    walked = {id(o) for o in gc.get_objects()}  # what a collection walks: not the frozen
    assert not {id(x) for x in made} & walked
    released()
    assert gc.get_freeze_count() == 0
    assert {id(x) for x in made} <= {id(o) for o in gc.get_objects()}
    released()  # twice: nothing more to give back
    gc.freeze()  # frozen by someone else: a preparation leaves it as it is
    try:
        count = gc.get_freeze_count()
        with preparation():
            pass
        assert gc.get_freeze_count() == count
        released()
        assert gc.get_freeze_count() == count
    finally:
        gc.unfreeze()


def test_a_runs_rows_are_written_with_its_preparation_set_aside(collector_on, tmp_path, monkeypatch):
    """kronsub simulate: the run streams its rows with the collector on and the preparation's
    objects frozen; the command gives them back at its end, with the collector as it was."""
    from click.testing import CliRunner

    from kronsub.cli import main
    from kronsub.simulation.table import CsvWriter

    seen = []
    real = CsvWriter.stream

    def stream(self, *args, **kwargs):
        seen.append((gc.isenabled(), gc.get_freeze_count() > 0))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(CsvWriter, "stream", stream)
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "run.csv"
    done = CliRunner().invoke(main, ["simulate", str(MODELS / "hoffmann" / "system1.yaml"), "--t", "0.2",
                                     "--output", str(out)])
    assert done.exit_code == 0, done.output
    assert seen == [(True, True)]
    assert gc.isenabled() and gc.get_freeze_count() == 0
