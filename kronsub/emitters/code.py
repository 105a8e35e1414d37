"""Code emitters: C (header + source) and a numpy module (the ``--lang`` registry).

Both compute the same functions from :mod:`.numeric`: ``Mbar``, ``hbar``,
``fbar``, the first-order right-hand side ``ydot = [qdot; Mbar^-1 (fbar - hbar)]``
(in-place ``L D L^T``: ``Mbar`` is symmetric positive definite), its canonical
form, the energies and the named points. No timestamps: output is byte-identical.
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import sympy
from sympy.printing.c import C99CodePrinter
from sympy.printing.numpy import NumPyPrinter

from ..collector import collector_paused
from ..core.known_system import KnownSystem
from ..errors import KronsubError
from ..version import __version__
from .escape import Markup
from .circle import circle_equations
from .block import Block
from .numeric import GUARD, NumericModel, identifier, prepare
from .projected import ROUTES, applies
from .projected_speeds import applies as frame_applies
from .text import template_environment


def _number(self, expr) -> str:
    """A constant such as pi or E as its value to 17 significant digits: ``-std=c99``
    defines no ``M_PI``, and numpy's names need not be imported."""
    return f"{float(expr):.17g}"


EXACT = 2 ** 53
"""Integers up to this size are exact in a double; larger ones (a product of powers can make
one past 64 bits, which no C or numpy integer holds) print as the nearest double."""


def _big(expr) -> bool:
    """Whether a rational number has a numerator or denominator past :data:`EXACT`."""
    return abs(int(expr.p)) > EXACT or int(expr.q) > EXACT


def _double(expr, infinity: str) -> str:
    """The nearest double to a rational number as a literal (``infinity`` past the double range)."""
    value = float(sympy.Float(expr, 20))
    return repr(value) if abs(value) < float("inf") else (infinity if value > 0 else f"(-{infinity})")


def terms_in_order(expr) -> list | None:
    """The terms of the sum ``expr`` in the order SymPy's code printers write them
    (``Expr.as_ordered_terms``, lexicographic: a term's exponents of the sum's bases, the bases in
    SymPy's sort order, compared largest first), or None where SymPy's own ordering is needed: a
    term with a number other than its rational coefficient (the coefficient then breaks ties, and
    a number alone comes first against a negative multiple: ``1 - x``), a non-integer power or a
    non-commutative factor. Where it answers, no two terms have the same exponents (they would
    be one term), so the coefficients, which SymPy converts by ``complex()`` one by one (most of
    printing a block), never decide."""
    exponents, bases = [], set()
    for term in expr.args:
        coefficient, rest = term.as_coeff_Mul()
        if not coefficient.is_Rational or rest is sympy.S.One:
            return None
        powers = {}
        for factor in sympy.Mul.make_args(rest):
            if factor.is_number or not factor.is_commutative:
                return None
            base, exponent = factor.as_base_exp()
            if not exponent.is_Integer:
                return None
            powers[base] = int(exponent)
        bases.update(powers)
        exponents.append(powers)
    place = {base: k for k, base in enumerate(sorted(bases, key=sympy.default_sort_key))}

    def key(k: int) -> tuple:
        monomial = [0] * len(place)
        for base, exponent in exponents[k].items():
            monomial[place[base]] = -exponent
        return tuple(monomial)

    return [expr.args[k] for k in sorted(range(len(expr.args)), key=key)]


class _OrderedSums:
    """A code printer's sums, their terms ordered by :func:`terms_in_order` where it answers."""

    def _as_ordered_terms(self, expr, order=None):
        if order is None and self.order is None and expr.is_Add:
            terms = terms_in_order(expr)
            if terms is not None:
                return terms
        return super()._as_ordered_terms(expr, order=order)


