"""Generated C and Python agree with the symbolic equations (every bundled and test model)."""
from __future__ import annotations

import ctypes
import json
import shutil
import subprocess

import numpy as np
import pytest
import sympy
from click.testing import CliRunner

import kronsub
from conftest import MODELS, ROOT
from helpers.generated import ALL_MODELS, CFLAGS, DOUBLE_P, c_agrees_with_symbolic, python_agrees_with_symbolic
from kronsub.cli import main
from kronsub.emitters.code import emit_c, emit_python

needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


@needs_cc
@pytest.mark.parametrize("path", ALL_MODELS)
def test_generated_c_agrees_with_symbolic(path, tmp_path):
    c_agrees_with_symbolic(path, tmp_path)


@pytest.mark.parametrize("path", ALL_MODELS)
def test_generated_python_agrees_with_symbolic(path, tmp_path):
    python_agrees_with_symbolic(path, tmp_path)


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


@needs_cc
@pytest.mark.parametrize("filename", ["DoublePendulum.yaml", "my model.yaml", "2-link.v1.yaml"])
def test_codegen_file_names_match_the_include(filename, tmp_path):
    """The .c includes the header it was written with, whatever the model file is called."""
    model = tmp_path / filename
    model.write_text((MODELS / "examples" / "double_pendulum.yaml").read_text())
    out = tmp_path / "out"
    out.mkdir()
    result = CliRunner().invoke(main, ["codegen", str(model), "--output", str(out)])
    assert result.exit_code == 0, result.output
    (c_file,) = out.glob("*.c")
    (h_file,) = out.glob("*.h")
    assert c_file.stem == h_file.stem and f'#include "{h_file.name}"' in c_file.read_text()
    assert all(ch.isalnum() or ch == "_" for ch in c_file.stem)
    subprocess.run(["gcc", *CFLAGS, "-c", c_file.name], cwd=out, check=True, capture_output=True, text=True)


def test_simulate_falls_back_to_numpy_when_the_compilation_fails(tmp_path, monkeypatch):
    """A compiler that fails is treated like a missing one: a warning, then the numpy module."""
    model = MODELS / "examples" / "double_pendulum.yaml"
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    runs = {}
    for cc in ("false", "gcc"):
        monkeypatch.setenv("CC", cc)
        result = CliRunner().invoke(main, ["simulate", str(model), "--t", "0.5", "--dt", "0.1", "--method", "RK45",
                                           "--output", str(tmp_path / f"{cc}.csv")])
        assert result.exit_code == 0, result.output
        text = (tmp_path / f"{cc}.csv").read_text()
        runs[cc] = np.loadtxt(text.splitlines()[1:], delimiter=",")
        if cc == "false":
            assert "compiling the generated C failed" in result.output and "numpy" in result.output
            assert json.loads((tmp_path / "false.json").read_text())["right_hand_side"] == "numpy"
        if shutil.which("gcc") is None:
            break
    if shutil.which("gcc") is not None:
        assert np.allclose(runs["false"], runs["gcc"], rtol=1e-6, atol=1e-8)


EVERY_FUNCTION = """\
name: every function
parameters: {k: 0.1}
components:
  cart: {type: particle1d, parameters: {mass: 1}, coordinates: [x]}
coordinates: [q]
connection: {x: q + tanh(q)/2 + atan(q)/3}
effects:
  well: {type: potential, value: "k*(sin(x) + cos(x) + tan(x/3) + asin(x/5) + acos(x/5) + atan(x) + atan2(x, 2)
    + sqrt(2 + x) + exp(x) + log(2 + x) + sinh(x) + cosh(x) + tanh(x) + abs(x) + sign(x)*x*pi + exp(1)*sqrt(2))"}
"""


