"""Generated C and Python agree with the symbolic equations (every bundled model)."""
from __future__ import annotations

import ctypes
import importlib.util
import shutil
import subprocess

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from conftest import MODELS, explicit_model_paths
from kronsub.cli import main
from kronsub.emitters.code import emit_c, emit_python

ALL_MODELS = explicit_model_paths()
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
DOUBLE_P = ctypes.POINTER(ctypes.c_double)


def _symbolic(system):
    """Reference values straight from the derived sympy expressions."""
    syms = [*system.coordinates, *system.velocities, *(p.symbol for p in system.parameters), sympy.Symbol("t", real=True)]
    exprs = [system.mass_matrix, system.velocity_terms, system.forces, system.kinetic_energy, system.potential_energy]
    f = sympy.lambdify(syms, exprs, modules="numpy")

    def at(t, y, param):
        M, h, fo, T, V = f(*y, *param, t)
        return (np.array(M, float), np.array(h, float).ravel(), np.array(fo, float).ravel(), float(T), float(V))

    return at


def _states(system, rng, count):
    n = len(system.coordinates)
    for _ in range(count):
        y = rng.uniform(-1.0, 1.0, 2 * n)
        param = rng.uniform(0.5, 1.5, len(system.parameters))
        names = [p.name for p in system.parameters]
        if "c" in names:  # System II: keep the subspace (26) real
            param[names.index("c")] = 0.1
            param[names.index("a1")] = 0.4
            param[names.index("a2")] = 1.0
            y[0] = rng.uniform(-0.3, 0.3)
        yield rng.uniform(0, 2), y, param


def _close(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.allclose(a, b, rtol=1e-12, atol=1e-12 * max(1.0, float(np.max(np.abs(b)))))


@needs_cc
@pytest.mark.parametrize("path", ALL_MODELS)
def test_generated_c_agrees_with_symbolic(path, tmp_path):
    system = kronsub.load(MODELS / path).derive()
    for generated in emit_c(system, "model", source=path):
        (tmp_path / generated.name).write_text(generated.text)
    lib_path = tmp_path / "libmodel.so"
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", str(lib_path), "-lm"],
                   cwd=tmp_path, check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(lib_path))
    for fn in ("ks_kinetic_energy", "ks_potential_energy"):
        getattr(lib, fn).restype = ctypes.c_double
    n = len(system.coordinates)
    symbolic = _symbolic(system)
    buf = lambda k: (ctypes.c_double * k)()  # noqa: E731
    arr = lambda a: (ctypes.c_double * len(a))(*a)  # noqa: E731
    for t, y, param in _states(system, np.random.default_rng(7), 100):
        M, h, f, T, V = symbolic(t, y, param)
        yc, pc = arr(y), arr(param)
        Mc, hc, fc, yd = buf(n * n), buf(n), buf(n), buf(2 * n)
        lib.ks_mass_matrix(yc, pc, Mc)
        lib.ks_velocity_terms(yc, ctypes.cast(ctypes.byref(yc, 8 * n), DOUBLE_P), pc, hc)
        lib.ks_forces(ctypes.c_double(t), yc, ctypes.cast(ctypes.byref(yc, 8 * n), DOUBLE_P), pc, fc)
        assert _close(np.array(Mc[:]).reshape(n, n), M)
        assert _close(hc[:], h)
        assert _close(fc[:], f)
        assert lib.ks_rhs(ctypes.c_double(t), yc, pc, yd) == 0
        assert _close(yd[:n], y[n:])
        assert _close(yd[n:], np.linalg.solve(M, f - h))
        assert _close([lib.ks_kinetic_energy(yc, pc)], [T])
        assert _close([lib.ks_potential_energy(ctypes.c_double(t), yc, pc)], [V])
        z, back = buf(2 * n), buf(2 * n)
        lib.ks_momentum(yc, pc, z)
        assert _close(z[n:], M @ y[n:])
        assert lib.ks_velocity(z, pc, back) == 0
        assert _close(back[:], y)


