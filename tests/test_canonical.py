"""The algebra's sympy expressions are built in canonical form directly
(:mod:`kronsub.core.canonical`); they must be the very expressions sympy's evaluating
constructors build, so printed output does not change."""
import glob
import random
import warnings

import pytest
import sympy

import kronsub
from conftest import SLOW_MODELS
from kronsub.core import canonical, trigpoly
from kronsub.core.trigpoly import TrigAlgebra

q1, q2, q3 = sympy.symbols("q1 q2 q3")
a, b, c, u = sympy.symbols("a b c u", positive=True)
x = sympy.Symbol("x")
PIECES = [q1, q2, q3, a, b, c, x, sympy.Integer(2), sympy.Rational(1, 3), sympy.sqrt(2), sympy.pi,
          sympy.sqrt(1 - a * sympy.sin(q1)), sympy.asin(c * sympy.sin(q2)), sympy.Abs(x + 1), sympy.exp(x),
          sympy.exp(2 * x), sympy.sign(x + 1), x + 1, sympy.sin(a), sympy.cos(q1 ** 2)]


def _random_expr(rng: random.Random, depth: int = 3) -> sympy.Expr:
    if depth == 0:
        return rng.choice(PIECES)
    op = rng.choice(["add", "mul", "pow", "sin", "cos", "leaf"])
    if op == "leaf":
        return rng.choice(PIECES)
    if op in ("sin", "cos"):
        arg = rng.choice([q1, q2, q1 - q2, 2 * q3, q1 + q2 / 2, q1 + a])
        return getattr(sympy, op)(arg) * _random_expr(rng, depth - 1)
    if op == "pow":
        return _random_expr(rng, depth - 1) ** rng.choice([2, 3, -1, sympy.Rational(1, 2)])
    parts = [_random_expr(rng, depth - 1) for _ in range(rng.randint(2, 4))]
    return sympy.Add(*parts) if op == "add" else sympy.Mul(*parts)


@pytest.mark.parametrize("seed", range(12))
def test_random_expressions_build_as_sympy_would(seed):
    rng = random.Random(seed)
    algebra = TrigAlgebra((q1, q2, q3))
    checked = 0
    for _ in range(40):
        try:
            p = algebra.from_expr(_random_expr(rng))
        except trigpoly.ExpansionTooLarge:
            continue
        assert sympy.srepr(algebra.to_expr(p)) == sympy.srepr(algebra.evaluated_expr(p))
        for j in range(3):
            d = algebra.diff(p, j)
            assert sympy.srepr(algebra.to_expr(d)) == sympy.srepr(algebra.evaluated_expr(d))
        checked += 1
    assert checked > 20


def test_every_bundled_model_builds_as_sympy_would(monkeypatch, tmp_path):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "none"))
    seen = []
    fast = TrigAlgebra.to_expr

    def both(self, p):
        expr = fast(self, p)
        seen.append(sympy.srepr(expr) == sympy.srepr(self.evaluated_expr(p)))
        return expr

    monkeypatch.setattr(TrigAlgebra, "to_expr", both)
    files = sorted(f for f in glob.glob("models/**/*.yaml", recursive=True) if f not in SLOW_MODELS)
    assert len(files) > 8
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for path in files:
            kronsub.load(path).derive(cache=False)
    assert len(seen) > 200 and all(seen)


def test_monomial_products_merge_like_a_dictionary_would():
    from kronsub.core.trigpoly import _mono_mul

    def reference(a, b):
        out = dict(a)
        for i, e in b:
            out[i] = out.get(i, 0) + e
        return tuple(sorted((i, e) for i, e in out.items() if e))

    rng = random.Random(7)
    for _ in range(3000):
        a, b = (tuple(sorted({rng.randint(0, 6): rng.choice([1, 2, -1, -2, sympy.Rational(1, 2)])
                              for _ in range(rng.randint(0, 4))}.items())) for _ in range(2))
        assert _mono_mul(a, b) == reference(a, b), (a, b)


