"""Fuzzing of the model loader and the expression parser (issue 6, section 7).

Hypothesis builds random YAML structures from the model's own vocabulary and
hostile strings, random token soups and random well-formed formulas. Each
example has a bounded budget (`max_examples`, and a time limit per call far
above a normal run), and must meet the contract of bad input:

- no traceback: `derive` exits 0, or 1 with ``Error:`` lines and hints
  (a `ModelError` in the library); never an internal error;
- no hang: every call returns within `LIMIT` seconds;
- the canary file named by the hostile strings is never created.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pytest
import sympy
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.deadline import within
from kronsub.cli import main
from kronsub.errors import ModelError
from kronsub.model.expressions import FUNCTIONS, constant_value, parse_expression
from kronsub.model.files import TOP_LEVEL
from kronsub.model.loader import load_model
from kronsub.simulation.values import parse_assignments, resolve

LIMIT = 30  # seconds per call: many times a normal run
BUDGET = settings(max_examples=50, deadline=None, derandomize=True,
                  suppress_health_check=list(HealthCheck))
CANARY = Path(tempfile.gettempdir()) / "kronsub-fuzz-canary"


def hostile_strings(canary: Path) -> list[str]:
    """Text that would do harm if it ever reached eval, a shell, C, Python or LaTeX."""
    return [
        f"__import__('os').system('touch {canary}')",
        f"open('{canary}', 'w')",
        "().__class__.__base__.__subclasses__()",
        f"*/ __attribute__((constructor)) static void f(void) {{ fopen(\"{canary}\", \"w\"); }} /*",
        f'""" ; open("{canary}", "w") ; """',
        f"\\input{{{canary}}}", "\\\\", "\\", "\n", "\r\n", "\x00", "\t", "'", '"', "${HOME}", "$(id)",
        "../../../../etc/passwd", "/dev/zero", "/proc/self/environ", "~", "*", "&a", "!!python/none",
        "1e400", "(x+1)**3000", "(x+y+z)**20", "2+sin(exp(exp(20)))", "acos(2)", "exp(exp(exp(1000)))",
        "9" * 5000, "(" * 200 + "1" + ")" * 200, "x" * 300, "é", "\u202e", "\ufeff", "🙂", "x\u0000y",
        "lambda: 1", "[1, 2]", "{a: b}", "<<", "=", "~", "null", "true", "0x10", "1_000", ".inf", "-.nan",
    ]


HOSTILE = hostile_strings(CANARY)
TYPES = ["particle1d", "particle2d", "rod", "pinned_rod", "disc", "gravity", "spring", "potential", "force"]
KEYS = list(TOP_LEVEL) + ["type", "parameters", "coordinates", "model", "value", "unit", "points",
                          "between", "stiffness", "g", "mass", "length", "x", "q", "p", "m"]
NAMES = ["q", "x", "m", "p", "p_x", "a.b", "q_dot", "t", "pi", "sin"]

scalars = st.one_of(
    st.sampled_from(HOSTILE), st.sampled_from(TYPES), st.sampled_from(NAMES),
    st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True), st.booleans(), st.none(),
    st.text(max_size=30),
)
structures = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.one_of(st.sampled_from(KEYS), st.sampled_from(HOSTILE), st.text(max_size=8)),
                        inner, max_size=5)),
    max_leaves=25,
)
models = st.fixed_dictionaries(
    {}, optional={key: structures for key in TOP_LEVEL},
).map(lambda d: d or {"name": "empty"})

PIECES = HOSTILE + [":", ": ", "- ", "\n  ", "{", "}", "[", "]", ",", "#", "&x ", "*x", "!!python/object/apply:os.system ",
                    "!!binary ", "%YAML 1.1\n", "---\n", "...\n", "? ", "|\n  ", ">\n  ", "name: a\n",
                    "components:\n  p: {type: particle1d}\n", "coordinates: [q]\n", "model: ", "type: "]


def derive_text(text: str, *options: str):
    """``kronsub derive`` on ``text`` in a fresh directory; the result and its output."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "model.yaml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        with within(LIMIT, "kronsub derive"):
            result = CliRunner().invoke(main, ["derive", "--no-cache", *options, str(path)])
    return result


def assert_contract(result, context) -> None:
    try:
        err = result.stderr
    except ValueError:
        err = result.output
    combined = result.output + err
    assert not CANARY.exists(), (context, "the canary file was created")
    assert "Traceback" not in combined and "internal error" not in combined, (context, combined)
    assert result.exit_code in (0, 1), (context, result.exit_code, repr(result.exception), combined)
    if result.exit_code == 1:
        assert isinstance(result.exception, SystemExit), (context, repr(result.exception))
        lines = err.splitlines()
        assert lines and lines[0].startswith("Error: "), (context, err)
        for i, line in enumerate(lines):
            if line.startswith("Error: "):
                assert i + 1 < len(lines) and lines[i + 1].startswith("  hint: "), (context, err)


@pytest.fixture(autouse=True)
def _no_canary():
    CANARY.unlink(missing_ok=True)
    yield
    assert not CANARY.exists()


