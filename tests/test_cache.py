"""The caches hold data, never code: the known-system JSON format, compiled-library digests,
the cache folder's safety checks and ``kronsub cache info|clear``."""
from __future__ import annotations

import dataclasses
import json
import os
import pickle
import shutil
import subprocess
import sys
import warnings
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

from conftest import MODELS, ROOT, SLOW_MODELS
import kronsub.cache as cache_module
from kronsub.cache import CacheWarning
from kronsub.cli import main
from kronsub.components.base import Body
from kronsub.core.deferred import DeferredMatrix
from kronsub.core.known_system import KnownSystem, ParameterInfo, Transition
from kronsub.emitters import EMITTERS
from kronsub.model import cache_format
from kronsub.model.derive import load_cached, store_cached
from kronsub.model.loader import load_model

BUNDLED = sorted(p for p in MODELS.glob("*/*.yaml") if p.relative_to(ROOT).as_posix() not in SLOW_MODELS) \
    + sorted((ROOT / "tests" / "models").glob("*.yaml"))
SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def _walk(value, path="system"):
    """Every expression and matrix of a stored value, with where it sits (for exact comparison)."""
    if isinstance(value, sympy.MatrixBase):  # a matrix built when first read is stored as the one it built
        kind = sympy.MutableDenseMatrix if isinstance(value, DeferredMatrix) else type(value)
        yield path, kind.__name__ + sympy.srepr(list(value)) + str(value.shape)
    elif isinstance(value, sympy.Basic):
        yield path, sympy.srepr(value)
    elif dataclasses.is_dataclass(value):
        yield path, type(value).__name__
        for f in dataclasses.fields(value):
            yield from _walk(getattr(value, f.name), f"{path}.{f.name}")
    elif isinstance(value, Sequence) and not isinstance(value, str):  # also PlacedBodies
        for i, x in enumerate(value):
            yield from _walk(x, f"{path}[{i}]")
    elif isinstance(value, Mapping):  # a dict, or points placed as they are read (PlacedPoints)
        for k, x in value.items():
            yield from _walk(x, f"{path}[{k!r}]")
    else:
        yield path, repr(value)


# ---------------------------------------------------------------------------------------------
# The known-system format
# ---------------------------------------------------------------------------------------------

_FRESH: dict = {}


def fresh(path) -> KnownSystem:
    """The model derived without any cache (once per test run)."""
    if path not in _FRESH:
        _FRESH[path] = load_model(path, cache=False).derive(cache=False)
    return _FRESH[path]


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_every_bundled_model_round_trips_exactly(path):
    """derive -> store -> load gives the same tree, node for node (srepr), for the known
    system and its transition, parameters and bodies."""
    system = fresh(path)
    assert system.parameters and system.transition is not None
    assert system.bodies or path.parent.name == "electrical"  # circuits have no bodies
    back = cache_format.loads(cache_format.dumps(system), KnownSystem)
    assert back == system
    assert list(_walk(back)) == list(_walk(system))
    parts = ((system.transition, Transition), (system.parameters[0], ParameterInfo),
             *(((system.bodies[0], Body),) if system.bodies else ()))
    for part, cls in parts:
        again = cache_format.loads(cache_format.dumps(part), cls)
        assert list(_walk(again)) == list(_walk(part))


def test_every_number_kind_and_function_round_trips():
    x, y = sympy.Symbol("x", real=True), sympy.Symbol("y", positive=True, integer=False)
    exprs = [sympy.Float("0.1", 30) * x, sympy.Float(-2.5e-300), sympy.Rational(-7, 3) * sympy.pi,
             sympy.Integer(10) ** 40 + x, sympy.E ** y, sympy.atan2(y, x) + sympy.Abs(x) * sympy.sign(y),
             sympy.log(sympy.cosh(x)) - sympy.asin(x / 2) + sympy.acos(x) * sympy.atan(y),
             sympy.tan(x) * sympy.tanh(y) / sympy.sinh(x), sympy.sqrt(x ** 2 + y)]
    info = ParameterInfo("p", x, exprs[0], "kg", "a mass")
    for e in exprs:
        back = cache_format.loads(cache_format.dumps(ParameterInfo("p", x, e)), ParameterInfo)
        assert sympy.srepr(back.value) == sympy.srepr(e)
        assert back.value.free_symbols == e.free_symbols  # assumptions kept
    assert cache_format.loads(cache_format.dumps(info)) == info


