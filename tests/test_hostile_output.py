"""No text a model controls reaches an output or the terminal raw (issue 31, section 3).

One model whose name, description, units, parameter, component, effect and scene descriptions
hold terminal escape sequences (a window title, clear screen, the one-byte CSI U+009B), a
direction override, line breaks and Markdown, LaTeX and HTML markup, in files and folders whose
names hold control characters too, runs through every command and output format. Then:

- no control, direction or line-separator character (``\\n`` apart) is on standard output or
  standard error (the terminal) or in any text file written;
- the Markdown has the text inline and inert: no heading, code span, math or HTML from it;
- the LaTeX has none of its control sequences or math;
- the JSON shows U+009B, U+202E and ``<`` as ``\\uXXXX`` and reads back to the model's text;
- the plots and animation give no missing-glyph warning (their labels show escapes).
"""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from kronsub.cli import main

HOSTILE = ("X\x1b]0;title\x07\x1b[2J\x9b31m\u202eAB\u2066\u2028 two\nline# two\r`tick` $x$ \\cmd % } "
           "<script>alert(1)</script>")
RAW = re.compile("[\x00-\x09\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
"""What must not reach a terminal or a text output: every control but the line feed, the
direction marks, overrides and isolates, the line and paragraph separators."""
FOLDER = "dir\x1b[2J\u202e"


def _yaml(text: str) -> str:
    """A YAML double-quoted scalar of ``text`` (every character survives)."""
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '\\"':
            out.append("\\" + ch)
        elif 0x20 <= code < 0x7F:
            out.append(ch)
        else:
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
    return '"' + "".join(out) + '"'


def _model(text: str) -> str:
    q = _yaml(text)
    return f"""\
name: {q}
description: {q}
parameters:
  m: {{value: 1.5, unit: {q}, description: {q}}}
  L: {{value: 0.7, unit: {q}}}
  g: {{value: 9.81, description: {q}}}
components:
  bob: {{type: particle2d, parameters: {{mass: m}}, coordinates: [x, y], description: {q}}}
coordinates: [q]
connection: {{x: L*sin(q), y: -L*cos(q)}}
effects:
  gravity: {{type: gravity, g: g, description: {q}}}
initial: {{q: 0.3}}
scenes:
  swing: {{effects: [gravity], description: {q}}}
"""


def _parent(text: str, sub: str) -> str:
    q = _yaml(text)
    return f"""\
name: {q}
description: {q}
parameters:
  k: {{value: 2, unit: {q}, description: {q}}}
components:
  arm: {{model: {_yaml(sub)}}}
  spring: {{type: particle1d, parameters: {{mass: 0.1}}, coordinates: [s]}}
coordinates: [q]
connection: {{s: q}}
effects:
  hold: {{type: spring, between: [spring.centre, [0]], stiffness: k}}
"""


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    """The hostile models (a single one with a scene; a parent using it by a hostile file name)."""
    folder = tmp_path_factory.mktemp("hostile") / FOLDER
    folder.mkdir()
    sub = "sub\x9b\u202e.yaml"
    (folder / sub).write_text(_model(HOSTILE), encoding="utf-8")
    (folder / "parent.yaml").write_text(_parent(HOSTILE, sub), encoding="utf-8")
    return folder, folder / sub, folder / "parent.yaml"


def _commands(single: Path, parent: Path, out: Path) -> dict[str, list[str]]:
    s, p, o = str(single), str(parent), str(out)
    commands = {
        "check": ["check", s], "check-parent": ["check", p],
        "derive-bad-set": ["simulate", s, "--set", "\x1b[2J=1"],
        "codegen-c": ["codegen", p, "--lang", "c", "--output", o],
        "codegen-python": ["codegen", p, "--lang", "python", "--output", o],
        "simulate": ["simulate", s, "--t", "0.05", "-o", f"{o}/sim.csv", "--plot", f"{o}/sim.png", "--points"],
        "simulate-stdout": ["simulate", p, "--t", "0.05", "--points"],
        "accuracy": ["accuracy", s, "--t", "0.05", "--quick", "--methods", "dop853,rk4", "--tolerances", "1e-4,1e-6",
                     "-o", f"{o}/acc.csv", "--plot", f"{o}/acc.png"],
        "animate": ["animate", s, "--t", "0.1", "-o", f"{o}/anim.gif", "--size", "64", "--fps", "5"],
        "cache-info": ["cache", "info"],
        "components": ["components"],
    }
    for fmt in ("markdown", "latex", "json"):
        commands[f"derive-{fmt}"] = ["derive", p, "--format", fmt]
        commands[f"derive-{fmt}-file"] = ["derive", s, "--format", fmt, "--reactions", "-o", f"{o}/derived.{fmt}"]
        commands[f"derive-scene-{fmt}"] = ["derive", s, "--scene", "swing", "--format", fmt]
        commands[f"linearize-{fmt}"] = ["linearize", s, "--format", fmt]
        commands[f"linearize-{fmt}-file"] = ["linearize", s, "--format", fmt, "-o", f"{o}/lin.{fmt}"]
    return commands


def _markdown_inert(text: str) -> None:
    for raw in ("<script>", "`tick`", "$x$", "line# two"):
        assert raw not in text, raw


def _latex_inert(text: str) -> None:
    for raw in ("<script>", "$x$", "\\cmd", "% }"):  # a backtick is a quote mark in LaTeX text
        assert raw not in text, raw


def _json_inert(text: str) -> None:
    assert "<script>" not in text and "\\u009b" in text and "\\u202e" in text and "\\u2028" in text
    assert any(HOSTILE in value for value in _strings(json.loads(text)))  # reads back as the model's text


def _strings(data):
    if isinstance(data, str):
        yield data
    elif isinstance(data, dict):
        for value in data.values():
            yield from _strings(value)
    elif isinstance(data, list):
        for value in data:
            yield from _strings(value)


def test_hostile_text_reaches_no_output_raw(hostile, tmp_path, monkeypatch):
    folder, single, parent = hostile
    out = folder / "out"
    out.mkdir(exist_ok=True)
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / f"cache{FOLDER}"))
    if shutil.which("gcc") is None:
        monkeypatch.setenv("CC", "kronsub-no-such-compiler")
    documents = {}
    for key, args in _commands(single, parent, out).items():
        result = CliRunner().invoke(main, args)
        expected = 1 if key == "derive-bad-set" else 0
        assert result.exit_code == expected, (key, result.output)
        for stream, text in (("stdout", result.stdout), ("stderr", result.stderr)):
            assert not RAW.search(text), (key, stream, RAW.search(text), text[:2000])
        assert "Glyph" not in result.stderr, (key, result.stderr)  # labels print escapes, not controls
        documents[key] = result.stdout
    for path in out.iterdir():
        if path.suffix not in (".png", ".gif"):
            text = path.read_text(encoding="utf-8")
            assert not RAW.search(text), (path.name, RAW.search(text))
            documents[path.name] = text

    for key, text in documents.items():
        if key.endswith("markdown") or key in ("derived.markdown", "lin.markdown", "accuracy"):
            _markdown_inert(text)
        elif key.endswith("latex"):
            _latex_inert(text)
        elif key.endswith("json") and text:
            _json_inert(text)
    for name in ("derived.json", "lin.json", "sim.json", "acc.json", "derive-json", "linearize-json"):
        assert name in documents, name
        back = json.loads(documents[name])
        names = [back.get("name"), (back.get("model") or {}).get("name")]
        assert any(n is not None and n.startswith(HOSTILE) for n in names), (name, names)
    assert "\\x1b]0;title\\x07" in documents["accuracy"] or "\\]0;title" in documents["accuracy"]


