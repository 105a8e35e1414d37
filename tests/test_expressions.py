"""Tests of kronsub.model.expressions: the whitelisted expression parser."""
from __future__ import annotations

import builtins
import io
import os
import subprocess
import sys
import time
import tokenize
from pathlib import Path

import pytest
import sympy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kronsub.errors import Location, ModelError
from kronsub.model import expressions
from kronsub.model.expressions import FUNCTIONS, parse_expression, parse_number

x, y, theta, phi, a1, a2, F, t = sympy.symbols("x y theta phi a1 a2 F t")
lower_y, tip_x = sympy.symbols("lower_y tip_x")
NAMES = {"x": x, "y": y, "theta": theta, "phi": phi, "a1": a1, "a2": a2, "F": F, "t": t,
         "lower.y": lower_y, "upper.tip.x": tip_x}
HERE = Location("m.yaml", 5, 7)


def parse(text: str, names=NAMES) -> sympy.Expr:
    return parse_expression(text, names, HERE)


def problem_of(text: str, names=NAMES):
    with pytest.raises(ModelError) as info:
        parse(text, names)
    (problem,) = info.value.problems
    assert problem.hint
    assert problem.message.startswith("in expression '")
    return problem


# -- accepted expressions ----------------------------------------------------

@pytest.mark.parametrize("text, value", [
    ("9.81", sympy.Rational(981, 100)),
    ("1e-3", sympy.Rational(1, 1000)),
    (".5", sympy.Rational(1, 2)),
    ("5.", sympy.Integer(5)),
    ("2.50E2", sympy.Integer(250)),
    ("1_000.25", sympy.Rational(4001, 4)),
    ("0.1", sympy.Rational(1, 10)),
    ("42", sympy.Integer(42)),
    ("0x1F", sympy.Integer(31)),
    ("-9.81", sympy.Rational(-981, 100)),
])
def test_exact_numbers(text, value):
    result = parse(text)
    assert result == value
    assert isinstance(result, sympy.Rational) and not result.has(sympy.Float)


def test_decimal_inside_expression_is_exact():
    assert parse("0.1*x + 0.2*x") == sympy.Rational(3, 10) * x
    assert not parse("9.81*sin(theta)").has(sympy.Float)


def test_function_table():
    assert set(FUNCTIONS) == {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sqrt",
                              "exp", "log", "sinh", "cosh", "tanh", "abs", "sign"}
    assert FUNCTIONS["atan2"] == (sympy.atan2, 2) and FUNCTIONS["abs"] == (sympy.Abs, 1)
    with pytest.raises(TypeError):
        FUNCTIONS["eval"] = (eval, 1)  # type: ignore[index]


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_every_function(name):
    function, arity = FUNCTIONS[name]
    args = [x, y][:arity]
    text = f"{name}({', '.join(str(a) for a in args)})"
    assert parse(text) == function(*args)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_argument_counts(name):
    arity = FUNCTIONS[name][1]
    problem = problem_of(f"{name}({', '.join(['x'] * (arity + 1))})")
    assert f"takes {arity} argument" in problem.message
    assert problem.location.column == 7


def test_dotted_names_and_pi():
    assert parse("lower.y + upper.tip.x") == lower_y + tip_x
    assert parse("upper . tip . x") == tip_x
    assert parse("2*pi") == 2 * sympy.pi
    assert parse("pi", {"pi": x}) == x


@pytest.mark.parametrize("text, built", [
    ("-x**2", -(x ** 2)),
    ("2*a1*sin(theta) + a2*sin(phi)", 2 * a1 * sympy.sin(theta) + a2 * sympy.sin(phi)),
    ("x - y - 3", (x - y) - 3),
    ("x/y/2", (x / y) / 2),
    ("2**3**2", sympy.Integer(512)),
    ("(x + y)*F", (x + y) * F),
    ("2*(x + y)*t", 2 * (x + y) * t),
    ("x**-1", 1 / x),
    ("--x", x),
    ("+x", x),
    ("F*cos(theta)/(a1 + a2)", F * sympy.cos(theta) / (a1 + a2)),
    ("sqrt(x**2 + y**2)", sympy.sqrt(x ** 2 + y ** 2)),
    ("  x + 1", x + 1),
    ("(x\n + y)", x + y),
])
def test_precedence_and_grouping(text, built):
    assert parse(text) == built


def test_long_sums_are_not_deep():
    text = " + ".join(f"{i}*x**{i}" for i in range(300))
    assert parse(text) == sum(i * x ** i for i in range(300))