@pytest.mark.parametrize("path", ALL_MODELS)
def test_generated_python_agrees_with_symbolic(path, tmp_path):
    system = kronsub.load(MODELS / path).derive()
    (generated,) = emit_python(system, "model", source=path)
    assert "sympy" not in generated.text
    (tmp_path / "model.py").write_text(generated.text)
    spec = importlib.util.spec_from_file_location(f"gen_{abs(hash(path))}", tmp_path / "model.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    n = len(system.coordinates)
    symbolic = _symbolic(system)
    for t, y, param in _states(system, np.random.default_rng(8), 100):
        M, h, f, T, V = symbolic(t, y, param)
        assert _close(module.mass_matrix(y[:n], param), M)
        assert _close(module.velocity_terms(y[:n], y[n:], param), h)
        assert _close(module.forces(t, y[:n], y[n:], param), f)
        assert _close(module.rhs(t, y, param)[n:], np.linalg.solve(M, f - h))
        assert _close([module.kinetic_energy(y, param)], [T])
        assert _close([module.potential_energy(t, y, param)], [V])


def test_canonical_form_matches_the_first_order_form():
    """zdot = [Mbar^-1 p; dT/dq + fbar] is d/dt of z = [q; Mbar qdot] along ydot."""
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    ns = {}
    exec(compile(emit_python(system, "m")[0].text, "m.py", "exec"), ns)  # our own generated code
    rng = np.random.default_rng(2)
    y = rng.uniform(-1, 1, 4)
    param = rng.uniform(0.5, 1.5, len(system.parameters))
    eps = 1e-6
    ydot = ns["rhs"](0.0, y, param)
    dz = (ns["momentum"](y + eps * ydot, param) - ns["momentum"](y - eps * ydot, param)) / (2 * eps)
    zdot = ns["rhs_canonical"](0.0, ns["momentum"](y, param), param)
    assert np.allclose(dz, zdot, rtol=1e-7, atol=1e-7)


def test_codegen_command_writes_byte_identical_files(tmp_path):
    runner = CliRunner()
    outs = []
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        for lang in ("c", "python"):
            result = runner.invoke(main, ["codegen", str(MODELS / "hoffmann" / "system1.yaml"), "--lang", lang,
                                          "--output", str(tmp_path / sub)])
            assert result.exit_code == 0, result.output
        outs.append({p.name: p.read_bytes() for p in sorted((tmp_path / sub).iterdir())})
    assert outs[0] == outs[1]
    assert set(outs[0]) == {"system1.c", "system1.h", "system1.py"}
    header = outs[0]["system1.h"].decode()
    assert "y[0] = theta" in header and "param[6] = g" in header and "Mbar(q) qddot" in header


@pytest.mark.parametrize("lang", ["c", "python"])
def test_generated_code_is_byte_identical_under_different_hash_seeds(lang, tmp_path):
    import os
    import subprocess
    import sys

    texts = []
    for seed in ("1", "777"):
        out = tmp_path / seed
        out.mkdir()
        env = dict(os.environ, PYTHONHASHSEED=seed, KRONSUB_CACHE_DIR="off")
        proc = subprocess.run([sys.executable, "-m", "kronsub", "codegen", str(MODELS / "examples" / "watt_governor.yaml"),
                               "--lang", lang, "--output", str(out)], capture_output=True, env=env)
        assert proc.returncode == 0, proc.stderr.decode()
        texts.append({p.name: p.read_bytes() for p in sorted(out.iterdir())})
    assert texts[0] == texts[1]


@needs_cc
def test_two_models_with_prefixes_link_into_one_program(tmp_path):
    """--prefix keeps the names of several generated models apart."""
    for path, prefix in (("hoffmann/system1.yaml", "sys1"), ("examples/double_pendulum.yaml", "dp")):
        system = kronsub.load(MODELS / path).derive()
        for generated in emit_c(system, prefix, prefix=prefix):
            (tmp_path / generated.name).write_text(generated.text)
    (tmp_path / "main.c").write_text(
        '#include <stdio.h>\n#include "sys1.h"\n#include "dp.h"\n'
        "int main(void) {\n"
        "    double y1[SYS1_NY] = {0.5, -0.2, 0.0, 0.0}, p1[SYS1_NPARAM] = {1, 1, 0.5, 0.5, 1.0/12, 1.0/12, 9.81, 0};\n"
        "    double y2[DP_NY] = {0.5, -0.2, 0.0, 0.0}, p2[DP_NPARAM] = {1, 1, 1, 1, 9.81};\n"
        "    double d1[SYS1_NY], d2[DP_NY];\n"
        "    if (sys1_rhs(0.0, y1, p1, d1) || dp_rhs(0.0, y2, p2, d2)) return 1;\n"
        '    printf("%.17g %.17g\\n", d1[2], d2[2]);\n    return 0;\n}\n')
    subprocess.run(["gcc", *CFLAGS, "main.c", "sys1.c", "dp.c", "-o", "main", "-lm"], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    out = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, check=True).stdout.split()
    assert all(np.isfinite(float(v)) for v in out)
