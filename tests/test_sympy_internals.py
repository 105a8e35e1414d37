"""Canary for the SymPy internals kronsub relies on (kronsub/core/sympy_internals.py): each is
checked against the installed SymPy for what kronsub needs of it, and a failure names it.

When one fails after a SymPy upgrade, kronsub's canonical builders or its cache encoding must
follow SymPy's change (or pyproject.toml's bound on SymPy stays where it is)."""
from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import pytest
import sympy

from kronsub.core import sympy_internals as si

ROOT = Path(__file__).resolve().parent.parent
x, y, z = sympy.symbols("x y z")


def _canonical_order():
    terms = [sympy.sin(y), 3 * x, z**2, x * y]
    assert sorted(terms, key=si.args_sortkey) == list(sympy.Add(*terms).args), "the order Add gives its terms"


def _ordering_of_classes():
    assert isinstance(si.ordering_of_classes, list) and {"Symbol", "Add", "Mul", "Pow"} <= set(si.ordering_of_classes)


def _assume_defined():
    assert {"commutative", "real", "positive", "integer"} <= set(si.assume_defined)


def _add_from_args():
    built = si.add_from_args(list(sympy.Add(x, y * z, 2).args))
    assert type(built) is sympy.Add and built == x + y * z + 2 and built.args == (x + y * z + 2).args


def _mul_from_args():
    built = si.mul_from_args(list(sympy.Mul(3, x, sympy.sin(y)).args))
    assert type(built) is sympy.Mul and built == 3 * x * sympy.sin(y)


def _keep_coeff():
    assert si.keep_coeff(sympy.Integer(-1), x + y, sign=True).args in ((-1, x + y), (x + y, -1))
    assert si.keep_coeff(sympy.Rational(1, 2), x * y, clear=False) == x * y / 2
    assert sympy.factor_terms(-2 * x - 2 * y * z) == si.keep_coeff(sympy.Integer(-2), x + y * z, clear=False, sign=True)


def _basic_new():
    value = si.basic_new(sympy.sin, x)
    value.nargs = sympy.sin(x, evaluate=False).nargs  # canonical.function sets it so
    assert value == sympy.sin(x, evaluate=False) and value.args == (x,)
    product = si.basic_new(sympy.Mul, *(2 * x * y).args)
    product.is_commutative = True  # cache_format._nodes sets it so
    assert product == 2 * x * y


def _float_round_trip():
    number = sympy.Float("0.1", 30)
    mpf, prec = si.float_parts(number)
    assert isinstance(mpf, tuple) and len(mpf) == 4 and isinstance(prec, int)
    again = si.float_new(mpf, prec)
    assert again == number and si.float_parts(again) == (mpf, prec)


def _parse_order():
    key, reverse = si.parse_order("lex")
    assert callable(key) and isinstance(reverse, bool)


def _hashable_content():
    content = si.hashable_content(x + y)
    assert isinstance(content, tuple) and set(content) == {x, y}


def _assumptions_given():
    assert si.assumptions_given(sympy.Symbol("r", positive=True)) == {"positive": True}
    assert si.assumptions_given(x) == {}


def _valid_nargs():
    assert si.valid_nargs(sympy.sin, 1) and not si.valid_nargs(sympy.sin, 2)
    assert si.valid_nargs(sympy.atan2, 2)


def _eval_evalf():
    value = si.eval_evalf(sympy.sin(sympy.Rational(1, 3), evaluate=False), 53)
    assert isinstance(value, sympy.Float) and abs(float(value) - 0.3271946967961522) < 1e-15


def _matrices():
    entries = [x, sympy.S.Zero, sympy.S.Zero, y]
    dense = sympy.Matrix(2, 2, entries)
    assert si.matrix_new(sympy.Matrix, 2, 2, entries) == dense
    built = si.matrix_from_dod(sympy.Matrix, 2, 2, {0: {0: x}, 1: {1: y}}, set(map(type, entries)))
    assert type(built) is type(dense) and built == dense
    assert si.matrix_from_dod(sympy.ImmutableMatrix, 2, 2, {0: {0: x}, 1: {1: y}}, {sympy.Symbol}) == dense
    from sympy.polys.domains import ZZ
    from sympy.polys.matrices import DomainMatrix
    ones = si.matrix_fromrep(sympy.Matrix, DomainMatrix({0: {1: ZZ(1)}}, (1, 2), ZZ))
    assert ones == sympy.Matrix([[0, 1]])


