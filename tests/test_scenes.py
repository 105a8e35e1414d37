"""Scenes: only the effects a scene switches on are derived, generated and computed.

Independent routes: a scene's equations equal those of the same model file with
the switched-off effects deleted (derived from scratch, cache off), and equal the
full model's with the switched-off effects' parameters set to zero, both at
random states; a switched-off effect is never projected at all.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import sympy
import yaml
from click.testing import CliRunner

from conftest import MODELS
from kronsub.cli import main
from kronsub.effects.loads import Force
from kronsub.emitters.code import emit_c, emit_python
from kronsub.errors import ModelError
from kronsub.model import derive as derive_module
from kronsub.model.loader import load_model
from kronsub.model.scenes import derive_scene, select_scene

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
SYSTEM2 = MODELS / "hoffmann" / "system2.yaml"


def _write(path, document) -> None:
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")


def _without(source, tmp_path, off, name=None):
    """The model file of ``source`` with the effects ``off`` deleted and no scenes."""
    document = yaml.safe_load(source.read_text(encoding="utf-8")) if not isinstance(source, str) \
        else yaml.safe_load(source)
    document.pop("scenes", None)
    for label in off:
        del document["effects"][label]
    path = tmp_path / (name or "pruned.yaml")
    _write(path, document)
    return path


def _numeric(system):
    """``(Mbar, hbar, fbar, V)`` of a system as a function of values by symbol name."""
    exprs = [system.mass_matrix, system.velocity_terms, system.forces, system.potential_energy]
    symbols = sorted(set().union(*(sympy.sympify(e).free_symbols for e in exprs)), key=lambda s: s.name)
    f = sympy.lambdify(symbols, exprs, modules="numpy")

    def at(values):
        return [np.array(x, dtype=float) for x in f(*[values[s.name] for s in symbols])]

    return at


def _random_values(system, rng, fixed=None):
    names = {s.name for e in (system.mass_matrix, system.velocity_terms, system.forces,
                              sympy.sympify(system.potential_energy)) for s in e.free_symbols}
    values = {n: float(rng.uniform(0.5, 1.5)) if n not in {q.name for q in system.coordinates}
              else float(rng.uniform(-1.0, 1.0)) for n in names}
    values.update(fixed or {})
    return values


def _assert_same_equations(a, b, rng, fixed=None, count=5):
    fa, fb = _numeric(a), _numeric(b)
    for _ in range(count):
        values = _random_values(a, rng, fixed)
        values.update({k: v for k, v in _random_values(b, rng, fixed).items() if k not in values})
        for x, y in zip(fa(values), fb(values)):
            assert np.allclose(x, y, rtol=1e-12, atol=1e-12), (x, y)


def _scene(path, name, cache=True):
    model = load_model(path, cache=cache)
    return model, derive_scene(model, select_scene(model, name), cache=cache)


# ------------------------------------------------------------------ pruned, not masked
CASES = [  # (model, scene, switched-off effects, their parameters)
    (SYSTEM1, "free", ["push"], {"F": 0.0}),
    (MODELS / "examples" / "cart_pole.yaml", "undamped", ["damping"], {"b": 0.0}),
    (MODELS / "examples" / "watt_governor.yaml", "idle", ["drive"], {"tau": 0.0}),
]


@pytest.mark.parametrize("path, scene, off, zero", CASES, ids=lambda v: getattr(v, "stem", None))
def test_scene_equals_the_model_without_its_switched_off_effects(path, scene, off, zero, tmp_path):
    _, pruned = _scene(path, scene, cache=False)
    reference = load_model(_without(path, tmp_path, off), cache=False).derive(cache=False)
    rng = np.random.default_rng(8)
    _assert_same_equations(pruned, reference, rng)
    # and the full equations with the switched-off effects set to zero
    full = load_model(path, cache=False).derive(cache=False)
    _assert_same_equations(pruned, full, rng, fixed=zero)
    assert set(pruned.effect_forces) == set(full.effect_forces) - set(off)


def test_chain_gravity_only_scene_equals_the_chain_without_hinges(tmp_path):
    text = chain_yaml(3, hinges=True)
    path = tmp_path / "chain3.yaml"
    path.write_text(text, encoding="utf-8")
    _, pruned = _scene(path, "gravity_only", cache=False)
    plain = tmp_path / "plain.yaml"
    plain.write_text(chain_yaml(3), encoding="utf-8")
    _assert_same_equations(pruned, load_model(plain, cache=False).derive(cache=False), np.random.default_rng(3))
    assert not {"k", "c"} & {p.name for p in pruned.parameters}
    _, full = _scene(path, "full", cache=False)
    _assert_same_equations(full, pruned, np.random.default_rng(4), fixed={"k": 0.0, "c": 0.0})


def test_known_system_effects_are_addressed_by_dotted_names(tmp_path):
    """System II ``without: [sys1.push]`` is System II built on System I without its push."""
    shutil.copy(SYSTEM1, tmp_path / "system1.yaml")
    document = yaml.safe_load(SYSTEM2.read_text(encoding="utf-8"))
    document["scenes"] = {"still": {"without": ["sys1.push"]}}
    _write(tmp_path / "system2.yaml", document)
    _, pruned = _scene(tmp_path / "system2.yaml", "still", cache=False)
    assert list(pruned.effect_forces) == ["sys1.gravity"]
    assert "F" not in {p.name for p in pruned.parameters}
    (tmp_path / "ref").mkdir()
    _without(SYSTEM1, tmp_path / "ref", ["push"], "system1.yaml")
    document.pop("scenes")
    _write(tmp_path / "ref" / "system2.yaml", document)
    reference = load_model(tmp_path / "ref" / "system2.yaml", cache=False).derive(cache=False)
    fixed = {"c": 0.1, "a1": 0.4, "a2": 1.0, "theta": 0.2}  # keep the subspace (26) real
    _assert_same_equations(pruned, reference, np.random.default_rng(5), fixed=fixed)


def test_a_switched_off_effect_is_never_projected(monkeypatch):
    def refuse(self, primitive):
        raise AssertionError(f"projected the switched-off force {self.name}")

    monkeypatch.setattr(Force, "generalized_force", refuse)
    _, system = _scene(SYSTEM1, "free", cache=False)
    assert list(system.effect_forces) == ["gravity"]


def _tokens(text: str) -> set[str]:
    return set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text))


def test_the_symbol_of_a_switched_off_force_appears_in_no_output(tmp_path):
    model, system = _scene(SYSTEM1, "free")
    runner = CliRunner()
    for fmt in ("markdown", "latex", "json"):
        result = runner.invoke(main, ["derive", str(SYSTEM1), "--scene", "free", "--format", fmt])
        assert result.exit_code == 0, result.output
        text = result.output
        if fmt == "json":
            data = json.loads(text)
            data.pop("description", None)
            for p in data.get("parameters", {}).values():
                p.pop("description", None)
            text = json.dumps(data)
        else:  # the model's own prose may say "F"; the equations may not
            text = text.replace(" ".join(model.description.split()), "")
        assert "F" not in _tokens(text), fmt
        assert "push" not in _tokens(text), fmt
    run = runner.invoke(main, ["simulate", str(SYSTEM1), "--scene", "free", "--t", "0.1", "--dt", "0.1", "--points"])
    assert run.exit_code == 0, run.output
    assert "F" not in _tokens(run.stdout), "the trajectory CSV"
    generated = emit_c(system, "free") + emit_python(system, "free")
    for g in generated:
        assert "F" not in _tokens(g.text), g.name
    assert "#define KS_NPARAM 7" in generated[0].text  # no slot for it either
    # the full model has it, so the check can fail
    full = load_model(SYSTEM1).derive()
    assert all("F" in _tokens(g.text) for g in emit_c(full, "full")[:1] + emit_python(full, "full"))


# ---------------------------------------------------------------------------- outputs
@needs_cc
def test_outputs_not_asked_for_are_not_generated(tmp_path):
    cart = MODELS / "examples" / "cart_pole.yaml"
    model = load_model(cart)
    scene = select_scene(model, "damped")  # coordinates and velocities only
    system = derive_scene(model, scene)
    files = emit_c(system, "cart", outputs=scene.outputs)
    (py,) = emit_python(system, "cart", outputs=scene.outputs)
    for g in files + [py]:
        assert "potential_energy" not in g.text and "kinetic_energy" not in g.text, g.name
        assert "_points" not in g.text and "def points" not in g.text, g.name
    for g in files:
        (tmp_path / g.name).write_text(g.text, encoding="utf-8")
    subprocess.run(["gcc", *CFLAGS, "-c", "cart.c", "-o", "cart.o"], cwd=tmp_path, check=True)
    governor = MODELS / "examples" / "watt_governor.yaml"
    model = load_model(governor)
    scene = select_scene(model, "loaded")
    system = derive_scene(model, scene)
    assert sorted(system.points) == ["ball1.centre", "sleeve.centre"]
    header = emit_c(system, "gov", outputs=scene.outputs)[0].text
    assert "#define KS_NPOINTS 6" in header and "ks_potential_energy" in header


def test_simulate_writes_the_columns_the_scene_asks_for(tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["simulate", str(MODELS / "examples" / "cart_pole.yaml"), "--scene", "damped",
                                  "--t", "0.5", "--dt", "0.25"])
    assert result.exit_code == 0, result.output
    rows = result.stdout.splitlines()
    assert rows[0] == "t,x,theta,x_dot,theta_dot"
    assert len(rows) == 4
    result = runner.invoke(main, ["simulate", str(SYSTEM1), "--scene", "pushed", "--t", "0.1", "--dt", "0.1",
                                  "--meta", str(tmp_path / "run.json")])
    assert result.exit_code == 0, result.output
    header = result.stdout.splitlines()[0].split(",")
    assert header[-2:] == ["lower.centre.x", "lower.centre.y"]
    meta = json.loads((tmp_path / "run.json").read_text())
    assert meta["parameters"]["F"] == 2.0 and meta["scene"] == "pushed"  # the scene's value of F


def test_a_model_with_one_scene_uses_it_by_default(tmp_path):
    document = yaml.safe_load(SYSTEM1.read_text(encoding="utf-8"))
    document["scenes"] = {"short": {"effects": ["gravity"], "t_end": 0.5, "dt": 0.25, "method": "gauss4",
                                    "initial": {"theta": 0.25}, "outputs": ["coordinates"]}}
    path = tmp_path / "one.yaml"
    _write(path, document)
    result = CliRunner().invoke(main, ["simulate", str(path), "--meta", str(tmp_path / "run.json")])
    assert result.exit_code == 0, result.output
    rows = result.stdout.splitlines()
    assert rows[0] == "t,theta,phi" and len(rows) == 4
    assert rows[1].split(",")[1] == "0.25"
    assert json.loads((tmp_path / "run.json").read_text())["method"] == "gauss4"
    derived = CliRunner().invoke(main, ["derive", str(path), "--format", "json"])
    assert "F" not in json.loads(derived.stdout)["parameters"]


# ----------------------------------------------------------------------------- errors
def test_unknown_scene_lists_the_valid_ones():
    result = CliRunner().invoke(main, ["codegen", str(SYSTEM1), "--scene", "fre"])
    assert result.exit_code == 1
    assert "--scene fre" in result.stderr and "free, pushed" in result.stderr
    assert "Traceback" not in result.output
    result = CliRunner().invoke(main, ["derive", str(SYSTEM2), "--scene", "free"])
    assert result.exit_code == 1 and "has no scenes" in result.stderr


@pytest.mark.parametrize("scene, line, words", [
    ({"s": {"effects": ["gravty"]}}, "effects", ["unknown effect 'gravty'", "gravity, push"]),
    ({"s": {"without": ["sys1.push"]}}, "without", ["unknown effect 'sys1.push'"]),
    ({"s": {"effects": ["push"], "without": ["gravity"]}}, "without", ["both `effects:` and `without:`"]),
    ({"s": {"outputs": ["energy"]}}, "outputs", ["unknown output 'energy'", "energies"]),
    ({"s": {"outputs": ["lower.tip"]}}, "outputs", ["unknown output 'lower.tip'"]),
    ({"s": {"method": "euler"}}, "method", ["unknown method 'euler'"]),
    ({"s": {"parameters": {"G": 1}}}, "G", ["'G', which is not a parameter", "a2, g, m1"]),
    ({"s": {"dt": -1}}, "dt", ["`dt:` of scene 's' must be a positive number"]),
    ({"s": {"colour": 1}}, "colour", ["unknown key 'colour' in scene 's'"]),
    ({"t": {}}, "t", ["scene name 't' is reserved"]),
])
def test_bad_scenes_are_reported_at_their_place(tmp_path, scene, line, words):
    document = yaml.safe_load(SYSTEM1.read_text(encoding="utf-8"))
    document["scenes"] = scene
    path = tmp_path / "bad.yaml"
    text = yaml.safe_dump(document, sort_keys=False)
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ModelError) as info:
        load_model(path)
    (problem,) = info.value.problems
    for word in words:
        assert word in problem.format()
    scenes_at = text.splitlines().index("scenes:") + 1
    assert problem.location.line > scenes_at
    assert line in " ".join(text.splitlines()[problem.location.line - 2:problem.location.line])


# ------------------------------------------------------------------------------ cache
def test_scenes_share_the_cached_inertia_and_effects(tmp_path, monkeypatch):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    calls = []
    inertia, effects = derive_module.project_inertia, derive_module.project_effects

    def count_inertia(*args, **kwargs):
        calls.append("inertia")
        return inertia(*args, **kwargs)

    def count_effects(sub, primitive, effects_, only=None):
        calls.append(tuple(sorted(only)))
        return effects(sub, primitive, effects_, only=only)

    monkeypatch.setattr(derive_module, "project_inertia", count_inertia)
    monkeypatch.setattr(derive_module, "project_effects", count_effects)
    model = load_model(SYSTEM1)
    free = derive_scene(model, select_scene(model, "free"))
    assert calls == ["inertia", ("gravity",)]
    pushed = derive_scene(model, select_scene(model, "pushed"))
    assert calls[2:] == [("push",)]  # the inertia and gravity come from the cache
    full = model.derive()
    assert calls[3:] == []
    fresh = load_model(SYSTEM1, cache=False).derive(cache=False)
    for a, b in ((free, free), (pushed, fresh), (full, fresh)):
        assert a.mass_matrix == b.mass_matrix and a.velocity_terms == b.velocity_terms
    assert full.forces == fresh.forces and full.potential_energy == fresh.potential_energy
    assert pushed.forces == fresh.forces


def test_editing_a_scene_keeps_the_cached_derivation(tmp_path):
    text = SYSTEM1.read_text(encoding="utf-8")
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    a.write_text(text, encoding="utf-8")
    b.write_text(text.replace("parameters: {F: 2}", "parameters: {F: 3}\n    t_end: 4"), encoding="utf-8")
    assert load_model(a).content_hash == load_model(b).content_hash
    c = tmp_path / "c.yaml"
    c.write_text(text.replace("vector: [F, 0]", "vector: [0, F]"), encoding="utf-8")
    assert load_model(c).content_hash != load_model(a).content_hash
    d = tmp_path / "d.yaml"  # scenes before another section: that section still counts
    document = yaml.safe_load(text)
    document = {"scenes": document.pop("scenes"), **document}
    _write(d, document)
    e = tmp_path / "e.yaml"
    document["initial"] = {"theta": 0.1}
    _write(e, document)
    assert load_model(d).content_hash != load_model(e).content_hash


# ----------------------------------------------------- a parameter the constraints still use
LOOP = MODELS.parent / "tests" / "models" / "closed_loops" / "loop_scene_parameter.yaml"


@needs_cc
def test_a_parameter_the_constraints_use_stays_when_its_other_users_are_switched_off(tmp_path):
    """``d`` places the rocker's pivot (so it is in the pin's constraint) and the spring's anchor;
    the scene `free` switches the spring off: derive, codegen (the C compiles) and simulate keep
    ``d`` as a parameter with its value, and drop the spring's ``k``."""
    runner = CliRunner()
    derived = runner.invoke(main, ["derive", str(LOOP), "--scene", "free", "--format", "json"])
    assert derived.exit_code == 0, derived.output
    parameters = json.loads(derived.stdout)["parameters"]
    assert "d" in parameters and "k" not in parameters
    out = tmp_path / "c"
    generated = runner.invoke(main, ["codegen", str(LOOP), "--scene", "free", "-o", str(out), "--name", "loop"])
    assert generated.exit_code == 0, generated.output
    header = (out / "loop.h").read_text(encoding="utf-8")
    assert "#define KS_P_d " in header and "KS_P_k " not in header
    subprocess.run(["gcc", *CFLAGS, "-c", "loop.c", "-o", "loop.o"], cwd=out, check=True)
    run = runner.invoke(main, ["simulate", str(LOOP), "--scene", "free", "--t", "0.2", "--dt", "0.1",
                               "--set", "d=0.95", "--meta", str(tmp_path / "run.json")])
    assert run.exit_code == 0, run.output
    meta = json.loads((tmp_path / "run.json").read_text())
    assert meta["parameters"]["d"] == 0.95 and "k" not in meta["parameters"]
    model = load_model(LOOP)
    system = derive_scene(model, select_scene(model, "free"))
    used = set().union(*(c.expression.free_symbols for c in system.implicit.constraints))
    assert {p.symbol for p in system.parameters} >= used - set(system.implicit.independent + system.implicit.dependent)
