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
from kronsub.core.printed import LexStrPrinter, _complex, ordered_terms
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
