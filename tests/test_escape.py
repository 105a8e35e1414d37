"""Free text of a model never becomes code: hostile names, units, descriptions and file names
through every template (issue 6, section 1).

Independent routes: the C compiler and Python's own parser read the escaped text back
(``sizeof``/``fwrite`` of a C string literal, ``ast.literal_eval``, a function's ``__doc__``);
the preprocessed C and the Python syntax tree of a hostile model equal those of a benign one
(free text changes comments and string constants only); the LaTeX and Markdown of a hostile
model have exactly the control sequences and structure characters of the benign one; and a
canary file that the payloads would create never appears.
"""
from __future__ import annotations

import ast
import ctypes
import importlib.util
import json
import re
import shutil
import subprocess
from pathlib import Path

import jinja2
import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from kronsub.cli import main
from kronsub.emitters.code import emit_c, emit_python, file_stem
from kronsub.emitters.escape import (LATEX_ESCAPES, UnescapedText, c_comment, c_string, environment, latex_text,
                                     markdown_text, python_string)
from kronsub.emitters.text import emit_json, emit_latex, emit_markdown

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler (gcc) on the PATH")


def c_payload(canary: str) -> str:
    """Closes a C comment, defines a constructor that creates ``canary``, reopens the comment."""
    return ("*/\n#include <stdio.h>\n#ifndef KS_CANARY_ONCE\n#define KS_CANARY_ONCE\n"
            "__attribute__((constructor)) static void ks_canary(void) { FILE *f = fopen(\"" + canary
            + "\", \"w\"); if (f) fclose(f); }\n#endif\n/*")


def py_payload(canary: str) -> str:
    """Closes a docstring (either quote), creates ``canary``, reopens the docstring."""
    return ('"""\nopen("' + canary + '", "w").write("x")\n"""' + "'''\nopen('" + canary + "', 'w')\n'''")


HOSTILE = ["*/", "/*", '"""', "'''", "\\", "\n", "\r", "\r\n", "\0", "??/", "??=", "\u2028", "\u2029",
           r"\input{/etc/passwd}", r"\write18{touch canary}", "$", "#", "%", "{", "}", "&", "_", "^", "~",
           "<script>alert(1)</script>", "[link](http://x)", "`code`", "| cell |", "1. item", "- item",
           "\\\n", "x\\", "\t", "\x1b[31m", "é ü 漢", "\U0001F600", "\ud800"]


def every(canary: str) -> list[str]:
    return HOSTILE + [c_payload(canary), py_payload(canary), "".join(HOSTILE)]


# -------------------------------------------------------------------- the escaping functions


@needs_cc
def test_c_string_is_read_back_by_the_compiler(tmp_path):
    texts = [t for t in every("canary") if "\ud800" not in t]
    body = "".join(f'static const char s{i}[] = "{c_string(t)}";\n' for i, t in enumerate(texts))
    calls = "".join(f"    fwrite(s{i}, 1, sizeof s{i} - 1, stdout); putchar(0xff);\n" for i in range(len(texts)))
    (tmp_path / "main.c").write_text("#include <stdio.h>\n" + body + "int main(void)\n{\n" + calls
                                     + "    return 0;\n}\n")
    subprocess.run(["gcc", *CFLAGS, "main.c", "-o", "main"], cwd=tmp_path, check=True, capture_output=True)
    out = subprocess.run([str(tmp_path / "main")], capture_output=True, check=True).stdout
    assert out.split(b"\xff")[:-1] == [t.encode() for t in texts]