# -- rejected expressions ----------------------------------------------------

@pytest.mark.parametrize("text, offset, fragment", [
    ("x ^ 2", 2, "'^'"),
    ("x % 2", 2, "'%'"),
    ("x // 2", 2, "'//'"),
    ("x @ y", 2, "'@'"),
    ("x << 1", 2, "'<<'"),
    ("x | y", 2, "'|'"),
    ("x & y", 2, "'&'"),
    ("not x", 0, "'not'"),
    ("~x", 0, "'~'"),
    ("os.system", 0, "unknown name 'os.system'"),
    ("x.real", 0, "unknown name 'x.real'"),
    ("(x).y.z + 1", 0, "unknown name 'x.y.z'"),
    ("(x + y).real", 8, "attribute access '.real'"),
    ("eval('1')", 0, "unknown function 'eval'"),
    ("__import__('os')", 0, "unknown function '__import__'"),
    ("x(1)", 0, "'x' is not a function"),
    ("sin(x=1)", 4, "keyword arguments"),
    ("sin(*x)", 4, "starred"),
    ("(lambda: 1)", 1, "lambda"),
    ("x[0]", 0, "subscripts"),
    ("x[1:2]", 0, "subscripts"),
    ("[x for x in y]", 0, "comprehensions"),
    ("{x for x in y}", 0, "comprehensions"),
    ("{x: y for x in y}", 0, "comprehensions"),
    ("sin(x for x in y)", 3, "generator"),
    ("'abc'", 0, "strings"),
    ("b'abc'", 0, "strings"),
    ("f'{x}'", 0, "f-strings"),
    ("True", 0, "'True'"),
    ("False + 1", 0, "'False'"),
    ("None", 0, "'None'"),
    ("x < y", 0, "comparisons"),
    ("x == y", 0, "comparisons"),
    ("x and y", 0, "'and'/'or'"),
    ("x or y", 0, "'and'/'or'"),
    ("(y := 2)", 1, "':='"),
    ("...", 0, "'...'"),
    ("1j", 0, "imaginary"),
    ("x + 2j", 4, "imaginary"),
    ("(x, y)", 0, "tuples"),
    ("x, y", 0, "tuples"),
    ("[x]", 0, "lists"),
    ("{x}", 0, "sets"),
    ("{x: y}", 0, "dictionaries"),
    ("x if y else 1", 0, "'if ... else'"),
    ("thetaa", 0, "unknown name 'thetaa'"),
    ("sin", 0, "'sin' is a function"),
    ("y + sin(zzz)", 8, "unknown name 'zzz'"),
])
def test_rejected_constructs(text, offset, fragment):
    problem = problem_of(text)
    assert fragment in problem.message
    assert problem.location == Location("m.yaml", 5, 7 + offset)


def test_caret_hint():
    assert "**" in problem_of("x^2").hint


def test_unknown_name_hints():
    assert "'theta'" in problem_of("thetaa").hint
    assert "parameters:" in problem_of("qqq").hint
    assert "'lower.y'" in problem_of("lower.z").hint


@pytest.mark.parametrize("text, offset, fragment", [
    ("F*cos(theta", 5, "expected ')'"),
    ("x +", 3, "unexpected end"),
    ("x) + (y", 1, "unmatched ')'"),
    ("2x", 0, "invalid number"),
    ("x y", 2, "unexpected 'y'"),
    ("1 +* 2", 3, "unexpected '*'"),
    ("a1[", 2, "expected ']'"),
    ("'abc", 0, "strings"),
    ("x = 1", 2, "unexpected '='"),
    ("θ*β λ", 4, "unexpected 'λ'"),
])
def test_syntax_errors(text, offset, fragment):
    problem = problem_of(text, {**NAMES, "θ": x, "β": y, "λ": t})
    assert fragment in problem.message
    assert problem.location == Location("m.yaml", 5, 7 + offset)


@pytest.mark.parametrize("text, offset, literal, hint", [
    ("170deg", 0, "170deg", "170*pi/180"),
    ("1 + 2.5e3kg", 4, "2.5e3kg", "2*x"),
    ("x + 12y", 4, "12y", "2*x"),
])
def test_invalid_number_quotes_what_was_written(text, offset, literal, hint):
    problem = problem_of(text)
    assert f"invalid number '{literal}'" in problem.message
    assert hint in problem.hint
    assert problem.location == Location("m.yaml", 5, 7 + offset)


def test_syntax_error_message_format():
    problem = problem_of("F*cos(theta")
    assert problem.message == "in expression 'F*cos(theta': expected ')'"