def test_a_coefficient_is_divided_by_its_common_monomial_as_a_dictionary_would():
    """`_common_monomial` and `_divided` (the common factor pulled out of a coefficient by
    `to_expr`) against the plain dictionary arithmetic they stand for."""
    from kronsub.core.trigpoly import Q as _Q, common_monomial as _common_monomial, rational_content as _content, _divided

    def common_reference(coef):
        monos = [dict(m) for m in coef]
        out = {}
        for i, e in monos[0].items():
            es = [m.get(i) for m in monos]
            if all(f is not None and (f > 0) == (e > 0) for f in es):
                out[i] = min(es) if e > 0 else max(es)
        return tuple(sorted(out.items()))

    def divided_reference(coef, common, content):
        out = {}
        for m, c in coef.items():
            d = dict(m)
            for i, e in common:
                d[i] -= e
            out[tuple(sorted((i, e) for i, e in d.items() if e))] = c if content == 1 else c / content
        return out

    rng = random.Random(5)
    exponents = [1, 2, 3, -1, -2, _Q(1, 2), _Q(-3, 2)]
    for _ in range(3000):
        coef = {}
        for _ in range(rng.randint(1, 5)):
            mono = tuple(sorted({rng.randint(0, 5): rng.choice(exponents) for _ in range(rng.randint(0, 4))}.items()))
            coef[mono] = rng.choice([1, 2, -3, 6, _Q(1, 2), _Q(-5, 6)])
        common = _common_monomial(coef)
        assert common == common_reference(coef)
        content = _content(coef.values())
        divided, reference = _divided(coef, common, content), divided_reference(coef, common, content)
        assert list(divided.items()) == list(reference.items())
        assert [type(c) for c in divided.values()] == [type(c) for c in reference.values()]


def test_the_order_key_sorts_as_sympy_compares():
    from functools import cmp_to_key

    from kronsub.core.canonical import order_key

    rng = random.Random(3)
    exprs = [_random_expr(rng, 2) for _ in range(150)] + PIECES + [sympy.Float(0.5), sympy.Float(-2.25), x ** 2]
    for _ in range(40):
        sample = rng.sample(exprs, 12)
        assert sorted(sample, key=order_key) == sorted(sample, key=cmp_to_key(sympy.Basic.compare))


def test_sines_and_cosines_are_the_objects_sympy_evaluates_to():
    from kronsub.core.trigpoly import COS, SIN

    rng = random.Random(11)
    names = ["q1", "q2", "q10", "q9", "theta", "phi", "a_b", "Z", "x_dot", "q11", "q3", "q12", "x1"]
    coords = [sympy.Symbol(n) for n in names] + [sympy.Symbol("r", real=True)]
    algebra = TrigAlgebra(coords)
    for _ in range(600):  # up to 12 coordinates in one angle: name orders beyond one digit
        picked = rng.sample(range(len(coords)), rng.choice([1, 2, 2, 3, 4, 11, 12]))
        freq = tuple(sorted((i, sympy.Integer(rng.choice([1, -1, 2, -2, 3])) / rng.choice([1, 1, 2]))
                            for i in picked))
        arg = sympy.Add(*[c * coords[i] for i, c in freq])
        freq = tuple((i, int(c) if c.is_Integer else trigpoly.Q(int(c.p), int(c.q))) for i, c in freq)
        if freq[0][1] < 0:
            continue  # the algebra keeps the first frequency positive
        assert sympy.srepr(algebra.trig_expr(COS, freq)) == sympy.srepr(sympy.cos(arg))
        assert sympy.srepr(algebra.trig_expr(SIN, freq)) == sympy.srepr(sympy.sin(arg))


@pytest.mark.parametrize("seed", range(4))
def test_the_join_count_is_a_lower_bound_of_count_ops(seed):
    """`simplify._joins_exceed` lets `tidy` skip a large entry without counting it: it may say
    "more than k" only where `count_ops` says so too."""
    from kronsub.core.simplify import _joins_exceed

    rng = random.Random(seed)
    told = 0
    for _ in range(60):
        e = sympy.expand(_random_expr(rng)) if rng.random() < 0.5 else _random_expr(rng)
        ops = sympy.count_ops(e)
        for limit in (0, 1, 3, 8, 20, 40):
            if _joins_exceed(e, limit):
                told += 1
                assert ops > limit, (e, ops, limit)
    assert told > 30


def test_kinetic_energy_is_the_expanded_quadratic_form(monkeypatch, tmp_path):
    """``T`` is built entry by entry (and once per system): the very expression of expanding
    ``qdot^T Mbar qdot / 2`` whole, on every bundled model."""
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "none"))
    models = sorted([f for f in glob.glob("models/*/*.yaml") if f not in SLOW_MODELS] + glob.glob("tests/models/*.yaml"))
    assert len(models) > 10
    for path in models:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            system = kronsub.load(path).derive()
        qd = sympy.Matrix(system.velocities)
        whole = sympy.expand((qd.T * system.mass_matrix * qd)[0, 0] / 2)
        assert sympy.srepr(system.kinetic_energy) == sympy.srepr(whole), path
        assert system.kinetic_energy is system.kinetic_energy