def test_json_document_escapes_what_acts_on_a_reader():
    from kronsub.emitters.escape import json_document

    data = {"a\u202e": ["\x9b[2J\x1b]0;t\x07", "<b>&amp;</b>", "é漢\U0001F600", "\u2028\u2029\U000E0001"]}
    text = json_document(data, indent=2)
    assert json.loads(text) == data
    assert not RAW.search(text) and "<" not in text and "&" not in text
    assert "\\u009b" in text and "\\u202e" in text and "\\udb40\\udc01" in text and "é漢\U0001F600" in text


def test_json_document_weighs_every_character_as_its_definition_says():
    """Every character of the BMP's first planes (and a few beyond) kept when visible and not
    markup, else ``\\uXXXX`` (surrogate pairs above U+FFFF), whatever stands around it."""
    import unicodedata

    from kronsub.emitters.escape import json_document

    def escaped(ch):
        if ch in " \n" or (ch.isprintable() and unicodedata.category(ch) not in ("Zl", "Zp", "Cf") and ch not in "<>&"):
            return ch
        return json.dumps(ch)[1:-1] if ord(ch) >= 0x10000 or ch in "\"\\" else f"\\u{ord(ch):04x}"

    chars = [chr(c) for c in range(0x3400)] + ["\U0001F600", "\U000E0001", "\uFEFF", "\uFFFB"]
    for ch in chars:
        if ch in "\"\\":
            continue  # JSON's own escapes
        text = json_document({"k": f"a{ch}b"})
        inner = json.dumps(f"a{ch}b", ensure_ascii=False)[1:-1]
        expected = "".join(escaped(c) if c == ch else c for c in inner) if inner == f"a{ch}b" else None
        if expected is not None:
            assert text == '{"k": "' + expected + '"}', repr(ch)
        assert json.loads(text) == {"k": f"a{ch}b"}