def test_reserved_word_as_name():
    problem = problem_of("lambda*x", {"lambda": x})
    assert "reserved word" in problem.message and "lambda_" in problem.hint


def test_positions_on_later_lines_and_after_spaces():
    problem = problem_of("(x\n + y ^ 2)")
    assert problem.location == Location("m.yaml", 6, 6)
    problem = problem_of("   x ^ 2")
    assert problem.location == Location("m.yaml", 5, 12)
    problem = problem_of("θ + zz", {"θ": x})
    assert problem.location == Location("m.yaml", 5, 11)


def test_default_location_and_what():
    with pytest.raises(ModelError) as info:
        parse_expression("x ^ 2", NAMES, what="force F")
    (problem,) = info.value.problems
    assert problem.location == Location("<expression>", 1, 3)
    assert problem.message.startswith("in force F 'x ^ 2': ")


@pytest.mark.parametrize("text, fragment", [
    ("", "empty"),
    ("   ", "empty"),
    ("x" * 10_001, "longer than"),
    ("-" * 200 + "x", "nested"),
    ("(" * 300 + "x" + ")" * 300, "nested"),
    ("sin(" * 150 + "x" + ")" * 150, "nested"),
    ("9**9**9**9", "too large"),
    ("2**19000 * 2**19000 * 2**19000 * 2**19000 * 2**19000 * 2**19000", "too large"),
    ("(1/3)**100000", "too large"),
    ("1e99999999", "too large"),
    ("1" + "0" * 5000, "too large"),
    ("*".join(["x"] * 150), "factors"),
    ("1/0", "undefined"),
    ("log(0)", "undefined"),
    ("sqrt(-1)", "not a real"),
    ("x\0", "null"),
])
def test_absurd_inputs(text, fragment):
    start = time.perf_counter()
    problem = problem_of(text)
    assert fragment in problem.message
    assert time.perf_counter() - start < 2


def test_non_text_input():
    with pytest.raises(ModelError):
        parse_expression(3.5, NAMES)  # type: ignore[arg-type]


# -- safety --------------------------------------------------------------------

ATTACKS = [
    "__import__('os').system('echo pwned')",
    "(lambda: 1)()",
    "().__class__.__bases__",
    "sin.__globals__",
    "open('x')",
    "open('x', 'w').write('pwned')",
    "().__class__.__bases__[0].__subclasses__()",
    "getattr(x, '__class__')",
    "exec('import os')",
    "sin.__globals__['__builtins__']['eval']('1')",
]


@pytest.mark.parametrize("text", ATTACKS)
def test_attacks_are_rejected_without_side_effects(text, tmp_path, monkeypatch, capfd):
    calls = []
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(os, "system", lambda *a: calls.append(("system", a)))
    real_open = builtins.open
    monkeypatch.setattr(builtins, "open", lambda *a, **k: calls.append(("open", a)) or real_open(*a, **k))
    with pytest.raises(ModelError) as info:
        parse_expression(text, {"x": x})
    assert info.value.problems[0].hint
    assert calls == []
    assert list(tmp_path.iterdir()) == []
    assert "pwned" not in capfd.readouterr().out


def test_module_never_evaluates_text():
    """No call of eval/exec/compile/sympify/parse_expr/S in the module's code."""
    source = Path(expressions.__file__).read_text(encoding="utf-8")
    tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    used = {tok.string for before, tok in zip(tokens, tokens[1:])
            if tok.type == tokenize.NAME and before.string != "."}  # re.compile is fine
    assert not used & {"eval", "exec", "compile", "sympify", "parse_expr", "S", "__import__"}
    assert "sympify(" not in source and "parse_expr(" not in source


# -- parse_number ---------------------------------------------------------------

@pytest.mark.parametrize("text, value", [
    ("9.81", sympy.Rational(981, 100)),
    (" -1.5e-3 ", sympy.Rational(-3, 2000)),
    ("+2", sympy.Integer(2)),
    ("1_000", sympy.Integer(1000)),
    (".25", sympy.Rational(1, 4)),
    (9.81, sympy.Rational(981, 100)),
    (7, sympy.Integer(7)),
])
def test_parse_number(text, value):
    result = parse_number(text)
    assert result == value and isinstance(result, sympy.Rational)


@pytest.mark.parametrize("text", ["", "abc", "1e99999", "inf", ".", "1.2.3", "x", True, None,
                                  float("nan"), "1" * 20_000])
