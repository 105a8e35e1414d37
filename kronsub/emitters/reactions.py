"""``derive --reactions``: the reactions of viewpoint (alpha) appended to the derivation."""
from __future__ import annotations

import json

import sympy

from ..collector import collector_paused
from ..core.known_system import KnownSystem
from ..core.reactions import MultiplierSystem, reactions
from .escape import json_document, latex_text
from .implicit_speeds import implicit_form, with_multipliers
from .latex_layout import lines as layout_lines, unbroken
from .report import latex_printer, plain

NOTE = ("Viewpoint (alpha): the workless reactions kept as unknowns and found from the motion; "
        "`<q>_ddot` are the accelerations the equations of motion give{where}. "
        "{what}")


def _what(system: KnownSystem) -> str:
    if system.speeds is not None:
        return ("`mu_<constraint>` are the multipliers of the velocity constraints, `M xddot + h = f + A^T mu` in "
                "the coordinates x with `xdot = C u + d`; the speeds' rates are those the equations in the speeds "
                "give. For a constraint that a contact point's velocity vanish along a direction, its multiplier "
                "is the contact force along it.")
    if system.implicit is not None:
        return ("`mu_<constraint>` are the multipliers of `M_y yddot + h_y = f_y + G^T mu`; for a pin [P, Q] the pair "
                "is the force of the joint on the body of P (minus it on that of Q).")
    return ("`R_<x>` = `M xddot + h - f` on each primitive coordinate x: on a body's centre coordinates the force "
            "of the interconnection on it, on an angle its moment; `C^T R = 0`.")


@collector_paused()  # see kronsub.collector
def with_reactions(text: str, system: KnownSystem, fmt: str) -> str:
    """The derivation ``text`` in ``fmt`` with the reactions added (their defining equation when
    the equations in the speeds are in the implicit form, :mod:`.implicit_speeds`)."""
    if implicit_form(system):
        return with_multipliers(text, system, fmt)
    items = reactions(system)
    where = " and the named intermediates above" if system.implicit is not None else ""
    note = NOTE.format(where=where, what=_what(system))
    if isinstance(items, MultiplierSystem):
        return _with_linear_system(text, system, fmt, items, note)
    if fmt == "json":
        data = json.loads(text)
        data["reactions"] = {"expressions": {name: plain(e) for name, e in items}, "note": note.replace("`", "")}
        return json_document(data, indent=2) + "\n"
    if fmt == "latex":
        coords = tuple(system.coordinates) + (tuple(system.transition.primitive_coordinates)
                                              if system.transition else ()) + (
            tuple(system.speeds.speeds) if system.speeds is not None else ())
        show = latex_printer(coords, system.implicit, breaks=True)
        return _latex_section(text, note, [(rf"\texttt{{{latex_text(name)}}}", show(e)) for name, e in items])
    lines = ["", "## Reactions (viewpoint (alpha))", "", note, ""]
    lines += [f"- `{name} = {plain(e)}`" for name, e in items]
    return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"


def _with_linear_system(text: str, system: KnownSystem, fmt: str, eqs: MultiplierSystem, note: str) -> str:
    """The multipliers of a closed loop with more than three dependent coordinates: their linear
    system ``G_d^T mu = r``, row by row (its closed-form inverse would swell; ``simulate
    --reactions`` solves it at each row)."""
    k = len(eqs.names)
    note += (f" With {k} dependent coordinates the multipliers are given by their linear system "
             "`G_d^T mu = r`, row by row (`simulate --reactions` solves it at each row).")
    if fmt == "json":
        data = json.loads(text)
        data["reactions"] = {"linear_system": {
            "unknowns": eqs.names,
            "matrix": [[plain(eqs.matrix[a, b]) for b in range(k)] for a in range(k)],
            "right_hand_side": [plain(e) for e in eqs.rows]}, "note": note.replace("`", "")}
        return json_document(data, indent=2) + "\n"

    unknowns = [sympy.Symbol(nm) for nm in eqs.names]

    def row(a, show):
        return show(sympy.Add(*[eqs.matrix[a, b] * unknowns[b] for b in range(k)])), show(eqs.rows[a])

    if fmt == "latex":
        coords = tuple(system.coordinates) + tuple(system.implicit.intermediates)
        show = latex_printer(coords, system.implicit, breaks=True)
        return _latex_section(text, note, [(unbroken(lhs), rhs) for lhs, rhs in (row(a, show) for a in range(k))])
    lines = ["", "## Reactions (viewpoint (alpha))", "", note, ""]
    lines += [f"- `{lhs} = {rhs}`" for lhs, rhs in (row(a, plain) for a in range(k))]
    return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"


def _latex_section(text: str, note: str, rows) -> str:
    """The document ``text`` with a Reactions section before its end: the note as text (escaped),
    each ``(left, right)`` an ``align*`` line, long right sides broken over lines as the
    equations are (`latex_layout.lines`)."""
    body = " \\\\\n".join(f"{left} &= " + " \\\\\n&\\quad ".join(layout_lines(right)) for left, right in rows)
    section = ("\\section*{Reactions}\n" + latex_text(note.replace("`", "")) + "\n\\begin{align*}\n" + body
               + "\n\\end{align*}\n")
    return text.replace("\\end{document}", section + "\\end{document}")


__all__ = ["NOTE", "with_reactions"]