def test_values_off_the_whitelist_are_not_stored():
    x = sympy.Symbol("x")
    for bad in (sympy.Function("f")(x), sympy.Dummy("d"), sympy.Integral(x, x), sympy.besselj(0, x)):
        with pytest.raises(cache_format.CacheFormatError):
            cache_format.dumps(ParameterInfo("p", x, bad))
    with pytest.raises(cache_format.CacheFormatError):
        cache_format.dumps({"a": object()})
    with pytest.raises(cache_format.CacheFormatError):  # more digits than JSON integers may have
        cache_format.dumps(ParameterInfo("p", x, sympy.Integer(10) ** 5000 + x))


def _stored(system) -> dict:
    return json.loads(cache_format.dumps(system))


def _text(data: dict) -> str:
    return json.dumps(data, separators=(",", ":"))


def _mutations(data: dict):
    """Damaged, foreign or hostile variants of a stored system's JSON."""
    nodes = data["nodes"]
    first_op = next(i for i, n in enumerate(nodes) if n[0] in ("Add", "Mul"))
    yield "other version", {**data, "format": "kronsub-known-system/0"}
    yield "extra key", {**data, "code": "print(1)"}
    for head in ("Function", "Symbol", "eval", "__import__", "Integral", "Lambda", "os.system"):
        bad = [list(n) for n in nodes]
        bad[first_op] = [head, *bad[first_op][1:]]
        yield f"head {head}", {**data, "nodes": bad}
    forward = [list(n) for n in nodes]
    forward[first_op] = [forward[first_op][0], len(nodes) - 1 + 5, *forward[first_op][2:]]
    yield "reference to a later node", {**data, "nodes": forward}
    self_ref = [list(n) for n in nodes]
    self_ref[first_op] = [self_ref[first_op][0], first_op, *self_ref[first_op][2:]]
    yield "reference to itself", {**data, "nodes": self_ref}
    for why, ref in (("negative", -1), ("bool", True), ("float", 0.0), ("string", "0"), ("list", [0])):
        bad = [list(n) for n in nodes]
        bad[first_op] = [bad[first_op][0], ref, *bad[first_op][2:]]
        yield f"{why} reference", {**data, "nodes": bad}
    last_function = max(i for i, n in enumerate(nodes) if n[0] in ("sin", "cos", "Pow"))
    for why, ref in (("negative", -1), ("bool", True), ("later", len(nodes))):
        bad = [list(n) for n in nodes]
        bad[last_function] = [bad[last_function][0], ref, *bad[last_function][2:]]
        yield f"{why} reference of a function or power", {**data, "nodes": bad}
    yield "unknown class", json.loads(_text(data).replace('"c":"Body"', '"c":"Popen"', 1))
    value = json.loads(json.dumps(data["value"]))
    value["f"]["__class__"] = None
    yield "unknown field", {**data, "value": value}
    value = json.loads(json.dumps(data["value"]))
    del value["f"]["name"]
    yield "missing field", {**data, "value": value}
    symbols = [list(n) for n in nodes]
    s = next(i for i, n in enumerate(symbols) if n[0] == "S")
    symbols[s] = ["S", "x", "__import__('os')"]
    yield "unknown assumption", {**data, "nodes": symbols}
    yield "float", {**data, "nodes": nodes + [["F", 0, "zz", 1, 2, 53]]}
    yield "matrix shape", json.loads(_text(data).replace('"m":["Matrix",', '"m":["Matrix",7,', 1))


