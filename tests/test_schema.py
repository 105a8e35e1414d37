"""The JSON Schema of the model format and its reference page agree with the code.

The schema (kronsub/model/schema.json) must be a valid draft 2020-12 schema,
accept every bundled model, reject documents the loader rejects for their
shape, and list exactly the registered component and effect types with their
keys, so neither it nor docs/model-format.md can drift from the registries.
"""
from __future__ import annotations

import copy
import importlib.util
import json
from pathlib import Path

import pytest
import yaml

from kronsub.components import REGISTRY
from kronsub.model.effects import BUILDERS

ROOT = Path(__file__).resolve().parent.parent
SCHEMA_PATH = ROOT / "kronsub" / "model" / "schema.json"
DOC_PATH = ROOT / "docs" / "model-format.md"
MODELS = sorted((ROOT / "models").rglob("*.yaml"))

MINIMAL = {
    "components": {"p": {"type": "particle1d", "parameters": {"mass": "m"}, "coordinates": ["x"]}},
    "coordinates": ["x"],
    "parameters": {"m": 1},
}


@pytest.fixture(scope="module")
def jsonschema():
    return pytest.importorskip("jsonschema")


@pytest.fixture(scope="module")
def schema():
    return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def validator(jsonschema, schema):
    return jsonschema.Draft202012Validator(schema)


def with_changes(**changes):
    doc = copy.deepcopy(MINIMAL)
    doc.update(changes)
    return doc


def test_schema_is_valid_draft_2020_12(jsonschema, schema):
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    jsonschema.Draft202012Validator.check_schema(schema)


def test_minimal_document_is_valid(validator):
    validator.validate(MINIMAL)


@pytest.mark.parametrize("path", MODELS, ids=lambda p: str(p.relative_to(ROOT / "models")))
def test_bundled_model_validates(validator, path):
    document = yaml.safe_load(path.read_text(encoding="utf-8"))
    errors = [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(document)]
    assert errors == []


def test_there_are_bundled_models():
    assert len(MODELS) >= 5


@pytest.mark.parametrize("document", [
    pytest.param(with_changes(frames={}), id="unknown top-level key"),
    pytest.param(with_changes(scenes={"s": {"effects": ["g"], "without": ["f"]}}), id="scene with effects and without"),
    pytest.param(with_changes(scenes={"s": {"switch": ["g"]}}), id="unknown scene key"),
    pytest.param(with_changes(scenes={"s": {"method": "euler"}}), id="unknown scene method"),
    pytest.param(with_changes(scenes={"s": {"outputs": ["speed"]}}), id="unknown scene output"),
    pytest.param(with_changes(scenes={"t": {}}), id="reserved scene name"),
    pytest.param(with_changes(constraints={"c": {"hinge": ["p.centre", [0]]}}), id="unknown joint"),
    pytest.param(with_changes(constraints={"c": {"pin": ["p.centre"]}}), id="pin of one point"),
    pytest.param(with_changes(coordinates="all"), id="coordinates neither a list nor auto"),
    pytest.param({"components": MINIMAL["components"]}, id="no coordinates"),
    pytest.param({"coordinates": ["x"]}, id="no components"),
    pytest.param(with_changes(coordinates=[]), id="empty coordinates"),
    pytest.param(with_changes(coordinates=["t"]), id="reserved coordinate name"),
    pytest.param(with_changes(effects={"g": {"g": 9.81}}), id="effect without type"),
    pytest.param(with_changes(effects={"g": {"type": "gravitation"}}), id="unknown effect type"),
    pytest.param(with_changes(effects={"g": {"type": "gravity", "strength": 1}}), id="unknown effect key"),
    pytest.param(with_changes(effects={"f": {"type": "force", "vector": [1]}}), id="force without point"),
    pytest.param(with_changes(effects={"f": {"type": "force", "point": "p.centre"}}), id="force without vector"),
    pytest.param(with_changes(effects={"s": {"type": "spring", "between": ["p.centre"], "stiffness": 1}}),
                 id="spring with one end"),
    pytest.param(with_changes(components={"p": {"parameters": {"mass": 1}}}), id="component without type or model"),
    pytest.param(with_changes(components={"p": {"type": "particle"}}), id="unknown component type"),
    pytest.param(with_changes(components={"p": {"type": "particle1d", "model": "a.yaml"}}), id="type and model"),
    pytest.param(with_changes(components={"p": {"type": "particle1d"}}), id="missing required parameter"),
    pytest.param(with_changes(components={"p": {"type": "particle1d", "parameters": {"mass": 1, "length": 2}}}),
                 id="unknown component parameter"),
    pytest.param(with_changes(components={"p": {"type": "particle1d", "parameters": {"mass": 1},
                                                "coordinates": ["x", "y"]}}), id="too many coordinate names"),
    pytest.param(with_changes(components={"p": {"type": "particle1d", "parameters": {"mass": 1},
                                                "coordinates": {"y": "x"}}}), id="unknown component coordinate"),
    pytest.param(with_changes(parameters={"m": {"value": 1, "units": "kg"}}), id="unknown parameter key"),
    pytest.param(with_changes(parameters={"m": True}), id="boolean is not an expression"),
    pytest.param(with_changes(connection={"x": [1]}), id="connection value not an expression"),
])
def test_invalid_document_is_rejected(validator, document):
    assert list(validator.iter_errors(document)), "the schema accepted an invalid model"


