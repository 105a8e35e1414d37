"""The exact Jacobian ``d ydot/dy`` in the generated C (``codegen --jacobian``, ``ks_jacobian``),
measured against central finite differences of the generated right-hand side on the machine
models and the circuits with first-order coordinates, and used by Radau (``simulate
--jacobian exact``) to the same trajectory as the exact solution of the DC motor."""
from __future__ import annotations

import ctypes
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS, ROOT
from kronsub.cli import main
from kronsub.emitters.code import emit_c

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
POINTER = ctypes.POINTER(ctypes.c_double)


def compiled(path, tmp_path):
    """``ks_rhs`` and ``ks_jacobian`` of the model at ``path``, built with warnings as errors."""
    system = kronsub.load(path).derive()
    for generated in emit_c(system, "model", jacobian=True):
        (tmp_path / generated.name).write_text(generated.text)
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", "libmodel.so", "-lm"],
                   cwd=tmp_path, check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(tmp_path / "libmodel.so"))
    for function in (lib.ks_rhs, lib.ks_jacobian):
        function.argtypes = [ctypes.c_double, POINTER, POINTER, POINTER]
    ny = 2 * len(system.coordinates)

    def call(function, size):
        def at(t, y, param):
            y, param, out = (np.ascontiguousarray(a, dtype=float) for a in (y, param, np.zeros(size)))
            assert function(t, *(a.ctypes.data_as(POINTER) for a in (y, param, out))) == 0
            return out
        return at

    return system, call(lib.ks_rhs, ny), lambda t, y, p: call(lib.ks_jacobian, ny * ny)(t, y, p).reshape(ny, ny)


@pytest.mark.parametrize("path", [
    MODELS / "electrical" / "synchronous_machine.yaml",
    MODELS / "electrical" / "machine_pair.yaml",
    MODELS / "electrical" / "dc_motor.yaml",
    MODELS / "electrical" / "magnetic_suspension.yaml",
    MODELS / "electrical" / "loudspeaker.yaml",
    ROOT / "tests" / "models" / "electrical" / "rlc_rc.yaml",
    MODELS / "examples" / "double_pendulum.yaml",
], ids=lambda p: p.stem)
def test_exact_jacobian_is_the_finite_difference_one(path, tmp_path):
    """Central differences of the C right-hand side, step 1e-6 (error ~1e-12 relative to the
    entries), at random states near the model's parameters."""
    system, rhs, jacobian = compiled(path, tmp_path)
    rng = np.random.default_rng(7)
    base = np.array([float(p.value) for p in system.parameters])
    ny = 2 * len(system.coordinates)
    for _ in range(4):
        param = base * rng.uniform(0.95, 1.05, len(base))
        y = rng.uniform(-1, 1, ny)
        if system.coordinates[0].name == "y":  # the ball below the magnet
            y[0] = abs(y[0])
        t = rng.uniform(0, 2)
        exact = jacobian(t, y, param)
        differences = np.zeros((ny, ny))
        for c in range(ny):
            h = 1e-6 * max(1.0, abs(y[c]))
            step = np.zeros(ny)
            step[c] = h
            differences[:, c] = (rhs(t, y + step, param) - rhs(t, y - step, param)) / (2 * h)
        assert np.allclose(exact, differences, rtol=1e-6, atol=1e-7 * max(1.0, float(np.max(np.abs(differences)))))


def test_radau_with_the_exact_jacobian_follows_the_dc_motor(tmp_path):
    """The motor's linear equations ``L i' = V - R i - k w``, ``J w' = k i - f w`` from rest
    (before the load step): Radau with the exact Jacobian agrees with their matrix exponential."""
    from scipy.linalg import expm

    args = ["simulate", str(MODELS / "electrical" / "dc_motor.yaml"), "--t", "0.4", "--dt", "0.1", "--method",
            "Radau", "--rtol", "1e-10", "--atol", "1e-12", "--jacobian", "exact"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    lines = result.output.strip().splitlines()
    header = lines[0].split(",")
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    system = kronsub.load(MODELS / "electrical" / "dc_motor.yaml").derive()
    p = {s.name: float(s.value) for s in system.parameters}
    assert p["t_load"] > 0.4  # no load yet
    R, L, k, J, f, V = (p[name] for name in ("R", "L", "k", "J", "f", "V"))
    A = np.array([[0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, -R / L, -k / L, V / L], [0, 0, k / J, -f / J, 0],
                  [0, 0, 0, 0, 0]])
    for row in rows:
        exact = expm(A * row[0]) @ np.array([0, 0, 0, 0, 1.0])
        got = [row[header.index(name)] for name in ("q", "theta", "i", "theta_dot")]
        assert np.allclose(got, exact[:4], rtol=1e-7, atol=1e-8)


def test_codegen_jacobian_is_for_c_only(tmp_path):
    result = CliRunner().invoke(main, ["codegen", str(MODELS / "electrical" / "dc_motor.yaml"), "--lang", "python",
                                       "--jacobian", "-o", str(tmp_path)])
    assert result.exit_code == 2 and "--jacobian is for --lang c" in result.output
    result = CliRunner().invoke(main, ["codegen", str(MODELS / "electrical" / "dc_motor.yaml"), "--jacobian",
                                       "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "int ks_jacobian(double t, const double *y, const double *param, double *jac)" in \
        (tmp_path / "dc_motor.h").read_text()
