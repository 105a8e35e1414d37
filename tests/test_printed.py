"""The faster printers (kronsub/core/printed.py) print exactly what sympy's do."""
from __future__ import annotations

import random
from functools import lru_cache
from pathlib import Path

import pytest
import sympy
from sympy.printing.latex import LatexPrinter as SympyLatex
from sympy.printing.str import StrPrinter

import kronsub
from helpers.expressions import random_coefficient, random_sum
from helpers.expressions import x as ATOM_X, y as ATOM_Y
from kronsub.core.printed import LexStrPrinter, _complex, _sort_key, ordered_terms
from kronsub.core.simplify import _factor_terms_of
from kronsub.emitters.latex_layout import LatexPrinter
from kronsub.emitters.report import ModelStrPrinter

REPO = Path(__file__).resolve().parent.parent
def test_complex_matches_sympy_on_rationals():
    rng = random.Random(5)
    for _ in range(2000):
        q = random_coefficient(rng)
        assert _complex(q) == complex(q), q


@pytest.mark.parametrize("seed", range(6))
def test_ordered_terms_match_sympy(seed):
    rng = random.Random(seed)
    for _ in range(150):
        e = random_sum(rng)
        if e.is_Add:
            assert ordered_terms(e) == e.as_ordered_terms(order="lex"), e


@pytest.mark.parametrize("seed", range(4))
def test_printers_match_sympy_on_random_expressions(seed):
    rng = random.Random(100 + seed)
    exprs = [random_sum(rng, depth=0) for _ in range(40)]
    lex, model, latex = LexStrPrinter(), ModelStrPrinter(), LatexPrinter({"order": "lex"})
    for e in exprs + exprs[::-1]:  # again, now remembered
        assert lex.doprint(e) == sympy.sstr(e, order="lex")
        assert latex._print(e) == SympyLatex({"order": "lex"})._print(e)
        assert model.doprint(e) == _ForgetfulModelPrinter().doprint(e)


class _ForgetfulModelPrinter(StrPrinter):
    """The model's printer on sympy's own machinery alone."""

    def __init__(self):
        super().__init__({"order": "lex"})
        self.reserved = frozenset()
        self.renamed = {}


for _k, _v in vars(ModelStrPrinter).items():
    if _k.startswith("_print_") or _k == "_call":
        setattr(_ForgetfulModelPrinter, _k, _v)


MODELS = sorted(p.relative_to(REPO).as_posix() for p in [*(REPO / "models" / "hoffmann").glob("*.yaml"),
                                                           *(REPO / "models" / "chain").glob("*.yaml"),
                                                           REPO / "models" / "examples" / "watt_governor.yaml"])


@lru_cache(maxsize=None)
def _derived(name):
    return kronsub.load(REPO / name).derive()


@pytest.mark.parametrize("name", MODELS)
def test_printers_match_sympy_on_bundled_models(name):
    system = _derived(name)
    entries = [*system.mass_matrix, *system.velocity_terms, *system.forces, system.potential_energy]
    lex, latex = LexStrPrinter(), LatexPrinter({"order": "lex"})
    for e in entries:
        assert lex.doprint(e) == sympy.sstr(e, order="lex")
        assert latex._print(e) == SympyLatex({"order": "lex"})._print(e)


def test_ordered_terms_match_sympy_over_many_bases():
    """Sums whose terms each hold a few of many bases, to positive and negative powers (a
    large system's kinetic energy): the order sympy gives through its dense exponent vectors."""
    rng = random.Random(34)
    bases = [*sympy.symbols("a b c d e"), sympy.sin(sympy.Symbol("q")), sympy.sqrt(sympy.Symbol("r")),
             sympy.Symbol("s") + 1]
    for _ in range(200):
        terms = []
        for _ in range(rng.randint(2, 9)):
            factors = [rng.choice(bases) ** rng.choice([-2, -1, 1, 1, 2, 3]) for _ in range(rng.randint(0, 4))]
            terms.append(sympy.Mul(rng.choice([1, -1, 2, sympy.Rational(-3, 4)]), *factors))
        e = sympy.Add(*terms)
        if e.is_Add:
            assert ordered_terms(e) == e.as_ordered_terms(order="lex"), e


def _random_expr(rng, depth):
    """Products, sums, powers and functions of symbols and numbers, some products unevaluated
    (nested, several rationals, a rational after the first place) and some numeric sums."""
    x, y, z = sympy.symbols("x y z")
    atoms = [x, y, z, -x, x - y, sympy.sin(x), sympy.cos(x - y), sympy.Rational(1, 2), sympy.Integer(-3),
             sympy.Rational(-2, 3), sympy.sqrt(2), sympy.pi, sympy.Float(1.5), sympy.E, sympy.I, sympy.Integer(2)]
    if depth == 0 or rng.random() < 0.25:
        return rng.choice(atoms)
    u, kind = _random_expr(rng, depth - 1), rng.randrange(8)
    if kind < 2:
        return u + _random_expr(rng, depth - 1)
    if kind < 4:
        return u * _random_expr(rng, depth - 1)
    if kind == 4:
        return u ** rng.choice([2, -1, -2, sympy.Rational(1, 2), sympy.Rational(-1, 2), x])
    if kind == 5:
        return sympy.Mul(u, _random_expr(rng, depth - 1), evaluate=False)
    if kind == 6:
        return sympy.cos(u)
    return -u


