"""``cse``'s "basic" rewritings (``BASIC_NODES`` in kronsub/emitters/numeric.py) are an
optimisation only: the generated right-hand sides compute the same function with them and
without them, to 1e-12 relative, for a planar chain, closed loops, a 3-D body and the spatial
chain on ball joints; in the numpy module and in the blocks the C is printed from."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import sympy
from sympy.simplify.cse_main import basic_optimizations

import kronsub
from kronsub.emitters import numeric
from kronsub.emitters.code import emit_python

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "models" / "chain"))
from generate import chain_yaml  # noqa: E402
from generate_spatial import spatial_chain_yaml  # noqa: E402

MODELS = {
    "chain3": lambda: kronsub.load("chain3.yaml", text=chain_yaml(3, hinges=True)),
    "four_bar": lambda: kronsub.load(ROOT / "models/examples/four_bar.yaml"),
    "system2_implicit": lambda: kronsub.load(ROOT / "models/hoffmann/system2_implicit.yaml"),
    "top_3d": lambda: kronsub.load(ROOT / "tests/models/top_3d.yaml"),
    "spatial1": lambda: kronsub.load("spatial1.yaml", text=spatial_chain_yaml(1)),
}
EXPLICIT = ("chain3", "top_3d")  # the C of a closed loop also solves for w[]: checked through numpy


@pytest.fixture(scope="module")
def systems():
    return {}


def _system(systems, name):
    if name not in systems:
        systems[name] = MODELS[name]().derive()
    return systems[name]


def _module(system, nodes: int, monkeypatch) -> dict:
    monkeypatch.setattr(numeric, "BASIC_NODES", nodes)
    namespace: dict = {}
    (generated,) = emit_python(system, "model")
    exec(compile(generated.text, "<generated>", "exec"), namespace)
    return namespace


def _close(a, b) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, float(np.max(np.abs(b)))))


def _states(system, count=4, seed=34):
    rng = np.random.default_rng(seed)
    n = len(system.coordinates)
    for _ in range(count):
        yield rng.uniform(0, 2), rng.uniform(-0.4, 0.4, 2 * n), rng.uniform(0.8, 1.2, len(system.parameters))


@pytest.mark.parametrize("name", ["chain3", "four_bar", "system2_implicit", "spatial1"])
def test_numpy_module_is_the_same_function(name, systems, monkeypatch):
    system = _system(systems, name)
    rewritten, plain = _module(system, 10**9, monkeypatch), _module(system, 0, monkeypatch)
    checked = 0
    for t, y, param in _states(system):
        try:
            expected = rewritten["rhs"](t, y, param)
        except (np.linalg.LinAlgError, ArithmeticError, ValueError):
            continue  # a closed loop's random state off its assembly: no right-hand side there
        assert _close(plain["rhs"](t, y, param), expected)
        checked += 1
    assert checked >= 2


def _evaluate(block: numeric.Block, values: dict) -> dict:
    """``block``'s outputs by target, its temporaries evaluated in order (``NearAxis`` by its
    own numeric value)."""
    env = {symbol: sympy.Float(value, 30) for symbol, value in values.items()}
    for symbol, expr in block.temporaries:
        env[symbol] = sympy.sympify(expr.xreplace(env)).evalf(30)
    return {target: float(sympy.sympify(expr.xreplace(env)).evalf(30)) for target, expr in block.outputs}


@pytest.mark.parametrize("name", EXPLICIT)
def test_c_blocks_are_the_same_function(name, systems, monkeypatch):
    system = _system(systems, name)
    n, k = len(system.coordinates), len(system.parameters)
    prepared = {}
    for nodes in (10**9, 0):
        monkeypatch.setattr(numeric, "BASIC_NODES", nodes)
        prepared[nodes] = numeric.prepare(system, guarded_angles=True)
    for t, y, param in _states(system, count=2):
        values = {sympy.Symbol(f"q[{i}]"): y[i] for i in range(n)}
        values.update({sympy.Symbol(f"qd[{i}]"): y[n + i] for i in range(n)})
        values.update({sympy.Symbol(f"pre[{i}]"): param[i] for i in range(k)})
        values.update({sympy.Symbol(f"param[{i}]"): param[i] for i in range(k)})
        values[sympy.Symbol("t")] = t
        assert system.implicit is None
        results = []
        for model in prepared.values():
            env = dict(values)
            env.update({sympy.Symbol(target): value for target, value in _evaluate(model.prepare, values).items()})
            out = _evaluate(model.equations, env)
            out.update({f"canonical {target}": v for target, v in _evaluate(model.canonical, env).items()})
            results.append(out)
        assert results[0].keys() == results[1].keys()
        keys = sorted(results[0])
        assert _close([results[1][key] for key in keys], [results[0][key] for key in keys])


X, Y, Z = sympy.symbols("x y z")


@pytest.mark.parametrize("expr", [X * Y + X * Z, -X - Y, 2 * X + 4 * Y, X / 2 + Y, sympy.sin(X * Y + X * Z) + Z,
                                  Z * (Y - X) ** 2 + Y, sympy.Float(1.5) * X + Y, X ** -1 + Y])
def test_what_the_rewritings_may_change_is_not_settled(expr):
    assert not numeric.settled(expr)


@pytest.mark.parametrize("expr", [X * Y + Z, X - Y, sympy.cos(X) * sympy.sin(Y) + 2 * Z * X ** 2 - 3 * Y,
                                  Z * sympy.sin(X + Y) * (X + 1) + Y, Z * (X - Y) ** 2 + Y])
def test_a_settled_expression_is_what_the_rewritings_return(expr):
    assert numeric.settled(expr)
    rewritten = expr
    for rewrite, _ in basic_optimizations:
        rewritten = rewrite(rewritten)
    assert rewritten == expr


@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_rewritings_skip_only_what_they_leave_as_it_is(name, systems, monkeypatch):
    """Every entry :func:`numeric.settled` lets through unrewritten comes back unchanged from
    the rewritings themselves, so the generated code is what the rewritings made before."""
    system = _system(systems, name)
    real, passed = numeric.settled, []

    def checked(expr):
        verdict = real(expr)
        if verdict:
            passed.append(expr)
        return verdict

    monkeypatch.setattr(numeric, "settled", checked)
    numeric.prepare(system, guarded_angles=True)
    for expr in passed:
        rewritten = expr
        for rewrite, _ in basic_optimizations:
            rewritten = rewrite(rewritten)
        assert rewritten == expr
    assert passed or name != "chain3"
