"""The equations in the speeds printed in Kron's implicit form (kronsub/emitters/implicit_speeds.py).

- The printed form is checkable: for small systems under velocity constraints (the rolling disc,
  the disc rolling by a joint with its rows as made, the disc with a configuration constraint,
  the sleigh on a moving belt with ``d(x, t)``; the disc without its transition, ``M`` and ``h``
  then printed in the coordinates), the implicit form is forced and its pieces, read
  back from the JSON and evaluated here independently (``A``, ``b`` by differentiating the rows,
  ``C``, ``d`` from ``[A; Y] C = [0; I]``, ``[A; Y] d = [-b; 0]``, ``M = J^T M_p J``,
  ``h = J^T (M_p Jdot xdot + h_p)``, ``Cdot u + ddot`` along the motion), give at random states the
  ``Mbar``, ``hbar``, ``fbar`` of the expanded report of the same system; the multipliers' defining
  equation ``A A^T mu = A (M xddot + h - f)`` gives the expanded ``--reactions``.
- The Whipple bicycle's model file is printed in that form by ``kronsub derive`` in all three
  formats within the default work budget, with its pieces; ``--reactions`` gives the multipliers'
  equation. The criterion is the one a run takes (``projected_in_numbers``).
- Generated code of such a system that stops at the work budget says which commands take the
  numeric route (``simulate``, ``linearize``, ``derive``); of any other system, the general hint.
"""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from kronsub import budget
from kronsub.api import code_files
from kronsub.cli import main
from kronsub.core import projection_work
from kronsub.emitters import EMITTERS
from kronsub.emitters.reactions import with_reactions

ROOT = Path(__file__).resolve().parent.parent
SMALL = [ROOT / "models" / "nonholonomic" / "rolling_disc.yaml"] + \
        [ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml"
         for name in ("rolling_disc_joint", "rolling_disc_height", "sleigh_on_a_belt")]
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"
T = sympy.Symbol("t")


def _reader(data: dict):
    """Each printed expression of ``data`` as a sympy expression, every name a plain symbol."""
    names = set(data["coordinates"]) | set(data["velocities"]) | set(data["parameters"]) | set(data["speeds"])
    names |= set(data.get("speed_rates", []))
    prim = data.get("primitive")
    if prim is not None:
        names |= set(prim["coordinates"]) | {f"{q}_dot" for q in prim["coordinates"]}
    table = {name: sympy.Symbol(name) for name in names} | {"t": T}
    return lambda text: sympy.sympify(text, locals=table)


def _numbers(data: dict, read) -> dict:
    return {sympy.Symbol(k): float(read(v["value"])) for k, v in data["parameters"].items()}


def _implicit(data: dict, read, x: np.ndarray, u: np.ndarray, t: float, values: dict):
    """``Mbar``, ``hbar``, ``fbar`` and ``(A, M, h, f, C, convective)`` from the printed pieces alone."""
    q = [sympy.Symbol(n) for n in data["coordinates"]]
    qd = [sympy.Symbol(n) for n in data["velocities"]]
    n, p = len(q), len(data["speeds"])
    rows = [read(e) for e in data["velocity_constraints"].values()]
    g = [read(e) for e in data.get("configuration_constraints", {}).values()]
    A = sympy.Matrix([[sympy.diff(r, v) for v in qd] for r in rows] + [[sympy.diff(e, s) for s in q] for e in g])
    b = sympy.Matrix([r.xreplace({v: 0 for v in qd}) for r in rows] + [sympy.diff(e, T) for e in g])
    Y = sympy.Matrix([[sympy.diff(read(e), v) for v in qd] for e in data["speed_definitions"].values()])
    S = A.col_join(Y).xreplace(values)
    r0 = (-b).col_join(sympy.zeros(p, 1)).xreplace(values)
    point = dict(zip(q, x)) | {T: t}

    def at(m, extra=None):
        return np.array(m.xreplace(point | (extra or {})).evalf(), dtype=float)

    Sx, rx = at(S), at(r0).ravel()
    C = np.linalg.solve(Sx, np.vstack([np.zeros((n - p, p)), np.eye(p)]))
    w = np.linalg.solve(Sx, rx + np.concatenate([np.zeros(n - p), u]))  # xdot = C u + d
    # Cdot u + ddot = d(C u + d)/dx^k w^k + d(C u + d)/dt, u held: from S w = r0 + [0; u]
    convective = np.linalg.solve(Sx, at(r0.diff(T)).ravel() - at(S.diff(T)) @ w + sum(
        (at(r0.diff(s)).ravel() - at(S.diff(s)) @ w) * w[k] for k, s in enumerate(q)))
    moving = dict(zip(qd, w))
    f = at(sympy.Matrix([read(e) for e in data["unconstrained"]["forces"]]).xreplace(values), moving).ravel()
    if data["projection"]["metric_from"] == "primitive":
        prim = data["primitive"]
        xp = [sympy.Symbol(c) for c in prim["coordinates"]]
        placed = {s: read(prim["connection"][s.name]) for s in xp}
        J = sympy.Matrix([[read(e) for e in row] for row in prim["transformation"]]).xreplace(values)
        W = sympy.Matrix([[read(e) for e in row] for row in prim["metric"]]).xreplace(placed).xreplace(values)
        Jx = at(J)
        Jdot = sum(at(J.diff(s)) * w[k] for k, s in enumerate(q))
        hp = sympy.Matrix([read(e) for e in prim["velocity_terms"]]).xreplace(placed).xreplace(values)
        hp = at(hp, dict(zip([sympy.Symbol(f"{c.name}_dot") for c in xp], Jx @ w)) | moving).ravel()
        Wx = at(W)
        M = Jx.T @ Wx @ Jx
        h = Jx.T @ (Wx @ (Jdot @ w) + hp)
    else:
        un = data["unconstrained"]
        M = at(sympy.Matrix([[read(e) for e in row] for row in un["mass_matrix"]]).xreplace(values))
        h = at(sympy.Matrix([read(e) for e in un["velocity_terms"]]).xreplace(values), moving).ravel()
    return C.T @ M @ C, C.T @ (M @ convective + h), C.T @ f, (at(A.xreplace(values)), M, h, f, C, convective)


