"""Tests of kronsub.model.source: YAML loading that keeps positions."""
from __future__ import annotations

import textwrap

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kronsub.errors import Location, ModelError
from kronsub.model.source import Node, load_yaml

MODEL = textwrap.dedent("""\
    name: pendulum
    parameters:
      g: 9.81
      m: {value: 2, unit: kg}
    forces:
      - "2*a1*sin(theta)"
      - F * cos(theta)
    flag: true
    nothing:
    """)


def problems_of(text: str, name: str = "m.yaml"):
    with pytest.raises(ModelError) as info:
        load_yaml(name, text)
    assert info.value.problems
    for problem in info.value.problems:
        assert problem.hint, problem
    return info.value.problems


def test_values_and_structure():
    root = load_yaml("m.yaml", MODEL)
    assert root.is_mapping and not root.is_scalar and not root.is_sequence
    assert list(root.value) == ["name", "parameters", "forces", "flag", "nothing"]
    assert root.get("name").value == "pendulum"
    assert root.get("parameters").get("g").value == 9.81
    assert root.get("parameters").get("m").get("value").value == 2
    forces = root.get("forces")
    assert forces.is_sequence and [f.value for f in forces.value] == ["2*a1*sin(theta)", "F * cos(theta)"]
    assert root.get("flag").value is True
    assert root.get("nothing").value is None
    assert root.get("missing") is None
    assert root.get("missing", forces) is forces
    assert forces.get("x") is None  # not a mapping
    assert root.to_python()["parameters"] == {"g": 9.81, "m": {"value": 2, "unit": "kg"}}


def test_raw_text_is_kept():
    root = load_yaml("m.yaml", MODEL)
    g = root.get("parameters").get("g")
    assert g.text == "9.81" and isinstance(g.value, float)
    assert root.get("forces").value[1].text == "F * cos(theta)"
    assert root.get("parameters").text is None
    assert load_yaml("m.yaml", "x: 1.50\ny: 1_000\n").get("x").text == "1.50"


def test_positions_of_keys_and_values():
    root = load_yaml("m.yaml", MODEL)
    assert root.location == Location("m.yaml", 1, 1)
    assert root.key_locations["parameters"] == Location("m.yaml", 2, 1)
    params = root.get("parameters")
    assert params.key_locations == {"g": Location("m.yaml", 3, 3), "m": Location("m.yaml", 4, 3)}
    assert params.get("g").location == Location("m.yaml", 3, 6)
    m = params.get("m")
    assert m.location == Location("m.yaml", 4, 6)
    assert m.key_locations["unit"] == Location("m.yaml", 4, 17)
    assert m.get("unit").location == Location("m.yaml", 4, 23)
    first, second = root.get("forces").value
    assert first.location == Location("m.yaml", 6, 5)
    assert first.text_location == Location("m.yaml", 6, 6)  # after the quote
    assert second.location == second.text_location == Location("m.yaml", 7, 5)
    assert str(second.location) == "m.yaml:7:5"
    assert root.get("flag").location == Location("m.yaml", 8, 7)


def test_block_scalar_text_location():
    root = load_yaml("m.yaml", "e: |\n\n    2*x\n")
    assert root.get("e").text == "\n2*x\n"
    assert root.get("e").text_location == Location("m.yaml", 3, 5)


def test_reads_files(tmp_path):
    path = tmp_path / "model.yaml"
    path.write_text("a: 1\n", encoding="utf-8")
    root = load_yaml(path)
    assert root.get("a").value == 1
    assert root.location.file == str(path)


def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(ModelError) as info:
        load_yaml(path)
    (problem,) = info.value.problems
    assert problem.location == Location(str(path))
    assert "not found" in problem.message and problem.hint


def test_directory_and_bad_encoding(tmp_path):
    with pytest.raises(ModelError):
        load_yaml(tmp_path)
    path = tmp_path / "bad.yaml"
    path.write_bytes(b"a: 1\nb: \xff\n")
    with pytest.raises(ModelError) as info:
        load_yaml(path)
    assert info.value.problems[0].location.line == 2


