"""Markdown, JSON and LaTeX of a linearisation: ``ydot ~ A (y - y*) + B (u - u*)``.

Numbers are printed in their shortest round-trip form (``repr``), symbolic entries
in sympy's ``str`` (Markdown, JSON) or LaTeX form; eigenvalues with 12 significant
digits. The model's name reaches the Markdown through :func:`~.escape.markdown_text` and the
JSON through :func:`~.escape.json_document`; no free text of the model reaches the LaTeX: only
symbols and numbers.
"""
from __future__ import annotations

import numpy as np
import sympy

from ..core.linearize import Linearization
from ..core.symbols import acceleration_symbol
from .escape import json_document, markdown_text
from .report import latex_printer, plain


def _number(x: float) -> str:
    x = float(x)
    if x == 0:
        return "0"
    return str(int(x)) if x.is_integer() and abs(x) < 1e15 else repr(x)


def _entry(value, show) -> str:
    if isinstance(value, (float, np.floating, int)):
        return _number(value)
    value = sympy.sympify(value)
    if value.is_Float:
        return _number(float(value))
    return show(value)


def _rows(matrix, show) -> list[list[str]]:
    if isinstance(matrix, np.ndarray):
        return [[_number(v) for v in row] for row in matrix]
    return [[_entry(matrix[i, j], show) for j in range(matrix.cols)] for i in range(matrix.rows)]


def _eigenvalue(c: complex) -> str:
    re, im = float(f"{c.real:.12g}"), float(f"{c.imag:.12g}")
    if im == 0:
        return _number(re)
    sign = "+" if im > 0 else "-"
    return f"{_number(re)} {sign} {_number(abs(im))}i" if re != 0 else f"{_number(im)}i"


def _summary(lin: Linearization) -> str:
    if lin.in_speeds:
        return "a steady motion" if lin.equilibrium else \
            "NOT a steady motion (the first-order term is kept: the kept coordinates or the speeds change there)"
    if lin.equilibrium:
        how = "an equilibrium, found from the initial values" if lin.found else "an equilibrium"
    else:
        how = "NOT an equilibrium (the first-order term is kept: ydot* = [qdot*; qddot*] != 0)"
    return how


def _stability(lin: Linearization) -> str:
    if lin.eigenvalues is None:
        return "unknown (parameters without values)"
    if any(e.real > 1e-9 for e in lin.eigenvalues):
        return "unstable (an eigenvalue with positive real part)"
    if all(e.real < -1e-9 for e in lin.eigenvalues):
        return "asymptotically stable"
    return "marginal (eigenvalues on the imaginary axis): the linearisation does not decide"


def emit_markdown(lin: Linearization, name: str) -> str:
    show = plain
    lines = [f"# Linearisation of {markdown_text(name)}", "", _SPEEDS_FORM if lin.in_speeds else
             "`ydot ~ A (y - y*) + B (u - u*)` with `y = [q; qdot]` and "
             "`ydot = [qdot; Mbar^-1 (fbar - hbar)]`.", ""]
    lines += ["## Operating point", "", f"The point is {_summary(lin)}."]
    lines += [f"Note: {note}." for note in lin.notes]
    lines += ["",
              "| name | value |", "|---|---|"]
    for s, v in lin.point:
        lines.append(f"| `{lin.name_of(s)}` | `{_entry(v, show)}` |")
    if lin.time != 0:
        lines.append(f"| `t` | `{_entry(lin.time, show)}` |")
    if lin.dependent:
        lines += ["", "Dependent coordinates there (from the constraints; the state is the reduced one): "
                  + ", ".join(f"`{s.name} = {_number(v)}`" for s, v in lin.dependent) + "."]
    if lin.in_speeds and not lin.equilibrium and all(np.isfinite(lin.acceleration)):
        speeds = lin.state[len(lin.state) - len(lin.acceleration):]
        lines += ["", "Rates of the speeds there: " + ", ".join(
            f"`d/dt {s.name} = {_number(a)}`" for s, a in zip(speeds, lin.acceleration)) + "."]
    elif not lin.equilibrium and all(np.isfinite(lin.acceleration)):
        lines += ["", "Accelerations there: " + ", ".join(
            f"`{lin.name_of(acceleration_symbol(s))} = {_number(a)}`" for s, a in zip(lin.state, lin.acceleration))
            + "."]
    if lin.parameters:
        lines += ["", "Parameter values: " + ", ".join(f"`{p.name} = {_entry(v, show)}`" for p, v in lin.parameters)
                  + "."]
    lines += ["", "## State and inputs", "",
              "State `y = [" + ", ".join(lin.name_of(s) for s in lin.state) + "]`; inputs `u = ["
              + ", ".join(u.name for u in lin.inputs) + "]`.", ""]
    state = [lin.name_of(s) for s in lin.state]
    lines += ["## A", ""] + _md_matrix(_rows(lin.A, show), state, state)
    lines += ["", "## B", ""]
    if lin.inputs:
        lines += _md_matrix(_rows(lin.B, show), state, [u.name for u in lin.inputs])
    else:
        lines.append("No inputs (give them with `--inputs NAME,...`).")
    lines += ["", "## Eigenvalues of A", ""]
    if lin.eigenvalues is None:
        lines.append("Not computed: some parameters have no value.")
    else:
        lines += [f"- `{_eigenvalue(e)}`" for e in lin.eigenvalues]
        lines += ["", f"Stability: {_stability(lin)}."]
    return "\n".join(lines) + "\n"