def test_function_values_are_the_objects_sympy_builds_unevaluated():
    """`canonical.function` skips sympy's per-value set of argument counts, nothing else."""
    from kronsub.core.canonical import function
    from kronsub.model.cache_format import FUNCTIONS

    for name, cls in FUNCTIONS.items():
        args = (q1 - q2, a) if name == "atan2" else (q1 - q2 / 3,)
        ours, theirs = function(cls, *args), cls(*args, evaluate=False)
        assert type(ours) is type(theirs) and ours == theirs and hash(ours) == hash(theirs)
        assert sympy.srepr(ours) == sympy.srepr(theirs) and ours.nargs == theirs.nargs
        assert ours.is_real == theirs.is_real and ours.free_symbols == theirs.free_symbols
    assert function(sympy.cos, -q1) != sympy.cos(-q1)  # unevaluated, as asked: the sign stays


@pytest.mark.parametrize("cls", [sympy.Matrix, sympy.ImmutableMatrix])
def test_matrix_is_the_matrix_sympy_builds(cls):
    """``canonical.matrix`` against sympy's own constructor: equal, of the same domain, and
    the zeros sympy leaves out of its sparse form left out (or kept) alike."""
    x, y = sympy.symbols("x y")
    kinds = [sympy.S.Zero, sympy.Integer(0), sympy.Float(0.0), sympy.Rational(1, 2), sympy.Integer(3),
             sympy.Float(2.5), x, -x, x * y, sympy.cos(x) + y, x ** 2, sympy.pi]
    rng = random.Random(5)
    for _ in range(200):
        rows, cols = rng.randint(0, 4), rng.randint(1, 4)
        pool = rng.choice([kinds, kinds[:2] + [sympy.Integer(3)], kinds[:2] + [sympy.Rational(1, 2)]])
        entries = [rng.choice(pool) for _ in range(rows * cols)]
        ours, theirs = canonical.matrix(rows, cols, entries, cls), cls(rows, cols, entries)
        assert type(ours) is type(theirs) and ours == theirs
        assert ours._rep.domain == theirs._rep.domain and ours._rep.to_sdm() == theirs._rep.to_sdm()
    with pytest.raises(ValueError):
        canonical.matrix(2, 2, [x])


def test_a_remembered_coefficient_is_the_one_sympy_builds_whatever_the_order():
    """``TrigAlgebra._coefficient`` builds each distinct coefficient once: the same sum met
    again in another order of its terms is the same expression, sympy's own."""
    m = sympy.symbols("m1:6", real=True)
    q = sympy.symbols("q1:3", real=True)
    algebra = TrigAlgebra(q)
    p = algebra.from_expr(sympy.Rational(1, 2) * m[0] + m[1] + 3 * m[2] * m[3] - m[4] ** 2)
    (coef,) = p.terms.values()
    first = algebra._coefficient(dict(coef))
    again = algebra._coefficient(dict(reversed(list(coef.items()))))
    assert again is first
    assert sympy.srepr(first) == sympy.srepr(algebra.coefficient_expr(coef))


def test_the_sign_sympy_takes_out_of_an_angle_of_many_coordinates():
    """Ties of as many minus as plus signs are broken by the order of the names, beyond ten
    coordinates too (``q10`` sorts before ``q2``)."""
    rng = random.Random(5)
    coords = sympy.symbols("q1:15")
    algebra = TrigAlgebra(coords)
    for _ in range(300):
        picked = sorted(rng.sample(range(len(coords)), rng.choice([2, 4, 10, 12, 14])))
        signs = [1] * (len(picked) // 2) + [-1] * (len(picked) // 2)
        rng.shuffle(signs)
        freq = tuple((i, s * rng.choice([1, 2])) for i, s in zip(picked, signs))
        arg = sympy.Add(*[c * coords[i] for i, c in freq])
        assert algebra._minus_sign(freq) == arg.could_extract_minus_sign()


def test_ones_at_is_the_matrix_of_those_integers():
    """`canonical.ones_at` (a renaming's C) is the very matrix `canonical.matrix` makes of the
    same ones and zeros: entries, kind and stored domain."""
    for rows, cols, columns in ((1, 1, [0]), (3, 2, [1, 0, 1]), (4, 4, [2, 0, 3, 1])):
        entries = [sympy.Integer(1 if columns[i] == j else 0) for i in range(rows) for j in range(cols)]
        fast, slow = canonical.ones_at(rows, cols, columns), canonical.matrix(rows, cols, entries)
        assert type(fast) is type(slow) and fast == slow and fast._rep == slow._rep