def test_parse_number_rejects(text):
    with pytest.raises(ModelError) as info:
        parse_number(text, HERE, what="mass")
    (problem,) = info.value.problems
    assert problem.location == HERE and problem.hint and "mass" in problem.message


# -- determinism -----------------------------------------------------------------

def test_output_does_not_depend_on_hash_seed():
    code = ("import sympy; from kronsub.model.expressions import parse_expression as p; "
            "s = sympy.symbols('a b c x y'); n = {str(v): v for v in s}; "
            "print(sympy.srepr(p('c*sin(x) + b*cos(y)**2 - a/(x + y) + 9.81*x*y', n)))")
    root = Path(__file__).resolve().parents[1]
    outputs = set()
    for seed in ("1", "12345"):
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": str(root)}
        outputs.add(subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                   capture_output=True, text=True).stdout)
    assert len(outputs) == 1


# -- properties -------------------------------------------------------------------

EXPRESSION_ALPHABET = "xyt0123456789.eE+-*/^%()[], _'\"sincoqrtlgpab\n\\:=<>!@~&|{}j"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.text(max_size=40), st.text(alphabet=EXPRESSION_ALPHABET, max_size=40)))
def test_random_text_only_raises_model_errors(text):
    try:
        result = parse_expression(text, NAMES, HERE)
    except ModelError as exc:
        assert exc.problems and all(p.hint for p in exc.problems)
    else:
        assert isinstance(result, sympy.Expr)


LEAVES = st.one_of(
    st.sampled_from([("x", x), ("y", y), ("theta", theta), ("lower.y", lower_y),
                     ("upper.tip.x", tip_x), ("pi", sympy.pi)]),
    st.integers(0, 1000).map(lambda n: (str(n), sympy.Integer(n))),
    st.tuples(st.integers(0, 10 ** 6), st.integers(1, 4)).map(
        lambda p: (f"{p[0] // 10 ** p[1]}.{p[0] % 10 ** p[1]:0{p[1]}d}", sympy.Rational(*p[:1], 10 ** p[1]))),
    st.tuples(st.integers(1, 999), st.integers(-5, 5)).map(
        lambda p: (f"{p[0]}e{p[1]}", sympy.Integer(p[0]) * sympy.Rational(10) ** p[1])),
).map(lambda leaf: (*leaf, False))
BINARY = {"+": lambda a, b: a + b, "-": lambda a, b: a - b,
          "*": lambda a, b: a * b, "/": lambda a, b: a / b}
UNARY_FUNCTIONS = sorted(name for name, (_, arity) in FUNCTIONS.items() if arity == 1)
DOUBLE_MAX = 1.7976931348623157e308


def _not_a_double(expr: sympy.Expr) -> bool:
    """A constant that is not a finite real double (mpmath at 30 digits)."""
    import mpmath

    if expr.free_symbols or expr.has(sympy.zoo, sympy.nan, sympy.oo, -sympy.oo, sympy.I):
        return False
    with mpmath.workdps(30):
        try:
            value = mpmath.mpc(sympy.lambdify([], expr, "mpmath")())
        except (ValueError, ZeroDivisionError, OverflowError):
            return True
        return bool(value.imag != 0 or not mpmath.isfinite(value.real) or abs(value.real) > DOUBLE_MAX)


def _node(text: str, value, *children) -> tuple[str, sympy.Expr, bool]:
    """(text, value, refused): refused when a part, or a constant the parts combine into
    (the value itself, or a constant factor or term of it), is not a finite real double.
    ``value()`` builds the value from the children's; it is not built after a refusal
    (as the parser stops there; sympy can take minutes on ``atan2(acos(pi), 0)``)."""
    if any(c[2] for c in children):
        return text, sympy.Integer(0), True
    try:
        expr = value(*(c[1] for c in children))
    except TypeError:  # sympy itself fails (atan2 of some constants): the parser reports it
        return text, sympy.Integer(0), True
    parts = [expr] if not expr.free_symbols else [a for a in expr.args if not a.free_symbols]
    return text, expr, any(_not_a_double(p) for p in parts)


