"""``kronsub check`` does not derive: the rank test of ``C = dx/dxbar`` evaluates ``C`` in
floating point (kronsub/core/numeric_jacobian.py), so a 200-rod chain is checked in seconds
(it took minutes when ``C`` was formed symbolically)."""
from __future__ import annotations

import subprocess
import sys

import pytest
import sympy

from conftest import MODELS
from kronsub.core.numeric_jacobian import jacobian

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402


def test_check_of_a_200_rod_chain_finishes(tmp_path):
    """A hang guard, not a timing: the fixed check answers in a few seconds."""
    path = tmp_path / "chain200.yaml"
    path.write_text(chain_yaml(200))
    done = subprocess.run([sys.executable, "-m", "kronsub", "check", str(path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "OK (200 generalized coordinates, 200 components, 1 effect)" in done.stdout
    assert "Warning" not in done.stderr


q1, q2, l, k = sympy.symbols("q1 q2 l k", real=True)
EXPRESSIONS = [
    l * sympy.sin(q1) + l / 2 * sympy.cos(q1 - q2),
    sympy.sqrt(l**2 + q1**2 - 2 * l * q1 * sympy.cos(q2)),
    sympy.atan2(l * sympy.sin(q2), 1 + q1) + sympy.exp(q1 * q2) - sympy.log(2 + q2**2),
    q1**q2 + sympy.tan(q1) * sympy.asin(q2 / 3) + sympy.atan(q1) / sympy.cosh(q2),
    sympy.Abs(q1 - 1) * q2 + sympy.sign(q2) * q1 + sympy.Piecewise((q1**2, q2 > 0), (q2, True)),
    sympy.sec(q1) + sympy.Max(q1, q2) * k,
]


@pytest.mark.parametrize("expr", EXPRESSIONS, ids=range(len(EXPRESSIONS)))
def test_numeric_jacobian_is_sympys(expr):
    values = {q1: 0.7, q2: 0.4, l: 1.3, k: 2.0}
    got = jacobian([expr], [q1, q2], values)[0]
    want = [float(sympy.diff(expr, q).subs(values).replace(sympy.DiracDelta, lambda *a: 0)) for q in (q1, q2)]
    assert got == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_numeric_jacobian_outside_the_domain_raises():
    with pytest.raises(ValueError):
        jacobian([sympy.sqrt(q1 - 1)], [q1], {q1: 0.5})
    with pytest.raises(ValueError):
        jacobian([sympy.asin(q1)], [q1], {q1: 2.0})
    with pytest.raises(OverflowError):
        jacobian([1 / q1], [q1], {q1: 1e-300})
    with pytest.raises(TypeError):  # a complex value
        jacobian([sympy.Piecewise((sympy.sqrt(q1 - 1), q1 < 1), (q1, True))], [q1], {q1: 0.5})


def test_the_jacobian_is_charged_to_the_work_budget():
    """Its work counts against the command's budget (kronsub/budget.py): a small one stops it,
    naming what grew."""
    from kronsub import budget

    qs = sympy.symbols("q1:41")
    rows = [sum(sympy.sin(q) for q in qs[:i + 1]) for i in range(len(qs))]
    with budget.limited(units=500):
        with pytest.raises(budget.WorkBudgetExceeded, match="the Jacobian C = dx/dxbar of the connection"):
            jacobian(rows, qs, {q: 0.1 for q in qs})
    with budget.limited(units=10**6):
        jacobian(rows, qs, {q: 0.1 for q in qs})