@pytest.mark.parametrize("text", ["", "   \n", "# just a comment\n"])
def test_empty_file(text):
    (problem,) = problems_of(text)
    assert "empty" in problem.message
    assert problem.location.file == "m.yaml"


def test_duplicate_keys_reported_with_both_lines():
    problems = problems_of("a: 1\nb: 2\na: 3\nc:\n  x: 1\n  x: 2\nb: 4\n")
    found = {(p.location.line, p.location.column): p.message for p in problems}
    assert set(found) == {(3, 1), (6, 3), (7, 1)}
    assert "'a'" in found[(3, 1)] and "line 1" in found[(3, 1)]
    assert "'x'" in found[(6, 3)] and "line 5" in found[(6, 3)]
    assert "'b'" in found[(7, 1)] and "line 2" in found[(7, 1)]


@pytest.mark.parametrize("text, line, column", [
    ("a:\n  b: 1\n c: 2\n", 3, 2),           # bad indentation
    ("a: [1, 2\nb: 3\n", 2, 2),              # unclosed bracket
    ("a: {x: 1\n", 2, 1),                    # unclosed brace
    ("a:\n\tb: 1\n", 2, 1),                  # tab
    ("a: b: c\n", 1, 5),                     # value with ': '
    ("a: 'abc\n", 2, 1),                     # unclosed quote
    ("a: 1\n---\nb: 2\n", 2, 1),             # two documents
    ("a: *nope\n", 1, 4),                    # unknown alias
    ("a: \x07\n", 1, 4),                     # control character
])
def test_malformed_yaml(text, line, column):
    (problem,) = problems_of(text)
    assert (problem.location.line, problem.location.column) == (line, column)
    assert problem.message.startswith(("invalid YAML", "the file contains"))


def test_tab_hint_and_expected_text():
    (problem,) = problems_of("a:\n\tb: 1\n")
    assert "tab" in problem.hint
    (problem,) = problems_of("a: [1, 2\nb: 3\n")
    assert "expected ',' or ']'" in problem.message and "']'" in problem.hint


def test_non_string_keys():
    problems = problems_of("1: x\ntrue: y\nok: 1\n[a]: z\n? {b: 1}\n: w\n")
    assert [p.location.line for p in problems] == [1, 2, 4, 5]
    assert "not a string" in problems[0].message and "quote" in problems[0].hint
    assert "cannot be used as a key" in problems[2].message


def test_quoted_numeric_key_is_fine():
    assert list(load_yaml("m.yaml", '"1": x\n').value) == ["1"]


@pytest.mark.parametrize("text", [
    "a: !!python/object/apply:os.system ['echo pwned']\n",
    "a: !!python/name:os.system\n",
    "a: !custom 1\n",
    "a: !!binary aGVsbG8=\n",
    "a: !!set {x}\n",
    "a: !!omap [b: 1]\n",
])
def test_tags_are_rejected(text, capfd):
    (problem,) = problems_of(text)
    assert "tag" in problem.message and problem.location.line == 1
    assert "pwned" not in capfd.readouterr().out


def test_standard_tags_and_bad_values():
    root = load_yaml("m.yaml", "a: !!str 12\nb: !!float '1.5'\n")
    assert root.get("a").value == "12" and root.get("b").value == 1.5
    (problem,) = problems_of("a: !!int abc\n")
    assert "abc" in problem.message


def test_anchors_aliases_and_merge_keys():
    text = "base: &b {m: 1, k: 2}\nx:\n  <<: *b\n  k: 3\ny: *b\n"
    root = load_yaml("m.yaml", text)
    assert root.get("x").to_python() == {"m": 1, "k": 3}
    assert root.get("x").key_locations["k"] == Location("m.yaml", 4, 3)
    assert root.get("x").key_locations["m"] == Location("m.yaml", 1, 11)
    assert root.get("y").to_python() == {"m": 1, "k": 2}


def test_merge_of_list_and_bad_merge():
    root = load_yaml("m.yaml", "a: &a {p: 1}\nb: &b {p: 2, q: 2}\nc:\n  <<: [*a, *b]\n")
    assert root.get("c").to_python() == {"p": 1, "q": 2}
    (problem,) = problems_of("a:\n  <<: 3\n")
    assert "'<<'" in problem.message