# ------------------------------------------------------------------ loader
@BUDGET
@given(models, st.sampled_from(["markdown", "latex", "json"]))
def test_random_yaml_structures(model, fmt):
    text = yaml.safe_dump(model, allow_unicode=True, sort_keys=False)
    assert_contract(derive_text(text, "--format", fmt), text)


@BUDGET
@given(st.lists(st.sampled_from(PIECES), min_size=1, max_size=12))
def test_random_yaml_text(pieces):
    text = "".join(pieces)
    assert_contract(derive_text(text), text)


@BUDGET
@given(st.sampled_from(HOSTILE), st.sampled_from(["name", "description", "unit", "model", "value", "type",
                                                 "coordinate", "effect", "component", "key"]))
def test_hostile_strings_in_every_place_of_a_valid_model(value, where):
    """A valid model with one hostile string in one place: derives, or fails cleanly."""
    quoted = yaml.safe_dump(value, allow_unicode=True).rstrip("\n").removesuffix("\n...")
    fields = {"name": "ok", "description": "ok", "unit": "kg", "value": "1", "type": "particle1d",
              "coordinate": "q", "effect": "g", "component": "p", "key": "m"}
    fields[where] = quoted
    model = (f"name: {fields['name']}\ndescription: {fields['description']}\n"
             f"parameters:\n  {fields['key']}: {{value: {fields['value']}, unit: {fields['unit']}}}\n"
             f"components:\n  {fields['component']}: {{type: {fields['type']}, parameters: {{mass: 1}}, "
             f"coordinates: [{fields['coordinate']}]}}\n")
    if where == "model":
        model += f"  sub: {{model: {quoted}}}\n"
    model += (f"coordinates: [{fields['coordinate']}]\n"
              f"effects:\n  {fields['effect']}: {{type: potential, value: {fields['coordinate']}**2}}\n")
    for fmt in ("markdown", "latex", "json"):
        assert_contract(derive_text(model, "--format", fmt), model)


# ------------------------------------------------------------ expressions
TOKENS = ["x", "y", "a.b", "1", "2.5", "1e3", "1e400", "+", "-", "*", "/", "**", "(", ")", ",", " ", ".",
          "pi", "t", "_", "'", "[", "]", "lambda", ":", "=", "\n", "9" * 40] + list(FUNCTIONS) + HOSTILE[:6]
X, Y, AB = sympy.symbols("x y a_b", real=True)
NAME_MAP = {"x": X, "y": Y, "a.b": AB, "t": sympy.Symbol("t", real=True)}


def parse_or_refuse(text: str):
    """The parsed expression, or None after a `ModelError`; nothing else may escape."""
    with within(LIMIT, f"parse_expression({text[:40]!r})"):
        try:
            value = parse_expression(text, NAME_MAP)
        except ModelError as exc:
            assert exc.problems and all(p.hint for p in exc.problems), text
            return None
    assert isinstance(value, sympy.Expr), (text, value)
    return value


@BUDGET
@given(st.lists(st.sampled_from(TOKENS), min_size=1, max_size=20))
def test_random_token_soup(tokens):
    parse_or_refuse("".join(tokens))


@BUDGET
@given(st.text(max_size=60))
def test_random_text(text):
    parse_or_refuse(text)


numbers = st.one_of(st.integers(-10**4, 10**4).map(str), st.sampled_from(["0", "1e400", "1e-400", "2.5", "pi",
                                                                            "1e308", "0.0"]))
formulas = st.recursive(
    st.one_of(numbers, st.sampled_from(["x", "y", "a.b"])),
    lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**"]), inner).map(lambda t: f"({t[0]}){t[1]}({t[2]})"),
        st.tuples(st.sampled_from([f for f, (_, n) in FUNCTIONS.items() if n == 1]), inner).map(
            lambda t: f"{t[0]}({t[1]})"),
        st.tuples(inner, inner).map(lambda t: f"atan2({t[0]}, {t[1]})"),
    ),
    max_leaves=12,
)


@BUDGET
@given(formulas)
def test_random_formulas(text):
    """Well-formed formulas parse or are refused; constant ones evaluate to a finite real double."""
    value = parse_or_refuse(text)
    if value is not None and not value.free_symbols:
        with within(LIMIT, f"constant_value({text[:40]!r})"):
            try:
                number = constant_value(value)
            except ModelError:
                return
        assert math.isfinite(number), (text, number)


@BUDGET
@given(st.lists(st.tuples(st.sampled_from(["m", "k", "L0", "c", "g", "r", "a_dot", "zz", ""]),
                          st.one_of(formulas, st.sampled_from(HOSTILE))), max_size=3))
def test_random_set_values(assignments):
    """``--set`` values: resolved to finite numbers or refused with a `ModelError`."""
    system = _polar_spring()
    items = tuple(f"{name}={value}" for name, value in assignments)
    with within(LIMIT, f"--set {items}"):
        try:
            values = resolve(system, {}, parse_assignments(items))
        except ModelError as exc:
            assert exc.problems and all(p.hint for p in exc.problems), items
            return
    assert all(math.isfinite(v) for v in values.parameters + values.y0), (items, values)


_SYSTEM = []


def _polar_spring():
    if not _SYSTEM:
        path = Path(__file__).parent / "models" / "polar_spring.yaml"
        _SYSTEM.append(load_model(path).derive())
    return _SYSTEM[0]
