"""Generated code of closed loops: C (built with -Werror), the numpy module and the symbolic
equations agree; the JSON contract alone evaluates the equations at a state."""
from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import sympy

import kronsub
from conftest import MODELS
from kronsub.core.constraints import Intermediates
from kronsub.emitters import emit_json
from kronsub.emitters.code import emit_c, emit_python
from kronsub.simulation.native import CompilerNotFound, NativeModel, compile_library

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
PATHS = ["examples/four_bar.yaml", "examples/slider_crank.yaml", "hoffmann/system3.yaml",
         "hoffmann/system2_implicit.yaml"]


def _symbolic(system):
    values = {p.symbol: p.value for p in system.parameters}
    inter = list(system.implicit.intermediates)
    fn = sympy.lambdify(list(system.coordinates) + list(system.velocities) + inter,
                        [system.mass_matrix.xreplace(values), (system.forces - system.velocity_terms).xreplace(values)],
                        "numpy")
    ev = Intermediates(system.implicit, values)

    def acc(q, qd, guess=None):
        if guess is not None:
            ev.guess = np.array(guess, dtype=float)
        w = ev.at(q, qd)
        M, r = fn(*q, *qd, *[w[s] for s in inter])
        return np.linalg.solve(np.array(M, float), np.array(r, float).ravel())

    return acc


