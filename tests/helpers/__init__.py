"""Test helpers shared by the test modules (a test module never imports another): symbols by
name, numeric comparison of expressions, generated code imported.

Submodules: :mod:`helpers.compare` (kronsub against a hand derivation at random states),
:mod:`helpers.generated` (generated C and numpy against the symbolic equations),
:mod:`helpers.systems` (systems and starting values of the simulation tests),
:mod:`helpers.expressions` (random expressions), :mod:`helpers.deadline` (a time limit)."""
from __future__ import annotations

import numpy as np
import sympy

from kronsub.core.symbols import symbol


def S(names: str):
    """kronsub's (real) symbols by name: ``S('m1 m2')``."""
    out = [symbol(n) for n in names.split()]
    return out[0] if len(out) == 1 else out


def by_name(expr):
    """Replace every symbol by a plain symbol of the same name (to compare across conventions)."""
    expr = sympy.sympify(expr)
    return expr.xreplace({s: sympy.Symbol(s.name) for s in expr.free_symbols})


def assert_same(a, b):
    """Exact symbolic equality of two expressions, up to symbol assumptions."""
    if isinstance(a, sympy.MatrixBase):
        diff = (a - b).applyfunc(lambda e: sympy.simplify(by_name(e)))
        assert diff.is_zero_matrix, f"{a}  !=  {b}  (difference {diff})"
        return
    diff = sympy.simplify(by_name(a) - by_name(b))
    assert diff == 0, f"{a}  !=  {b}  (difference {diff})"


def random_values(names, rng, low=0.3, high=1.7):
    return {n: float(rng.uniform(low, high)) for n in sorted(names)}


def evaluate(expr, values: dict[str, float]) -> float:
    expr = by_name(expr)
    subs = {sympy.Symbol(k): v for k, v in values.items()}
    return float(expr.xreplace(subs).evalf(30))


def constraint_residual(system, header: list[str], data: np.ndarray) -> float:
    """The largest |g| of a closed-loop run's CSV rows, with the constraint expressions
    lambdified apart from the generated code (the dependent coordinates as the run reports them)."""
    col = {name: i for i, name in enumerate(header)}
    imp = system.implicit
    values = {p.symbol: p.value for p in system.parameters}
    y = list(imp.independent) + list(imp.dependent)
    g = sympy.lambdify(y, [c.expression.xreplace(values) for c in imp.constraints], "numpy")
    return float(np.max(np.abs(np.array(g(*[data[:, col[q.name]] for q in y]), dtype=float))))


def _values(system, params: dict):
    return {p.symbol: params[p.name] for p in system.parameters if p.name in params}


_LAMBDIFIED: dict = {}


def implicit_numeric(system, params: dict):
    """Numbers of a derived system (with implicit constraints or not): ``(Mbar, hbar, fbar, T)`` at ``(q, qdot)``, intermediates by Newton on the branch."""
    values = _values(system, params)
    from kronsub.core.constraints import Intermediates

    ev = Intermediates(system.implicit, values) if system.implicit is not None else None
    inter = list(system.implicit.intermediates) if ev else []
    symbols = [p.symbol for p in system.parameters]
    if id(system) not in _LAMBDIFIED:
        exprs = [system.mass_matrix, system.velocity_terms, system.forces, sympy.Matrix([system.kinetic_energy])]
        args = list(system.coordinates) + list(system.velocities) + inter + symbols
        _LAMBDIFIED[id(system)] = (system, sympy.lambdify(args, exprs, "numpy"))
    fn = _LAMBDIFIED[id(system)][1]
    n = len(system.coordinates)

    def at(q, qdot, guess=None):
        extra = []
        if ev is not None:
            if guess is not None:
                ev.guess = np.array(guess, dtype=float)
            w = ev.at(q, qdot)
            extra = [w[s] for s in inter]
        M, h, f, T = fn(*q, *qdot, *extra, *[float(values.get(s, 0.0)) for s in symbols])
        return (np.array(M, float).reshape(n, n), np.array(h, float).reshape(n), np.array(f, float).reshape(n),
                float(np.array(T, float).ravel()[0]))

    at.evaluator = ev
    return at


def close(a: float, b: float, rel=1e-12, abs_=1e-12) -> bool:
    return bool(np.isclose(a, b, rtol=rel, atol=abs_))


# A compound pendulum (a pinned rod with its own inertia), for the API and linearisation tests.
COMPOUND = """
name: compound pendulum
parameters:
  m: {value: 2, unit: kg}
  L: {value: 1.5, unit: m}
  I: {value: 0.3, unit: kg m^2}
  g: {value: 9.81}
components:
  rod: {type: pinned_rod, parameters: {mass: m, length: L, inertia: I}, coordinates: [theta]}
coordinates: [theta]
effects:
  gravity: {type: gravity}
initial: {theta: 0.4}
"""


def Rx(u):
    """The rotation by ``u`` about x (independent references of spatial models)."""
    return sympy.Matrix([[1, 0, 0], [0, sympy.cos(u), -sympy.sin(u)], [0, sympy.sin(u), sympy.cos(u)]])


def Ry(u):
    """The rotation by ``u`` about y."""
    return sympy.Matrix([[sympy.cos(u), 0, sympy.sin(u)], [0, 1, 0], [-sympy.sin(u), 0, sympy.cos(u)]])


def Rz(u):
    """The rotation by ``u`` about z."""
    return sympy.Matrix([[sympy.cos(u), -sympy.sin(u), 0], [sympy.sin(u), sympy.cos(u), 0], [0, 0, 1]])


def generated_numpy_module(tmp_path, model_path):
    """The numpy module ``kronsub codegen --lang python`` writes for ``model_path``, imported."""
    import importlib.util
    from pathlib import Path

    from click.testing import CliRunner

    from kronsub.cli import main

    model_path = Path(model_path)
    result = CliRunner().invoke(main, ["codegen", str(model_path), "--lang", "python", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    stem = model_path.stem
    spec = importlib.util.spec_from_file_location(f"generated_{model_path.parent.name}_{stem}", tmp_path / f"{stem}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def sweep_models(folder):
    """``(loaded, derived)``: a sweep folder's models by file name, each loaded and derived
    (whole: every effect) once per test process."""
    from functools import lru_cache

    import kronsub

    @lru_cache(maxsize=None)
    def loaded(name):
        return kronsub.load(folder / name)

    @lru_cache(maxsize=None)
    def derived(name):
        return loaded(name).derive(scene=False)  # the whole model, also of a model with one scene

    return loaded, derived


def scene_of(loaded):
    """``scene(name, which)``: the scene ``which`` of a sweep model, derived (``loaded`` from
    :func:`sweep_models`)."""
    def scene(name, which):
        from kronsub.model.scenes import derive_scene, select_scene

        model = loaded(name)
        return derive_scene(model, select_scene(model, which))

    return scene