def _extend(children):
    binary = st.tuples(children, st.sampled_from(sorted(BINARY)), children, st.sampled_from(["", " "])).map(
        lambda p: _node(f"({p[0][0]}{p[3]}{p[1]}{p[3]}{p[2][0]})", BINARY[p[1]], p[0], p[2]))
    chain = st.tuples(children, st.sampled_from(["+", "-", "*", "/"]), children, children).map(
        lambda p: _node(f"({p[0][0]} {p[1]} {p[2][0]} {p[1]} {p[3][0]})",
                        lambda a, b, c: BINARY[p[1]](BINARY[p[1]](a, b), c), p[0], p[2], p[3]))
    power = st.tuples(children, st.integers(-2, 3)).map(
        lambda p: _node(f"({p[0][0]})**{p[1]}" if p[1] >= 0 else f"({p[0][0]})**({p[1]})",
                        lambda a: a ** sympy.Integer(p[1]), p[0]))
    negate = children.map(lambda c: _node(f"-({c[0]})", lambda a: -a, c))
    call = st.tuples(st.sampled_from(UNARY_FUNCTIONS), children).map(
        lambda p: _node(f"{p[0]}({p[1][0]})", FUNCTIONS[p[0]][0], p[1]))
    atan2 = st.tuples(children, children).map(
        lambda p: _node(f"atan2({p[0][0]}, {p[1][0]})", sympy.atan2, p[0], p[1]))
    return st.one_of(binary, chain, power, negate, call, atan2)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.recursive(LEAVES, _extend, max_leaves=8))
def test_well_formed_expressions_round_trip(pair):
    text, built, refused = pair
    if refused or built.has(sympy.zoo, sympy.nan, sympy.oo, -sympy.oo, sympy.I):
        with pytest.raises(ModelError):
            parse_expression(text, NAMES)
    else:
        assert parse_expression(text, NAMES) == built


def test_parts_built_once_are_the_parts_built_each_time():
    """``shared``: a part met again with the same text and the same names is the value built
    the first time; with other values behind the same names, or at another depth, it is built
    anew; a problem is reported where it is, as without it."""
    other = {**NAMES, "x": sympy.Symbol("z"), "upper.tip.x": sympy.Symbol("u")}
    texts = ["a1*sin(theta) + x/2", "2*(a1*sin(theta) + x/2)**2", "a1*sin(theta)", "x*y - a1*sin(theta)",
             "sqrt(1 - (a1*sin(theta) - x)**2/a2**2)", "-(a1*sin(theta)) + x/2", "upper . tip.x*2 + 1",
             "cos(phi - theta)*(F + t)", "a1  *  sin( theta )"]
    shared: dict = {}
    for names in (NAMES | {"upper.tip.x": sympy.Symbol("w")}, other, NAMES | {"upper.tip.x": sympy.Symbol("w")}):
        for text in texts + texts[::-1]:
            got = parse_expression(text, names, HERE, shared=shared)
            assert sympy.srepr(got) == sympy.srepr(parse_expression(text, names, HERE))
    assert shared
    for bad in ("a1*sin(theta) + 1/0", "a1*sin(theta) + nope", "x/2 + a1*sin(theta, x)"):
        with pytest.raises(ModelError) as with_shared:
            parse_expression(bad, NAMES, HERE, shared=shared)
        with pytest.raises(ModelError) as alone:
            parse_expression(bad, NAMES, HERE)
        assert str(with_shared.value) == str(alone.value)


@pytest.mark.parametrize("text", ["x/exp(-800)", "x*exp(400)*exp(400)", "x + exp(800) - exp(800)",
                                  "x + 10**400", "sin(x)*2**2000"])
def test_constants_made_in_combining_parts_are_checked(text):
    """A constant sympy makes in combining the parts (``x/exp(-800)`` is ``x*exp(800)``) is
    checked like one written: found by `is_number`, which stops at the first symbol."""
    x = sympy.Symbol("x", real=True)
    with pytest.raises(ModelError):
        parse_expression(text, {"x": x}, HERE)


def test_is_number_finds_the_constants_free_symbols_would():
    """Every part of a parsed expression is a number (`Expr.is_number`) exactly when it has no
    free symbol: the parser builds no undefined function, the one difference."""
    names = {n: sympy.Symbol(n, real=True) for n in ("x", "y", "l1", "q1", "q2")}
    for text in ["l1*sin(q1) + l1/2*sin(q2) - pi/2 + sqrt(2)*x", "-x*cos(q1 - pi/2) + exp(2)*atan2(y, 3)",
                 "abs(x - 1)**(1/3) + log(2)*sign(y) + asin(1/3)*q1", "(x + 1)**2*tanh(1) + 7/3",
                 "sqrt(l1**2 - x**2)/cosh(q2) + acos(1/2)"]:
        for part in sympy.preorder_traversal(parse_expression(text, names, HERE)):
            assert bool(part.is_number) == (not part.free_symbols), (text, part)