def _expanded(data: dict, read, x, u, t, values):
    point = dict(zip([sympy.Symbol(n) for n in data["coordinates"]], x)) | {T: t} | values
    point |= dict(zip([sympy.Symbol(n) for n in data["speeds"]], u))

    def at(m):
        return np.array(sympy.Matrix(m).xreplace(point).evalf(), dtype=float)

    return (at([[read(e) for e in row] for row in data["mass_matrix"]]),
            at([read(e) for e in data["velocity_terms"]]).ravel(), at([read(e) for e in data["forces"]]).ravel(), at)


@pytest.mark.parametrize("path, primitive", [(p, True) for p in SMALL] + [(SMALL[0], False)],
                         ids=lambda v: v.stem if isinstance(v, Path) else "primitive" if v else "coordinates")
def test_the_printed_implicit_form_gives_the_expanded_equations(path, primitive, monkeypatch):
    system = kronsub.load(path).derive(cache=False)
    if not primitive:  # no transition to take M from: M and h in the coordinates are printed as derived
        system = dataclasses.replace(system, transition=None)
    expanded = json.loads(with_reactions(EMITTERS["json"](system), system, "json"))
    assert "speeds_form" not in expanded
    monkeypatch.setattr(projection_work, "NUMERIC_FROM", 1)  # force the implicit form: the one criterion
    assert projection_work.projected_in_numbers(system)
    implicit = json.loads(with_reactions(EMITTERS["json"](system), system, "json"))
    assert implicit["speeds_form"] == "implicit" and "mass_matrix" not in implicit
    assert implicit["projection"]["metric_from"] == ("primitive" if primitive else "coordinates")
    md, tex = EMITTERS["markdown"](system), EMITTERS["latex"](system)
    assert "## Equations in the speeds (implicit form)" in md and ("`M = J^T M_p J` (9')" in md) is primitive
    assert ("Metric `Mbar = C^T M C` (22):" in md) is not primitive and "Kinematic equations" not in md
    assert "\\section*{Equations in the speeds (implicit form)}" in tex
    assert implicit["projection"]["work"] == projection_work.projection_work(system) >= 1
    assert implicit["reactions"]["implicit"]["unknowns"] == list(expanded["reactions"]["expressions"])
    read = _reader(implicit)
    values = _numbers(implicit, read)
    rng = np.random.default_rng(37)
    n, p = len(implicit["coordinates"]), len(implicit["speeds"])
    rates = [sympy.Symbol(a) for a in expanded["speed_rates"]]
    for _ in range(3):
        x, u, t = rng.uniform(-0.8, 0.8, n), rng.uniform(-1.0, 1.0, p), float(rng.uniform(0.0, 1.0))
        Mbar, hbar, fbar, (A, M, h, f, C, convective) = _implicit(implicit, read, x, u, t, values)
        M0, h0, f0, at = _expanded(expanded, _reader(expanded), x, u, t, values)
        scale = max(1.0, np.max(np.abs(M0)), np.max(np.abs(h0)), np.max(np.abs(f0)))
        assert np.max(np.abs(Mbar - M0)) <= 1e-10 * scale, (Mbar, M0)
        assert np.max(np.abs(hbar - h0)) <= 1e-10 * scale, (hbar, h0)
        assert np.max(np.abs(fbar - f0)) <= 1e-10 * scale, (fbar, f0)
        # the multipliers: A A^T mu = A (M xddot + h - f), xddot = C udot + Cdot u + ddot
        udot = np.linalg.solve(Mbar, fbar - hbar)
        residual = M @ (C @ udot + convective) + h - f
        mu = np.linalg.solve(A @ A.T, A @ residual)
        assert np.max(np.abs(A.T @ mu - residual)) <= 1e-9 * max(1.0, np.max(np.abs(residual)))
        given = dict(zip(rates, udot))
        read0 = _reader(expanded)
        mu0 = at([read0(e).xreplace(given) for e in expanded["reactions"]["expressions"].values()]).ravel()
        assert np.max(np.abs(mu - mu0)) <= 1e-9 * max(1.0, np.max(np.abs(mu0))), (mu, mu0)