def test_recursive_alias_and_alias_bomb():
    (problem,) = problems_of("a: &x [*x]\n")
    assert "alias" in problem.message
    levels = "".join(f"a{i}: &a{i} [*a{i - 1}, *a{i - 1}, *a{i - 1}]\n" for i in range(1, 40))
    few = load_yaml("m.yaml", "a0: &a0 [1, 2]\n" + levels.split("a7:")[0])
    assert len(few.value) == 7  # aliases repeating a few thousand values are read (and shared)
    # issue 31: a bomb is refused where it is written, before anything walks its billions of values
    (problem,) = problems_of("a0: &a0 [1, 2]\n" + levels)
    assert "aliases repeat more than 10,000 values" in problem.message
    assert problem.location.line == 7  # a6, anchored there, which a7 repeats past the bound


def test_deep_nesting_is_an_error():
    problems_of("[" * 5000 + "]" * 5000)


def test_all_problems_reported_at_once():
    problems = problems_of("a: 1\na: 2\n1: x\nb: !foo y\n")
    assert [p.location.line for p in problems] == [2, 3, 4]


def test_node_is_frozen():
    root = load_yaml("m.yaml", "a: 1\n")
    assert isinstance(root, Node)
    with pytest.raises(AttributeError):
        root.value = {}


YAML_ALPHABET = " \t\n:-[]{},&*!|>'\"#?abc123.%@<=~\x07"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.text(max_size=60), st.text(alphabet=YAML_ALPHABET, max_size=60)))
def test_random_text_gives_node_or_model_error(text):
    try:
        node = load_yaml("m.yaml", text)
    except ModelError as exc:
        assert exc.problems and all(p.hint and p.location for p in exc.problems)
    else:
        assert isinstance(node, Node)


# --- outlines: what a cache key needs, the rest left unconverted ------------------------------

OUTLINE = {"components": {"*": {"model": None}}}


def test_an_outline_converts_only_what_it_names():
    text = textwrap.dedent("""\
        name: two arms
        parameters: {m: !!python/name:os.system ''}
        components:
          left: {model: arm.yaml, parameters: {m: 2}}
          right: {type: rod, parameters: {mass: m, length: 1}}
        scenes: {free: {effects: []}}
        """)
    root = load_yaml("m.yaml", text, only=OUTLINE)
    assert list(root.key_locations) == ["name", "parameters", "components", "scenes"]
    assert root.key_locations["scenes"] == Location("m.yaml", 6, 1)
    assert root.get("name").value is None and root.get("parameters").value is None  # the tag is never read
    left = root.get("components").get("left")
    assert left.get("model").value == "arm.yaml" and left.get("parameters").value is None
    assert root.get("components").get("right").get("type").value is None
    with pytest.raises(ModelError):  # the whole file still refuses the tag
        load_yaml("m.yaml", text)


def test_an_outline_follows_aliases_and_merges_into_what_it_names():
    text = textwrap.dedent("""\
        shared: &arm {model: arm.yaml}
        base: &base {model: base.yaml, parameters: {m: 1}}
        components:
          a: *arm
          b: {<<: *base, parameters: {m: 2}}
        """)
    full, outline = load_yaml("m.yaml", text), load_yaml("m.yaml", text, only=OUTLINE)
    for name in ("a", "b"):
        assert outline.get("components").get(name).get("model").value == \
            full.get("components").get(name).get("model").value
    assert outline.get("components").get("b").get("parameters").get("m").value == 2  # merged: whole
    assert outline.get("shared").value is None and full.get("shared").get("model").value == "arm.yaml"


# ------------------------------------------------------- files that are not models, and depth
def _check(path):
    from click.testing import CliRunner

    from kronsub.cli import main

    return CliRunner().invoke(main, ["check", str(path)])


SECRET = "ghp_16C7e42F292c6912E7710c838347Ae178B4a"


