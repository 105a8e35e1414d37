"""Generated code checked against the derived symbolic equations (the C compiled with warnings
as errors, the numpy module imported), for tests/test_codegen.py and tests/test_codegen_odd.py."""
from __future__ import annotations

import ctypes
import importlib.util
import subprocess
from pathlib import Path

import numpy as np
import sympy

import kronsub
from kronsub.model.requirements import unmet
from conftest import ROOT, explicit_model_paths
from kronsub.core.rheonomic import depends_on_time
from kronsub.emitters.code import emit_c, emit_python

# every bundled model without `constraints:` and every test model (and test circuit), relative to the repository
# (the closed loops have their own code tests: tests/test_constraints_codegen.py)
ALL_MODELS = sorted([str(Path("models") / p) for p in explicit_model_paths()]
                    + [str(p.relative_to(ROOT)) for p in (ROOT / "tests" / "models").glob("*.yaml")]
                    + [str(p.relative_to(ROOT)) for p in (ROOT / "tests" / "models" / "electrical").glob("*.yaml")])
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
DOUBLE_P = ctypes.POINTER(ctypes.c_double)
MACHINES = ("Synchronous machine", "Synchronous machine on an infinite bus", "Two synchronous machines in parallel")
"""Models whose metric is positive only near their own parameters' values: drawn within 10 % of them."""


def symbolic_values(system):
    """Reference values straight from the derived sympy expressions."""
    syms = [*system.coordinates, *system.velocities, *(p.symbol for p in system.parameters), sympy.Symbol("t", real=True)]
    exprs = [system.mass_matrix, system.velocity_terms, system.forces, system.kinetic_energy, system.potential_energy]
    f = sympy.lambdify(syms, exprs, modules="numpy", dummify=True)  # model names may be numpy's (sqrt, cos)

    def at(t, y, param):
        M, h, fo, T, V = f(*y, *param, t)
        return (np.array(M, float), np.array(h, float).ravel(), np.array(fo, float).ravel(), float(T), float(V))

    return at


def random_states(system, rng, count):
    """``count`` random ``(t, y, parameters)``, System II kept where its subspace (26) is real."""
    n = len(system.coordinates)
    for _ in range(count):
        y = rng.uniform(-1.0, 1.0, 2 * n)
        for _ in range(100):  # parameters the components accept (coupled coils: M^2 <= L1 L2)
            param = rng.uniform(0.5, 1.5, len(system.parameters))
            if not unmet(system.requirements, {p.symbol: v for p, v in zip(system.parameters, param)}):
                break
        names = [p.name for p in system.parameters]
        model = system.name.split(" (scene ")[0]  # a model's only scene is derived by default
        if model == "System II":  # keep the subspace (26) real
            param[names.index("c")] = 0.1
            param[names.index("a1")] = 0.4
            param[names.index("a2")] = 1.0
            y[0] = rng.uniform(-0.3, 0.3)
        if model == "Magnetic suspension of a ball":  # the ball below the magnet: L(y) > 0
            y[0] = abs(y[0])
        if model in MACHINES:  # the inductances of a machine (L0 = Laa0 - 2 Lab0 > 0, ...)
            param = np.array([float(p.value) for p in system.parameters]) * rng.uniform(0.9, 1.1, len(param))
        yield rng.uniform(0, 2), y, param


def expected_rates(symbolic, t, y, param):
    """``ydot`` from the symbolic equations: ``[qdot; Mbar^-1 (fbar - hbar)]``, or, where rows J of
    ``Mbar`` vanish (first-order coordinates: a loop without inductance), their velocities solved
    from ``(fbar - hbar)_J = 0`` (affine in them: read off at 0 and at unit values), the others'
    accelerations from the rest with those velocities put in, and 0 in J's acceleration slots."""
    n = len(y) // 2
    M, h, f, _, _ = symbolic(t, y, param)
    first = [j for j in range(n) if not np.any(M[j])]
    if not first:
        return np.concatenate([y[n:], np.linalg.solve(M, f - h)]), first

    def residual(v):
        z = y.copy()
        z[[n + j for j in first]] = v
        _, h_, f_, _, _ = symbolic(t, z, param)
        return (f_ - h_), z

    base, _ = residual(np.zeros(len(first)))
    D = np.array([residual(e)[0][first] - base[first] for e in np.eye(len(first))]).T
    solved = np.linalg.solve(D, -base[first])
    r, z = residual(solved)
    rest = [i for i in range(n) if i not in first]
    a = np.zeros(n)
    a[rest] = np.linalg.solve(M[np.ix_(rest, rest)], r[rest])
    return np.concatenate([z[n:], a]), first