def test_damaged_foreign_or_hostile_files_are_misses():
    system = load_model(SYSTEM1, cache=False).derive(cache=False)
    data = _stored(dataclasses.replace(system, transition=None))
    seen = 0
    for why, variant in _mutations(data):
        with pytest.raises(cache_format.CacheFormatError):
            cache_format.loads(json.dumps(variant), KnownSystem)
        seen += 1
    assert seen > 15
    text = cache_format.dumps(dataclasses.replace(system, transition=None))
    for bad in (text[: len(text) // 2], "", "[" * 100_000, "null", '"x"', "\x00"):
        with pytest.raises(cache_format.CacheFormatError):
            cache_format.loads(bad, KnownSystem)
    with pytest.raises(cache_format.CacheFormatError):  # a Transition is not a KnownSystem
        cache_format.loads(cache_format.dumps(system.transition), KnownSystem)


def test_a_damaged_cache_entry_is_rebuilt(cache):
    model = load_model(SYSTEM1)
    model.derive()
    key = model.content_hash
    entry = cache / f"{key}.system.json"
    entry.write_text(entry.read_text()[:-40])
    assert load_cached(key) is None
    assert model.derive() == fresh(SYSTEM1)
    assert load_cached(key) == fresh(SYSTEM1)  # stored again


def test_a_planted_pickle_is_never_executed(cache, tmp_path):
    """A pickle that would create a canary, under the old and the new cache file names."""
    canary = tmp_path / "canary"

    class Plant:
        def __reduce__(self):
            return (os.system, (f"touch {canary}",))

    model = load_model(SYSTEM1)
    cache.mkdir(parents=True)
    payload = pickle.dumps(Plant())
    for part in ("system", "transition"):
        for ext in ("json", "pickle"):
            (cache / f"{model.content_hash}.{part}.{ext}").write_bytes(payload)
    system = model.derive()
    assert not canary.exists()
    assert system == fresh(SYSTEM1)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.stem)
def test_output_is_identical_with_and_without_the_cache(cache, path):
    """Every bundled model, every format: derived afresh and read from the cache, the same bytes."""
    system = fresh(path)
    model = load_model(path)
    store_cached(model.content_hash, system)
    hit = model.derive()
    assert hit is not system and load_cached(model.content_hash) is not None
    for fmt, emit in EMITTERS.items():
        assert emit(hit) == emit(system), (path.name, fmt)


def test_the_same_text_under_two_names_prints_each_name(cache, tmp_path):
    """The model's name (its file's stem, when it has no `name:`) comes from the current file."""
    text = "\n".join(line for line in SYSTEM1.read_text().splitlines() if not line.startswith(("name:",)))
    for stem in ("first", "second"):
        (tmp_path / f"{stem}.yaml").write_text(text)
    runner = CliRunner()
    one = runner.invoke(main, ["derive", str(tmp_path / "first.yaml")])
    two = runner.invoke(main, ["derive", str(tmp_path / "second.yaml")])
    assert one.exit_code == two.exit_code == 0, two.output
    assert one.output.startswith("# first") and two.output.startswith("# second")
    assert "first" not in two.output
    assert two.output == runner.invoke(main, ["derive", str(tmp_path / "second.yaml"), "--no-cache"]).output


# ---------------------------------------------------------------------------------------------
# The cache folder
# ---------------------------------------------------------------------------------------------

def test_a_folder_others_may_write_is_refused(cache, monkeypatch):
    import kronsub.cache

    cache.mkdir()
    cache.chmod(0o777)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        system = load_model(SYSTEM1).derive()
    assert any(issubclass(w.category, CacheWarning) and "group or others" in str(w.message) for w in caught)
    assert list(cache.iterdir()) == []
    assert system == fresh(SYSTEM1)
    monkeypatch.setattr(kronsub.cache, "_WARNED", set())  # warned once per process
    result = CliRunner().invoke(main, ["derive", str(SYSTEM1)])
    assert result.exit_code == 0 and "Warning: not using the cache folder" in result.output


def test_a_new_cache_folder_is_private_whatever_the_umask(cache):
    old = os.umask(0o002)
    try:
        load_model(SYSTEM1).derive()
    finally:
        os.umask(old)
    assert cache.stat().st_mode & 0o777 == 0o700 and any(cache.iterdir())


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="needs root to give a folder away")
def test_a_folder_of_another_user_is_refused(cache):
    cache.mkdir(mode=0o755)
    os.chown(cache, 65534, 65534)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_model(SYSTEM1).derive()
    assert any("another user" in str(w.message) for w in caught)
    assert list(cache.iterdir()) == []


def test_cache_info_and_clear_touch_only_kronsub_entries(cache):
    load_model(SYSTEM1).derive()
    (cache / "notes.txt").write_text("mine")
    (cache / "native").mkdir()
    (cache / "native" / "keep-me").mkdir()
    (cache / "native" / "model-0123456789abcdef01234567").mkdir()
    (cache / "native" / "model-0123456789abcdef01234567" / "libmodel.so").write_bytes(b"x" * 10)
    runner = CliRunner()
    info = runner.invoke(main, ["cache", "info"])
    assert info.exit_code == 0, info.output
    assert str(cache) in info.output and "derived known systems: 1" in info.output
    assert "compiled models: 1" in info.output
    cleared = runner.invoke(main, ["cache", "clear"])
    assert cleared.exit_code == 0, cleared.output
    assert sorted(p.name for p in cache.rglob("*")) == ["keep-me", "native", "notes.txt"]
    assert "derived known systems: 0" in runner.invoke(main, ["cache", "info"]).output


