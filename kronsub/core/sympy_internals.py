"""The SymPy internals kronsub relies on, in one place: names SymPy does not promise to keep.

kronsub builds expressions that are already in canonical form without SymPy canonicalising
them again (``canonical.py``), and stores them in the known-system cache exactly
(``model/cache_format.py``); both need SymPy's private constructors and attributes. Every
other module takes them from here; tests/test_sympy_internals.py checks each against the
installed SymPy and names the one that changed, and pyproject.toml bounds SymPy to the
releases tested.

SymPy's printer and evaluation hooks that kronsub's printers subclass (``_print_<Class>``,
``_print``, ``_default_settings``, ``_settings``, ``_as_ordered_terms``, ``_eval_evalf``)
are listed in :data:`HOOKS`: they are overridden, not imported, and checked there too.
"""
from __future__ import annotations

import sympy
from sympy.core import basic
from sympy.core.assumptions import _assume_defined
from sympy.core.basic import _args_sortkey
from sympy.core.mul import _keep_coeff
from sympy.core import random as sympy_random

__all__ = ["HOOKS", "add_from_args", "args_sortkey", "assume_defined", "assumptions_given", "assumptions_rng",
           "basic_new", "eval_evalf", "float_new", "float_parts", "hashable_content", "keep_coeff", "matrix_from_dod", "matrix_fromrep", "matrix_new",
           "mul_from_args", "ordering_of_classes", "parse_order", "valid_nargs"]

args_sortkey = _args_sortkey
"""``Basic``'s sort key of arguments: the canonical order of an ``Add``'s or a ``Mul``'s."""


def assumptions_rng():
    """The second random generator of ``sympy.core.random`` (``_assumptions_rng``), which
    ``sympy.core.random.seed`` also seeds: :mod:`.seeded` saves and restores its state."""
    return sympy_random._assumptions_rng

ordering_of_classes = basic.ordering_of_classes
"""The class names in the order ``Basic.compare`` ranks classes first."""

assume_defined = _assume_defined
"""The names of every assumption SymPy defines (``commutative``, ``real``, ...)."""

add_from_args = sympy.Add._from_args
"""``Add`` of terms already flat, combined and in canonical order: no checks, no cache."""

mul_from_args = sympy.Mul._from_args
"""``Mul`` of factors already flat, combined and in canonical order: no checks, no cache."""

basic_new = sympy.Basic.__new__
"""The bare node constructor under every class's ``__new__``: ``basic_new(cls, *args)``."""

float_new = sympy.Float._new
"""``Float`` from an mpmath ``(sign, mantissa, exponent, bitcount)`` tuple and a precision."""

keep_coeff = _keep_coeff
"""``coeff * factors`` as ``factor_terms`` puts a content back in front of a primitive part
(a sum's sign out: ``-(x + y)``, not ``-x - y``)."""

parse_order = sympy.Expr._parse_order
"""``(key, reverse)`` that sorts the described terms of a sum in a monomial order."""


def hashable_content(expr: sympy.Basic) -> tuple:
    """What ``Basic.compare`` compares after the class: ``expr._hashable_content()``."""
    return expr._hashable_content()


def float_parts(number: sympy.Float) -> tuple[tuple, int]:
    """The mpmath tuple and the precision of a ``Float`` (what :data:`float_new` takes)."""
    return number._mpf_, number._prec


def assumptions_given(symbol: sympy.Symbol) -> dict:
    """The assumptions a ``Symbol`` was made with (not those SymPy deduced)."""
    return symbol._assumptions_orig


def eval_evalf(expr: sympy.Expr, prec: int):
    """``expr``'s value to ``prec`` bits, as ``evalf`` asks each node: ``expr._eval_evalf(prec)``."""
    return expr._eval_evalf(prec)


def valid_nargs(cls: type, n: int) -> bool:
    """Whether the ``Function`` class ``cls`` takes ``n`` arguments."""
    return cls._valid_nargs(n)


def matrix_new(cls: type, rows: int, cols: int, entries: list) -> sympy.MatrixBase:
    """``cls(rows, cols, entries)`` without the argument parsing of ``cls(...)``."""
    return cls._new(rows, cols, entries)


def matrix_from_dod(cls: type, rows: int, cols: int, dod: dict, types: set) -> sympy.MatrixBase:
    """The matrix of the nonzero entries ``dod[i][j]`` (of the classes ``types``), built as
    ``RepMatrix._flat_list_to_DomainMatrix`` builds it."""
    return cls._fromrep(cls._dod_to_DomainMatrix(rows, cols, dod, types))


def matrix_fromrep(cls: type, rep) -> sympy.MatrixBase:
    """The matrix of class ``cls`` holding the ``DomainMatrix`` ``rep``."""
    return cls._fromrep(rep)


HOOKS: tuple[tuple[str, str], ...] = (
    ("sympy.printing.str.StrPrinter", "_print"),
    ("sympy.printing.str.StrPrinter", "_as_ordered_terms"),
    ("sympy.printing.str.StrPrinter", "_print_Add"),
    ("sympy.printing.str.StrPrinter", "_print_Mul"),
    ("sympy.printing.str.StrPrinter", "parenthesize"),
    ("sympy.printing.latex.LatexPrinter", "_default_settings"),
    ("sympy.printing.latex.LatexPrinter", "_print_Symbol"),
    ("sympy.printing.latex.LatexPrinter", "_as_ordered_terms"),
    ("sympy.printing.c.C99CodePrinter", "_print_Integer"),
    ("sympy.printing.c.C99CodePrinter", "_print_Rational"),
    ("sympy.printing.c.C99CodePrinter", "_print_sign"),
    ("sympy.printing.c.C99CodePrinter", "_print_Pow"),
    ("sympy.printing.numpy.NumPyPrinter", "_print_Integer"),
    ("sympy.printing.numpy.NumPyPrinter", "_print_Rational"),
    ("sympy.printing.numpy.NumPyPrinter", "_print_Pow"),
    ("sympy.core.expr.Expr", "_eval_evalf"),
)
"""The SymPy hooks kronsub's subclasses override, as ``(class path, attribute)``."""
