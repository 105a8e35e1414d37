"""Free text of a model made inert in generated code: one escaping function per target.

A model's name, description, parameter units and descriptions, labels and file path are
data. They reach generated C, Python, LaTeX and Markdown only through these functions:

- :func:`c_comment`: text inside a ``/* ... */`` comment;
- :func:`c_string`: the body of a C string literal ``"..."``;
- :func:`python_string`: the body of a Python ``"..."`` literal or ``\"\"\"...\"\"\"`` docstring;
- :func:`latex_text`: LaTeX text mode (``\\title{}``, paragraphs, ``\\texttt{}``);
- :func:`latex_name`: a name (coordinate, parameter...) in LaTeX math mode;
- :func:`markdown_text`: Markdown inline text (headings, paragraphs, table cells);
- :func:`json_document`: a JSON document of data holding such text;
- :func:`plot_text`: a matplotlib title, label or legend entry;
- :func:`terminal_text`: a message for the terminal (standard error, a status line).

Templates call them as filters (``c_comment``, ``c_string``, ``py_str``, ``latex``, ``md``);
``c_double`` writes a number as a C ``double`` literal (past the double range too).
:func:`environment` makes forgetting one an error rather than a hole: with it, every
``{{ ... }}`` must print a number or :class:`~markupsafe.Markup` (the mark of text already
made safe for its target: the filters' output, or code the emitters generated themselves);
any other string stops the rendering with :class:`UnescapedText`. The filters that would mark
text safe without escaping it for the target (``safe``, ``tojson``, ``replace``, ``format``,
``map``...) are not available; ``join`` joins only safe parts.
"""
from __future__ import annotations

import json
import re
import unicodedata
from typing import Callable

import jinja2
from markupsafe import Markup

from ..errors import printable

__all__ = ["C_IDENTIFIER", "c_comment", "c_string", "python_string", "latex_text", "latex_name", "markdown_text", "json_document",
           "plot_text", "terminal_text", "environment", "UnescapedText", "Markup"]

_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t", "\0": "\\0"}


def _visible(ch: str) -> bool:
    """Printable and not a line or paragraph separator (U+2028, U+2029) or a format character."""
    return ch.isprintable() and unicodedata.category(ch) not in ("Zl", "Zp", "Cf")


def _codepoint(ch: str) -> str:
    code = ord(ch)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def c_comment(text: str) -> str:
    """Text for a C block comment: printable ASCII only, on one line, that cannot end the comment.

    Control and non-ASCII characters are shown as escapes (``\\n``, ``\\u2028``); ``*/`` and
    ``/*`` get a space between their characters (so the comment neither ends nor nests:
    ``-Wcomment``), and so does ``??`` (no trigraph such as ``??/``, a backslash, can form).
    """
    out = []
    for ch in str(text):
        if " " <= ch <= "~":
            out.append(ch)
        else:
            out.append(_NAMED.get(ch) or _codepoint(ch))
    s = "".join(out)
    s = re.sub(r"\*(?=/)", "* ", s)
    s = re.sub(r"/(?=\*)", "/ ", s)
    return re.sub(r"\?(?=\?)", "? ", s)


def c_string(text: str) -> str:
    """The body of a C string literal whose bytes are the UTF-8 of ``text``.

    ``\\`` and ``"`` are escaped, ``?`` is ``\\?`` (no trigraphs), and every byte outside
    printable ASCII is a three-digit octal escape (which, unlike ``\\x``, cannot swallow the
    digits that follow). A NUL in ``text`` becomes ``\\000``: C functions reading the string
    stop there, ``sizeof`` still counts every byte.
    """
    out = []
    for byte in str(text).encode("utf-8", "surrogatepass"):
        ch = chr(byte)
        if ch in '\\"?':
            out.append("\\" + ch)
        elif 0x20 <= byte <= 0x7E:
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return "".join(out)


def python_string(text: str) -> str:
    """The body of a Python ``"..."`` literal or ``\"\"\"...\"\"\"`` docstring whose value is ``text``.

    ``\\``, ``"`` and ``'`` are backslash-escaped (no quote can close the literal, nor touch its
    closing quotes); characters that are not printable, or that some tools take for a line end
    (U+2028, U+2029), are ``\\n``, ``\\x00``, ``\\u2028``... Printable non-ASCII is kept.
    """
    out = []
    for ch in str(text):
        if ch in "\\\"'":
            out.append("\\" + ch)
        elif _visible(ch):
            out.append(ch)
        else:
            out.append({"\0": "\\x00"}.get(ch) or _NAMED.get(ch) or _codepoint(ch))
    return "".join(out)