UNWRITABLE = [p for p in ("/proc", "/proc/self", "/sys/kernel") if os.path.isdir(p)]


@pytest.mark.parametrize("folder", UNWRITABLE)
def test_cache_info_says_a_folder_no_file_can_be_created_in_is_not_used(folder, monkeypatch):
    """Owned by the user (root) and not writable by others, yet no file can be created there: the
    probe, not the permissions, decides."""
    monkeypatch.setenv("KRONSUB_CACHE_DIR", folder)
    result = CliRunner().invoke(main, ["cache", "info"])
    assert result.exit_code == 0, result.output
    assert result.output.startswith(f"cache: {folder} (not used: no file can be created in it (")


def test_cache_info_says_a_file_or_a_path_under_one_is_not_used(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    for folder, reason in [(tmp_path / "file", "it is not a folder"),
                           (tmp_path / "file" / "cache", f"it cannot be created: {tmp_path / 'file'} is not a folder"),
                           (tmp_path / "new" / "cache", None)]:
        monkeypatch.setenv("KRONSUB_CACHE_DIR", str(folder))
        result = CliRunner().invoke(main, ["cache", "info"])
        assert result.exit_code == 0, result.output
        first = result.output.splitlines()[0]
        assert first == (f"cache: {folder} (not used: {reason})" if reason else f"cache: {folder} (empty)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # info creates nothing, leaves no probe


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root may write to a read-only folder")
def test_a_read_only_folder_is_not_used(cache, monkeypatch):
    cache.mkdir(mode=0o500)
    try:
        result = CliRunner().invoke(main, ["cache", "info"])
        assert "(not used: no file can be created in it (Permission denied))" in result.output, result.output
    finally:
        cache.chmod(0o700)


@pytest.mark.parametrize("folder", UNWRITABLE[:1] + ["/proc/kronsub-cache"])
def test_commands_work_without_a_cache_that_cannot_be_written(folder, monkeypatch):
    import kronsub.cache

    monkeypatch.setenv("KRONSUB_CACHE_DIR", folder)
    monkeypatch.setattr(kronsub.cache, "_WARNED", set())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        system = load_model(SYSTEM1).derive()
    assert system == fresh(SYSTEM1)
    assert [str(w.message).split(":")[0] for w in caught if issubclass(w.category, CacheWarning)] == \
        [f"not using the cache folder {folder}"]
    result = CliRunner().invoke(main, ["derive", str(SYSTEM1)])
    assert result.exit_code == 0 and result.stdout.startswith("# System I"), result.output


def test_a_usable_folder_keeps_no_probe(cache):
    load_model(SYSTEM1).derive()
    assert CliRunner().invoke(main, ["cache", "info"]).exit_code == 0
    assert not [p for p in cache.iterdir() if "probe" in p.name]


# ---------------------------------------------------------------------------------------------
# Compiled libraries
# ---------------------------------------------------------------------------------------------

needs_cc = pytest.mark.skipif(shutil.which(os.environ.get("CC", "gcc").split()[0] if os.environ.get("CC") else "gcc")
                              is None, reason="no C compiler")


def _library(system) -> Path:
    """The library ``simulate`` builds for ``system`` (the generated C, its identity, the
    integrators), built but not loaded here (a test that changes it in place would change this
    process's mapped copy)."""
    from kronsub.simulation import compiled
    from kronsub.simulation.native import compile_library

    identity = compiled.identity_source(compiled.fingerprint(system, canonical=False), len(system.coordinates),
                                        len(system.parameters))
    return compile_library([*compiled.generated_sources(system, canonical=False), identity], "model")


def _simulate(cache_folder: Path, *args) -> subprocess.CompletedProcess:
    """kronsub simulate in a fresh process (a crash there does not take the tests down)."""
    env = {**os.environ, "KRONSUB_CACHE_DIR": str(cache_folder)}
    return subprocess.run([sys.executable, "-m", "kronsub", "simulate", str(SYSTEM1), "--t", "0.5", "--dt", "0.25",
                           *args], capture_output=True, text=True, env=env, timeout=300)


@needs_cc
def test_a_library_is_recorded_and_verified(cache):
    from kronsub.simulation.native import sidecar, verified

    library = _library(load_model(SYSTEM1).derive())
    assert verified(library)
    digest, key = sidecar(library).read_text().split()  # its bytes' sha256, its sources' key
    assert len(digest) == 64 and library.parent.name.endswith(key[:24]) and verified(library, key)
    assert not verified(library, "0" * 64)  # a folder moved under another key's name
    assert not [p for p in library.parent.iterdir() if p.name.endswith(".tmp")]


@needs_cc
def test_a_planted_library_is_never_loaded(cache, tmp_path):
    from kronsub.simulation.native import sidecar, verified

    library = _library(load_model(SYSTEM1).derive())
    canary = tmp_path / "canary"
    plant = tmp_path / "plant.c"
    plant.write_text('#include <stdio.h>\n__attribute__((constructor)) static void grow(void) {\n'
                     f'  FILE *f = fopen("{canary}", "w"); if (f) fclose(f);\n}}\n')
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(library), str(plant)], check=True)
    assert not verified(library)  # the sidecar records the real library's digest
    result = _simulate(cache)
    assert result.returncode == 0, result.stderr
    assert not canary.exists()
    assert verified(library)  # rebuilt
    sidecar(library).unlink()  # a library without a sidecar is not trusted either
    assert not verified(library)