@needs_cc
def test_c_comment_stays_one_comment(tmp_path):
    canary = tmp_path / "canary"
    texts = every(str(canary))
    source = "".join(f"/* {c_comment(t)} */\n" for t in texts) + "int ks_only(void) { return 1; }\n"
    for t in texts:
        escaped = c_comment(t)
        assert "*/" not in escaped and "/*" not in escaped and "??" not in escaped
        assert all(" " <= ch <= "~" for ch in escaped)
    (tmp_path / "x.c").write_text(source)
    pre = subprocess.run(["gcc", "-std=c99", "-E", "-P", "x.c"], cwd=tmp_path, check=True, capture_output=True,
                         text=True).stdout
    assert pre.split() == "int ks_only(void) { return 1; }".split()
    subprocess.run(["gcc", *CFLAGS, "-c", "x.c"], cwd=tmp_path, check=True, capture_output=True)
    assert not canary.exists()


def test_python_string_is_read_back_by_python():
    for text in every("canary"):
        body = python_string(text)
        assert ast.literal_eval('"' + body + '"') == text
        assert ast.literal_eval("'" + body + "'") == text
        namespace = {}
        exec(compile(f'def f():\n    """{body}"""\n', "doc", "exec"), namespace)  # our own escaped text
        assert namespace["f"].__doc__ == text
        assert "\n" not in body and "\r" not in body and "\0" not in body and "\u2028" not in body


_CONTROL = re.compile(r"\\(?:[A-Za-z@]+|.)", re.S)


def test_latex_text_has_no_control_sequence_of_its_own():
    for text in every("canary"):
        escaped = plain = latex_text(text)
        for escape in sorted(LATEX_ESCAPES, key=len, reverse=True):
            plain = plain.replace(escape, "")
        for ch in "\\{}$&#%_^~\n\r\0\u2028":
            assert ch not in plain, (text, escaped)


def _unescaped(text: str, chars: str) -> int:
    """Characters of ``chars`` not preceded by a backslash escape."""
    return len(re.findall(r"(?<!\\)(?:\\\\)*[" + re.escape(chars) + "]", text))


def test_markdown_text_is_inline_and_inert():
    for text in every("canary"):
        escaped = markdown_text(text)
        assert "\n" not in escaped and "\r" not in escaped and "\u2028" not in escaped
        assert _unescaped(escaped, "`*_[]<>|&$#~") == 0, escaped
        assert not re.match(r"\s|[-+=>]|\d+[.)]", escaped), escaped


def test_templates_refuse_text_that_skipped_the_escaping_filters():
    env = environment(jinja2.DictLoader({
        "raw": "/* {{ name }} */", "ok": "/* {{ name | c_comment }} {{ n }} */",
        "joined": "{{ names | join(', ') }}", "safe": "{{ name | safe }}", "json": "{{ name | tojson }}",
        "concat": "{{ name ~ '' }}"}))
    assert env.get_template("ok").render(name="*/ x", n=3) == "/* * / x 3 */"
    for name in ("raw", "joined", "concat"):
        with pytest.raises(UnescapedText):
            env.get_template(name).render(name="*/ x", names=["a"])
    for name in ("safe", "json"):
        with pytest.raises(jinja2.TemplateError):
            env.get_template(name).render(name="*/ x")


def test_file_stem_is_safe_to_write_and_include():
    assert file_stem("DoublePendulum") == "DoublePendulum"
    assert file_stem("my model") == "my_model"
    assert file_stem("../../etc/x") == "etc_x"
    assert file_stem('a"""*/') == "a"
    assert file_stem("") == file_stem("///") == "model"


# ------------------------------------------------------------------------ hostile models


MODEL = """\
name: {name}
description: {description}
parameters:
  m: {{value: 1.5, unit: {unit}, description: {pdesc}}}
  L: {{value: 0.7, unit: {unit}}}
  g: {{value: 9.81, description: {pdesc}}}
components:
  bob: {{type: particle2d, parameters: {{mass: m}}, coordinates: [x, y], description: {pdesc}}}
coordinates: [q]
connection: {{x: L*sin(q), y: -L*cos(q)}}
effects:
  gravity: {{type: gravity, g: g, description: {pdesc}}}
initial: {{q: 0.3}}
"""

