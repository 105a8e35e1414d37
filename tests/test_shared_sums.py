"""Shared sums of the trigonometric-polynomial algebra (`TrigAlgebra.shared_sum`): an entry
holding them is written exactly as the same entry multiplied out (`flat`), and the projection
of a chain forms each sum of the masses below a link once, its ``Mbar`` equal to the closed form."""
from __future__ import annotations

import random
import sys

import pytest
import sympy

import kronsub
from conftest import MODELS
from kronsub.core.simplify import compact
from kronsub.core import subspace
from kronsub.core.primitive import christoffel_terms
from kronsub.core.subspace import Subspace, project_inertia
from kronsub.core.trigpoly import TrigAlgebra, TrigPoly
from kronsub.model.loader import load_model

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402

q1, q2, q3 = sympy.symbols("q1 q2 q3")
m1, m2, m3, m4, l1, l2, k = sympy.symbols("m1 m2 m3 m4 l1 l2 k")


def _written_both_ways(algebra: TrigAlgebra, expr_of) -> None:
    """``expr_of(S)`` with the shared sums ``S`` and with their expressions gives one expression."""
    p = expr_of(True)
    flat = algebra.flat(p)
    assert not algebra.has_shared(flat)
    assert flat.key() == expr_of(False).key()
    assert algebra.to_expr(p) == algebra.to_expr(flat)
    assert compact(algebra, p) == compact(algebra, flat)


SUMS = [m1 + m2 + m3, m2 / 2 + 2 * m4, l1 * m1 + l1 * m2, -m3 + k * m4, m1 + m2]


@pytest.mark.parametrize("case", [
    lambda s: l1 * l2 * (s[0] + m4 / 2) * sympy.cos(q1 - q2),  # a chain's entry
    lambda s: -l1 * s[0] * sympy.sin(q1) + l2 * s[1] * sympy.sin(q1),  # two sums in one coefficient
    lambda s: l1 * s[2] * sympy.cos(q1) + l1 ** 2 * m3 * sympy.cos(q1),  # the sum holds the factor pulled out
    lambda s: s[0] * sympy.cos(q1) - (m1 + m2 + m3) * sympy.cos(q1) + sympy.sin(q2),  # cancels when written out
    lambda s: (s[0] - s[4]) * l2 * sympy.cos(q2),  # one monomial written out
    lambda s: s[3] * sympy.cos(q1) ** 2 + k * s[1] / l1,  # signs, negative powers, a multiple angle
    lambda s: s[4] * l1 * (sympy.cos(q1) * sympy.cos(q2) + sympy.sin(q1) * sympy.sin(q2))
    - m1 * l1 * sympy.cos(q1 - q2),
])
def test_an_entry_with_shared_sums_is_written_as_multiplied_out(case):
    algebra = TrigAlgebra([q1, q2, q3])
    shared = [algebra.shared_sum(algebra.from_expr(s)) for s in SUMS]

    def expr_of(with_shared: bool):
        if not with_shared:
            return algebra.from_expr(sympy.expand(case(SUMS)))
        symbols = sympy.symbols("S0:5")
        p = algebra.from_expr(sympy.expand(case(symbols)))
        return _substituted(algebra, p, symbols, shared)

    _written_both_ways(algebra, expr_of)


def _substituted(algebra: TrigAlgebra, p, symbols, shared):
    """``p`` (in atoms ``symbols``) with each symbol replaced by its shared sum, by products in the
    algebra (never through a sympy expression)."""
    index = {_atom_index(algebra, s): t for s, t in zip(symbols, shared)}
    out = TrigPoly()
    for key, coef in p.terms.items():
        for mono, c in coef.items():
            term = TrigPoly({key: {tuple((i, e) for i, e in mono if i not in index): c}})
            for i, e in mono:
                if i in index:
                    for _ in range(e):
                        term = term * index[i]
            out.add(term)
    return out


def _atom_index(algebra: TrigAlgebra, symbol: sympy.Symbol) -> int:
    (((index, _),), _), = algebra.from_expr(symbol).terms[(0, ())].items()
    return index


def test_random_entries_with_shared_sums_are_written_as_multiplied_out():
    rng = random.Random(34)
    atoms = [m1, m2, m3, m4, l1, l2, k]
    trig = [sympy.S.One, sympy.cos(q1), sympy.sin(q2), sympy.cos(q1 - q2), sympy.sin(q1 + q3), sympy.cos(2 * q3)]
    for _ in range(16):
        algebra = TrigAlgebra([q1, q2, q3])
        sums = [sympy.Add(*[rng.choice([-2, -1, sympy.Rational(1, 2), 1, 3]) * rng.choice(atoms)
                            * rng.choice([1, rng.choice(atoms)]) for _ in range(rng.randint(2, 4))])
                for _ in range(3)]
        sums = [s for s in sums if len(algebra.from_expr(s).terms.get((0, ()), {})) > 1]
        shared = [algebra.shared_sum(algebra.from_expr(s)) for s in sums]
        symbols = sympy.symbols(f"S0:{len(sums)}")
        terms = [rng.choice([-1, 1, sympy.Rational(3, 2)]) * rng.choice(atoms) ** rng.choice([1, 2, -1])
                 * rng.choice([*symbols, 1]) * rng.choice(trig) for _ in range(rng.randint(1, 6))]
        case = sympy.Add(*terms)

        def expr_of(with_shared: bool):
            if not with_shared:
                return algebra.from_expr(sympy.expand(case.xreplace(dict(zip(symbols, sums)))))
            return _substituted(algebra, algebra.from_expr(sympy.expand(case)), symbols, shared)

        _written_both_ways(algebra, expr_of)