def _assumptions_rng():
    from sympy.core import random as sympy_random

    rng = si.assumptions_rng()
    sympy_random.seed(7)
    first = rng.random()
    sympy_random.seed(7)
    assert rng.random() == first  # seed() seeds it too, so seeded.py must restore it


CHECKS = {
    "sympy.core.random._assumptions_rng": _assumptions_rng,
    "sympy.core.basic._args_sortkey": _canonical_order,
    "sympy.core.basic.ordering_of_classes": _ordering_of_classes,
    "sympy.core.assumptions._assume_defined": _assume_defined,
    "sympy.Add._from_args": _add_from_args,
    "sympy.Mul._from_args": _mul_from_args,
    "sympy.core.mul._keep_coeff": _keep_coeff,
    "sympy.Basic.__new__ (bare nodes; nargs and is_commutative set on them)": _basic_new,
    "sympy.Float._new, Float._mpf_, Float._prec": _float_round_trip,
    "sympy.Expr._parse_order": _parse_order,
    "sympy.Basic._hashable_content": _hashable_content,
    "sympy.Symbol._assumptions_orig": _assumptions_given,
    "sympy.Function._valid_nargs": _valid_nargs,
    "sympy.Expr._eval_evalf": _eval_evalf,
    "MatrixBase._new, RepMatrix._fromrep, RepMatrix._dod_to_DomainMatrix": _matrices,
}


@pytest.mark.parametrize("internal", CHECKS)
def test_sympy_internal_still_behaves(internal):
    try:
        CHECKS[internal]()
    except Exception as error:  # noqa: BLE001: any failure is the canary's message
        pytest.fail(f"SymPy {sympy.__version__} changed the internal {internal} that kronsub relies on "
                    f"(kronsub/core/sympy_internals.py): {type(error).__name__}: {error}")


def test_every_internal_of_the_module_has_a_check():
    checked = {f.__name__ for f in CHECKS.values()}
    assert len(checked) == len(CHECKS)
    names = set(si.__all__) - {"HOOKS"}
    used = {name for check in CHECKS.values() for name in names if f"si.{name}(" in _source(check)
            or f"si.{name}," in _source(check) or f"si.{name})" in _source(check)}
    assert names == used, f"not checked here: {sorted(names - used)}"


def _source(function) -> str:
    return inspect.getsource(function)


@pytest.mark.parametrize("hook", si.HOOKS, ids=lambda h: f"{h[0].rsplit('.', 1)[1]}.{h[1]}")
def test_sympy_hook_kronsub_overrides_still_exists(hook):
    path, attribute = hook
    module, name = path.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    assert hasattr(cls, attribute), (f"SymPy {sympy.__version__}: {path} no longer has {attribute}, which "
                                     f"kronsub's printers override (kronsub/core/sympy_internals.py HOOKS)")


def test_latex_printer_keeps_its_settings_where_kronsub_reads_them():
    from sympy.printing.latex import LatexPrinter

    settings = LatexPrinter()._settings
    assert "order" in settings, f"SymPy {sympy.__version__}: LatexPrinter()._settings has no 'order'"


def test_no_module_reaches_for_a_sympy_internal_elsewhere():
    """Private SymPy names are taken from kronsub/core/sympy_internals.py only."""
    pattern = re.compile(r"\._(args_sortkey|from_args|fromrep|new_rawargs|hashable_content|mpf_|prec|"
                         r"assumptions_orig|assumptions_rng|valid_nargs|parse_order|dod_to_DomainMatrix|new)\b"
                         r"|_assume_defined|Basic\.__new__\(|basic\.ordering_of_classes")
    found = []
    for path in sorted((ROOT / "kronsub").rglob("*.py")):
        if path.name == "sympy_internals.py":
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if pattern.search(code) and not code.lstrip().startswith(('"""', "``")) and "``" not in code:
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
