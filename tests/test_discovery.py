"""Discovery: ``kronsub components``, ``kronsub new``, ``kronsub check``; the stated
inertia convention of ``rigid_body3d``."""
from __future__ import annotations

import json
import os
import re
import stat

import pytest
import sympy
from click.testing import CliRunner
from sympy.physics.mechanics import ReferenceFrame, inertia

import kronsub
from reference import mechanics as mr
from conftest import MODELS, ROOT
from helpers import assert_same
from kronsub.cli import main
from kronsub.commands.starters import STARTERS
from kronsub.components import REGISTRY
from kronsub.model.effects import BUILDERS


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


# -- kronsub components ------------------------------------------------------------------------

def test_components_lists_every_registered_type():
    result = invoke("components")
    assert result.exit_code == 0, result.output
    for name in (*REGISTRY, *BUILDERS):
        assert f"  {name} " in result.output, name


def test_components_json_follows_the_registries():
    data = json.loads(invoke("components", "--format", "json").output)
    assert [c["type"] for c in data["components"]] == sorted(REGISTRY)
    assert [e["type"] for e in data["effects"]] == sorted(BUILDERS)
    for c in data["components"]:
        cls = REGISTRY[c["type"]]
        assert c["coordinates"] == list(cls.coordinates)
        assert [(p["name"], p["default"], p["unit"]) for p in c["parameters"]] == \
            [(s.name, s.default, s.unit) for s in cls.parameters]
    for e in data["effects"]:
        assert [k["name"] for k in e["keys"]] == list(BUILDERS[e["type"]][1])
    spring = next(e for e in data["effects"] if e["type"] == "spring")
    assert {k["name"]: k["required"] for k in spring["keys"]} == {"between": True, "stiffness": True,
                                                                  "length": False}


def test_components_detail_of_a_component():
    result = invoke("components", "pinned_rod")
    assert result.exit_code == 0, result.output
    out = result.output
    assert "coordinates (in order): angle" in out and "inertia = mass*length**2/12 [kg m^2]" in out
    assert "tip: (length*sin(angle) + pivot_x, -length*cos(angle) + pivot_y)" in out
    assert "downward vertical" in out


def test_components_detail_of_an_effect():
    out = invoke("components", "force").output
    assert "point*" in out and "needs one of: vector | direction + magnitude" in out


def test_components_unknown_type_suggests():
    result = invoke("components", "pined_rod")
    assert result.exit_code == 1
    assert "no component type, effect type or joint 'pined_rod'" in result.output and "'pinned_rod'" in result.output


def test_components_lists_the_joints_with_their_keys():
    """Every joint ``constraints:`` accepts is listed, its keys those the reader checks and the
    schema describes; ``kronsub components pin`` shows one."""
    from kronsub.commands.catalogue import joint
    from kronsub.model.constraints import JOINT_KEYS, JOINTS

    out = invoke("components").output
    assert "Joints (under `constraints:`" in out
    for name in JOINTS:
        assert f"  {name} " in out, name
    schema = json.loads((ROOT / "kronsub" / "model" / "schema.json").read_text())
    branches = {b["required"][0]: b["properties"] for b in schema["$defs"]["constraint"]["oneOf"] if "required" in b}
    assert set(branches) == set(JOINTS)
    for name, keys in JOINT_KEYS.items():
        spec = branches[name][name]
        assert tuple(spec.get("properties", {})) == keys, name
        assert [k["name"] for k in joint(name)["keys"]] == list(keys)
        assert {k["name"] for k in joint(name)["keys"] if k["required"]} == set(spec.get("required", ()))
        detail = invoke("components", name)
        assert detail.exit_code == 0, detail.output
        assert detail.output.startswith(f"{name} (joint, under `constraints:`): ")
        assert all(f"  {k}" in detail.output for k in keys)
    data = json.loads(invoke("components", "--format", "json").output)
    assert [j["type"] for j in data["joints"]] == sorted(JOINTS)
    pin = json.loads(invoke("components", "pin", "--format", "json").output)
    assert pin["kind"] == "joint" and pin["form"] == "pin: [P, Q]"
    assert "did you mean 'pin'?" in invoke("components", "pn").output


