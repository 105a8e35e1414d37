"""The projection onto the speeds kept at run time in the generated C (emitters/projected_speeds.py):
``S = [G; A; Y]``, ``C``, ``Cdot u + ddot`` solved by an LU in C, ``Mbar = C^T M C`` and
``fbar - hbar`` from the primitive's pieces.

Independent routes: on the small models under velocity constraints (a configuration constraint
beside them, a constraint in time, the rows of a rolling joint as made), where the symbolic projection
is made (the expanded C of the same model, compiled into the same library under another prefix),
the run-time projection gives the same right-hand side, ``Mbar``, ``hbar``, ``fbar``, energies and
held coordinates at random states to ~1e-12; its C builds with warnings as errors and is the same
bytes under two hash seeds; a singular ``S`` is reported as a singular ``Mbar`` is (``rhs``
returns 1). The route is taken by itself only from the projection work on: the smaller models'
code stays the expanded one. The Whipple bicycle, which takes it, is checked in
tests/test_nonholonomic_numeric_route.py.
"""
from __future__ import annotations

import ctypes
import shutil
import subprocess

import numpy as np
import pytest

from helpers.seeded import emitted_under_seed
import kronsub
from kronsub.emitters.code import emit_c
from kronsub.core.projection_work import NUMERIC_FROM, projection_work
from kronsub.core.projection_work import projected_in_numbers as numeric_route
from kronsub.emitters.projected_speeds import applies
from kronsub.errors import KronsubError

from conftest import ROOT

SMALL = [ROOT / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc", "chaplygin_sleigh", "differential_drive")] + \
        [ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc_joint", "rolling_disc_height", "sleigh_on_a_belt")]
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
DOUBLE = ctypes.c_double
needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


def _both(system, folder):
    """One library of the expanded C (prefix ``ks``) and the run-time projection (``kp``)."""
    folder.mkdir()
    sources = []
    for route, prefix in (("auto", "ks"), ("projected", "kp")):
        for generated in emit_c(system, f"model_{prefix}", prefix=prefix, route=route):
            (folder / generated.name).write_text(generated.text)
        sources.append(f"model_{prefix}.c")
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", *sources, "-o", "lib.so", "-lm"], cwd=folder, check=True,
                   capture_output=True, text=True)
    lib = ctypes.CDLL(str(folder / "lib.so"))
    for prefix in ("ks", "kp"):
        for name in ("kinetic_energy", "potential_energy"):
            getattr(lib, f"{prefix}_{name}").restype = DOUBLE
    timed = ["#define KS_TIMED" in (folder / "model_ks.h").read_text(),
             "#define KP_TIMED" in (folder / "model_kp.h").read_text()]
    return lib, timed


def _array(values):
    return (DOUBLE * len(values))(*values)


def _evaluate(lib, prefix, timed, n, p, t, y, param, held) -> dict:
    """Every function of the generated C in the speeds at one state."""
    def f(name):
        return getattr(lib, f"{prefix}_{name}")

    yc, pc, u = _array(y), _array(param), _array(y[n:])
    out = {name: (DOUBLE * size)() for name, size in (("rhs", n + p), ("M", p * p), ("h", p), ("f", p),
                                                      ("momentum", n + p), ("q", n))}
    code = f("rhs")(DOUBLE(t), yc, pc, out["rhs"])
    f("mass_matrix")(yc, pc, out["M"])
    if timed:
        f("velocity_terms")(DOUBLE(t), yc, u, pc, out["h"])
    else:
        f("velocity_terms")(yc, u, pc, out["h"])
    f("forces")(DOUBLE(t), yc, u, pc, out["f"])
    f("momentum")(yc, pc, out["momentum"])
    values = {name: np.array(v[:]) for name, v in out.items()}
    values["code"] = code
    values["T"] = f("kinetic_energy")(yc, pc)
    values["V"] = f("potential_energy")(DOUBLE(t), yc, pc)
    if held:
        values["hold"] = f("hold")(DOUBLE(t), yc, pc, out["q"])
        values["q"] = np.array(out["q"][:])
    return values