def test_known_system_component_is_valid(validator):
    validator.validate(with_changes(components={"sys1": {"model": "system1.yaml", "parameters": {"F": 0},
                                                         "coordinates": {"theta": "x"}}}))


def test_scenes_are_valid(validator):
    validator.validate(with_changes(scenes={
        "free": {"effects": ["gravity", "sys1.push"], "parameters": {"m": 2}, "initial": {"x": 0.1},
                 "t_end": 5, "dt": 0.01, "method": "gauss4", "outputs": ["coordinates", "energies", "p.centre"]},
        "other": {"without": ["gravity"], "description": "no gravity"},
        "empty": None}))


def test_scene_keys_methods_and_outputs_follow_the_code(schema):
    from kronsub.model.scenes import KEYS, OUTPUT_KINDS
    from kronsub.simulation.run import METHODS

    scene = schema["$defs"]["scene"]
    assert sorted(scene["properties"]) == sorted(KEYS)
    assert scene["properties"]["method"]["enum"] == list(METHODS)
    assert scene["properties"]["outputs"]["items"]["pattern"].startswith("^(" + "|".join(OUTPUT_KINDS) + "|")


def test_a_scene_names_the_methods_of_the_simulation():
    """The model reader checks a scene's ``method:`` against the schema's list (the model sits
    below the simulation): that list is the simulation's method table, in its order."""
    from kronsub.model.schema import scene_methods
    from kronsub.simulation.run import METHODS

    assert scene_methods() == tuple(METHODS)


def test_component_type_enum_is_the_registry(schema):
    assert schema["$defs"]["libraryComponent"]["properties"]["type"]["enum"] == sorted(REGISTRY)


def test_component_parameters_and_coordinates_follow_the_registry(schema):
    rules = {rule["if"]["properties"]["type"]["const"]: rule["then"]
             for rule in schema["$defs"]["libraryComponent"]["allOf"]}
    assert sorted(rules) == sorted(REGISTRY)
    for name, cls in REGISTRY.items():
        params = rules[name]["properties"]["parameters"]
        assert list(params["properties"]) == [p.name for p in cls.parameters], name
        assert params["required"] == [p.name for p in cls.parameters if p.default is None], name
        as_list, as_mapping = rules[name]["properties"]["coordinates"]["oneOf"]
        assert as_list["minItems"] == as_list["maxItems"] == len(cls.coordinates), name
        assert as_mapping["propertyNames"]["enum"] == list(cls.coordinates), name


def test_effect_types_and_keys_follow_the_builders(schema):
    defs = schema["$defs"]
    branches = [defs[ref["$ref"].rsplit("/", 1)[1]] for ref in defs["effect"]["oneOf"]]
    types = [b["properties"]["type"]["const"] for b in branches]
    assert sorted(types) == sorted(BUILDERS)
    assert defs["effect"]["properties"]["type"]["enum"] == sorted(BUILDERS)
    for branch, name in zip(branches, types):
        assert set(branch["properties"]) == {"type", "description", *BUILDERS[name][1]}, name
        assert branch["additionalProperties"] is False