PARENT = """\
name: {name}
description: {description}
parameters:
  k: {{value: 2, unit: {unit}, description: {pdesc}}}
components:
  arm: {{model: {sub}}}
  spring: {{type: particle1d, parameters: {{mass: 0.1}}, coordinates: [s]}}
coordinates: [q]
connection: {{s: q}}
effects:
  hold: {{type: spring, between: [spring.centre, [0]], stiffness: k}}
"""


def _yaml_string(text: str) -> str:
    """A YAML double-quoted scalar of ``text``: every character survives, printable ASCII as is."""
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '\\"':
            out.append("\\" + ch)
        elif 0x20 <= code < 0x7F:
            out.append(ch)
        else:
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return '"' + "".join(out) + '"'


def _model_text(template: str, text: str, **extra) -> str:
    q = _yaml_string
    return template.format(name=q(text), description=q(text), unit=q(text), pdesc=q(text), **extra)


def _write_models(folder: Path, text: str, filename: str = "model.yaml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sub.yaml").write_text(_model_text(MODEL, text), encoding="utf-8")
    path = folder / filename
    path.write_text(_model_text(PARENT, text, sub="sub.yaml"), encoding="utf-8")
    return path


def _preprocessed(folder: Path) -> str:
    return subprocess.run(["gcc", "-std=c99", "-E", "-P", "model.c"], cwd=folder, check=True, capture_output=True,
                          text=True).stdout


def _syntax(text: str) -> str:
    """The Python syntax tree with every string constant emptied."""
    tree = ast.parse(text)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            node.value = ""
    return ast.dump(tree)


def _latex_shape(text: str) -> tuple:
    """The control sequences and special characters of a document, less the text escapes."""
    for escape in sorted(LATEX_ESCAPES, key=len, reverse=True):
        text = text.replace(escape, "")
    return sorted(m.group() for m in _CONTROL.finditer(text)), text.count("\n"), _unescaped(text, "{}$&#%^_~")


def _markdown_shape(text: str) -> tuple:
    return text.count("\n"), _unescaped(text, "`*_[]<>|&$#~")


# each string above on its own through the escaping functions; through every template, these
# (each in every free-text field at once) and all of them together
HOSTILE_CASES = {f"h{i}": t for i, t in enumerate(["*/", '"""', "\\", "\n", "\r", "\0", "??/", "\u2028",
                                                   r"\input{/etc/passwd}", "\U0001F600", "<c>", "<py>", "<all>"])}


@pytest.fixture(scope="module")
def benign(tmp_path_factory):
    """The same models with plain text: its generated code, preprocessed C and documents."""
    folder = tmp_path_factory.mktemp("benign")
    system = kronsub.load(_write_models(folder, "x")).derive()
    (py,) = emit_python(system, "model", source="x")
    preprocessed = None
    if shutil.which("gcc") is not None:
        for generated in emit_c(system, "model", source="x"):
            (folder / generated.name).write_text(generated.text, encoding="utf-8")
        preprocessed = _preprocessed(folder)
    return {"python": _syntax(py.text), "c": preprocessed, "latex": _latex_shape(emit_latex(system)),
            "markdown": _markdown_shape(emit_markdown(system))}


def _hostile_text(key: str, canary: Path) -> str:
    text = HOSTILE_CASES[key]
    return {"<c>": c_payload(str(canary)), "<py>": py_payload(str(canary)),
            "<all>": "".join(every(str(canary))).replace("\ud800", "")}.get(text, text)  # no lone surrogate in UTF-8