_SPEEDS_FORM = ("`ydot ~ A (y - y*) + B (u - u*)` with `y = [x; w]`, the kept coordinates `x` and the speeds `w`, "
                "and `ydot = [xdot; Mbar^-1 (fbar - hbar)]`, `xdot = C w + d` (the velocity constraints), the "
                "dependent coordinates on the configuration constraints and the ignorable ones left out.")


def _md_matrix(rows, row_names, col_names) -> list[str]:
    out = ["| | " + " | ".join(f"`{c}`" for c in col_names) + " |",
           "|---|" + "---|" * len(col_names)]
    for name, row in zip(row_names, rows):
        out.append(f"| d/dt `{name}` | " + " | ".join(f"`{v}`" for v in row) + " |")
    return out


def emit_json(lin: Linearization, name: str) -> str:
    def cell(v):
        if lin.symbolic:
            return _entry(v, plain)
        try:
            return float(v)
        except (TypeError, ValueError):
            return _entry(v, plain)

    def matrix(m):
        return [[cell(v) for v in row] for row in (m.tolist() if not isinstance(m, np.ndarray) else m)]

    data = {
        "name": name,
        "state": [lin.name_of(s) for s in lin.state],
        "inputs": [u.name for u in lin.inputs],
        "operating_point": {lin.name_of(s): cell(v) for s, v in lin.point},
        "time": cell(lin.time),
        "equilibrium": lin.equilibrium,
        "found": [s.name for s in lin.found],
        "acceleration": [None if not np.isfinite(a) else float(a) for a in lin.acceleration],
        "parameters": {p.name: cell(v) for p, v in lin.parameters},
        "symbolic": lin.symbolic,
        "notes": list(lin.notes),
        "dependent": {s.name: float(v) for s, v in lin.dependent},
        "A": matrix(lin.A),
        "B": matrix(lin.B),
        "eigenvalues": None if lin.eigenvalues is None else
        [{"re": float(f"{e.real:.12g}"), "im": float(f"{e.imag:.12g}")} for e in lin.eigenvalues],
        "form": "d/dt [x; w] = A ([x; w] - point) + B (inputs - point)" if lin.in_speeds else
        "d/dt [q; qdot] = A ([q; qdot] - point) + B (inputs - point)",
    }
    return json_document(data, indent=2) + "\n"


def emit_latex(lin: Linearization, name: str) -> str:
    """A standalone document; ``name`` is not printed (free text never reaches LaTeX)."""
    coords = [s for s in lin.state[: len(lin.state) // 2]]
    show = latex_printer(coords, currents={q.name: lin.printed[v] for q, v in zip(coords, lin.state[len(coords):])
                                           if v in lin.printed})

    def bmatrix(rows) -> str:
        if not rows or not rows[0]:
            return r"\varnothing"
        return "\\begin{bmatrix}\n" + " \\\\\n".join(" & ".join(r) for r in rows) + "\n\\end{bmatrix}"

    def cell(v) -> str:
        return _entry(v, show)

    state = bmatrix([[show(s)] for s in lin.state])
    lines = [r"\documentclass{article}", r"\usepackage{amsmath}", r"\begin{document}",
             r"\section*{Linearisation}",
             r"$\dot{y} \approx A\,(y - y^*) + B\,(u - u^*)$ with $y = " + state + "$"
             + (r", $u = " + bmatrix([[show(u)] for u in lin.inputs]) + "$" if lin.inputs else "") + ".",
             "", r"Operating point" + (" (an equilibrium)" if lin.equilibrium else " (not an equilibrium)") + ":",
             r"\[ " + ",\\quad ".join(f"{show(s)} = {cell(v)}" for s, v in lin.point) + r" \]",
             r"\[ A = " + bmatrix(_rows(lin.A, show)) + r" \]"]
    if lin.inputs:
        lines.append(r"\[ B = " + bmatrix(_rows(lin.B, show)) + r" \]")
    if lin.eigenvalues is not None:
        lines.append(r"Eigenvalues of $A$: $" + ",\\ ".join(_eigenvalue(e).replace("i", r"\,i")
                                                             for e in lin.eigenvalues) + "$.")
    lines += [r"\end{document}", ""]
    return "\n".join(lines)


EMITTERS = {"markdown": emit_markdown, "json": emit_json, "latex": emit_latex}


__all__ = ["EMITTERS", "emit_json", "emit_latex", "emit_markdown"]