_LATEX = {
    "\\": r"\textbackslash{}", "{": r"\{", "}": r"\}", "$": r"\$", "&": r"\&", "#": r"\#", "%": r"\%",
    "_": r"\_", "^": r"\textasciicircum{}", "~": r"\textasciitilde{}", "<": r"\textless{}",
    ">": r"\textgreater{}", "|": r"\textbar{}",
}
_GREEK_COMMANDS = {"alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa",
                   "lambda", "mu", "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi",
                   "omega", "Gamma", "Delta", "Theta", "Lambda", "Xi", "Pi", "Sigma", "Upsilon", "Phi", "Psi",
                   "Omega"}


def _greek() -> dict[str, str]:
    """Greek letters as math commands (``θ`` -> ``\\ensuremath{\\theta}``); a capital with no
    command of its own as its Latin twin (``Α`` -> ``A``)."""
    out = {}
    for code in range(0x391, 0x3CA):
        name = unicodedata.name(chr(code), "")
        if not name.startswith("GREEK ") or " LETTER " not in name:
            continue
        word = name.split(" LETTER ")[1].lower().replace("lamda", "lambda")
        if word == "final sigma":
            out[chr(code)] = r"\ensuremath{\varsigma}"
            continue
        command = word.capitalize() if "CAPITAL" in name else word
        if command in _GREEK_COMMANDS:
            out[chr(code)] = rf"\ensuremath{{\{command}}}"
        elif word == "omicron":
            out[chr(code)] = "O" if "CAPITAL" in name else "o"
        elif "CAPITAL" in name:
            out[chr(code)] = unicodedata.lookup(f"LATIN CAPITAL LETTER {_LATIN_TWIN.get(word, 'X')}") \
                if word in _LATIN_TWIN else "?"
    return out


_LATIN_TWIN = {"alpha": "A", "beta": "B", "epsilon": "E", "zeta": "Z", "eta": "H", "iota": "I", "kappa": "K",
               "mu": "M", "nu": "N", "rho": "P", "tau": "T", "chi": "X"}
_BEYOND_LATIN1 = {**_greek(), "\u2264": r"\ensuremath{\leq}", "\u2265": r"\ensuremath{\geq}",
                  "\u2260": r"\ensuremath{\neq}", "\u2248": r"\ensuremath{\approx}",
                  "\u221e": r"\ensuremath{\infty}", "\u2192": r"\ensuremath{\to}", "\u2212": "-",
                  "\u2013": "--", "\u2014": "---", "\u2018": "`", "\u2019": "'", "\u201c": "``",
                  "\u201d": "''", "\u201e": ",,", "\u201a": ",", "\u2026": "...", "\u2032": "'"}
"""Characters past Latin-1 that pdflatex's default setup cannot print, as what it can; any
other one prints as ``[U+XXXX]``."""
LATEX_ESCAPES = frozenset(_LATEX.values()) | frozenset(v for v in _BEYOND_LATIN1.values() if v.startswith("\\"))
"""Everything :func:`latex_text` writes that starts with a backslash."""


def latex_text(text: str) -> str:
    """LaTeX text mode: the ten special characters (and ``< > |``) as their escapes.

    Line breaks and every other invisible character become a space, so the text stays one
    paragraph and cannot end a command or start a new one; no control sequence of the text
    survives (``\\input{x}`` prints as ``\\textbackslash{}input\\{x\\}``).
    """
    out = []
    for ch in str(text):
        if ch in _LATEX:
            out.append(_LATEX[ch])
        elif not _visible(ch):
            out.append(" ")
        elif ord(ch) <= 0xFF:
            out.append(ch)
        else:  # past Latin-1: what pdflatex can print (a Greek letter once stopped the build)
            out.append(_BEYOND_LATIN1.get(ch, f"[U+{ord(ch):04X}]"))
    return "".join(out)


_READ_AS_OTHER = frozenset({
    "nan", "oo", "zoo", "inf", "infty", "Abs", "abs", "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos",
    "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log", "ln", "sqrt", "sign", "min", "max", "Min", "Max",
    "re", "im", "arg", "det"})
"""Words a reader takes for a number or a function (sympy's NaN and infinities, the functions of a
model's expressions and of mathematics): as a name, each is an italic word of its own."""
_WORD = re.compile(r"[A-Za-z]+")
_WORD_DIGITS = re.compile(r"(?P<word>[A-Za-z]+)(?P<digits>[0-9]*)")