@pytest.mark.parametrize("seed", range(3))
def test_products_print_as_sympy_prints_them(seed):
    """RememberingStr's products (remembered sort keys) against sympy's ``_print_Mul``."""
    rng = random.Random(200 + seed)
    lex = LexStrPrinter()  # one printer for all: what it remembers must not leak between expressions
    for _ in range(400):
        e = _random_expr(rng, 4)
        assert lex.doprint(e) == StrPrinter({"order": "lex"}).doprint(e), sympy.srepr(e)


@pytest.mark.parametrize("seed", range(3))
def test_remembered_sort_keys_are_sympys(seed):
    rng = random.Random(300 + seed)
    for _ in range(400):
        e = _random_expr(rng, 4)
        assert _sort_key(e) == sympy.default_sort_key(e), sympy.srepr(e)


@pytest.mark.parametrize("seed", range(3))
def test_factor_terms_of_a_product_is_sympys(seed):
    """simplify's factor_terms of a product, from its factors remembered (a difference of
    symbols its own), against ``sympy.factor_terms`` of the whole."""
    rng = random.Random(400 + seed)
    for _ in range(300):
        e = _random_expr(rng, 3) * _random_expr(rng, 3) * sympy.cos(_random_expr(rng, 1))
        expected = sympy.factor_terms(e)
        got = _factor_terms_of(e)
        assert got == expected and sympy.srepr(got) == sympy.srepr(expected), sympy.srepr(e)


def _random_entry(rng):
    """An entry of a projected metric's kind: a product of symbols, sums, sines and cosines
    with a rational coefficient, or one factor, a rational, zero, or (for the formed route)
    a reciprocal, a root, a float or an exponential among the factors."""
    x, y = ATOM_X, ATOM_Y  # (a symbol named as another but of other assumptions would tie in sympy's key)
    m, l = sympy.symbols("m l")
    factors = [x, y, m, l, m + 2 * l, sympy.cos(x - y), sympy.sin(x), l ** 2, (m + l) ** 2, 1 / (m + l),
               sympy.sqrt(1 - x ** 2), sympy.exp(y), sympy.Float(0.5), sympy.sqrt(2), sympy.Symbol("x_dot")]
    kind = rng.randrange(10)
    if kind == 0:
        return rng.choice([sympy.S.Zero, sympy.Integer(3), sympy.Rational(-2, 5)])
    if kind == 1:
        return rng.choice(factors)
    coefficient = rng.choice([1, 1, -1, 2, sympy.Rational(1, 2), sympy.Rational(-3, 4), sympy.Rational(5, 3)])
    return sympy.Mul(coefficient, *rng.sample(factors, rng.randint(1, 4)))


@pytest.mark.parametrize("seed", range(4))
def test_sum_of_products_prints_the_sum_sympy_forms(seed):
    """Sums of an entry times velocities (``Mbar qddot + hbar``, ``T``) printed from the entries'
    factors against sympy's printing of the sum formed, including the cases it hands back
    to the formed sum (like terms, a number, a velocity the entry holds)."""
    rng = random.Random(500 + seed)
    v = sympy.symbols("x_dot y_dot q_ddot")
    extras = [(v[0],), (v[1],), (v[2],), (v[0], v[1]), (v[0] ** 2,), (v[1] ** 2, v[2]), ()]
    printer = ModelStrPrinter()  # one for all: what it remembers must not leak between sums
    for _ in range(300):
        products = [(_random_entry(rng), sympy.Rational(rng.choice([1, 1, 1, -1, 2]), rng.choice([1, 1, 2])),
                     rng.choice(extras)) for _ in range(rng.randint(0, 6))]
        others = [t for t in sympy.Add.make_args(random_sum(rng, depth=1)) if rng.random() < 0.5]
        formed = sympy.Add(*[sympy.Mul(c, e, *x) for e, c, x in products], *others)
        assert printer.sum_of_products(products, others) == _ForgetfulModelPrinter().doprint(formed), formed


@pytest.mark.parametrize("name", MODELS)
def test_equations_and_kinetic_energy_printed_from_entries_as_formed(name):
    """The report's ``Mbar qddot + hbar`` and ``T`` by the printer's sums of products equal
    the same sums formed and printed (the LaTeX report's route)."""
    from kronsub.emitters.report import build_report, sum_printer

    system = _derived(name)
    printer = ModelStrPrinter()
    direct = build_report(system, printer.doprint, sums=printer.sum_of_products)
    formed = build_report(system, ModelStrPrinter().doprint, sums=sum_printer(ModelStrPrinter().doprint))
    assert direct["equations"] == formed["equations"]
    assert direct["kinetic_energy"] == formed["kinetic_energy"]