class _CPrinter(_OrderedSums, C99CodePrinter):
    """C99 with small integer powers written as products, constants as numbers (no ``M_PI``),
    integers past :data:`EXACT` and rationals of them as double literals, ``sign`` a double
    (``fabs`` of an ``int`` fails ``-Werror``): every math call gets a double argument."""

    def __init__(self, prefix: str = "ks"):
        super().__init__({"math_macros": {}})
        self.prefix = prefix
        self.near_axis = False  # whether a guarded angle needs <prefix>_near_axis

    def _print_NearAxis(self, expr):
        """A guarded angle (numeric.py) as one conditional expression on one line."""
        self.near_axis = True
        angle, kind, product = expr.args[:3]
        p = self._print(product)
        below = self._print(sympy.StrictLessThan(sympy.Abs(product, evaluate=False), GUARD, evaluate=False))
        return f"(({below}) ? ({self.prefix}_near_axis({self._print(angle)}, {int(kind)}, {p})) : ({p}))"

    _print_NumberSymbol = _print_Pi = _print_Exp1 = _print_EulerGamma = _print_GoldenRatio = \
        _print_Catalan = _print_TribonacciConstant = _number

    def _print_Integer(self, expr):
        return _double(expr, "HUGE_VAL") if _big(expr) else super()._print_Integer(expr)

    def _print_Rational(self, expr):
        return _double(expr, "HUGE_VAL") if _big(expr) else super()._print_Rational(expr)

    def _print_sign(self, expr):
        return f"((double){super()._print_sign(expr)})"

    def _print_Pow(self, expr):
        base, exp = expr.args
        if exp.is_Integer and 2 <= int(exp) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exp)) + ")"
        if exp == -1:
            return f"(1.0/{self.parenthesize(base, 100)})"
        return super()._print_Pow(expr)


class _PyPrinter(_OrderedSums, NumPyPrinter):
    """numpy, with small integer powers written as products, constants as numbers, integers past
    :data:`EXACT` and rationals of them as floats (a Python integer past 64 bits overflows numpy)."""

    _print_NumberSymbol = _print_Pi = _print_Exp1 = _print_EulerGamma = _print_GoldenRatio = \
        _print_Catalan = _print_TribonacciConstant = _number

    def _print_Integer(self, expr):
        return _double(expr, "numpy.inf") if _big(expr) else super()._print_Integer(expr)

    def _print_Rational(self, expr):
        return _double(expr, "numpy.inf") if _big(expr) else super()._print_Rational(expr)

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


WRITTEN_OUT = 12
"""Up to this many coordinates the ``L D L^T`` solve is written out in scalars (n^3/6 lines)."""


def ldlt_lines(n: int) -> list[Markup]:
    """The ``L D L^T`` solve of ``M x = r`` for ``n`` coordinates written out, in the loops'
    order of operations (the same roundings, so the same result to the last bit): no loop
    bounds, indices or array stores, every intermediate in a register the compiler schedules.
    Every sum ends with the term that is ready last (the back substitution runs from the last
    coordinate down), so each step waits for one product and one subtraction, not a whole sum."""
    out = []
    for j in range(n):
        out += [f"const double w{j}_{k} = l{j}_{k} * d{k};" for k in range(j)]
        out.append(f"const double d{j} = M[{j * n + j}]" + "".join(f" - l{j}_{k} * w{j}_{k}" for k in range(j)) + ";")
        out.append(f"if (!(d{j} > 1e-12 * M[{j * n + j}])) return 1;")
        out.append(f"const double inv{j} = 1.0 / d{j};")
        out += [f"const double l{i}_{j} = (M[{i * n + j}]" + "".join(f" - l{i}_{k} * w{j}_{k}" for k in range(j))
                + f") * inv{j};" for i in range(j + 1, n)]
    out += [f"const double y{i} = r[{i}]" + "".join(f" - l{i}_{k} * y{k}" for k in range(i)) + ";" for i in range(n)]
    out += [f"const double x{i} = y{i} * inv{i}" + "".join(f" - l{k}_{i} * x{k}" for k in reversed(range(i + 1, n)))
            + ";" for i in reversed(range(n))]
    out += [f"r[{i}] = x{i};" for i in range(n)]
    return [Markup(line) for line in out]


