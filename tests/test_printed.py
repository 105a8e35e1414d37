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
from kronsub.core.printed import LexStrPrinter, _complex, ordered_terms
from kronsub.emitters.latex_layout import LatexPrinter
from kronsub.emitters.report import ModelStrPrinter

REPO = Path(__file__).resolve().parent.parent
x, y, z, a, b = sympy.symbols("x y z a b", real=True)
ATOMS = [x, y, z, a, b, sympy.sin(x - y), sympy.cos(x), sympy.cos(2 * x - y), sympy.sqrt(1 - x ** 2),
         sympy.exp(a), sympy.Abs(y), sympy.pi, sympy.sqrt(2), sympy.Rational(3, 7), sympy.Float("0.125")]


def _coefficient(rng: random.Random, huge: bool = True):
    kind = rng.randrange(6) if huge else rng.choice((0, 1, 2, 4, 5))
    if kind == 0:
        return sympy.Integer(rng.randint(-9, 9) or 1)
    if kind == 1:
        return sympy.Rational(rng.randint(-50, 50) or 1, rng.randint(1, 60))
    if kind == 2:  # beyond 2**53: rounding of p/q is where a shortcut would differ
        return sympy.Rational(rng.getrandbits(90) + 1, rng.getrandbits(70) + 1) * rng.choice((1, -1))
    if kind == 3:  # beyond the shortcut's range: sympy's own path
        return sympy.Integer(rng.getrandbits(1100) + 1)
    if kind == 4:
        return sympy.Float(rng.uniform(-3, 3))
    return rng.choice((sympy.pi, sympy.sqrt(3), sympy.Rational(1, 3) * sympy.sqrt(2)))


def _random_expr(rng: random.Random, depth: int = 2):
    terms = []
    for _ in range(rng.randint(1, 6)):
        factors = [_coefficient(rng, huge=depth == 2)]  # no root of a huge integer
        for _ in range(rng.randint(0, 3)):
            atom = rng.choice(ATOMS)
            if depth and rng.random() < 0.25:
                atom = _random_expr(rng, depth - 1)
            factors.append(atom ** rng.choice((1, 1, 2, 3, -1, sympy.Rational(1, 2))))
        terms.append(sympy.Mul(*factors))
    return sympy.Add(*terms)


def test_complex_matches_sympy_on_rationals():
    rng = random.Random(5)
    for _ in range(2000):
        q = _coefficient(rng)
        assert _complex(q) == complex(q), q


@pytest.mark.parametrize("seed", range(6))
def test_ordered_terms_match_sympy(seed):
    rng = random.Random(seed)
    for _ in range(150):
        e = _random_expr(rng)
        if e.is_Add:
            assert ordered_terms(e) == e.as_ordered_terms(order="lex"), e


@pytest.mark.parametrize("seed", range(4))
def test_printers_match_sympy_on_random_expressions(seed):
    rng = random.Random(100 + seed)
    exprs = [_random_expr(rng, depth=0) for _ in range(40)]
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