def _plain_word(word: str) -> bool:
    """Whether sympy prints ``word`` as itself or as one Greek letter (or other symbol) command:
    not as a modifier (``xdot`` -> ``\\dot{x}``, the velocity's look; ``xabs`` -> ``|x|``), not as
    a Latin twin (``Alpha`` -> ``A``), and not a word read as something else (``nan``)."""
    from sympy.printing.latex import translate

    if not _WORD.fullmatch(word) or word in _READ_AS_OTHER:
        return False
    tex = translate(word)
    return tex == word or tex == "\\" + word


def _plain_subscript(part: str) -> bool:
    """A part of a subscript sympy prints as it is: digits, a plain word, or letters and digits
    (``B1``) whose letters are not a Greek letter's name (``phi1`` would print as its letters)."""
    from sympy.printing.latex import translate

    split = _WORD_DIGITS.fullmatch(part)
    if part.isascii() and part.isdigit():
        return True
    if split is None:
        return False
    word = split["word"]
    return _plain_word(word) if not split["digits"] else translate(word) == word and word not in _READ_AS_OTHER


def _faithful(name: str) -> bool:
    """Whether sympy's LaTeX of the name shows it as it is: a plain word (:func:`_plain_word`)
    with digits (``m1`` -> ``m_{1}``) or with subscripts (``bob_phi`` -> ``bob_{\\phi}``,
    ``mu_B_x`` -> ``\\mu_{B x}``), no two of them numbers side by side (``x_1_2`` -> ``x_{1 2}``,
    which reads as ``x_{12}``), none empty (``a__b`` -> the power ``a^{b}``, ``x_`` -> ``x_{}``)."""
    base, *subs = name.split("_")
    split = _WORD_DIGITS.fullmatch(base)
    if split is None or not _plain_word(split["word"]) or (split["digits"] and subs):
        return False
    numbers = [p.isdigit() for p in subs]
    return all(_plain_subscript(p) for p in subs) and not any(a and b for a, b in zip(numbers, numbers[1:]))


def latex_name(name: str) -> str:
    """A validated name (coordinate, parameter, intermediate) in LaTeX math mode, one way for
    every name: sympy's form where it shows the name faithfully (:func:`_faithful`: ``m1`` ->
    ``m_{1}``, ``theta`` -> ``\\theta``, ``bob_phi`` -> ``bob_{\\phi}``), else the italic word
    of its letters, escaped by :func:`latex_text`: ``nan`` -> ``\\mathit{nan}`` (not NaN),
    ``x_1_2`` -> ``\\mathit{x\\_1\\_2}``, ``a__b``, ``xdot`` (sympy: ``\\dot{x}``, the velocity of
    ``x``), ``θ``."""
    import sympy

    if _faithful(name):
        return sympy.latex(sympy.Symbol(name))
    return r"\mathit{" + latex_text(name) + "}"


_MARKDOWN_SPECIAL = set("\\`*_[]<>#|~&$")


def markdown_text(text: str) -> str:
    """Markdown inline text: every character that can start emphasis, a link, a code span,
    HTML, an entity, a table cell or math is backslash-escaped (CommonMark shows ``\\*`` as
    ``*``); line breaks and every other invisible character become a space, and a leading
    ``-``, ``+``, ``=``, ``>`` or ``1.`` is escaped, so the text cannot start a block either.
    """
    out = []
    for ch in str(text):
        if ch in _MARKDOWN_SPECIAL:
            out.append("\\" + ch)
        elif _visible(ch):
            out.append(ch)
        else:
            out.append(" ")
    s = "".join(out).strip()
    s = re.sub(r"^(\d+)([.)])", r"\1\\\2", s)
    return "\\" + s if s[:1] in ("-", "+", "=", ">") else s


_JSON_INERT = re.compile("[<>&]")


def _json_escape(ch: str) -> str:
    code = ord(ch)
    if code < 0x10000:
        return f"\\u{code:04x}"
    high, low = 0xD800 + ((code - 0x10000) >> 10), 0xDC00 + ((code - 0x10000) & 0x3FF)
    return f"\\u{high:04x}\\u{low:04x}"