def test_terminal_and_plot_text_show_escapes():
    from kronsub.emitters.escape import plot_text, terminal_text

    assert terminal_text("a\x1b[2J\nb\u202ec\x9b") == "a\\x1b[2J\nb\\u202ec\\x9b"
    assert plot_text("$x$ \\$\n") == "\\$x\\$ \\\\$\\n"
    assert not RAW.search(plot_text(HOSTILE)) and "\n" not in plot_text(HOSTILE)


def test_a_nul_in_the_name_is_text_like_any_other(tmp_path, monkeypatch):
    """A NUL in `name:` reaches the numpy fallback's code name and the animation's title as an
    escape (it was an internal error there), and the terminal and the documents not at all."""
    path = tmp_path / "nul.yaml"
    path.write_text(_model("a\0b"), encoding="utf-8")
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "kronsub-no-such-compiler")
    for args in (["simulate", str(path), "--t", "0.05"], ["animate", str(path), "--t", "0.1", "-o",
                                                         str(tmp_path / "a.gif"), "--size", "64", "--fps", "5"],
                 ["derive", str(path)], ["linearize", str(path), "--format", "json"]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 0, (args[0], result.output)
        assert "\0" not in result.stdout and "\0" not in result.stderr


def test_a_nul_in_a_model_path_is_a_located_error(tmp_path):
    path = tmp_path / "parent.yaml"
    path.write_text(_parent("p", "sub\0.yaml"), encoding="utf-8")
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1, result.output
    assert f"Error: {path}:6:" in result.stderr and "NUL character" in result.stderr, result.stderr
    assert "internal error" not in result.stderr


def test_no_escape_function_lets_a_control_or_direction_character_through():
    """Random texts over the characters that act on a terminal, a renderer or a parser: no
    function's output has a raw one (the terminal keeps its line feeds), and JSON reads back."""
    import random

    from kronsub.emitters.escape import json_document, latex_text, markdown_text, plot_text, terminal_text

    alphabet = ([chr(c) for c in range(0x20)] + [chr(c) for c in range(0x7F, 0xA0)]
                + list("\u061c\u200e\u200f\u2028\u2029\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
                + list("ab$%}{\\`<>&#|*_[]~^\"'") + ["\U000E0001", "\ufeff", "é", "漢"])
    rng = random.Random(31)
    for _ in range(300):
        text = "".join(rng.choice(alphabet) for _ in range(rng.randint(1, 30)))
        for escape in (markdown_text, latex_text, plot_text):
            assert not RAW.search(escape(text)) and "\n" not in escape(text), (escape.__name__, text)
        assert not RAW.search(terminal_text(text)) and terminal_text(text).count("\n") == text.count("\n")
        document = json_document({"t": text})
        assert not RAW.search(document) and "<" not in document and json.loads(document) == {"t": text}