@pytest.fixture(scope="module")
def bicycle():
    return kronsub.load(BICYCLE).derive()


def test_the_bicycle_is_printed_in_the_implicit_form(bicycle):
    assert projection_work.projected_in_numbers(bicycle)
    with budget.limited():  # the default work budget of a command
        texts = {fmt: EMITTERS[fmt](bicycle) for fmt in ("markdown", "latex")}
    md, tex = texts["markdown"], texts["latex"]
    assert "## Equations in the speeds (implicit form)" in md and "`Mbar = C^T M C` (9'), (D)" in md
    assert "`[A; Y] C = [0; I]`" in md and f"its work, {projection_work.projection_work(bicycle)}" in md
    assert "- `Mbar [roll_ddot, steer_ddot, rear_ddot] + hbar = fbar`" in md
    assert "**front\\_touches**" in md and "**rear\\_rolls.x**" in md
    assert "\\section*{Equations in the speeds (implicit form)}" in tex and tex.rstrip().endswith("\\end{document}")


def test_derive_prints_the_bicycle_within_the_default_budget():
    result = CliRunner().invoke(main, ["derive", str(BICYCLE), "--format", "json", "--reactions", "--no-cache"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["speeds_form"] == "implicit" and data["projection"]["metric_from"] == "primitive"
    assert data["projection"]["work"] >= data["projection"]["numeric_from"]
    assert data["speeds"] == ["roll_dot", "steer_dot", "rear_dot"]
    assert list(data["velocity_constraints"]) == ["rear_rolls.x", "rear_rolls.y", "front_rolls.x", "front_rolls.y"]
    assert list(data["configuration_constraints"]) == ["front_touches"] and data["dependent"] == ["pitch"]
    assert len(data["primitive"]["metric"]) == len(data["primitive"]["coordinates"]) == 31
    assert len(data["unconstrained"]["forces"]) == 8 and "mass_matrix" not in data
    assert data["reactions"]["implicit"]["unknowns"][-1] == "mu_front_touches"


def test_a_budget_spent_on_generated_code_says_how_to_simplify_and_the_numeric_route_spends_none(monkeypatch):
    """Code generated with the equations in the speeds formed symbolically stops at the budget
    with the general hint; on the route projected in numbers at run time (forced here) neither the
    C nor the numpy module forms them, so the same budget is not spent."""
    system = kronsub.load(SMALL[0]).derive(cache=False)
    with budget.limited(1), pytest.raises(budget.WorkBudgetExceeded) as info:
        code_files(system, "disc", "python")
    assert info.value.problems[0].hint.endswith("or write a simpler form")
    monkeypatch.setattr(projection_work, "NUMERIC_FROM", 1)
    fresh = [kronsub.load(SMALL[0]).derive(cache=False) for _ in range(2)]
    with budget.limited(1):
        (module,) = code_files(fresh[0], "disc", "python")
        c_files = code_files(fresh[1], "disc", "c")
    assert "The projection onto the speeds is made in numbers at every call" in module[1]
    assert any("S = [G; A; Y]" in text for _, text in c_files)