@pytest.mark.parametrize("key", sorted(HOSTILE_CASES))
def test_hostile_text_changes_no_generated_code(key, tmp_path, benign):
    canary = tmp_path / "canary"
    text = _hostile_text(key, canary)
    system = kronsub.load(_write_models(tmp_path / "m", text)).derive()
    assert system.name == text and system.parameters[0].unit == text

    # Python: only string constants differ, and they read back as the model's text
    (py,) = emit_python(system, "model", source=text)
    assert _syntax(py.text) == benign["python"]
    (tmp_path / "gen.py").write_text(py.text, encoding="utf-8")
    spec = importlib.util.spec_from_file_location(f"hostile_{key}", tmp_path / "gen.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.MODEL_NAME == text and module.__doc__.startswith(text + ":")
    y = np.array([0.3, -0.4])
    param = np.array([float(p.value) for p in system.parameters])
    assert np.all(np.isfinite(module.rhs(0.0, y, param)))

    # LaTeX and Markdown: the same commands and structure as the benign model's
    assert _latex_shape(emit_latex(system)) == benign["latex"]
    assert "\\input" not in emit_latex(system) and "\\write18" not in emit_latex(system)
    lines, marks = _markdown_shape(emit_markdown(system))
    no_description = 2 if not system.description.strip() else 0  # a blank description has no paragraph
    assert (lines + no_description, marks) == benign["markdown"]
    assert json.loads(emit_json(system))["name"] == text

    if shutil.which("gcc") is not None:
        # C: the preprocessed code is the benign model's; the name reads back from its macro
        for generated in emit_c(system, "model", source=text):
            (tmp_path / generated.name).write_text(generated.text, encoding="utf-8")
        assert _preprocessed(tmp_path) == benign["c"]
        values = ", ".join(repr(float(v)) for v in param)
        (tmp_path / "main.c").write_text(
            '#include <stdio.h>\n#include "model.h"\nint main(void)\n{\n'
            f"    double y[KS_NY] = {{0.3, -0.4}}, param[KS_NPARAM] = {{{values}}}, ydot[KS_NY];\n"
            "    if (ks_rhs(0.0, y, param, ydot)) return 1;\n"
            '    fprintf(stderr, "%.17g %.17g", ydot[0], ydot[1]);\n'
            "    fwrite(KS_MODEL_NAME, 1, sizeof KS_MODEL_NAME - 1, stdout);\n"
            "    return 0;\n}\n")
        subprocess.run(["gcc", *CFLAGS, "main.c", "model.c", "-o", "main", "-lm"], cwd=tmp_path, check=True,
                       capture_output=True)
        run = subprocess.run([str(tmp_path / "main")], capture_output=True, check=True)
        assert run.stdout == text.encode()
        assert np.allclose([float(v) for v in run.stderr.split()], module.rhs(0.0, y, param), rtol=1e-13)
    assert not canary.exists()


def _cli(args, cwd: Path, monkeypatch, **env):
    """The command line, in this process (a payload that ran would create the canary all the same)."""
    monkeypatch.chdir(cwd)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    result = CliRunner().invoke(main, args)
    for key in env:
        monkeypatch.delenv(key)
    return result


@pytest.mark.parametrize("payload", ["c", "python"])
def test_the_issue_attacks_run_nothing(payload, tmp_path, monkeypatch):
    """The reproducers of issue 6: `*/` or `\"\"\"` in the name and the unit, then codegen,
    simulate (compiled, and on the no-compiler fallback with --points) and import."""
    canary = tmp_path / "canary"
    text = c_payload(str(canary)) if payload == "c" else py_payload(str(canary))
    path = _write_models(tmp_path, text)
    out = tmp_path / "out"
    out.mkdir()
    for lang in ("c", "python"):
        result = CliRunner().invoke(main, ["codegen", str(path), "--lang", lang, "--output", str(out)])
        assert result.exit_code == 0, result.output
    if shutil.which("gcc") is not None:
        subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", "libmodel.so", "-lm"], cwd=out,
                       check=True, capture_output=True)
        ctypes.CDLL(str(out / "libmodel.so"))
    spec = importlib.util.spec_from_file_location(f"attack_{payload}", out / "model.py")
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    for env in ({}, {"CC": "kronsub-no-such-compiler"}):
        result = _cli(["simulate", str(path), "--t", "0.05", "--points"], tmp_path, monkeypatch,
                      KRONSUB_CACHE_DIR=str(tmp_path / "cache"), **env)
        assert result.exit_code == 0, result.output
        assert "Traceback" not in result.output
    assert not canary.exists()


