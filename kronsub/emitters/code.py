"""Code emitters: C (header + source) and a numpy module (the ``--lang`` registry).

Both compute the same functions from :mod:`.numeric`: ``Mbar``, ``hbar``,
``fbar``, the first-order right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]``
(in-place ``L D L^T``: ``Mbar`` is symmetric positive definite), its canonical
form, the energies and the named points. No timestamps: output is byte-identical.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from sympy import S
from sympy.printing.c import C99CodePrinter
from sympy.printing.numpy import NumPyPrinter

from .. import __version__
from ..core.known_system import KnownSystem
from .escape import Markup
from .numeric import Block, NumericModel, identifier, prepare
from .text import _environment


def _number(self, expr) -> str:
    """A constant such as pi or E as its value to 17 significant digits: ``-std=c99``
    defines no ``M_PI``, and numpy's names need not be imported."""
    return f"{float(expr):.17g}"


class _CPrinter(C99CodePrinter):
    """C99 with small integer powers written as products, constants as numbers (no ``M_PI``)."""

    def __init__(self):
        super().__init__({"math_macros": {}})

    _print_NumberSymbol = _print_Pi = _print_Exp1 = _print_EulerGamma = _print_GoldenRatio = \
        _print_Catalan = _print_TribonacciConstant = _number

    def _print_Pow(self, expr):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exp)) + ")"
        if exp == -1:
            return f"(1.0/{self.parenthesize(base, 100)})"
        return super()._print_Pow(expr)

    def _print_Piecewise(self, expr):
        """A guarded angle (numeric.py) as one conditional expression on one line."""
        if expr.args[-1].cond is not S.true:
            return super()._print_Piecewise(expr)  # no default: sympy's printer says so
        parts = [(self._print(e), self._print(c)) for e, c in expr.args]
        text = parts[-1][0]
        for e, c in reversed(parts[:-1]):
            text = f"(({c}) ? ({e}) : ({text}))"
        return text


class _PyPrinter(NumPyPrinter):
    _print_NumberSymbol = _print_Pi = _print_Exp1 = _print_EulerGamma = _print_GoldenRatio = \
        _print_Catalan = _print_TribonacciConstant = _number

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exp)) + ")"
        return super()._print_Pow(expr, rational=rational)


def _lines(block: Block, show, declare: str, end: str) -> dict:
    """Code lines, generated here from array slots and numbers: output as they are."""
    return {
        "temporaries": [Markup(f"{declare}{s} = {show(e)}{end}") for s, e in block.temporaries],
        "outputs": [Markup(f"{t} = {show(e)}{end}") for t, e in block.outputs],
    }


def file_stem(text: str) -> str:
    """A file stem safe to write and to ``#include``: letters, digits and ``_`` only
    (``my model`` -> ``my_model``; ``../x`` -> ``x``), case kept."""
    return re.sub(r"[^0-9A-Za-z_]+", "_", text).strip("_") or "model"


@dataclass(frozen=True)
class GeneratedFile:
    name: str
    text: str


def _context(model: NumericModel, show, declare: str, end: str) -> dict:
    blocks = {name: _lines(getattr(model, name), show, declare, end)
              for name in ("mass", "velocity_terms", "forces", "equations", "canonical", "prepare", "potential",
                           "positions")}
    if model.implicit is not None:  # the dependent-coordinate solve (numeric_implicit)
        blocks.update({f"implicit_{name}": _lines(getattr(model.implicit, name), show, declare, end)
                       for name in ("closed_form", "residual", "sensitivity", "quadratic")})
    return {"m": model, "b": blocks, "version": __version__,
            "n_points": sum(d for _, d in model.points),
            "defaults": [(name, Markup(value)) for name, value, _ in model.parameters if value]}


def emit_c(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
           outputs=None) -> list[GeneratedFile]:
    """``<stem>.h`` and ``<stem>.c`` (``stem`` made safe by :func:`file_stem`): C99, libc and
    libm only; names start with ``<prefix>_`` (macros with ``<PREFIX>_``), so several models
    can live in one program. A scene's ``outputs`` leave out the energy and point functions
    it does not ask for."""
    model = prepare(system, source, outputs, guarded_angles=True)
    printer = _CPrinter()
    ctx = _context(model, printer.doprint, "const double ", ";")
    stem = file_stem(stem)
    p = identifier(prefix)
    ctx.update(p=Markup(p), P=Markup(p.upper()), header=Markup(f"{stem}.h"),
               guard=Markup(f"{p.upper()}_{identifier(stem).upper()}_H"))
    env = _environment()
    return [GeneratedFile(f"{stem}.h", env.get_template("model.h.j2").render(**ctx)),
            GeneratedFile(f"{stem}.c", env.get_template("model.c.j2").render(**ctx))]


def emit_python(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
                outputs=None) -> list[GeneratedFile]:
    """``<stem>.py`` (``stem`` made safe by :func:`file_stem`): a numpy module that does not
    import sympy (``outputs`` as for C)."""
    model = prepare(system, source, outputs)
    printer = _PyPrinter({"fully_qualified_modules": False})
    ctx = _context(model, printer.doprint, "", "")
    text = _environment().get_template("model.py.j2").render(**ctx)
    return [GeneratedFile(f"{file_stem(stem)}.py", text)]


LANGUAGES = {"c": emit_c, "python": emit_python}