def test_a_joint_as_shown_derives(tmp_path):
    """The form ``kronsub components slider`` shows, filled in, is a model that derives."""
    form = json.loads(invoke("components", "slider", "--format", "json").output)["form"]
    assert form == "slider: {point: ..., body: ...}"
    model = tmp_path / "m.yaml"
    model.write_text("name: bead\ncomponents:\n"
                     "  bar: {type: pinned_rod, parameters: {mass: 1, length: 2}, coordinates: {angle: a}}\n"
                     "  bead: {type: particle2d, parameters: {mass: 1}, coordinates: [x, y]}\n"
                     "coordinates: auto\nconstraints:\n"
                     "  on_bar: {" + form.replace("...", "bead.centre", 1).replace("...", "bar") + "}\n"
                     "initial: {a: 0.1, x: 0.05, y: -0.5}\n")
    result = invoke("derive", model)
    assert result.exit_code == 0, result.output


def test_no_sphinx_markup_reaches_the_terminal():
    """Help texts and the catalogue show docstrings as plain text: no ``:func:`x``` or ````x````."""
    from kronsub.cli import main as group
    from kronsub.commands.catalogue import names

    markup = re.compile(r":(?:py:)?[a-z]+:`|``")
    commands = [[]] + [[name] for name in group.commands]
    commands += [[name, sub] for name, cmd in group.commands.items() for sub in getattr(cmd, "commands", {})]
    outputs = [invoke(*args, "--help").output for args in commands]
    outputs += [invoke("components").output] + [invoke("components", n).output for n in names()]
    outputs += [invoke("components", "--format", "json").output]
    for text in outputs:
        assert not markup.search(text), markup.search(text).string[max(0, markup.search(text).start() - 80):][:200]


# -- the inertia convention of rigid_body3d ----------------------------------------------------

def test_rigid_body3d_tensor_is_sympys_inertia_convention():
    """The parameters enter as SymPy's inertia(frame, ixx, iyy, izz, ixy, iyz, izx) builds it."""
    names = "Ixx Iyy Izz Ixy Iyz Ixz"
    s = dict(zip(names.split(), sympy.symbols(names)))
    body = REGISTRY["rigid_body3d"](x={}, p=s)
    N = ReferenceFrame("N")
    reference = inertia(N, s["Ixx"], s["Iyy"], s["Izz"], s["Ixy"], s["Iyz"], s["Ixz"]).to_matrix(N)
    assert body.inertia() == reference


def test_rigid_body3d_convention_is_stated_everywhere():
    tensor = "[[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]]"
    assert tensor in invoke("components", "rigid_body3d").output
    assert tensor in (ROOT / "docs" / "model-format.md").read_text(encoding="utf-8")
    schema = json.loads((ROOT / "kronsub" / "model" / "schema.json").read_text(encoding="utf-8"))
    rule = next(r for r in schema["$defs"]["libraryComponent"]["allOf"]
                if r["if"]["properties"]["type"]["const"] == "rigid_body3d")
    for name in ("Ixy", "Iyz", "Ixz"):
        text = rule["then"]["properties"]["parameters"]["properties"][name]["description"]
        assert tensor in text and "inertia()" in text