@pytest.mark.parametrize("filename", ['x"""; open("canary", "w").write("x"); """.yaml',
                                      "X*/\n#include <stdio.h>\n__attribute__((constructor)) static void c(void) "
                                      '{ FILE *f = fopen("canary", "w"); if (f) fclose(f); }\n/*y.yaml'])
def test_a_hostile_file_name_runs_nothing(filename, tmp_path, monkeypatch):
    """The model's path goes into the generated code's comments and docstring."""
    parts = filename.split("/")
    folder = tmp_path.joinpath(*parts[:-1])
    path = _write_models(folder, "pendulum", parts[-1])
    relative = path.relative_to(tmp_path)
    for lang in ("c", "python"):
        result = _cli(["codegen", str(relative), "--lang", lang, "--output", "."], tmp_path, monkeypatch)
        assert result.exit_code == 0, result.output
    stem = file_stem(Path(relative).stem)
    assert (tmp_path / f"{stem}.c").is_file() and (tmp_path / f"{stem}.py").is_file()
    assert f'#include "{stem}.h"' in (tmp_path / f"{stem}.c").read_text()
    if shutil.which("gcc") is not None:
        subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", f"{stem}.c", "-o", "lib.so", "-lm"], cwd=tmp_path,
                       check=True, capture_output=True)
        ctypes.CDLL(str(tmp_path / "lib.so"))
    spec = importlib.util.spec_from_file_location("hostile_file_name", tmp_path / f"{stem}.py")
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    assert not (tmp_path / "canary").exists()


@pytest.mark.parametrize("key", sorted(HOSTILE_CASES))
def test_hostile_text_stays_in_the_trajectory_metadata(key, tmp_path):
    """The model's name and path go only to the JSON metadata, which reads back as the same
    text; the CSV is its header row and rows of numbers."""
    from kronsub.simulation.run import simulate
    from kronsub.simulation.table import metadata_json, trajectory_csv
    from kronsub.simulation.values import resolve

    text = _hostile_text(key, tmp_path / "canary")
    model = kronsub.load(_write_models(tmp_path / "m", text))
    system = model.derive()
    values = resolve(system, dict(model.initial), {})
    traj = simulate(system, values, 0.02, 0.01, "dop853", progress=False)
    csv, meta = trajectory_csv(system, text, traj, values, 1e-10, 1e-10)
    lines = csv.split("\n")
    assert lines[0].startswith("t,") and lines[-1] == "" and len(lines) == len(traj.t) + 2
    assert all(float(v) == float(v) for line in lines[1:-1] for v in line.split(","))  # numbers only
    back = json.loads(metadata_json(meta))
    assert back["model"] == {"name": system.name, "file": text, "sha256": None}


@pytest.mark.parametrize("name, tex", [
    ("nan", r"\mathit{nan}"), ("oo", r"\mathit{oo}"), ("zoo", r"\mathit{zoo}"), ("Abs", r"\mathit{Abs}"),
    ("sin", r"\mathit{sin}"), ("x_1_2", r"\mathit{x\_1\_2}"), ("a__b", r"\mathit{a\_\_b}"), ("x_", r"\mathit{x\_}"),
    ("xdot", r"\mathit{xdot}"), ("Alpha", r"\mathit{Alpha}"), ("x1_a", r"\mathit{x1\_a}"),
    # sympy's form where it is faithful: the names of the bundled models print as they did
    ("E", "E"), ("I", "I"), ("q12", "q_{12}"), ("theta", r"\theta"), ("theta1", r"\theta_{1}"),
    ("Gamma", r"\Gamma"), ("bob_phi", r"bob_{\phi}"), ("wheel", "wheel"), ("Jm", "Jm"), ("rod_x", "rod_{x}"),
    ("mu_A_x", r"\mu_{A x}"), ("mu_B1_y", r"\mu_{B1 y}"), ("x_1_y", "x_{1 y}"), ("mu_phi1_x", r"\mathit{mu\_phi1\_x}"),
])
def test_latex_name_prints_each_name_as_itself(name, tex):
    """`nan` printed as `nan` read as NaN (and its acceleration as `\\ddot{nan}`), `x_1_2` as
    `x_{1 2}` (which reads as `x_{12}`), `a__b` as the power `a^{b}`, `xdot` as `\\dot{x}` (the
    velocity of `x`): names sympy prints unfaithfully are italic words, escaped by latex_text."""
    from kronsub.emitters.escape import latex_name

    assert latex_name(name) == tex


