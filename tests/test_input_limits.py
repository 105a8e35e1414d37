"""Inputs that would exhaust memory or time get a clear error (issue 6, section 5).

Model files: only regular files of at most `MAX_MODEL_BYTES` are read (stat
before open, non-blocking); devices, FIFOs, /proc files, symbolic-link loops
and unreadable files are errors at the `model:` that names them; a file that
is not a model is never echoed beyond one line. Expressions: powers of sums
are refused before they are expanded (checked against sympy's own expansion),
and constants are checked as finite real doubles before any exact evaluation
(values checked against mpmath at 60 digits).
"""
from __future__ import annotations

import errno
import itertools
import math
import os
import re
from pathlib import Path

import mpmath
import pytest
import sympy
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.deadline import within
from kronsub.cli import main
from kronsub.core.trigpoly import (MAX_EXPANDED_POWER, MAX_EXPANSION_TERMS, ExpansionTooLarge, TrigAlgebra,
                                   _expansion_width, expansion_terms)
from kronsub.core.symbols import symbol
from kronsub.errors import ModelError
from kronsub.model import file_reading
from kronsub.model.expressions import constant_value, parse_expression
from kronsub.model.loader import load_model
from kronsub.model.file_reading import MAX_MODEL_BYTES, read_model_text

SLIDER = ("name: slider\nparameters: {m: 1, k: 2}\ncomponents:\n"
          "  s: {type: particle1d, parameters: {mass: m}, coordinates: [x]}\ncoordinates: [x]\n")
THREE = ("name: three\nparameters: {m: 1}\ncomponents:\n"
         "  w: {type: particle1d, parameters: {mass: m}, coordinates: [w]}\n"
         "  a: {type: particle1d, parameters: {mass: m}, coordinates: [x]}\n"
         "  b: {type: particle1d, parameters: {mass: m}, coordinates: [y]}\n"
         "  c: {type: particle1d, parameters: {mass: m}, coordinates: [z]}\n"
         "coordinates: [x, y, z]\n")
LIMIT = 30  # seconds: many times a normal run, far below the minutes a hang takes


def run(*args: str):
    with within(LIMIT, "kronsub " + " ".join(args)):
        return CliRunner().invoke(main, list(args))


def stderr_of(result) -> str:
    try:
        return result.stderr
    except ValueError:
        return result.output


def error_of(result) -> str:
    """The output of a run that failed cleanly with exit code 1."""
    text = result.output + stderr_of(result)
    assert result.exit_code == 1, (result.exit_code, text, repr(result.exception))
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in text and "internal error" not in text, text
    err = stderr_of(result)
    assert err.startswith("Error: ") and "\n  hint: " in err, err
    return err


def place(text: str, needle: str) -> str:
    """``LINE:COL`` (1-based) of ``needle`` in ``text``."""
    index = text.index(needle)
    return f"{text.count(chr(10), 0, index) + 1}:{index - (text.rfind(chr(10), 0, index) + 1) + 1}"


def including(tmp_path: Path, target: str) -> tuple[Path, str]:
    text = f"name: a\ncomponents:\n  sub: {{model: '{target}'}}\ncoordinates: [q]\n"
    path = tmp_path / "main.yaml"
    path.write_text(text)
    return path, text


# ---------------------------------------------------------------- model files
@pytest.mark.parametrize("target, kind", [
    ("/dev/zero", "character device"), ("/dev/urandom", "character device"),
    ("/proc/self/environ", "under /proc"), ("/proc/self/status", "under /proc"),
])
def test_special_files_are_never_read(tmp_path, target, kind):
    if not os.path.exists(target):
        pytest.skip(f"{target} does not exist here")
    path, text = including(tmp_path, target)
    err = error_of(run("derive", str(path)))
    assert err.startswith(f"Error: {path}:{place(text, target)}: model file '{target}': "), err
    assert kind in err
    err = error_of(run("derive", target))  # the model itself
    assert err.startswith(f"Error: {target}: ") and kind in err, err


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)  # no writer: opening it for reading would block for ever
    path, text = including(tmp_path, "pipe.yaml")
    err = error_of(run("derive", str(path)))
    assert err.startswith(f"Error: {path}:{place(text, 'pipe.yaml')}: model file '{tmp_path / 'pipe.yaml'}': "
                          "is a named pipe (FIFO), not a regular file"), err
    assert "FIFO" in error_of(run("derive", str(fifo)))