@pytest.mark.parametrize("path", PATHS)
def test_c_numpy_and_symbolic_agree(path):
    model = kronsub.load(MODELS / path)
    system = model.derive()
    params = np.array([float(p.value) for p in system.parameters])
    namespace: dict = {}
    (py,) = emit_python(system, "model")
    exec(compile(py.text, "generated", "exec"), namespace)
    try:
        native = NativeModel(compile_library([(g.name, g.text) for g in emit_c(system, "model")], "model"),
                             len(system.coordinates), len(system.parameters))
    except CompilerNotFound:
        pytest.skip("no C compiler")
    acc = _symbolic(system)
    n = len(system.coordinates)
    q0 = np.array([float(model.initial.get(q, 0)) for q in system.coordinates])
    rng = np.random.default_rng(11)
    for _ in range(10):
        q = q0 + rng.uniform(-0.02, 0.02, n)
        qd = rng.uniform(-1.5, 1.5, n)
        y = np.concatenate([q, qd])
        expected = acc(q, qd)
        assert np.allclose(native.rhs(0.0, y, params)[n:], expected, rtol=1e-9, atol=1e-9)
        assert np.allclose(namespace["rhs"](0.0, y, params)[n:], expected, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("path", ["examples/four_bar.yaml", "hoffmann/system2_implicit.yaml"])
def test_json_alone_evaluates_the_equations(path):
    system = kronsub.load(MODELS / path).derive()
    data = json.loads(emit_json(system))
    imp = data["implicit"]

    def expr(text):  # the test's own reading of the contract (sympy's str form; `lambda` is a Python keyword)
        text = re.sub(r"\blambda\b", "lambda_", text)
        return sympy.sympify(text, locals={k: sympy.Symbol(k) for k in ["lambda_", "gamma", "beta", "I", "E", "S", "N"]})

    params = {sympy.Symbol(k): sympy.nsimplify(v["value"]) for k, v in data["parameters"].items() if v["value"]}
    indep = [sympy.Symbol(n) for n in imp["independent"]]
    deps = [sympy.Symbol(n) for n in imp["dependent"]]
    q = {s: 0.5 + 0.1 * i for i, s in enumerate(indep)}
    if path.endswith("four_bar.yaml"):
        q = {indep[0]: 2.05}
    qd = {sympy.Symbol(f"{s}_dot"): 0.7 for s in indep}
    # dependent coordinates: closed form, else Newton on the constraints from the branch
    g = sympy.Matrix([expr(e) for e in imp["constraints"].values()]).xreplace(params).xreplace(q)
    y = {d: float(imp["dependent"][d.name]["branch"]) for d in deps}
    for d in deps:
        if "closed_form" in imp["dependent"][d.name]:
            y[d] = float(expr(imp["dependent"][d.name]["closed_form"]).xreplace(params).xreplace(q))
    if not all("closed_form" in imp["dependent"][d.name] for d in deps):
        sol = sympy.nsolve(list(g), deps, [y[d] for d in deps])
        y = {d: float(v) for d, v in zip(deps, sol)}
    point = {**params, **q, **y, **qd}
    Gd = sympy.Matrix([[expr(c) for c in row] for row in imp["jacobian_dependent"]]).xreplace(point)
    Gi = sympy.Matrix([[expr(c) for c in row] for row in imp["jacobian_independent"]]).xreplace(point)
    lam = -(Gd.inv() * Gi)
    lam_names = list(imp["sensitivities"])
    point.update({sympy.Symbol(re.sub(r"^lambda$", "lambda_", k)): lam[i // len(indep), i % len(indep)]
                  for i, k in enumerate(lam_names)})
    quad = sympy.Matrix([expr(v["quadratic"]) for v in imp["convective"].values()]).xreplace(point)
    gam = Gd.inv() * quad
    point.update({sympy.Symbol(k): gam[i] for i, k in enumerate(imp["convective"])})
    M = sympy.Matrix([[expr(c) for c in row] for row in data["mass_matrix"]]).xreplace(point)
    h = sympy.Matrix([expr(c) for c in data["velocity_terms"]]).xreplace(point)
    f = sympy.Matrix([expr(c) for c in data["forces"]]).xreplace(point)
    acc_json = np.array((M.inv() * (f - h)).evalf(), dtype=float).ravel()
    acc = _symbolic(system)([q[s] for s in indep], [0.7] * len(indep))
    assert np.allclose(acc_json, acc, rtol=1e-9, atol=1e-9)


def test_c_newton_state_belongs_to_the_caller():
    """Two callers of one compiled four-bar on its two assembly modes, interleaved: each keeps
    its own warm start (the state after the parameters), so each stays on its own branch; the
    accelerations equal the symbolic ones with the intermediates by Newton on that branch."""
    model = kronsub.load(MODELS / "examples/four_bar.yaml")
    system = model.derive()
    imp = system.implicit
    params = np.array([float(p.value) for p in system.parameters])
    try:
        library = compile_library([(g.name, g.text) for g in emit_c(system, "model")], "model")
    except CompilerNotFound:
        pytest.skip("no C compiler")
    first, second = (NativeModel(library, 1, len(params)) for _ in range(2))
    assert first.nstate == 3
    values = {p.symbol: float(p.value) for p in system.parameters}
    evaluator = Intermediates(imp, values)
    q = np.array([2.0])
    branch = evaluator.dependent(q)
    other = None
    for guess in ([2.5, 1.5], [-2.0, 2.0], [1.5, -2.5], [3.0, 0.5]):  # the other assembly mode
        evaluator.guess = np.array(guess)
        try:
            found = evaluator.dependent(q)
        except Exception:
            continue
        if np.max(np.abs(found - branch)) > 0.1:
            other = found
            break
    assert other is not None
    first.set_newton(branch, 1e-13)
    second.set_newton(other, 1e-13)
    acc = _symbolic(system)
    rng = np.random.default_rng(5)
    for _ in range(5):
        for native, start in ((first, branch), (second, other)):
            qd = rng.uniform(-1, 1, 1)
            got = native.rhs(0.0, np.concatenate([q, qd]), params)[1:]
            evaluator.guess = np.array(start)
            assert np.max(np.abs(native.dependent - evaluator.dependent(q))) < 1e-9
            assert np.allclose(got, acc(q, qd, guess=start), rtol=1e-9, atol=1e-9)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
def test_c_of_a_closed_loop_never_writes_a_const_param(tmp_path):
    """The functions taking ``param`` read the warm start after the parameters and write nothing
    there: a ``static const`` array (read-only memory, where a write is a segfault) works, under
    -Werror. The ``_pre`` functions carry the warm start in ``pre``, declared writable (a const
    ``pre`` does not compile); along a path they follow the same branch as ``param``'s calls."""
    model = kronsub.load(MODELS / "examples/four_bar.yaml")
    system = model.derive()
    for generated in emit_c(system, "model"):
        (tmp_path / generated.name).write_text(generated.text, encoding="utf-8")
    header = (tmp_path / "model.h").read_text()
    assert re.search(r"int ks_rhs\(double t, const double \*y, const double \*param, double \*ydot\);", header)
    assert re.search(r"int ks_rhs_pre\(double t, const double \*y, double \*pre, double \*ydot\);", header)
    evaluator = Intermediates(system.implicit, {p.symbol: p.value for p in system.parameters})
    q0 = float(model.initial[system.coordinates[0]])
    warm = [float(v) for v in evaluator.dependent(np.array([q0]))]
    values = ", ".join(repr(float(p.value)) for p in system.parameters)
    driver = f"""\
#include <stdio.h>
#include "model.h"
static const double param[KS_NPARAM + KS_NSTATE] = {{{values}, {warm[0]!r}, {warm[1]!r}, 1e-12}};
int main(void)
{{
    double y[KS_NY] = {{{q0!r}, 0.7}}, ydot[KS_NY], M[KS_NQ * KS_NQ], w[KS_NW], state[KS_NSTATE];
    double pre[KS_NPRE + 1], ydot_pre[KS_NY], points[KS_NPOINTS];
    int i, k;
    if (ks_rhs(0.0, y, param, ydot)) return 1;
    ks_mass_matrix(y, param, M);
    ks_points(y, param, points);
    for (k = 0; k < KS_NSTATE; ++k) state[k] = param[KS_NPARAM + k];
    if (ks_dependent(y, y + KS_NQ, param, w, state)) return 2;
    ks_prepare(param, pre);
    if (ks_rhs_pre(0.0, y, pre, ydot_pre)) return 3;
    for (i = 0; i < 40; ++i) {{  /* along the crank's turn: the param calls from their warm start */
        y[0] = {q0!r} + 0.01 * i;
        if (ks_rhs(0.0, y, param, ydot) || ks_rhs_pre(0.0, y, pre, ydot_pre)) return 4;
        if (ydot[1] != ydot[1] || ydot_pre[1] != ydot_pre[1]) return 5;
    }}
    printf("%.17g %.17g %.17g %.17g %.17g\\n", ydot[1], ydot_pre[1], M[0], kinetic(y), w[0]);
    return 0;
}}
""".replace("kinetic(y)", "ks_kinetic_energy(y, param)")
    (tmp_path / "main.c").write_text(driver, encoding="utf-8")
    subprocess.run(["gcc", *CFLAGS, "main.c", "model.c", "-o", "main", "-lm"], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    run = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, (run.returncode, run.stderr)
    from_param, from_pre, mass, kinetic, dependent = map(float, run.stdout.split())
    assert np.isclose(from_param, from_pre, rtol=1e-9, atol=1e-9) and mass > 0 and kinetic > 0
    assert np.isclose(dependent, warm[0], atol=1e-9)
    # a const pre is refused by the compiler (the _pre functions write the warm start there)
    (tmp_path / "bad.c").write_text(driver.replace("double pre[KS_NPRE + 1]", "const double pre[KS_NPRE + 1] = {0}")
                                    .replace("    ks_prepare(param, pre);\n", ""), encoding="utf-8")
    refused = subprocess.run(["gcc", *CFLAGS, "-c", "bad.c"], cwd=tmp_path, capture_output=True, text=True)
    assert refused.returncode != 0 and "pre" in refused.stderr