def close_enough(a, b):
    """Equal to 1e-12, relative to the largest entry of ``b``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, float(np.max(np.abs(b)))))


def c_agrees_with_symbolic(path, tmp_path):
    """The C of the model at ``path`` (relative to the repository) agrees with its symbolic
    equations at 100 random states. Built with -std=c99 -Wall -Wextra -Werror -O2: no M_PI or M_SQRT2, which c99 lacks."""
    system = kronsub.load(ROOT / path).derive()
    for generated in emit_c(system, "model", source=path):
        (tmp_path / generated.name).write_text(generated.text)
        assert "M_PI" not in generated.text and "M_SQRT" not in generated.text
    lib_path = tmp_path / "libmodel.so"
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", str(lib_path), "-lm"],
                   cwd=tmp_path, check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(lib_path))
    for fn in ("ks_kinetic_energy", "ks_potential_energy"):
        getattr(lib, fn).restype = ctypes.c_double
    n = len(system.coordinates)
    driven = system.transition is not None and depends_on_time(dict(system.transition.connection))
    symbolic = symbolic_values(system)
    buf = lambda k: (ctypes.c_double * k)()  # noqa: E731
    arr = lambda a: (ctypes.c_double * len(a))(*a)  # noqa: E731
    for t, y, param in random_states(system, np.random.default_rng(7), 100):
        M, h, f, T, V = symbolic(t, y, param)
        yc, pc = arr(y), arr(param)
        Mc, hc, fc, yd = buf(n * n), buf(n), buf(n), buf(2 * n)
        lib.ks_mass_matrix(yc, pc, Mc)
        timed = (ctypes.c_double(t),) if driven else ()  # a prescribed motion: hbar and the points take t
        lib.ks_velocity_terms(*timed, yc, ctypes.cast(ctypes.byref(yc, 8 * n), DOUBLE_P), pc, hc)
        lib.ks_forces(ctypes.c_double(t), yc, ctypes.cast(ctypes.byref(yc, 8 * n), DOUBLE_P), pc, fc)
        assert close_enough(np.array(Mc[:]).reshape(n, n), M)
        assert close_enough(hc[:], h)
        assert close_enough(fc[:], f)
        assert lib.ks_rhs(ctypes.c_double(t), yc, pc, yd) == 0
        rates, first = expected_rates(symbolic, t, y, param)
        assert close_enough(yd[:n], rates[:n])
        assert close_enough(yd[n:], rates[n:])
        assert close_enough([lib.ks_kinetic_energy(yc, pc)], [T])
        assert close_enough([lib.ks_potential_energy(ctypes.c_double(t), yc, pc)], [V])
        z, back = buf(2 * n), buf(2 * n)
        lib.ks_momentum(yc, pc, z)
        assert close_enough(z[n:], M @ y[n:])
        if first:  # a singular Mbar: no velocity from the momentum, said so
            assert lib.ks_velocity(z, pc, back) != 0
            continue
        assert lib.ks_velocity(z, pc, back) == 0
        assert close_enough(back[:], y)


def python_agrees_with_symbolic(path, tmp_path):
    """The numpy module of the model at ``path`` agrees with its symbolic equations at 100 random states."""
    system = kronsub.load(ROOT / path).derive()
    (generated,) = emit_python(system, "model", source=path)
    assert "sympy" not in generated.text
    (tmp_path / "model.py").write_text(generated.text)
    spec = importlib.util.spec_from_file_location(f"gen_{abs(hash(path))}", tmp_path / "model.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    n = len(system.coordinates)
    symbolic = symbolic_values(system)
    for t, y, param in random_states(system, np.random.default_rng(8), 100):
        M, h, f, T, V = symbolic(t, y, param)
        assert close_enough(module.mass_matrix(y[:n], param), M)
        timed = (t,) if getattr(module, "TIMED", False) else ()  # a prescribed motion: hbar names t
        assert close_enough(module.velocity_terms(*timed, y[:n], y[n:], param), h)
        assert close_enough(module.forces(t, y[:n], y[n:], param), f)
        assert close_enough(module.rhs(t, y, param), expected_rates(symbolic, t, y, param)[0])
        assert close_enough([module.kinetic_energy(y, param)], [T])
        assert close_enough([module.potential_energy(t, y, param)], [V])


def header_order(header, prefix):
    """Parameter names by their ``KS_P_`` index and the points by their ``out[]`` slots."""
    params, points = {}, []
    for line in header.splitlines():
        if line.startswith(f"#define {prefix}_P_"):
            _, name, index = line.split()
            params[int(index)] = name[len(prefix) + 3:]
        if line.strip().startswith("*   out["):
            points.append(line.split("=")[1].strip())
    return [params[i] for i in sorted(params)], points