def test_a_file_swapped_for_a_fifo_after_the_check_is_refused(tmp_path, monkeypatch):
    """The descriptor is checked again after the non-blocking open."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    model = tmp_path / "m.yaml"
    model.write_text(SLIDER)
    regular = os.stat(model)
    real_stat = os.stat
    monkeypatch.setattr(file_reading.os, "stat", lambda p, *a, **k: regular if str(p) == str(fifo) else real_stat(p, *a, **k))
    with within(LIMIT), pytest.raises(ModelError, match="named pipe"):
        read_model_text(fifo)


def test_a_loop_of_symbolic_links(tmp_path):
    (tmp_path / "a.yaml").symlink_to("b.yaml")
    (tmp_path / "b.yaml").symlink_to("a.yaml")
    err = error_of(run("derive", str(tmp_path / "a.yaml")))
    assert err.startswith(f"Error: {tmp_path / 'a.yaml'}: is a loop of symbolic links\n  hint: "), err
    path, text = including(tmp_path, "a.yaml")
    err = error_of(run("derive", str(path)))
    assert err.startswith(f"Error: {path}:{place(text, 'a.yaml')}: model file "), err
    assert "loop of symbolic links" in err


def test_an_unreadable_file(tmp_path, monkeypatch):
    model = tmp_path / "sub.yaml"
    model.write_text(SLIDER)
    real_open = os.open

    def refuse(p, *args, **kwargs):  # as chmod 000 does (the tests may run as root)
        if str(p) == str(model):
            raise PermissionError(errno.EACCES, "Permission denied", str(p))
        return real_open(p, *args, **kwargs)

    monkeypatch.setattr(file_reading.os, "open", refuse)
    path, text = including(tmp_path, "sub.yaml")
    err = error_of(run("derive", str(path)))
    assert err.startswith(f"Error: {path}:{place(text, 'sub.yaml')}: model file '{model}': permission denied\n"
                          "  hint: check the file's permissions"), err


def test_a_directory(tmp_path):
    (tmp_path / "d.yaml").mkdir()
    path, _ = including(tmp_path, "d.yaml")
    assert "is a directory, not a regular file" in error_of(run("derive", str(path)))


def test_size_limit_is_checked_before_reading(tmp_path, monkeypatch):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as fh:  # sparse: 10 MB that cost no disk
        fh.truncate(10 * 2 ** 20)
    monkeypatch.setattr(file_reading, "_read_at_most", lambda *a: pytest.fail("read a file over the limit"))
    err = error_of(run("derive", str(big)))
    assert err.startswith(f"Error: {big}: is too large (10,485,760 bytes; a model file may have at most "
                          f"{MAX_MODEL_BYTES:,} bytes)\n"), err


def test_size_limit_boundary(tmp_path):
    at_limit = tmp_path / "at.yaml"
    at_limit.write_text(SLIDER + "#" * (MAX_MODEL_BYTES - len(SLIDER) - 1) + "\n")
    assert at_limit.stat().st_size == MAX_MODEL_BYTES
    assert load_model(at_limit, cache=False).name == "slider"
    over = tmp_path / "over.yaml"
    over.write_text(at_limit.read_text() + "\n")
    with pytest.raises(ModelError, match="too large"):
        load_model(over, cache=False)


def test_a_file_that_is_not_a_model_is_echoed_one_line_at_most(tmp_path):
    secrets = tmp_path / "passwd"
    secrets.write_text("root:x:0:0:root:/root:/bin/bash\nsecond-line-secret:x:1:1\nthird\n")
    mapping = tmp_path / "config"
    mapping.write_text("first_key: 1\nsecond_key_secret: 2\nthird_key_secret: 3\n")
    for target in (secrets, mapping):
        path, _ = including(tmp_path, str(target))
        for result in (run("derive", str(path)), run("derive", str(target))):
            err = error_of(result)
            assert "secret" not in err, err
            assert len(err.strip().splitlines()) == 2, err  # one error and its hint


def test_relative_sub_model_paths_start_at_the_including_file(tmp_path, monkeypatch):
    (tmp_path / "models" / "parts").mkdir(parents=True)
    (tmp_path / "models" / "parts" / "slider.yaml").write_text(SLIDER)
    main_text = ("name: outer\ncomponents:\n  s: {model: parts/slider.yaml}\ncoordinates: [x]\n")
    (tmp_path / "models" / "outer.yaml").write_text(main_text)
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    model = load_model(Path("..") / "models" / "outer.yaml", cache=False)
    assert [q.name for q in model.coordinates] == ["x"]


@pytest.mark.parametrize("value, kind", [("[a, b]", "a list"), ("{x: 1}", "a mapping"), ("3", "'3'"),
                                         ("''", "''"), ("null", "nothing")])
def test_model_key_must_name_a_file(tmp_path, value, kind):
    text = f"name: a\ncomponents:\n  sub: {{model: {value}}}\ncoordinates: [q]\n"
    path = tmp_path / "m.yaml"
    path.write_text(text)
    err = error_of(run("derive", str(path)))
    if value != "null":  # `model: null` is a component without a model: no `type:`
        assert err.startswith(f"Error: {path}:{place(text, value)}: `model:` of component 'sub' must be a file "
                              f"name, found {kind}"), err
    assert "Node(" not in err


# --------------------------------------------------------- powers of sums
def test_multinomial_count_matches_sympy_expansion():
    """`expansion_terms` is exact for a sum of independent terms (sympy's expand counts)."""
    for terms, power in itertools.product(range(1, 5), range(0, 7)):
        names = sympy.symbols(f"a0:{terms}")
        expanded = sympy.expand(sympy.Add(*names) ** power)
        assert expansion_terms(terms, power) == len(sympy.Add.make_args(expanded)), (terms, power)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.sampled_from(["1", "x", "y", "cos(x)", "sin(y)", "cos(x - y)", "sin(2*x)"]),
                          st.integers(1, 3)), min_size=2, max_size=4), st.integers(2, 4))