def _context(model: NumericModel, show, declare: str, end: str) -> dict:
    show = functools.lru_cache(maxsize=None)(show)  # a block's part (numeric.prepare's mass) is printed once
    blocks = {name: _lines(getattr(model, name), show, declare, end)
              for name in ("mass", "velocity_terms", "forces", "equations", "canonical", "prepare", "potential",
                           "positions")}
    if model.jacobian is not None:
        blocks["jacobian"] = _lines(model.jacobian, show, declare, end)
    if model.implicit is not None:  # the dependent-coordinate solve (numeric_implicit)
        blocks.update({f"implicit_{name}": _lines(getattr(model.implicit, name), show, declare, end)
                       for name in ("closed_form", "residual", "sensitivity", "quadratic")})
    if model.kinematics is not None:  # qdot = C(q) u under velocity constraints
        blocks["kinematics"] = _lines(model.kinematics, show, declare, end)
    if model.held is not None:  # g and G_D of the configuration constraints beside them (numeric_held)
        blocks["held_residual"] = _lines(model.held.residual, show, declare, end)
    return {"m": model, "b": blocks, "version": __version__,
            "n_points": sum(d for _, d in model.points),
            "defaults": [(name, Markup(value)) for name, value, _ in model.parameters if value],
            "c_defaults": [(name, Markup(f"({value})" if value.startswith("-") else value))
                           for name, value, _ in model.parameters if value]}


@collector_paused()  # see kronsub.collector
def emit_c(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
           outputs=None, jacobian: bool = False, route: str = "auto", terms_apart: bool = True,
           canonical: bool = True, circle_apart: bool = False, mass_apart: bool = True,
           metric_apart: bool = False) -> list[GeneratedFile]:
    """``<stem>.h`` and ``<stem>.c`` (``stem`` made safe by :func:`file_stem`): C99, libc and
    libm only; names start with ``<prefix>_`` (macros with ``<PREFIX>_``), so several models
    can live in one program. A scene's ``outputs`` leave out the energy and point functions
    it does not ask for; ``jacobian`` adds ``<prefix>_jacobian``, the exact ``d ydot/dy``.
    ``route`` (:data:`.projected.ROUTES`): ``Mbar``, ``hbar`` and ``fbar`` from the derived
    expressions or projected at run time (:mod:`.projected`). ``terms_apart`` (``<prefix>_velocity_terms``,
    ``<prefix>_forces``) and ``canonical`` (``<prefix>_rhs_canonical``): left out when False (a
    library that runs a method on ``y = [q; qdot]`` calls neither). ``circle_apart``: the circle
    state's right-hand side in a file of its own, ``<stem>_circle.c``, so that a build compiles
    the two files side by side (where it stands alone: not with the projection kept for run
    time, nor with guarded angles left in it). ``metric_apart``: with the projection kept for run
    time, ``Mbar``'s entries in a file of their own, ``<stem>_metric.c``, compiled side by side too. ``mass_apart`` False: ``<prefix>_mass_matrix`` (the
    energies', the momentum's) is the equations' block's part for ``Mbar`` instead of a block of its
    own, where that block holds it as it is (:func:`.numeric.prepare`)."""
    if route not in ROUTES:
        raise ValueError(f"route must be one of {', '.join(ROUTES)}, not {route!r}")
    # under velocity constraints the projection onto the speeds is kept (.projected_speeds)
    kept = frame_applies(system) if system.speeds is not None else applies(system)
    if route == "projected" and (not kept or jacobian):
        raise KronsubError("cannot keep the projection for run time: the system has a closed loop, a "
                           "prescribed motion, first-order coordinates, an effect applied in the subspace "
                           "or no primitive, or the exact Jacobian is asked for")
    model = prepare(system, source, outputs, guarded_angles=True, jacobian=jacobian, route=route,
                    terms_apart=terms_apart, canonical=canonical, mass_apart=mass_apart)
    p = identifier(prefix)
    printer = _CPrinter(p)
    ctx = _context(model, printer.doprint, "const double ", ";")
    circle, circle_block = ((), None)
    if model.projected is not None:
        ctx["b"]["projected"] = _lines(model.projected.block, printer.doprint, "const double ", ";")
        ctx["b"]["projected_kinetic"] = _lines(model.projected.kinetic, printer.doprint, "const double ", ";")
    if model.frame is not None:  # the projection onto the speeds at run time (projected_speeds)
        ctx["b"]["projected"] = _lines(model.frame.metric.block, printer.doprint, "const double ", ";")
        ctx["b"]["frame"] = _lines(model.frame.frame, printer.doprint, "const double ", ";")
        ctx["b"]["frame_rates"] = _lines(model.frame.rates, printer.doprint, "const double ", ";")
    if model.implicit is None and not model.first_order and not model.speeds:  # the circle state (circle.py)
        rhs = model.equations if model.projected is None else model.projected.block
        circle, circle_block = circle_equations(rhs, [sympy.Symbol(f"q[{i}]") for i in range(model.n)])
    alone = circle_block is not None and model.projected is None  # no helper of <stem>.c needed
    if circle_block is not None:
        circle_printer = _CPrinter(p)
        ctx["b"]["circle"] = _lines(circle_block, circle_printer.doprint, "const double ", ";")
        printer.near_axis = printer.near_axis or circle_printer.near_axis
        alone = alone and not circle_printer.near_axis
    ctx["circle"] = [(k, i, model.coordinates[i]) for k, i in enumerate(circle)]
    ctx["circle_apart"] = circle_apart and alone
    ctx["metric_apart"] = metric_apart and model.projected is not None
    stem = file_stem(stem)
    ctx.update(near_axis=printer.near_axis, ldlt=ldlt_lines(model.nv) if 0 < model.nv <= WRITTEN_OUT else None,
               p=Markup(p), P=Markup(p.upper()), header=Markup(f"{stem}.h"),
               NV=Markup(f"{p.upper()}_NU" if model.speeds else f"{p.upper()}_NQ"),
               guard=Markup(f"{p.upper()}_{identifier(stem).upper()}_H"))
    ctx["stem"] = Markup(stem)
    env = template_environment()
    files = [GeneratedFile(f"{stem}.h", env.get_template("model.h.j2").render(**ctx)),
             GeneratedFile(f"{stem}.c", env.get_template("model.c.j2").render(**ctx))]
    if ctx["circle_apart"]:
        files.append(GeneratedFile(f"{stem}_circle.c", env.get_template("model_circle.c.j2").render(**ctx)))
    if ctx["metric_apart"]:
        files.append(GeneratedFile(f"{stem}_metric.c", env.get_template("model_metric.c.j2").render(**ctx)))
    return files


