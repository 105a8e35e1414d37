"""The generated C of a sweep's libraries kept (kronsub.sweep.emitted): a second sweep of the same
derived system takes the same files from the cache without emitting them; a system that differs
in anything its C prints (a parameter's value), a damaged or foreign entry, or the cache off
emit it again."""
from __future__ import annotations

import dataclasses
import json

import pytest

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

import kronsub.emitters.code as code  # noqa: E402
import kronsub.simulation.taylor_c as taylor_c  # noqa: E402
from kronsub.cache import KEPT, SEAL, load_entry, store_entry  # noqa: E402
from kronsub.commands.common import scene_system  # noqa: E402
from kronsub.sweep import emitted  # noqa: E402
from kronsub.sweep.ensemble import ensemble_sources, taylor_sources  # noqa: E402

SYSTEM1 = "models/hoffmann/system1.yaml"


@pytest.fixture
def system():
    return scene_system(SYSTEM1, None)[2]


@pytest.fixture
def emissions(monkeypatch):
    """The number of times the model's C and its Taylor integrator were emitted."""
    told = {"c": 0, "taylor": 0}
    emit_c, generated_c = code.emit_c, taylor_c.generated_c

    def counted_c(*args, **kwargs):
        told["c"] += 1
        return emit_c(*args, **kwargs)

    def counted_taylor(*args, **kwargs):
        told["taylor"] += 1
        return generated_c(*args, **kwargs)

    monkeypatch.setattr(code, "emit_c", counted_c)
    monkeypatch.setattr(taylor_c, "generated_c", counted_taylor)
    return told


def test_the_second_sweep_takes_the_same_c_from_the_cache(cache, system, emissions):
    first = ensemble_sources(system), taylor_sources(system, 1e-13)
    assert emissions == {"c": 1, "taylor": 1}
    again = ensemble_sources(system), taylor_sources(system, 1e-13)
    assert emissions == {"c": 1, "taylor": 1}  # nothing emitted
    assert again == first  # the same files, so the same sha256 and library
    taylor_sources(system, 1e-6)  # another order is another integrator
    assert emissions["taylor"] == 2
    kept = sorted((cache / KEPT).glob("*.json"))
    assert len(kept) == 3 and all(load_entry(p) is not None for p in kept)


def test_a_system_that_prints_otherwise_is_emitted_again(cache, system, emissions):
    ensemble_sources(system)
    heavier = dataclasses.replace(system, parameters=tuple(
        dataclasses.replace(p, value=p.value + 1) if i == 0 else p for i, p in enumerate(system.parameters)))
    assert emitted.key("ensemble", heavier, "None") != emitted.key("ensemble", system, "None")
    other = ensemble_sources(heavier)
    assert emissions["c"] == 2
    assert other.files == ensemble_sources(heavier).files and emissions["c"] == 2


def test_a_damaged_or_foreign_entry_is_not_used(cache, system, emissions):
    first = ensemble_sources(system)
    (path,) = (cache / KEPT).glob("*.json")
    data = path.read_bytes()
    path.write_bytes(data.replace(b"double", b"float_", 1))  # the seal no longer matches
    assert ensemble_sources(system) == first and emissions["c"] == 2
    payload = json.loads(load_entry(path).decode())
    for files in ([["../model.c", "int x;"]], [["model.c", 3]], []):  # a path, not a text, nothing
        store_entry(path, json.dumps({**payload, "files": files}).encode())
        assert ensemble_sources(system) == first
    assert emissions["c"] == 5
    path.chmod(0o644)  # others may read it: not this user's private entry
    assert ensemble_sources(system) == first and emissions["c"] == 6
    assert path.read_bytes().startswith(SEAL)


def test_without_a_cache_the_c_is_emitted_each_time(monkeypatch, system, emissions):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", "off")
    assert ensemble_sources(system) == ensemble_sources(system)
    assert emissions["c"] == 2
