"""LaTeX that fits the page: long sums broken over lines, wide matrices entry by entry.

`LatexPrinter` marks the places between the terms of a top-level sum; `lines` packs
the terms into lines no wider than `WIDTH` by `width`, a conservative estimate of
the printed width in ems of a formula (fractions as wide as their wider part,
scripts smaller, ``\\sin`` three letters wide...). The page is A4 landscape with
2 cm margins (``templates/derive.tex.j2``): about 73 ems of 10 pt text.
"""
from __future__ import annotations

import re

import sympy
from sympy.printing.latex import LatexPrinter as _SympyLatex

from ..core.printed import Remembering
from .escape import latex_name

BREAK = "\x00"
"""Between the terms of a top-level sum; removed or turned into a line break by `lines`."""
WIDTH = 50.0
"""Widest line, in estimated ems (the text width is about 73 ems; the rest is the margin
of the estimate, which a line of System III showed to be 25 % low, and the
``\\bar{M}_{12} &= \\quad`` before the line)."""


class LatexPrinter(Remembering, _SympyLatex):
    """sympy's LaTeX, with `BREAK` between the terms of the top-level sum (remembering what
    it printed: one printer per report); with the setting ``escaped_names``, a name not given
    in ``symbol_names`` is printed by :func:`~.escape.latex_name` (without it, as sympy does)."""

    _default_settings = {**_SympyLatex._default_settings, "escaped_names": False}

    def _print_Symbol(self, expr, style="plain"):
        given = self._settings["symbol_names"].get(expr)
        if given is not None or not self._settings["escaped_names"]:
            return super()._print_Symbol(expr, style)
        return latex_name(expr.name)

    def doprint(self, expr):
        if getattr(expr, "is_Add", False):
            terms = self._as_ordered_terms(expr, order=self._settings["order"])
            out = self._term(terms[0])
            for term in terms[1:]:
                text = self._term(term)
                if text.startswith("-"):
                    out += BREAK + " - " + text[1:].lstrip()
                else:
                    out += BREAK + " + " + text
            return out
        return self._term(expr)

    def _term(self, expr) -> str:
        """A product too wide for a line with its widest sum opened up:
        ``\\frac{a}{b} \\Bigl(t_1 + t_2 ...\\Bigr)``, breakable between the ``t``."""
        text = self._print(expr)
        if not getattr(expr, "is_Mul", False) or measure(text) <= WIDTH:
            return text
        numer, denom = expr.as_numer_denom()
        sums = [f for f in sympy.Mul.make_args(numer) if f.is_Add]
        if not sums:
            return text
        widest = max(sums, key=lambda f: len(self._print(f)))
        rest = (numer / widest) / denom
        inner = self.doprint(widest)
        if rest == 1:
            return rf"\Bigl({inner}\Bigr)"
        if rest == -1:
            return rf"- \Bigl({inner}\Bigr)"
        return rf"{self._print(rest)} \Bigl({inner}\Bigr)"


def unbroken(text: str) -> str:
    """The formula on one line."""
    return text.replace(BREAK, "")


def lines(text: str, width: float = WIDTH) -> list[str]:
    """The terms of ``text`` packed greedily into lines of at most ``width`` ems (a single
    term wider than that is a line of its own)."""
    pieces = str(text).split(BREAK)
    out = [pieces[0]]
    for piece in pieces[1:]:
        if measure(out[-1] + piece) <= width:
            out[-1] += piece
        else:
            out.append(piece)
    return out


_FUNCTION_WORDS = re.compile(r"\\(operatorname|mathrm|text|mathsf|texttt|mathit)\{([^{}]*)\}")
_NAMED = {"sin", "cos", "tan", "log", "exp", "asin", "acos", "atan", "sinh", "cosh", "tanh",
          "arcsin", "arccos", "arctan", "sign", "min", "max", "det"}
_INVISIBLE = {"left", "right", "displaystyle", "limits", "nonumber", "big", "Big", "bigg", "Bigg"}
_SPACES = {"quad": 1.0, "qquad": 2.0, ",": 0.17, ";": 0.28, ":": 0.22, "!": 0.0, " ": 0.33}


def measure(text: str) -> float:
    """A conservative estimate of the printed width of a formula, in ems."""
    width, _ = _group(str(text).replace(BREAK, ""), 0, None)
    return width


def _group(s: str, i: int, end: str | None) -> tuple[float, int]:
    """Width of ``s[i:]`` up to the closing ``end`` brace (or the end); returns (width, next index)."""
    total = 0.0
    n = len(s)
    while i < n:
        ch = s[i]
        if end is not None and ch == end:
            return total, i + 1
        if ch == "{":
            w, i = _group(s, i + 1, "}")
            total += w
        elif ch == "\\":
            w, i = _command(s, i)
            total += w
        elif ch in "^_":
            w, i = _argument(s, i + 1)
            total += 0.75 * w
        elif ch in "+-=<>":
            total += 1.6  # the sign and the spaces around it
            i += 1
        elif ch in " &\n":
            i += 1
        elif ch in "()[]|,;.":
            total += 0.5
            i += 1
        else:
            total += 0.65 if ch.isalnum() else 0.8
            i += 1
    return total, i


def _argument(s: str, i: int) -> tuple[float, int]:
    """Width of one argument: ``{...}``, a command, or a single character."""
    if i >= len(s):
        return 0.0, i
    if s[i] == "{":
        return _group(s, i + 1, "}")
    if s[i] == "\\":
        return _command(s, i)
    return 0.65, i + 1


def _command(s: str, i: int) -> tuple[float, int]:
    m = _FUNCTION_WORDS.match(s, i)
    if m:
        return 0.55 * len(m.group(2)) + 0.3, m.end()
    j = i + 1
    while j < len(s) and s[j].isalpha():
        j += 1
    name = s[i + 1:j]
    if not name:  # \, \; \\ \{ ...
        sym = s[i + 1:i + 2]
        return _SPACES.get(sym, 0.5 if sym in "{}|" else 0.0), i + 2
    if name == "frac":
        a, j = _argument(s, j)
        b, j = _argument(s, j)
        return max(a, b) + 0.4, j
    if name == "sqrt":
        if j < len(s) and s[j] == "[":
            close = s.index("]", j)
            j = close + 1
        a, j = _argument(s, j)
        return a + 1.0, j
    if name in ("dot", "ddot", "bar", "hat", "tilde", "mathbf", "boldsymbol", "overline", "vec"):
        return _argument(s, j)
    if name in _INVISIBLE:
        return 0.0, j
    if name in _SPACES:
        return _SPACES[name], j
    if name in _NAMED:
        return 0.55 * len(name) + 0.3, j
    return 0.7, j  # a Greek letter, \cdot, \partial...


__all__ = ["BREAK", "LatexPrinter", "WIDTH", "lines", "measure", "unbroken"]
