"""The report's names (kronsub/emitters/report.py): the model's names gathered from its
expressions, and the repeated subexpressions named in the "where" block."""
from __future__ import annotations

import sympy
from sympy.core.cache import clear_cache

from kronsub.emitters.report import _free_symbols, named_subexpressions

q, a, x = sympy.symbols("q a x")


def _copies():
    """Two expressions holding equal but distinct copies of ``sqrt(1 - a q^2)``."""
    first = a * sympy.sqrt(1 - a * q ** 2) * sympy.cos(q)
    clear_cache()  # (sympy hands back the object it made before, otherwise)
    second = sympy.sqrt(1 - a * q ** 2) * sympy.sin(q) + a
    return first, second


def test_free_symbols_are_sympys_over_shared_copies_and_bound_variables():
    first, second = _copies()
    bound = sympy.Integral(x * a * sympy.cos(q), (x, 0, 1))  # x bound: not free
    exprs = [first, second, bound * first, sympy.S(3)]
    assert _free_symbols(exprs) == set().union(*(e.free_symbols for e in exprs)) == {q, a}


def test_a_root_repeated_in_equal_copies_is_named_once():
    first, second = _copies()
    where, reduced = named_subexpressions([first, second], taken={"a", "q"}, coordinates=[q])
    assert [name.name for name, _ in where] == ["w1"]
    assert where[0][1] == sympy.sqrt(1 - a * q ** 2)
    assert [e.xreplace({where[0][0]: where[0][1]}) for e in reduced] == [first, second]


def test_sines_and_cosines_alone_are_not_named():
    exprs = [a * sympy.cos(q) ** 2 + sympy.sin(q), sympy.cos(q) ** 2 * sympy.sin(q)]
    assert named_subexpressions(exprs, taken=set(), coordinates=[q]) == ([], exprs)