EFFECTS = {
    "gravity_default": {"type": "gravity", "components": ["p", "q"]},  # one world: its default direction
    "gravity_full": {"type": "gravity", "g": "g", "direction": [0, -1], "components": ["p"]},
    "force_vector": {"type": "force", "point": "p.centre", "vector": ["F", 0]},
    "force_direction": {"type": "force", "point": "q.centre", "direction": [1, 1], "magnitude": 2},
    "torque_plane": {"type": "torque", "component": "p", "value": "tau"},
    "torque_space": {"type": "torque", "component": "b", "value": [0, 0, "tau"]},
    "spring": {"type": "spring", "between": ["p.b", [0, 0]], "stiffness": "k", "length": 1},
    "damper": {"type": "damper", "between": ["p.a", "q.centre"], "coefficient": "c"},
    "torsional_spring": {"type": "torsional_spring", "angle": "a - u", "stiffness": "k", "rest": "pi/2"},
    "torsional_damper": {"type": "torsional_damper", "angle": "a", "coefficient": 0.5},
    "generalized_force": {"type": "generalized_force", "coordinate": "p.x", "value": "-c*x_dot"},
    "potential": {"type": "potential", "value": "k*u**4/4", "description": "quartic"},
    "capacitor": {"type": "capacitor", "charge": "u", "capacitance": "k"},
    "resistor": {"type": "resistor", "charge": "u - v", "resistance": "c"},
    "voltage_source": {"type": "voltage_source", "charge": "u", "voltage": "F*sin(t)"},
    "gyrator": {"type": "gyrator", "between": ["u", "a"], "constant": "k"},
}
EFFECT_MODEL = {
    "parameters": {"m": 1, "g": {"value": 9.81, "unit": "m/s^2"}, "F": None, "tau": 0, "k": 1, "c": 0.5},
    "components": {
        "p": {"type": "rod", "parameters": {"mass": "m", "length": 1}, "coordinates": ["x", "y", "a"]},
        "q": {"type": "particle2d", "parameters": {"mass": "m"}, "coordinates": {"x": "u", "y": "v"}},
        "b": {"type": "rigid_body3d", "parameters": {"mass": "m", "Ixx": 1, "Iyy": 2, "Izz": 3}},
    },
    "coordinates": ["x", "y", "a", "u", "v", "b_x", "b_y", "b_z", "b_psi", "b_theta", "b_phi"],
    "effects": EFFECTS,
    "initial": {"a": "pi/4", "u_dot": 1},
}


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_valid_effect_is_accepted(validator, name):
    validator.validate({**EFFECT_MODEL, "effects": {name: EFFECTS[name]}})


def test_every_effect_type_has_an_accepted_example():
    assert {e["type"] for e in EFFECTS.values()} == set(BUILDERS)


def test_schema_examples_load(tmp_path):
    """The documents the schema accepts here are models the loader accepts too."""
    try:
        from kronsub.model.loader import load_model
    except ImportError as exc:  # the expression parser may not have landed yet
        pytest.skip(f"the loader cannot be imported: {exc}")
    path = tmp_path / "effects.yaml"
    path.write_text(yaml.safe_dump(EFFECT_MODEL, sort_keys=False), encoding="utf-8")
    model = load_model(path)
    assert sorted(e.name for e in model.effects) == sorted(EFFECTS)
    load_model(tmp_path / "minimal.yaml", text=yaml.safe_dump(MINIMAL))


def test_reference_mentions_every_component_and_effect_type():
    text = DOC_PATH.read_text(encoding="utf-8")
    missing = [name for name in (*REGISTRY, *BUILDERS) if f"`{name}`" not in text]
    assert missing == []


def test_reference_component_table_is_current():
    spec = importlib.util.spec_from_file_location("gen_components", ROOT / "docs" / "gen_components.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.component_tables() in DOC_PATH.read_text(encoding="utf-8"), \
        "paste the output of `python docs/gen_components.py` into docs/model-format.md"