def test_a_shared_sum_is_constant_in_the_coordinates():
    algebra = TrigAlgebra([q1])
    with pytest.raises(ValueError):
        algebra.shared_sum(algebra.from_expr(m1 * sympy.cos(q1) + m2))
    at = algebra.numeric({q1: 0.3, m1: 2.0, m2: 5.0})
    s = algebra.shared_sum(algebra.from_expr(m1 + m2))
    assert at(s * algebra.from_expr(sympy.cos(q1))) == pytest.approx(7.0 * 0.955336489125606)


def _projected(tmp_path, n: int, hinges: bool = False):
    path = tmp_path / f"chain{n}.yaml"
    path.write_text(chain_yaml(n, hinges=hinges))
    model = load_model(path, cache=False)
    sub = Subspace(model.primitive, model.coordinates, model.connection)
    return sub, project_inertia(sub, model.primitive)


@pytest.mark.parametrize("n", [3, 9, subspace.SHARED_FROM])
def test_the_chain_forms_each_sum_of_the_masses_below_a_link_once(tmp_path, monkeypatch, n):
    """``Mbar_ij = l_i l_j (m_j/2 + sum_(k>j) m_k) cos(q_i - q_j)`` (i < j), ``Mbar_ii = l_i^2 (m_i/3 +
    sum_(k>i) m_k)``: written out exactly so, from ``n - 2`` shared sums ``m_(k+1) + ... + m_n``
    (below `SHARED_FROM` coordinates only when asked for)."""
    monkeypatch.setattr(subspace, "SHARED_FROM", min(n, subspace.SHARED_FROM))
    sub, system = _projected(tmp_path, n)
    named = {s.name: s for s in system.mass_matrix.free_symbols}
    m, l, q = ([named[f"{x}{i}"] for i in range(1, n + 1)] for x in "mlq")
    below = [sum(m[i + 1:], sympy.S.Zero) for i in range(n)]
    for i in range(n):
        for j in range(i, n):
            want = l[i] ** 2 * (m[i] / 3 + below[i]) if i == j else \
                l[i] * l[j] * (m[j] / 2 + below[j]) * sympy.cos(q[i] - q[j])
            assert sympy.expand(system.mass_matrix[i, j] - want) == 0
            assert system.mass_matrix[j, i] == system.mass_matrix[i, j]
    expansions = [sub.algebra.to_expr(p) for p in sub.algebra.shared_sums.values()]
    assert sorted(expansions, key=sympy.default_sort_key) == \
        sorted((below[i] for i in range(n - 2)), key=sympy.default_sort_key)


@pytest.mark.parametrize("n", [4, 7])
def test_the_shared_sums_print_the_equations_of_the_rows(tmp_path, monkeypatch, n):
    """The chain (with a spring and a damper at every hinge) projected over shared sums and row
    by row: the same entries of ``Mbar`` and ``hbar``, as printed."""
    monkeypatch.setattr(subspace, "SHARED_FROM", 10**9)
    rows = _projected(tmp_path, n, hinges=True)[1]
    monkeypatch.setattr(subspace, "SHARED_FROM", 0)
    sub, shared = _projected(tmp_path, n, hinges=True)
    assert sub.algebra.shared_sums
    assert shared.mass_matrix == rows.mass_matrix
    assert shared.velocity_terms == rows.velocity_terms


def test_a_long_chain_is_derived_over_shared_sums(tmp_path):
    """From `SHARED_FROM` coordinates: ``hbar`` is Lagrange's operator on ``Mbar`` (the Christoffel
    form, an independent route), evaluated at a random state."""
    n = subspace.SHARED_FROM + 1
    sub, system = _projected(tmp_path, n)
    assert len(sub.algebra.shared_sums) == n - 2
    want = christoffel_terms(system.mass_matrix, system.coordinates, system.velocities)
    symbols = sorted(system.velocity_terms.free_symbols | want.free_symbols, key=lambda s: s.name)
    rng = random.Random(7)
    values = {s: rng.uniform(0.3, 1.2) for s in symbols}
    for got, expected in zip(system.velocity_terms, want):
        assert float(got.xreplace(values)) == pytest.approx(float(expected.xreplace(values)), rel=1e-10, abs=1e-10)


def test_the_chain_is_derived_as_before():
    """The bundled chain's equations, printed as the row-by-row projection printed them."""
    system = kronsub.load(MODELS / "chain" / "chain5.yaml", cache=False).derive(cache=False)
    assert str(system.mass_matrix[0, 1]) == "l1*l2*(m2 + 2*m3 + 2*m4 + 2*m5)*cos(q1 - q2)/2"
    assert str(system.velocity_terms[1]).startswith("-l1*l2*q1_dot**2*(m2 + 2*m3 + 2*m4 + 2*m5)*sin(q1 - q2)/2")