HOSTILE_NAMES = r"""name: 'Hostile \ { $ % # _ ^ ~ } & names'
description: 'a description with \ { $ % # _ ^ ~ }'
parameters:
  oo: {value: 0.3, unit: 'N \ { $ % # _ ^ ~ }', description: '\input{x} $ % # _ ^ ~'}
  zoo: {value: 0.7}
  Abs: {value: 0.25}
  E: {value: 0.5}
  k_1_2: {value: 2}
  a__b: {value: 1}
components:
  arm: {type: pinned_rod, parameters: {mass: E, length: 1}, coordinates: [nan]}
  cart: {type: particle1d, parameters: {mass: Abs}, coordinates: [x_1_2]}
coordinates: [nan, x_1_2]
effects:
  spring_1: {type: potential, value: k_1_2*x_1_2**2/2 + a__b*nan**2}
  push: {type: generalized_force, coordinate: x_1_2, value: oo*cos(zoo*t)}
initial: {nan: 0.5}
"""


def test_hostile_names_print_as_latex_names(tmp_path):
    path = tmp_path / "hostile.yaml"
    path.write_text(HOSTILE_NAMES, encoding="utf-8")
    tex = CliRunner().invoke(main, ["derive", str(path), "--format", "latex"])
    lin = CliRunner().invoke(main, ["linearize", str(path), "--at", "nan=0", "--at", "x_1_2=0", "--format", "latex"])
    assert tex.exit_code == 0 and lin.exit_code == 0, tex.output + lin.output
    for doc in (tex.stdout, lin.stdout):
        assert r"\mathit{nan}" in doc and r"\mathit{x\_1\_2}" in doc
        for bad in (r"\ddot{nan}", r"\dot{nan}", "x_{1 2}", "k_{1 2}", "a^{b}", "(nan", " oo ", "t zoo"):
            assert bad not in doc, bad
    doc = tex.stdout
    assert r"\ddot{\mathit{nan}}" in doc and r"\dot{\mathit{nan}}" in doc and r"\mathit{oo}" in doc
    assert r"\mathit{Abs}" in doc and r"\mathit{k\_1\_2}" in doc and r"\mathit{a\_\_b}" in doc
    assert r"\title{Hostile \textbackslash{} \{ \$ \% \# \_ \textasciicircum{} \textasciitilde{} \} \& names}" in doc
    assert r"\texttt{spring\_1}" in doc
    assert "input{x}" not in doc  # the units and descriptions do not reach the LaTeX
    if shutil.which("pdflatex"):
        for stem, text in (("derive", doc), ("linearize", lin.stdout)):
            (tmp_path / f"{stem}.tex").write_text(text, encoding="utf-8")
            run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", f"{stem}.tex"],
                                 cwd=tmp_path, capture_output=True, text=True, timeout=120)
            assert run.returncode == 0, run.stdout[-2000:]


def test_a_double_literal_is_one_c_reads_past_the_double_range():
    from kronsub.emitters.escape import c_double

    assert [str(c_double(v)) for v in (0.5, -2, 1e308 * 10, -1e308 * 10, float("nan"))] == \
        ["0.5", "-2.0", "HUGE_VAL", "(-HUGE_VAL)", "NAN"]
    assert float(str(c_double(1 / 3))) == 1 / 3
    for bad in (True, "1.0", None):
        with pytest.raises(UnescapedText):
            c_double(bad)