def test_expansion_count_bounds_the_algebra(terms, power):
    """The width counted as exponentials bounds the terms the algebra produces."""
    x, y = sympy.symbols("x y")
    base = sympy.Add(*(c * parse_expression(t, {"x": x, "y": y}) for t, c in terms))
    algebra = TrigAlgebra((x, y))
    inner = algebra.from_expr(base)
    expanded = algebra.from_expr(base ** power)
    produced = sum(len(coef) for coef in expanded.terms.values())
    assert produced <= expansion_terms(_expansion_width(inner), power)
    difference = sympy.lambdify((x, y), algebra.to_expr(expanded) - base ** power)
    for point in ((0.3, -1.1), (2.0, 0.7), (-0.4, 0.25)):  # the same function (numerically)
        assert abs(difference(*point)) < 1e-9


def test_the_algebra_refuses_a_large_power_before_expanding():
    x, y, z = sympy.symbols("x y z")
    algebra = TrigAlgebra((x, y, z))
    with within(LIMIT), pytest.raises(ExpansionTooLarge, match=r"higher than \*\*8"):
        algebra.from_expr((x + 1) ** 3000)
    with within(LIMIT), pytest.raises(ExpansionTooLarge, match="would expand to 252 terms"):
        algebra.from_expr((x + y + z + x * y + x * z + y * z) ** 5)
    assert len(algebra.from_expr((x + y + z) ** MAX_EXPANDED_POWER).terms[(0, ())]) == 45
    assert MAX_EXPANSION_TERMS >= 45
    # a single term is not a sum: cos(x)**9 is 5 cosines; only the count of terms limits it
    assert sorted(k for _, ((_, k),) in algebra.from_expr(sympy.cos(x) ** 9).terms) == [1, 3, 5, 7, 9]
    with pytest.raises(ExpansionTooLarge, match="would expand to 201 terms"):
        algebra.from_expr(sympy.cos(x) ** 200)


