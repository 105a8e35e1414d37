"""Code emitters: C (header + source) and a numpy module (the ``--lang`` registry).

Both compute the same functions from :mod:`.numeric`: ``Mbar``, ``hbar``,
``fbar``, the first-order right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]``
(in-place ``L D L^T``: ``Mbar`` is symmetric positive definite), its canonical
form, the energies and the named points. No timestamps: output is byte-identical.
"""
from __future__ import annotations

from dataclasses import dataclass

from sympy.printing.c import C99CodePrinter
from sympy.printing.numpy import NumPyPrinter

from .. import __version__
from ..core.known_system import KnownSystem
from .numeric import Block, NumericModel, identifier, prepare
from .text import _environment


class _CPrinter(C99CodePrinter):
    """C99 with small integer powers written as products."""

    def _print_Pow(self, expr):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exp)) + ")"
        if exp == -1:
            return f"(1.0/{self.parenthesize(base, 100)})"
        return super()._print_Pow(expr)


class _PyPrinter(NumPyPrinter):
    def _print_Pow(self, expr, rational=False):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exp)) + ")"
        return super()._print_Pow(expr, rational=rational)


def _lines(block: Block, show, declare: str, end: str) -> dict:
    return {
        "temporaries": [f"{declare}{s} = {show(e)}{end}" for s, e in block.temporaries],
        "outputs": [f"{t} = {show(e)}{end}" for t, e in block.outputs],
    }


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
            "n_points": sum(d for _, d in model.points)}


def emit_c(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
           outputs=None) -> list[GeneratedFile]:
    """``<stem>.h`` and ``<stem>.c``: C99, libc and libm only; names start with ``<prefix>_``
    (macros with ``<PREFIX>_``), so several models can live in one program. A scene's
    ``outputs`` leave out the energy and point functions it does not ask for."""
    model = prepare(system, source, outputs)
    printer = _CPrinter()
    ctx = _context(model, printer.doprint, "const double ", ";")
    ctx["stem"] = identifier(stem)
    ctx["p"] = identifier(prefix)
    ctx["P"] = identifier(prefix).upper()
    env = _environment()
    return [GeneratedFile(f"{stem}.h", env.get_template("model.h.j2").render(**ctx)),
            GeneratedFile(f"{stem}.c", env.get_template("model.c.j2").render(**ctx))]


def emit_python(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
                outputs=None) -> list[GeneratedFile]:
    """``<stem>.py``: a numpy module that does not import sympy (``outputs`` as for C)."""
    model = prepare(system, source, outputs)
    printer = _PyPrinter({"fully_qualified_modules": False})
    ctx = _context(model, printer.doprint, "", "")
    ctx["stem"] = identifier(stem)
    text = _environment().get_template("model.py.j2").render(**ctx)
    return [GeneratedFile(f"{stem}.py", text)]


LANGUAGES = {"c": emit_c, "python": emit_python}