def json_document(data, **options) -> str:
    """``json.dumps(data, ensure_ascii=False, **options)`` in which no character can act on a
    reader: C0 and C1 controls (U+009B is a terminal's CSI), direction overrides and isolates
    (U+202E, U+2066), line separators and every other invisible character are ``\\uXXXX``, and
    so are ``<``, ``>`` and ``&`` (no markup when the JSON lands in a web page). Readable
    non-ASCII stays as it is; the document reads back to the same data."""
    text = json.dumps(data, ensure_ascii=False, **options)
    # outside strings a JSON document has only ASCII structure, digits, spaces and line breaks
    return _JSON_WEIGHED.sub(_json_character, text)


_JSON_WEIGHED = re.compile("[^\n -%'-;=?-~]")
"""The characters `json_document` weighs one by one: all but printable ASCII other than
``<``, ``>``, ``&`` (kept as they are) and the line break."""


def _json_character(match: re.Match) -> str:
    ch = match[0]
    return ch if _visible(ch) and not _JSON_INERT.match(ch) else _json_escape(ch)


def terminal_text(text: str) -> str:
    """A message for the terminal: its lines kept, every other control, format or direction
    character in each line shown as an escape (``\\x1b``, ``\\x9b``, ``\\u202e``), so no escape
    sequence reaches the terminal and no text is reordered (:func:`kronsub.errors.printable`)."""
    return "\n".join(printable(line) for line in str(text).split("\n"))


def plot_text(text: str) -> str:
    """A matplotlib title, label or legend entry that shows ``text``: invisible characters as
    escapes (``\\n``, ``\\x1b``: one line, no missing-glyph warnings) and ``$`` as ``\\$``, so no
    mathtext is parsed and the text is shown as it is."""
    return printable(str(text)).replace("$", r"\$")


class UnescapedText(jinja2.TemplateError):
    """A template printed a string that went through no escaping filter."""


def _finalize(value):
    """What ``{{ ... }}`` may print: safe text or a number; anything else is a template bug."""
    if isinstance(value, Markup):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return Markup(repr(value))
    raise UnescapedText(f"template prints {value!r} without an escaping filter "
                        "(c_comment, c_string, py_str, latex, md)")


def _join(items, separator: str = "") -> Markup:
    """``join`` of safe parts with a template-literal separator."""
    parts = [_finalize(item) for item in items]
    return Markup(str(separator).join(str(p) for p in parts))


def _filter(escape: Callable[[str], str]) -> Callable[[object], Markup]:
    def apply(value) -> Markup:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = repr(value)
        if not isinstance(value, str):
            raise UnescapedText(f"escaping filter {escape.__name__} expects text, got {value!r}")
        return Markup(escape(value))

    apply.__name__ = escape.__name__
    return apply


def c_double(value) -> Markup:
    """A number as a C ``double`` literal: its ``repr`` where finite, ``HUGE_VAL`` (signed) past
    the double range and ``NAN`` for NaN (both from ``<math.h>``), never the bare ``inf`` or
    ``nan`` that ``repr`` writes and no C compiler reads."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UnescapedText(f"c_double expects a number, got {value!r}")
    value = float(value)
    if value != value:
        return Markup("NAN")
    if value in (float("inf"), float("-inf")):
        return Markup("HUGE_VAL" if value > 0 else "(-HUGE_VAL)")
    return Markup(repr(value))


C_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""A C identifier (and a prefix of generated names): the one pattern every check uses."""


def c_identifier(text: str) -> str:
    """A model name as part of a C identifier (an index macro); names are validated identifiers
    already, so anything else is a bug and is refused rather than mangled."""
    if not C_IDENTIFIER.fullmatch(str(text)):
        raise UnescapedText(f"{text!r} is not a C identifier")
    return str(text)


FILTERS = {
    "c_comment": _filter(c_comment),
    "c_string": _filter(c_string),
    "py_str": _filter(python_string),
    "latex": _filter(latex_text),
    "md": _filter(markdown_text),
    "c_ident": _filter(c_identifier),
    "c_double": c_double,
}
_KEPT_FILTERS = ("length", "upper", "indent")  # indent keeps safe text safe


def environment(loader: jinja2.BaseLoader) -> jinja2.Environment:
    """A Jinja environment in which text reaches the output only through an escaping filter."""
    env = jinja2.Environment(loader=loader, autoescape=True, finalize=_finalize, keep_trailing_newline=True,
                             trim_blocks=True, lstrip_blocks=True, undefined=jinja2.StrictUndefined)
    env.filters = {name: env.filters[name] for name in _KEPT_FILTERS}
    env.filters.update(FILTERS)
    env.filters["join"] = _join
    return env