@pytest.mark.parametrize("section, expression, needle", [
    ("effects:\n  p: {type: potential, value: '(x+1)**3000'}\n", "(x+1)**3000", "**3000"),
    ("connection:\n  w: (x+y+z)**20\n", "(x+y+z)**20", "**20"),
    ("connection:\n  w: (x+y+z+x*y+x*z+y*z)**5\n", "(x+y+z+x*y+x*z+y*z)**5", "**5"),
])
def test_a_power_of_a_sum_too_large_to_expand_is_located(tmp_path, section, expression, needle):
    text = (SLIDER if "potential" in section else THREE) + section
    path = tmp_path / "m.yaml"
    path.write_text(text)
    err = error_of(run("derive", "--no-cache", str(path)))
    assert err.startswith(f"Error: {path}:{place(text, needle)}: in "), err
    assert "power" in err and "hint: powers of sums are expanded up to **8" in err


def test_a_power_that_grows_by_substitution_is_refused(tmp_path):
    """w = (x+y)**4 and a potential w**4 make (x+y)**12 only after the connection."""
    text = THREE.replace("coordinates: [x, y, z]", "coordinates: [x, y]").replace(
        "  c: {type: particle1d, parameters: {mass: m}, coordinates: [z]}\n", "")
    text += "connection:\n  w: (x+y)**4\neffects:\n  p: {type: potential, value: w**4}\n"
    path = tmp_path / "m.yaml"
    path.write_text(text)
    err = error_of(run("derive", "--no-cache", str(path)))
    assert err.startswith(f"Error: {path}: (x + y)**12: a power of a sum higher than **8"), err


def test_an_allowed_power_of_a_sum_derives_correctly(tmp_path):
    """Potential (x+1)**8: m x'' = -8 (x+1)**7, from sympy's derivative (a hand Lagrangian)."""
    text = SLIDER + "effects:\n  p: {type: potential, value: (x+1)**8}\n"
    path = tmp_path / "m.yaml"
    path.write_text(text)
    system = load_model(path, cache=False).derive(cache=False)
    x, m = symbol("x"), symbol("m")
    force = -sympy.diff((x + 1) ** 8, x)
    (mass,), = system.mass_matrix.tolist()
    assert sympy.simplify(mass - m) == 0
    assert sympy.expand(system.forces[0] - system.velocity_terms[0] - force) == 0


# ------------------------------------------------------------- constants
HOSTILE_VALUES = {
    "acos(2)": "is not a real number",
    "1e400": "is too large for a double",
    "exp(exp(exp(1000)))": "'exp(1000)' is too large",
    "2+sin(exp(exp(20)))": "'exp(exp(20))' is too large",
    "(-8)**(1/3)": "is not a real number",
    "2**1024": "is too large for a double",
    "log(-1)": "not a real number",
    "1/0": "undefined",
}


@pytest.mark.parametrize("value", list(HOSTILE_VALUES))
def test_set_values_are_bounded_finite_and_real(value):
    path = Path(__file__).parent / "models" / "polar_spring.yaml"
    err = error_of(run("simulate", str(path), "--t", "0.01", "--set", f"m={value}"))
    assert err.startswith(f"Error: --set m: in value of m '{value}': "), err
    assert HOSTILE_VALUES[value] in err.splitlines()[0], err


@pytest.mark.parametrize("value", list(HOSTILE_VALUES))
def test_parameter_values_are_bounded_finite_and_real(tmp_path, value):
    text = SLIDER.replace("k: 2}", f"k: '{value}'}}")
    path = tmp_path / "m.yaml"
    path.write_text(text)
    err = error_of(run("derive", str(path)))
    assert re.match(re.escape(f"Error: {path}:2:") + r"\d+: in value of parameter 'k'", err), err
    assert HOSTILE_VALUES[value] in err.splitlines()[0], err