@needs_cc
def test_a_truncated_library_is_rebuilt_instead_of_crashing(cache):
    from kronsub.simulation.native import verified

    library = _library(load_model(SYSTEM1).derive())
    data = library.read_bytes()
    library.write_bytes(data[: len(data) // 3])
    result = _simulate(cache)
    assert result.returncode == 0, (result.returncode, result.stderr)
    assert verified(library) and library.stat().st_size == len(data)


@needs_cc
def test_compiled_models_go_to_a_private_folder_when_the_cache_is_unsafe(cache):
    cache.mkdir()
    cache.chmod(0o757)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CacheWarning)
        library = _library(load_model(SYSTEM1, cache=False).derive(cache=False))
    assert cache not in library.parents
    assert not (library.parent.parent.stat().st_mode & 0o077)


@pytest.mark.parametrize("spec", ["  arm: {model: arm.yaml}\n",
                                  "  arm: *arm\n",
                                  "  arm: {<<: *arm}\n"])
def test_a_changed_sub_model_changes_the_key_however_it_is_named(tmp_path, spec):
    """The key reads only an outline of each file (files.model_key): a sub-model named
    through an alias or a merge still counts."""
    from kronsub.model.files import model_key

    arm = tmp_path / "arm.yaml"
    arm.write_text(SYSTEM1.read_text(encoding="utf-8"), encoding="utf-8")
    top = tmp_path / "top.yaml"
    top.write_text("name: top\nshared: &arm {model: arm.yaml}\ncomponents:\n" + spec
                   + "coordinates: [theta, phi]\n", encoding="utf-8")
    before = model_key(top)
    assert model_key(top) == before
    arm.write_text(arm.read_text(encoding="utf-8").replace("value: 9.81", "value: 9.8"), encoding="utf-8")
    assert model_key(top) != before


def test_a_file_that_names_no_model_is_keyed_by_its_text_alone(monkeypatch):
    """The key of a file that plainly names no sub-model and no scene is read off its text
    (files.alone): the same key as reading its outline gives, for every bundled model."""
    from kronsub.model import files

    keys = {path: files.model_key(path) for path in BUNDLED}
    assert any(files.alone(path.read_text(encoding="utf-8")) for path in BUNDLED)
    monkeypatch.setattr(files, "alone", lambda text: False)
    assert {path: files.model_key(path) for path in BUNDLED} == keys


def test_the_key_is_made_when_first_asked_for(cache):
    """A derivation without the cache never makes the model's key (nor hashes kronsub's code);
    asked for, it is the key the outline of the file gives (`model_key`), for every bundled model."""
    from kronsub.model import derive, files

    for path in BUNDLED:
        model = load_model(path, cache=False)
        model.derive(cache=False)
        assert "content_hash" not in model.__dict__
        assert model.content_hash == files.model_key(path) and model.content_hash


@pytest.mark.parametrize("spec", ['  arm: {"mod\\x65l": arm.yaml}\n', "  arm: {? model : arm.yaml}\n"])
def test_a_sub_model_named_in_escapes_still_counts(tmp_path, spec):
    from kronsub.model.files import model_key

    arm = tmp_path / "arm.yaml"
    arm.write_text(SYSTEM1.read_text(encoding="utf-8"), encoding="utf-8")
    top = tmp_path / "top.yaml"
    top.write_text("name: top\ncomponents:\n" + spec + "coordinates: [theta, phi]\n", encoding="utf-8")
    before = model_key(top)
    arm.write_text(arm.read_text(encoding="utf-8").replace("value: 9.81", "value: 9.8"), encoding="utf-8")
    assert model_key(top) != before


# ---------------------------------------------------------------------------------------------
# Issue 31: clearing never leaves the cache; entries private, sealed, read bounded; libraries
# checked to belong to their model; a build survives `cache clear`
# ---------------------------------------------------------------------------------------------

NATIVE_NAME = "model-0123456789abcdef01234567"
INDEX_NAME = "0" * 64 + ".json"


def _precious(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "precious").write_text("keep me")
    return folder


def test_cache_clear_never_follows_a_linked_native_folder(cache, tmp_path):
    outside = tmp_path / "outside"
    _precious(outside / NATIVE_NAME)
    _precious(outside / "index")
    (outside / "index" / INDEX_NAME).write_text("{}")
    load_model(SYSTEM1).derive()
    (cache / "native").symlink_to(outside)
    result = CliRunner().invoke(main, ["cache", "clear"])
    assert result.exit_code == 0, result.output
    assert (outside / NATIVE_NAME / "precious").read_text() == "keep me"
    assert (outside / "index" / INDEX_NAME).exists() and (outside / "index" / "precious").exists()
    assert (cache / "native").is_symlink()  # not kronsub's: left as it is
    from kronsub.simulation import native

    assert outside not in native.build_root().parents and native.build_root() != outside  # nor built in


def test_cache_clear_removes_linked_entries_as_links_only(cache, tmp_path):
    outside = _precious(tmp_path / "outside")
    (outside / "system.json").write_text("mine")
    load_model(SYSTEM1).derive()
    native = cache / "native"
    (native / "index").mkdir(parents=True)
    (native / NATIVE_NAME).symlink_to(outside)  # a compiled model's folder that is a link
    (native / "index" / INDEX_NAME).symlink_to(outside / "precious")
    (cache / ("1" * 64 + ".system.json")).symlink_to(outside / "system.json")
    os.mkfifo(cache / ("2" * 64 + ".transition.json"))  # listed without opening it
    assert "derived known systems: 1 (" in CliRunner().invoke(main, ["cache", "info"]).output
    result = CliRunner().invoke(main, ["cache", "clear"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in outside.iterdir()) == ["precious", "system.json"]
    assert (outside / "precious").read_text() == "keep me"
    assert not any(p.is_symlink() for p in cache.rglob("*")) and not list(cache.glob("2" * 64 + "*"))


def test_cache_info_and_clear_count_alike(cache):
    load_model(SYSTEM1).derive()
    load_model(MODELS / "hoffmann" / "system2.yaml").derive()
    runner = CliRunner()
    info = runner.invoke(main, ["cache", "info"]).output
    cleared = runner.invoke(main, ["cache", "clear"]).output
    assert "derived known systems: 2 (" in info and "derived known systems: 2 (" in cleared
    counted = [line.split(": ", 1)[1] for line in info.splitlines()[1:]]
    assert all(part in cleared for part in counted), (info, cleared)


def _modes(folder: Path) -> set[tuple[str, int]]:
    return {("d" if p.is_dir() else "f", p.stat().st_mode & 0o777) for p in folder.rglob("*")}


@needs_cc
def test_every_entry_is_private_whatever_the_umask(cache):
    (cache / "native").mkdir(parents=True)
    cache.chmod(0o755)
    (cache / "native").chmod(0o755)  # as an older kronsub left it
    old = os.umask(0)
    try:
        result = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.1"])
    finally:
        os.umask(old)
    assert result.exit_code == 0, result.output
    assert (cache / "native" / "index").is_dir() and list(cache.glob("*.system.json"))
    assert _modes(cache) == {("d", 0o700), ("f", 0o600)}
    assert cache.stat().st_mode & 0o777 == 0o755  # the user's own folder, as the user made it


def _one_digit_changed(path: Path) -> None:
    """A digit of an integer node changed, the entry's seal left as it was."""
    data = path.read_bytes()
    at = data.index(b'["N",') + 5
    while not data[at:at + 1].isdigit():
        at += 1
    digit = data[at:at + 1]
    path.write_bytes(data[:at] + (b"7" if digit != b"7" else b"3") + data[at + 1:])


def test_a_known_system_entry_with_one_digit_changed_is_ignored_and_rebuilt(cache):
    model = load_model(SYSTEM1)
    model.derive()
    key = model.content_hash
    for part in ("system", "inertia"):
        _one_digit_changed(cache / f"{key}.{part}.json")
    assert load_cached(key) is None
    assert model.derive() == fresh(SYSTEM1)
    assert load_cached(key) == fresh(SYSTEM1)  # stored again
    out = CliRunner().invoke(main, ["derive", str(SYSTEM1)]).output
    assert out == CliRunner().invoke(main, ["derive", str(SYSTEM1), "--no-cache"]).output


def test_an_entry_others_may_write_is_ignored(cache):
    model = load_model(SYSTEM1)
    model.derive()
    entry = cache / f"{model.content_hash}.system.json"
    entry.chmod(0o666)
    assert load_cached(model.content_hash) is None
    entry.chmod(0o600)
    assert load_cached(model.content_hash) == fresh(SYSTEM1)


def _limited(child: str, cache_folder: Path, *args) -> subprocess.CompletedProcess:
    """``kronsub`` in a child limited to 2 GiB of memory and 60 s (a regression fails the test
    instead of taking the machine's memory or hanging it)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    env = {**os.environ, "KRONSUB_CACHE_DIR": str(cache_folder)}
    return subprocess.run([sys.executable, "-m", "kronsub", child, *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=60, preexec_fn=limit)


@pytest.mark.parametrize("plant", ["fifo", "zero", "folder"])
def test_an_entry_that_is_not_a_regular_file_is_ignored(cache, plant):
    model = load_model(SYSTEM1)
    model.derive()
    for part in ("system", "inertia", "transition", "inertia-transition"):
        entry = cache / f"{model.content_hash}.{part}.json"
        entry.unlink()
        if plant == "fifo":
            os.mkfifo(entry)
        elif plant == "zero":
            entry.symlink_to("/dev/zero")
        else:
            entry.mkdir()
    result = _limited("derive", cache, SYSTEM1)
    assert result.returncode == 0, result.stderr
    assert result.stdout == CliRunner().invoke(main, ["derive", str(SYSTEM1), "--no-cache"]).output


def test_a_node_table_doubling_a_term_is_refused_quickly():
    nodes = [["S", "q", "real"]] + [["Add", i, i] for i in range(80)]
    text = json.dumps({"format": cache_format.FORMAT, "nodes": nodes,
                       "value": {"t": [{"x": len(nodes) - 1}]}})
    with pytest.raises(cache_format.CacheFormatError, match="as a tree"):
        cache_format.loads(text)


def _first_matrix(value):
    if isinstance(value, dict):
        if "m" in value:
            return value["m"]
        for x in value.values():
            found = _first_matrix(x)
            if found is not None:
                return found
    elif isinstance(value, list):
        for x in value:
            found = _first_matrix(x)
            if found is not None:
                return found
    return None


def test_a_sealed_entry_doubling_a_term_80_times_is_rebuilt_not_walked(cache):
    """Even with a valid seal (anyone who can write an entry can compute a sha256), an entry
    whose expressions grow as trees without bound is refused: `simulate` derives afresh."""
    from kronsub import cache as kcache

    model = load_model(SYSTEM1)
    model.derive()
    expected = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.2"]).output
    for part in ("system", "inertia"):
        entry = cache / f"{model.content_hash}.{part}.json"
        data = json.loads(kcache.load_entry(entry))
        nodes = data["nodes"]
        q = next(i for i, n in enumerate(nodes) if n[0] == "S")
        first = len(nodes)
        nodes.append(["Add", q, q])
        for i in range(79):
            nodes.append(["Add", first + i, first + i])
        matrix = _first_matrix(data["value"])
        matrix[3][0] = len(nodes) - 1
        kcache.store_entry(entry, json.dumps(data).encode())
    result = _limited("simulate", cache, SYSTEM1, "--t", "0.2")
    assert result.returncode == 0, result.stderr
    assert result.stdout == expected


@needs_cc
def test_swapped_index_entries_never_run_one_model_with_the_others_library(cache):
    from kronsub import cache as kcache
    from kronsub.api import simulate
    from kronsub.simulation import compiled

    one = load_model(SYSTEM1).derive()
    two = load_model(MODELS / "examples" / "double_pendulum.yaml").derive()
    expected = {s.name: simulate(s, t=0.5, dt=0.25, dataframe=False).y for s in (one, two)}
    keys = [compiled.fingerprint(s, canonical=False) for s in (one, two)]  # dop853's libraries
    files = [compiled._index_file(k) for k in keys]
    entries = [kcache.load_entry(f) for f in files]
    kcache.store_entry(files[0], entries[1])
    kcache.store_entry(files[1], entries[0])
    assert compiled.lookup(keys[0]) is not None  # a verified library, of the other model
    assert not compiled.belongs(compiled.lookup(keys[0]), keys[0], len(one.coordinates), len(one.parameters))
    for system in (one, two):
        library = compiled.compiled_library(system, canonical=False)
        assert compiled.belongs(library, compiled.fingerprint(system, canonical=False), len(system.coordinates),
                                len(system.parameters))
        np.testing.assert_array_equal(simulate(system, t=0.5, dt=0.25, dataframe=False).y, expected[system.name])


@needs_cc
def test_a_library_loaded_for_other_counts_is_refused(cache):
    from kronsub.simulation.native import NativeError, NativeModel

    system = load_model(SYSTEM1).derive()
    library = _library(system)
    n, p = len(system.coordinates), len(system.parameters)
    assert NativeModel(library, n, p).nq == n
    with pytest.raises(NativeError, match="was built for"):
        NativeModel(library, n + 1, p)


@needs_cc
def test_cache_clear_during_a_build_rebuilds_instead_of_blaming_the_compiler(cache, monkeypatch):
    from kronsub import cache as kcache
    from kronsub.simulation import compiled, native

    real = native._run_compiler
    cleared = []

    def clearing(command, cwd):
        if not cleared:  # `kronsub cache clear` in another terminal, just as gcc starts
            cleared.append(kcache.clear())
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", clearing)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = compiled.native_model(load_model(SYSTEM1).derive())
    assert cleared and model.path.is_file()
    assert not [w for w in caught if "compiler" in str(w.message)]
    result = CliRunner().invoke(main, ["simulate", str(SYSTEM1), "--t", "0.1"])
    assert result.exit_code == 0 and "compiler" not in result.output


@needs_cc
def test_a_library_removed_between_build_and_load_is_built_again(cache, monkeypatch):
    from kronsub.simulation import compiled

    real = compiled.compiled_library
    calls = []

    def removed(system, outputs=None, jacobian=False, canonical=True):
        library = real(system, outputs, jacobian, canonical)
        if not calls:
            shutil.rmtree(cache / "native")
        calls.append(library)
        return library

    monkeypatch.setattr(compiled, "compiled_library", removed)
    system = load_model(SYSTEM1).derive()
    model = compiled.native_model(system)  # loaded already (checked to belong), or built again
    assert calls
    values = np.ones(len(system.parameters))
    assert np.all(np.isfinite(model.rhs(0.0, np.full(2 * len(system.coordinates), 0.1), values)))


@needs_cc
def test_a_cache_cleared_again_and_again_still_gets_the_model_built(cache, monkeypatch):
    """`kronsub cache clear` in a loop meanwhile: the build moves to the process's private
    temporary folder after two tries; the run uses C, and says nothing of a compiler."""
    from kronsub import cache as kcache
    from kronsub.simulation import compiled, native

    real = native._run_compiler

    def clearing(command, cwd):
        kcache.clear()
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", clearing)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = compiled.native_model(load_model(SYSTEM1).derive())
    assert cache not in model.path.parents and model.path.is_file()
    assert not [w for w in caught if "compiler" in str(w.message)]


def test_a_changed_template_changes_every_key(monkeypatch, tmp_path):
    """The templates may be installed apart from the package (``kronsub.templates``): a changed
    one must change the keys of the derivation cache, the kept outputs and the compiled models,
    or a library emitted from the old template would be loaded for the new one."""
    real = resources.files("kronsub.templates")
    copy = tmp_path / "templates"
    copy.mkdir()
    for item in real.iterdir():
        if item.name.endswith(".j2"):
            (copy / item.name).write_bytes(item.read_bytes())
    monkeypatch.setattr(cache_module, "_FINGERPRINT", None)
    monkeypatch.setattr(cache_module.resources, "files", lambda name: copy)
    same = cache_module.code_fingerprint()
    monkeypatch.setattr(cache_module, "_FINGERPRINT", None)
    (copy / "model.c.j2").write_text((copy / "model.c.j2").read_text() + "\n/* changed */\n")
    changed = cache_module.code_fingerprint()
    monkeypatch.setattr(cache_module, "_FINGERPRINT", None)
    assert same != changed
    monkeypatch.undo()
    monkeypatch.setattr(cache_module, "_FINGERPRINT", None)
    assert cache_module.code_fingerprint() == same