@collector_paused()  # see kronsub.collector
def emit_python(system: KnownSystem, stem: str, source: str = "", prefix: str = "ks",
                outputs=None, route: str = "auto") -> list[GeneratedFile]:
    """``<stem>.py`` (``stem`` made safe by :func:`file_stem`): a numpy module that does not
    import sympy (``outputs`` as for C). Its equations are the derived expressions, but under
    velocity constraints ``route`` (:data:`.projected.ROUTES`) chooses as for C: the projection
    onto the speeds is kept for run time (:mod:`.projected_speeds`, made there in numpy) when
    ``projected``, or when ``auto`` and its symbolic projection is too large."""
    if route not in ROUTES:
        raise ValueError(f"route must be one of {', '.join(ROUTES)}, not {route!r}")
    if system.speeds is None:
        route = "expanded"  # numpy code keeps the derived expressions (the projected route's loops are C's)
    elif route == "projected" and not frame_applies(system):
        raise KronsubError("cannot keep the projection onto the speeds for run time: the system has no primitive, "
                           "a prescribed motion or an effect applied in the subspace")
    model = prepare(system, source, outputs, route=route)
    printer = _PyPrinter({"fully_qualified_modules": False})
    ctx = _context(model, printer.doprint, "", "")
    if model.frame is not None:  # the projection onto the speeds at run time (projected_speeds)
        ctx["b"]["projected"] = _lines(model.frame.metric.block, printer.doprint, "", "")
        ctx["b"]["frame"] = _lines(model.frame.frame, printer.doprint, "", "")
        ctx["b"]["frame_rates"] = _lines(model.frame.rates, printer.doprint, "", "")
    ctx["NV"] = Markup("NU" if model.speeds else "NQ")
    text = template_environment().get_template("model.py.j2").render(**ctx)
    return [GeneratedFile(f"{file_stem(stem)}.py", text)]


LANGUAGES = {"c": emit_c, "python": emit_python}


__all__ = ["EXACT", "GeneratedFile", "LANGUAGES", "WRITTEN_OUT", "emit_c", "emit_python", "file_stem", "ldlt_lines"]
