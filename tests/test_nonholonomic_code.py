"""Generated code of systems under velocity constraints (models/nonholonomic): the state [q; u], the
C (compiled with warnings as errors) and the numpy module's right-hand side ``[C(q) u; Mbar^-1
(fbar - hbar)]`` and kinetic energy against the derived symbolic equations in the speeds."""
import ctypes
import importlib.util
import subprocess
from pathlib import Path

import jinja2
import numpy as np
import pytest
import sympy

import kronsub.emitters.code as code
from kronsub.core.symbols import TIME
from kronsub.emitters.escape import environment
from kronsub.model.loader import load_model

ROOT = Path(__file__).resolve().parent.parent
MODELS = ("rolling_disc", "chaplygin_sleigh", "differential_drive")
IN_TIME = ROOT / "tests" / "models" / "nonholonomic" / "sleigh_on_a_belt.yaml"  # A xdot + b(x, t) = 0
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
DOUBLE_P = ctypes.POINTER(ctypes.c_double)


@pytest.fixture(autouse=True)
def _worktree_templates(monkeypatch):
    """The templates of this checkout (an editable install may map kronsub.templates elsewhere)."""
    monkeypatch.setattr(code, "template_environment",
                        lambda: environment(jinja2.FileSystemLoader(str(ROOT / "templates"))))


def _symbolic(system):
    s = system.speeds
    x, u = system.coordinates, s.speeds
    params = [p.symbol for p in system.parameters]
    rates = s.mass_matrix.LUsolve(s.forces - s.velocity_terms)
    f = sympy.lambdify([*x, *u, *params, TIME], [s.kinematics.col_join(rates), s.kinetic_energy], modules="numpy")

    def at(t, y, param):
        ydot, T = f(*y, *param, t)
        return np.array(ydot, float).ravel(), float(T)

    return at


def _states(system, rng, count=4):
    n, p = len(system.coordinates), len(system.speeds.speeds)
    for _ in range(count):
        yield rng.uniform(-1.0, 1.0, n + p), rng.uniform(0.5, 1.5, len(system.parameters))


@pytest.mark.parametrize("path", [ROOT / "models" / "nonholonomic" / f"{name}.yaml" for name in MODELS] + [IN_TIME],
                         ids=lambda p: p.stem)
def test_generated_code_integrates_the_state_in_the_speeds(tmp_path, path):
    name = path.stem
    system = load_model(path).derive(cache=False)
    n, p = len(system.coordinates), len(system.speeds.speeds)
    reference = _symbolic(system)
    (py,) = code.emit_python(system, "model")
    (tmp_path / py.name).write_text(py.text)
    spec = importlib.util.spec_from_file_location(f"generated_nonholonomic_{name}", tmp_path / py.name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.NQ == n and module.NU == p
    assert module.STATE == [q.name for q in system.coordinates] + [u.name for u in system.speeds.speeds]
    header, source = code.emit_c(system, "model")
    assert f"#define KS_NY {n + p}" in header.text and f"#define KS_NU {p}" in header.text
    for f in (header, source):
        (tmp_path / f.name).write_text(f.text)
    library = tmp_path / "model.so"
    subprocess.run(["gcc", *CFLAGS, "-shared", "-fPIC", "-o", str(library), str(tmp_path / source.name), "-lm"],
                   check=True, capture_output=True, timeout=120)
    lib = ctypes.CDLL(str(library))
    lib.ks_rhs.argtypes = [ctypes.c_double, DOUBLE_P, DOUBLE_P, DOUBLE_P]
    lib.ks_kinetic_energy.argtypes = [DOUBLE_P, DOUBLE_P]
    lib.ks_kinetic_energy.restype = ctypes.c_double
    lib.ks_rhs_canonical.argtypes = [ctypes.c_double, DOUBLE_P, DOUBLE_P, DOUBLE_P]
    rng = np.random.default_rng(11)
    for y, param in _states(system, rng):
        t = float(rng.uniform(0, 3))
        ydot, T = reference(t, y, param)
        assert np.allclose(module.rhs(t, y, param), ydot, rtol=1e-10, atol=1e-12)
        assert module.kinetic_energy(y, param) == pytest.approx(T, rel=1e-10, abs=1e-14)
        out = np.empty(n + p)
        yc, pc = np.ascontiguousarray(y), np.ascontiguousarray(param)
        state, values, result = (a.ctypes.data_as(DOUBLE_P) for a in (yc, pc, out))
        assert lib.ks_rhs(t, state, values, result) == 0
        assert np.allclose(out, ydot, rtol=1e-10, atol=1e-12)
        assert lib.ks_kinetic_energy(yc.ctypes.data_as(DOUBLE_P), pc.ctypes.data_as(DOUBLE_P)) == pytest.approx(
            T, rel=1e-10, abs=1e-14)
        assert lib.ks_rhs_canonical(0.0, yc.ctypes.data_as(DOUBLE_P), pc.ctypes.data_as(DOUBLE_P),
                                    out.ctypes.data_as(DOUBLE_P)) == 1  # no canonical form in the speeds