@pytest.mark.parametrize("content", [
    f"{SECRET}\n", f"{SECRET}: 1\n", f"token: {SECRET}\n", f"- {SECRET}\n", f"!!int {SECRET}\n",
    f"*{SECRET}\n", f"[{SECRET}\n", f"123456789012: {SECRET}\n", f"{SECRET}: !!timestamp x\n",
    f"root:{SECRET}:19000:0:99999:7:::\n", "",
], ids=["line", "key", "value", "list", "tag", "alias", "unclosed", "number key", "timestamp", "shadow", "empty"])
def test_nothing_of_a_model_file_that_is_not_a_model_is_shown(tmp_path, content):
    """A `model:` file none of whose lines begins with a model section is no model: the error
    says so at the `model:` entry and shows nothing of the file (a secret's first line)."""
    (tmp_path / "secret.txt").write_text(content)
    text = "name: a\ncomponents:\n  sub: {model: secret.txt}\ncoordinates: [q]\n"
    (tmp_path / "model.yaml").write_text(text)
    result = _check(tmp_path / "model.yaml")
    assert result.exit_code == 1, result.output
    assert f"model.yaml:3:16: model file 'secret.txt' is not a kronsub model" in result.output
    assert SECRET not in result.output and "ghp_" not in result.output and "19000" not in result.output


def test_a_file_that_is_not_a_model_echoes_no_key(tmp_path):
    (tmp_path / "model.yaml").write_text(f"{SECRET}: 1\nother: 2\n")
    result = _check(tmp_path / "model.yaml")
    assert result.exit_code == 1 and "this is not a kronsub model" in result.output
    assert SECRET not in result.output


def test_a_model_in_flow_style_is_still_a_model(tmp_path):
    (tmp_path / "sub.yaml").write_text("{name: s, components: {p: {type: particle1d, parameters: {mass: 1}}}, "
                                       "coordinates: [p_x]}\n")
    (tmp_path / "model.yaml").write_text("name: a\ncomponents:\n  s: {model: sub.yaml}\ncoordinates: [p_x]\n")
    result = _check(tmp_path / "model.yaml")
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("path", ["/proc/kcore", "/proc/no-such-file.yaml", "/sys/kernel/nothing.yaml",
                                  "/proc/self/status"])
def test_a_path_under_proc_or_sys_is_a_system_file_whether_or_not_it_exists(tmp_path, path):
    root = path.split("/")[1]
    result = _check(path)
    assert result.exit_code == 1
    assert result.output.startswith(f"Error: {path}: is a system file under /{root}, not a model file\n")
    (tmp_path / "model.yaml").write_text(f"name: a\ncomponents:\n  sub: {{model: {path}}}\ncoordinates: [q]\n")
    result = _check(tmp_path / "model.yaml")
    assert f"model.yaml:3:16: model file '{path}': is a system file under /{root}" in result.output, result.output


def test_model_files_nested_too_deeply_say_so_with_the_limit(tmp_path):
    """Known systems in known systems, one level more than the limit: the error names the
    levels of `model:` files and the limit (not "YAML nested too deeply"); at the limit, it loads."""
    from kronsub.model.files import MAX_MODEL_DEPTH

    (tmp_path / "m0.yaml").write_text("name: m0\ncomponents:\n  p: {type: particle1d, parameters: {mass: 1}, "
                                      "coordinates: [x]}\ncoordinates: [x]\n")
    for i in range(1, MAX_MODEL_DEPTH + 1):
        (tmp_path / f"m{i}.yaml").write_text(f"name: m{i}\ncomponents:\n  s: {{model: m{i - 1}.yaml}}\n"
                                             "coordinates: [x]\n")
    assert _check(tmp_path / f"m{MAX_MODEL_DEPTH - 1}.yaml").exit_code == 0  # MAX_MODEL_DEPTH files
    result = _check(tmp_path / f"m{MAX_MODEL_DEPTH}.yaml")
    assert result.exit_code == 1, result.output
    assert (f"m1.yaml:3:14: too many levels of `model:` files: 'm0.yaml' would be level {MAX_MODEL_DEPTH + 1}, "
            f"and the limit is {MAX_MODEL_DEPTH}") in result.output
    assert "nested too deeply" not in result.output
