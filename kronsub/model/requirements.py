"""What components need of their parameters' values, checked once the values are numbers.

Each library component declares it (``ParameterSpec.sign``, :meth:`Component.requirements`): a
length above zero, a mass or moment of inertia not below zero (zero is a massless part), a 3-D
inertia tensor that a body can have. A known system's bodies need the same of their masses and
inertias. The loader checks the model's values and each scene's; a run checks ``--set`` values.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
import sympy

from ..components.base import COUPLING, INERTIA, NONNEGATIVE, POSITIVE, Requirement
from ..errors import Location, Problem
from .source import Node

_PHRASE = {POSITIVE: "must be positive", NONNEGATIVE: "must not be negative",
           COUPLING: "couples more than the coils allow (M^2 <= L1 L2)"}
_HINT = {POSITIVE: "give it a value above zero",
         NONNEGATIVE: "give it a value of zero or more (zero: a massless part, docs/model-format.md)",
         INERTIA: "each principal moment of a body is at least 0 and at most the sum of the other two: check "
                  "the moments, and the signs of the products of inertia (the tensor's entries, "
                  "docs/model-format.md)",
         COUPLING: "the coupling coefficient M/sqrt(L1 L2) is at most 1 in size: lower |M|, or raise the "
                   "self-inductances (docs/electrical.md)"}


def component_requirements(cname: str, component, given: Node | None) -> list[Requirement]:
    """What a library component needs of the values under its ``parameters:`` (``given``), each
    at its value; a parameter left to its default is the library's formula of given ones
    (``mass*length**2/12``), which keeps their sign."""
    found = []
    for name, value, kind in component.requirements():
        node = given.get(name) if given is not None and given.is_mapping else None
        if node is not None:
            what = f"the inertia tensor of component '{cname}'" if kind == INERTIA else f"{name} of component '{cname}'"
            found.append(Requirement(what, value, kind, node.location))
    return found


def body_requirements(label: str, body, location: Location | None) -> list[Requirement]:
    """A known system's body: its mass not negative, its inertia that of a body."""
    found = [Requirement(f"mass of body '{label}'", body.mass, NONNEGATIVE, location)]
    if body.inertia is not None and body.inertia.shape == (1, 1):
        found.append(Requirement(f"inertia of body '{label}'", body.inertia[0, 0], NONNEGATIVE, location))
    elif body.inertia is not None:
        found.append(Requirement(f"the inertia tensor of body '{label}'", body.inertia, INERTIA, location))
    return found


def parameters_in(req: Requirement) -> list:
    """The symbols in a requirement's value, by name."""
    value = req.value
    return sorted(value.free_symbols, key=lambda s: s.name) if isinstance(value, (sympy.Basic, sympy.MatrixBase)) \
        else []


def unmet(requirements, values: Mapping, where: Callable[[Requirement], Location | None] = lambda req: None
          ) -> list[Problem]:
    """A problem per requirement that the parameter ``values`` (symbol -> number) break; a
    requirement still in symbols is not judged. ``where(requirement)`` places the problem,
    None: at the requirement's own place."""
    problems = []
    for req in requirements:
        value = req.value.xreplace(values) if isinstance(req.value, (sympy.Basic, sympy.MatrixBase)) else req.value
        number = _number(value)
        if number is None:
            continue
        why = _inertia_problem(number) if req.kind == INERTIA else \
            None if number > 0 or (number == 0 and req.kind in (NONNEGATIVE, COUPLING)) else _PHRASE[req.kind]
        if why is None:
            continue
        shown = _shown(req.value, number, parameters_in(req), values)
        problems.append(Problem(where(req) or req.location, f"{req.what} {why}: {shown}", _HINT[req.kind]))
    return problems