@pytest.mark.parametrize("text", ["sin(1e300)", "cos(exp(700))", "exp(709)", "1e-400", "pi/3 + sqrt(2)",
                                  "atan2(-1, -2) * tanh(3)", "2**(1/2) - sqrt(2)", "abs(-7/3) * sign(-2)"])
def test_constant_values_are_correctly_rounded(text):
    """The value is the exact one rounded to a double (mpmath at 60 digits from the exact form)."""
    expr = parse_expression(text, {})
    with mpmath.workdps(60):
        reference = float(mpmath.mpmathify(sympy.N(expr, 60)))
    assert constant_value(expr) == reference


def test_large_but_finite_constants_in_formulas_are_accepted():
    x = sympy.Symbol("x")
    assert parse_expression("x*exp(700)", {"x": x}) == x * sympy.exp(700)
    with pytest.raises(ModelError, match="'exp[(]1000[)]' is too large"):
        parse_expression("x*exp(1000)", {"x": x})
    assert math.isfinite(constant_value(parse_expression("1e308", {})))
    with pytest.raises(ModelError, match="too large"):  # sympy makes x*exp(800) of it
        parse_expression("x/exp(-800)", {"x": x})


def test_a_special_file_two_levels_down_is_reported_in_the_file_that_names_it(tmp_path):
    (tmp_path / "a.yaml").write_text("name: a\ncomponents:\n  sub: {model: b.yaml}\ncoordinates: [q]\n")
    b_text = "name: b\ncomponents:\n  sub: {model: /dev/zero}\ncoordinates: [q]\n"
    (tmp_path / "b.yaml").write_text(b_text)
    err = error_of(run("derive", str(tmp_path / "a.yaml")))
    assert err.startswith(f"Error: {tmp_path / 'b.yaml'}:{place(b_text, '/dev/zero')}: model file '/dev/zero': "
                          "is a character device"), err


def test_quoted_model_text_cannot_break_a_message_into_lines(tmp_path):
    """A name holding a line break and a fake message is shown escaped, on its own line."""
    text = SLIDER.replace("k: 2}", '"k\\nError: all is well\\r": 2}')
    path = tmp_path / "m.yaml"
    path.write_text(text)
    err = error_of(run("derive", str(path)))
    lines = err.strip().splitlines()
    assert len(lines) == 2 and lines[1].startswith("  hint: "), err
    assert "parameter name 'k\\nError: all is well\\r' is not a valid name" in lines[0], err


def test_a_square_may_expand_further_than_a_higher_power():
    """A square's terms grow only as the square of the sum's: kronsub's own |p_b - p_a|^2 of a
    spring at a corner of a turning 3-D body needs some 500 (tests/models/sweep/box_on_springs_3d.yaml);
    the square's own limit still holds, and a cube keeps the general one."""
    from kronsub.core.trigpoly import MAX_SQUARE_TERMS

    xs = sympy.symbols("x0:70")
    algebra = TrigAlgebra(xs)
    fits = next(n for n in range(2, 200) if expansion_terms(n + 1, 2) > MAX_SQUARE_TERMS)
    assert expansion_terms(fits, 2) > MAX_EXPANSION_TERMS  # beyond the general limit, within the square's
    assert len(algebra.from_expr(sympy.Add(*xs[:fits]) ** 2).terms[(0, ())]) == expansion_terms(fits, 2)
    with pytest.raises(ExpansionTooLarge, match=f"more than {MAX_SQUARE_TERMS}"):
        algebra.from_expr(sympy.Add(*xs[:fits + 1]) ** 2)
    with pytest.raises(ExpansionTooLarge, match=f"more than {MAX_EXPANSION_TERMS}"):
        algebra.from_expr(sympy.Add(*xs[:12]) ** 3)