# -- kronsub new -------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", sorted(STARTERS))
def test_every_starter_is_written_checked_and_derived(kind, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("new", "mine", "--from", kind)
    assert result.exit_code == 0, result.output
    path = tmp_path / "mine.yaml"
    assert invoke("check", path).exit_code == 0
    system = kronsub.load(path).derive()
    assert system.name == "mine" and len(system.coordinates) >= 1
    mode = stat.S_IMODE(os.stat(path).st_mode)
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_new_never_overwrites(tmp_path):
    path = tmp_path / "model.yaml"
    path.write_text("keep me")
    result = invoke("new", tmp_path / "model", "--from", "cart_pole")
    assert result.exit_code == 1 and "never overwrites" in result.output
    assert path.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.yaml"]  # no temporary file left


def test_new_quotes_any_name(tmp_path):
    result = invoke("new", tmp_path / "it's: #odd")
    assert result.exit_code == 0, result.output
    assert kronsub.load(tmp_path / "it's: #odd.yaml").name == "it's: #odd"


def test_chain_starter_matches_kanes_method(tmp_path):
    """Two links: the mass matrix and forces of sympy.physics.mechanics' rod chain."""
    assert invoke("new", tmp_path / "chain2", "--from", "chain", "--links", 2).exit_code == 0
    system = kronsub.load(tmp_path / "chain2.yaml").derive()
    ref = mr.rod_chain(2)
    assert_same(system.mass_matrix, ref.mass_matrix)
    assert_same(system.forces, ref.forces)
    assert_same(system.velocity_terms, ref.velocity_terms)


def test_pendulum_starter_linearises_to_the_compound_pendulum(tmp_path):
    assert invoke("new", tmp_path / "p").exit_code == 0
    lin = kronsub.load(tmp_path / "p.yaml").derive().linearize(symbolic=True)
    m, L, g = sympy.symbols("m L g")
    # +-i sqrt(m g d / (I + m d^2)) with d = L/2, I = m L^2/12: omega^2 = 3 g / (2 L)
    assert sympy.simplify(lin.A[1, 0].subs({s: sympy.Symbol(s.name) for s in lin.A[1, 0].free_symbols})
                          + 3 * g / (2 * L)) == 0


def test_new_through_a_missing_folder_names_the_users_path(tmp_path, monkeypatch):
    """``missing/../../p``: the path resolves to an existing folder, but the system cannot go
    through ``missing``: the error names the user's path, not the temporary file."""
    monkeypatch.chdir(tmp_path)
    result = invoke("new", "missing/../../p")
    assert result.exit_code == 1
    assert result.output.startswith("Error: missing/../../p.yaml: cannot create a file in missing/../..")
    assert ".tmp" not in result.output and not list(tmp_path.parent.glob(".p.yaml.*"))


# -- kronsub check -----------------------------------------------------------------------------

def test_check_reports_every_problem_and_exits_1(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("components:\n  p: {type: particel1d}\n  q: {type: rod, parameters: {mass: 1}}\n"
                    "coordinates: [x]\neffects:\n  e: {type: sprung}\n")
    result = invoke("check", path)
    assert result.exit_code == 1
    assert "particel1d" in result.output and "sprung" in result.output
    assert "problems found." in result.output and "Traceback" not in result.output


def test_check_does_not_derive(monkeypatch):
    import kronsub.model.derive as derive
    import kronsub.model.loader as loader

    def fail(*args, **kwargs):
        raise AssertionError("check derived the model")

    monkeypatch.setattr(derive, "derive_model", fail)
    monkeypatch.setattr(loader, "derive_model", fail)
    result = invoke("check", MODELS / "examples" / "cart_pole.yaml")
    assert result.exit_code == 0, result.output
    assert "OK (2 generalized coordinates, 2 components, 3 effects, 2 scenes)" in result.output


def test_check_warns_when_the_coordinates_are_not_independent(tmp_path):
    path = tmp_path / "dependent.yaml"
    path.write_text("parameters: {m: 1}\ncomponents:\n  p: {type: particle2d, parameters: {mass: m}, "
                    "coordinates: [x, y]}\ncoordinates: [a, b]\nconnection: {x: a + b, y: 2*a + 2*b}\n")
    result = invoke("check", path)
    assert result.exit_code == 0 and "rank 1 < 2" in result.output