def first_unmet(requirements, symbols, columns) -> tuple[int, Requirement, Problem] | None:
    """The first row at which a requirement fails, the requirement, and the problem as :func:`unmet` words it,
    over many sets of values at once: ``columns[k]`` the values of ``symbols[k]`` (arrays of one
    length, or numbers). A requirement none of whose symbols is among ``symbols`` is skipped (the
    model's own values were checked when it was read)."""
    chosen = set(symbols)
    arrays = [np.asarray(c, dtype=float) for c in columns]
    count = max((a.size for a in arrays if a.ndim), default=1)
    first: tuple[int, Requirement, Problem] | None = None
    for req in requirements:
        if not set(parameters_in(req)) & chosen:
            continue
        bad = _failing(req, list(symbols), arrays, count)
        if len(bad) and (first is None or bad[0] < first[0]):
            row = int(bad[0])
            values = {s: float(a if a.ndim == 0 else a[row]) for s, a in zip(symbols, arrays)}
            found = unmet([req], values)
            if found:
                first = (row, req, found[0])
    return first


def _failing(req: Requirement, symbols: list, arrays: list, count: int) -> np.ndarray:
    """The rows at which ``req`` fails (NaN fails), its value evaluated in numpy over them."""
    def evaluated(expr) -> np.ndarray:
        f = sympy.lambdify(symbols, expr, "numpy")
        with np.errstate(all="ignore"):
            return np.broadcast_to(np.asarray(f(*arrays), dtype=float), (count,))

    if req.kind == INERTIA:
        tensors = np.stack([np.stack([evaluated(e) for e in row], axis=-1) for row in req.value.tolist()], axis=-2)
        finite = np.all(np.isfinite(tensors), axis=(1, 2))
        moments = np.linalg.eigvalsh((tensors + np.swapaxes(tensors, 1, 2)) / 2 * finite[:, None, None])
        slack = 1e-12 * np.max(np.abs(moments), axis=1)
        ok = (moments[:, 0] >= -slack) & (moments[:, 2] <= moments[:, 0] + moments[:, 1] + slack)
        return np.flatnonzero(~ok & finite)  # (a tensor of no finite value: unmet leaves it unjudged)
    value = evaluated(req.value)
    ok = (value > 0) | ((value == 0) if req.kind in (NONNEGATIVE, COUPLING) else False)
    return np.flatnonzero(~ok)


def _number(value):
    """``value`` as a float (a tensor: an array), None if it is not a finite real number."""
    try:
        if isinstance(value, sympy.MatrixBase):
            array = np.array(value.evalf(), dtype=float)
            return array if np.all(np.isfinite(array)) else None
        number = float(sympy.sympify(value))
    except (TypeError, ValueError, OverflowError):
        return None
    return number  # NaN fails every sign: it is neither above nor at zero


def _inertia_problem(tensor) -> str | None:
    """Why a symmetric tensor is no body's: a negative principal moment, or one larger than the
    other two together (the triangle inequality)."""
    moments = np.linalg.eigvalsh((tensor + tensor.T) / 2)
    slack = 1e-12 * float(np.max(np.abs(moments)))  # rounding of the eigenvalues (a flat plate: C = A + B)
    if moments[0] >= -slack and moments[2] <= moments[0] + moments[1] + slack:
        return None
    listed = ", ".join(f"{m:.6g}" for m in moments)
    return (f"is not a body's: its principal moments {listed} must not be negative and each at most the sum "
            "of the other two")


def _shown(expr, number, names, values) -> str:
    """``m1 = -0.1``; an expression with the parameter values it has: ``2*m - 1 = -0.2 (m = 0.4)``."""
    given = ", ".join(f"{s.name} = {_g(values.get(s))}" for s in names if s in values)
    if isinstance(expr, sympy.Symbol):
        return f"{expr.name} = {_g(number)}"
    if isinstance(expr, sympy.Basic) and expr.is_number:
        return _g(number)
    if isinstance(expr, sympy.MatrixBase):
        return given or sympy.sstr(expr.tolist())
    written = sympy.sstr(expr)
    text = f"{written if len(written) <= 80 else written[:77] + '...'} = {_g(number)}"
    return f"{text} ({given})" if given else text


def _g(value) -> str:
    try:
        return f"{float(value):.6g}"
    except (TypeError, ValueError):
        return sympy.sstr(value)


__all__ = ["body_requirements", "component_requirements", "first_unmet", "parameters_in", "unmet"]