@needs_cc
@pytest.mark.parametrize("path", SMALL, ids=lambda p: p.stem)
def test_the_same_equations_as_the_symbolic_projection(path, tmp_path):
    system = kronsub.load(path).derive(cache=False)
    assert applies(system) and not numeric_route(system) and 0 < projection_work(system) < NUMERIC_FROM
    lib, timed = _both(system, tmp_path / "c")
    assert timed[0] == timed[1]
    n, p = len(system.coordinates), len(system.speeds.speeds)
    held = bool(system.speeds.holonomic)
    rng = np.random.default_rng(37)
    for _ in range(6):
        y = rng.uniform(-1.0, 1.0, n + p)
        param = np.array([float(q.value) for q in system.parameters]) * rng.uniform(0.8, 1.2, len(system.parameters))
        t = float(rng.uniform(0.0, 1.0))
        ours = _evaluate(lib, "kp", timed[1], n, p, t, y, param, held)
        theirs = _evaluate(lib, "ks", timed[0], n, p, t, y, param, held)
        assert ours["code"] == theirs["code"] == 0
        for name in ("rhs", "M", "h", "f", "momentum", "T", "V") + (("q",) if held else ()):
            a, b = np.atleast_1d(ours[name]), np.atleast_1d(theirs[name])
            scale = max(1.0, float(np.max(np.abs(b))))
            assert np.max(np.abs(a - b)) <= 1e-12 * scale, (path.stem, name, a, b)


@needs_cc
def test_a_singular_frame_is_reported_as_a_singular_mass_matrix(tmp_path):
    """The rolling disc flat on its plane (lean = pi/2): its speeds no longer fix the velocities."""
    system = kronsub.load(SMALL[0]).derive(cache=False)
    lib, _ = _both(system, tmp_path / "c")
    n, p = len(system.coordinates), len(system.speeds.speeds)
    names = [q.name for q in system.coordinates]
    param = np.array([float(q.value) for q in system.parameters])
    ok = np.full(n + p, 0.3)
    assert lib.kp_rhs(DOUBLE(0.0), _array(ok), _array(param), (DOUBLE * (n + p))()) == 0
    flat = ok.copy()
    flat[names.index("lean")] = np.pi / 2
    codes = [getattr(lib, f"{prefix}_rhs")(DOUBLE(0.0), _array(flat), _array(param), (DOUBLE * (n + p))())
             for prefix in ("kp", "ks")]
    assert codes[0] == 1, codes


def test_the_generated_code_is_deterministic():
    assert emitted_under_seed("emit_c", SMALL[3], "1") == emitted_under_seed("emit_c", SMALL[3], "2")


def test_the_route_refuses_a_system_it_cannot_keep():
    system = kronsub.load(ROOT / "models" / "examples" / "double_pendulum.yaml").derive()
    assert not applies(system)
    with pytest.raises(KronsubError, match="cannot keep the projection"):
        emit_c(system, "m", route="projected", jacobian=True)


@pytest.mark.parametrize("name", ["rolling_disc_height", "sleigh_on_a_belt"])
def test_the_reference_projected_on_its_tape_follows_the_symbolic_one(name, monkeypatch):
    """`kronsub accuracy`'s reference of a system projected at run time solves ``S``, ``C`` and
    ``Mbar`` order by order on its tape: the same states as the series of the symbolic equations."""
    from kronsub.simulation import reference

    system = kronsub.load(ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml").derive(cache=False)
    param = [float(p.value) for p in system.parameters]
    y0 = list(np.random.default_rng(5).uniform(-0.5, 0.5, len(system.coordinates) + len(system.speeds.speeds)))
    symbolic = reference.taylor(system, param, y0, [0.3], digits=20)
    monkeypatch.setattr(reference, "projected_in_numbers", lambda s: True)
    tape = reference.taylor(system, param, y0, [0.3], digits=20)
    assert max(abs(a - b) for a, b in zip(symbolic.states[0], tape.states[0])) < 1e-18
    assert max(abs(a - b) for a, b in zip(symbolic.states[0], y0)) > 1e-3  # it moved