@needs_cc
def test_every_function_builds_and_its_force_is_minus_the_gradient(tmp_path):
    """Every function an expression may call, pi and e: the C builds (c99 -Werror), a sign()
    differentiated (DiracDelta) is zero, and fbar = -dV/dq by central differences of the
    generated potential, in C and in Python alike."""
    (tmp_path / "f.yaml").write_text(EVERY_FUNCTION)
    system = kronsub.load(tmp_path / "f.yaml").derive()
    for generated in emit_c(system, "model"):
        (tmp_path / generated.name).write_text(generated.text)
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", "libmodel.so", "-lm"], cwd=tmp_path,
                   check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(tmp_path / "libmodel.so"))
    lib.ks_potential_energy.restype = ctypes.c_double
    ns = {}
    exec(compile(emit_python(system, "m")[0].text, "m.py", "exec"), ns)  # our own generated code
    param = [0.1]
    pc = (ctypes.c_double * 1)(*param)
    V = lambda q: lib.ks_potential_energy(ctypes.c_double(0.0), (ctypes.c_double * 2)(q, 0.0), pc)  # noqa: E731
    for q in (-0.9, -0.4, 0.2, 0.9, 1.7):
        y = (ctypes.c_double * 2)(q, 0.3)
        f = (ctypes.c_double * 1)()
        lib.ks_forces(ctypes.c_double(0.0), y, ctypes.cast(ctypes.byref(y, 8), DOUBLE_P), pc, f)
        eps = 1e-6
        assert f[0] == pytest.approx(-(V(q + eps) - V(q - eps)) / (2 * eps), rel=1e-7, abs=1e-9)
        assert f[0] == pytest.approx(ns["forces"](0.0, np.array([q]), np.array([0.3]), param)[0], rel=1e-13)
        exact = system.potential_energy.subs({system.coordinates[0]: sympy.Rational(str(q)),
                                               system.parameters[0].symbol: sympy.Rational(1, 10)})
        assert V(q) == pytest.approx(float(exact.evalf(30)), rel=1e-13)
        ydot = (ctypes.c_double * 2)()
        assert lib.ks_rhs(ctypes.c_double(0.0), y, pc, ydot) == 0
        assert np.allclose(ydot[:], ns["rhs"](0.0, np.array([q, 0.3]), param), rtol=1e-13)


@pytest.mark.skipif(shutil.which("g++") is None or shutil.which("gcc") is None, reason="needs gcc and g++")
def test_header_indexes_the_state_and_parameters_and_links_from_cpp(tmp_path):
    """codegen creates its --output folder; KS_Y_<name> / KS_P_<name> index the arrays in the
    order the header comment documents; a C++ program includes the header and links."""
    out = tmp_path / "new" / "folder"
    result = CliRunner().invoke(main, ["codegen", str(MODELS / "hoffmann/system1.yaml"), "--output", str(out)])
    assert result.exit_code == 0, result.output
    system = kronsub.load(MODELS / "hoffmann/system1.yaml").derive()
    names = [q.name for q in system.coordinates] + [v.name for v in system.velocities]
    # print each macro's value from C++, and compare with the order of the state and parameters
    prints = " ".join(f'std::printf("%d ", KS_Y_{n});' for n in names)
    prints += " ".join(f'std::printf("%d ", KS_P_{p.name});' for p in system.parameters)
    (out / "main.cpp").write_text('#include <cstdio>\n#include "system1.h"\n'
                                  f"int main() {{ {prints} return 0; }}\n")
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-c", "system1.c"], cwd=out, check=True)
    subprocess.run(["g++", "-Wall", "-Wextra", "-Werror", "main.cpp", "system1.o", "-lm", "-o", "main"], cwd=out,
                   check=True)
    shown = subprocess.run([str(out / "main")], capture_output=True, text=True, check=True).stdout.split()
    assert [int(v) for v in shown] == list(range(len(names))) + list(range(len(system.parameters)))


