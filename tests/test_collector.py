"""kronsub.collector: the cyclic garbage collector paused around loading, deriving and
emitting, and always given back as it was."""
from __future__ import annotations

import gc

import pytest

import kronsub
from conftest import MODELS
from kronsub.collector import collector_paused
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