def test_remembered_rewritings_give_what_cse_basic_gives():
    """`numeric._Rewritings` (one per model, shared by the blocks) is ``cse``'s "basic"."""
    from kronsub.emitters.numeric import _Rewritings

    x, y, z = sympy.symbols("x y z")
    exprs = [2 * x * sympy.cos(y - z) - 2 * x * sympy.sin(z), -x - y + (z - x) ** 2, x * y - x * z,
             sympy.sqrt(-y + z) * (x - y), 3 * x + 3 * y]
    rewritings = _Rewritings()
    for _ in range(2):  # the second round is read from memory
        ours = sympy.cse(exprs, optimizations=rewritings.optimizations(), order="canonical")
        assert ours == sympy.cse(exprs, optimizations="basic", order="canonical")
    assert len(rewritings.done) == len(exprs)


def test_sums_print_in_sympys_order_of_terms():
    """`code.terms_in_order` (the printers' sums) is SymPy's ``as_ordered_terms``, on every sum of
    the blocks of models of several kinds, and leaves to SymPy the sums whose order a number decides."""
    from kronsub.emitters.code import terms_in_order
    from kronsub.emitters.numeric import prepare

    answered = 0
    for path in (MODELS / "chain" / "chain5.yaml", MODELS / "examples" / "watt_governor.yaml",
                 MODELS / "hoffmann" / "system3.yaml", MODELS / "electrical" / "machine.yaml"):
        model = prepare(kronsub.load(path).derive(), guarded_angles=True)
        for block in (model.mass, model.equations, model.canonical, model.prepare, model.potential, model.positions):
            for _, expr in block.temporaries + block.outputs:
                for sub in sympy.preorder_traversal(expr):
                    if sub.is_Add and (ours := terms_in_order(sub)) is not None:
                        assert ours == sub.as_ordered_terms()
                        answered += 1
    assert answered > 100
    x, y, z = sympy.symbols("x y z")
    assert terms_in_order(z**2 * y + x**3 + y * z + x * y**4) == [x**3, x * y**4, y * z**2, y * z]
    for left in (1 - 2 * x, x + sympy.sqrt(2) * y, x**sympy.Rational(1, 2) + y):
        assert terms_in_order(left) is None


@needs_cc
def test_written_out_solve_is_the_loops_to_the_last_bit(tmp_path, monkeypatch):
    """``code.ldlt_lines`` writes the ``L D L^T`` solve out in scalars in the loops' order of
    operations: the 6-link chain's accelerations agree bit for bit with the loop version (the
    one emitted beyond ``WRITTEN_OUT`` coordinates) at random states."""
    import sys

    from kronsub.emitters import code

    sys.path.insert(0, str(ROOT / "models" / "chain"))
    from generate import chain_yaml

    system = kronsub.load("chain6.yaml", text=chain_yaml(6)).derive()
    libs = []
    for written_out in (code.WRITTEN_OUT, 0):
        monkeypatch.setattr(code, "WRITTEN_OUT", written_out)
        folder = tmp_path / str(written_out)
        folder.mkdir()
        text = {g.name: g.text for g in emit_c(system, "model")}
        assert ("const double x0 = y0" in text["model.c"]) == bool(written_out)
        for name, body in text.items():
            (folder / name).write_text(body)
        subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", "model.c", "-o", "libmodel.so", "-lm"],
                       cwd=folder, check=True, capture_output=True, text=True)
        libs.append(ctypes.CDLL(str(folder / "libmodel.so")))
    rng = np.random.default_rng(3)
    param = (ctypes.c_double * len(system.parameters))(*rng.uniform(0.5, 1.5, len(system.parameters)))
    for _ in range(200):
        y = (ctypes.c_double * 12)(*rng.uniform(-4, 4, 12))
        out = [(ctypes.c_double * 12)() for _ in libs]
        for lib, buf in zip(libs, out):
            assert lib.ks_rhs(ctypes.c_double(0.0), y, param, buf) == 0
        assert out[0][:] == out[1][:]
