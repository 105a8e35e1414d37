"""Scenes: a scene switches effects off in nested known systems, in the generated C and numpy
module (``codegen --scene``) and in runs; free scenes keep energy (and angular momentum where the
model has the symmetry) along simulated trajectories; each against a hand derivation.
"""
from __future__ import annotations

import ctypes
import dataclasses
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from kronsub.api import System
import kronsub
from helpers.compare import compare_energies, compare_explicit, TOL, worst
from kronsub.cli import main
from reference import sweep3, sweep4, sweep5, sweep6
from reference.lagrange import dots, gradient_force, kinetic, lagrange, S, t


def test_two_cart_pendulums_scene_switches_off_nested_effects():
    """A scene switching off effects two levels down (`left.base.push`): the hand equations with
    those loads zero, none of their parameters left, and the total energy kept in a run."""
    from kronsub.model.scenes import derive_scene, select_scene

    q, M, h, f, V = sweep3.two_cart_reference()
    model = kronsub.load(sweep3.HERE / "two_cart_pendulums.yaml")
    system = derive_scene(model, select_scene(model, "conservative"))
    names = {p.name for p in system.parameters}
    assert not names & {"c", "cp", "cc", "P", "om", "Q"}, names
    off = {sp.Symbol(n): 0 for n in ("c", "cp", "cc", "P", "Q")}
    fixed = lambda rng: {"x1": rng.uniform(0, 0.5), "x2": rng.uniform(0, 0.5)}  # noqa: E731
    assert compare_explicit(system, (M, h, f.subs(off)), 45, fixed=fixed) < TOL
    run = System.of(dataclasses.replace(system, initial=dict(model.initial))).simulate(t=2.0, dt=0.5, dataframe=False)
    energy = run["total_energy"]
    assert run.complete and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))


def test_kepler_scene_keeps_energy_and_angular_momentum():
    from kronsub.model.scenes import derive_scene, select_scene

    q, T, V, _ = sweep4.kepler_reference()
    model = sweep4.loaded("kepler_polar.yaml")
    system = derive_scene(model, select_scene(model, "kepler"))
    fixed = lambda rng: {"r": rng.uniform(0.3, 2)}  # noqa: E731
    assert compare_explicit(system, lagrange(T, V, q, [0, 0]), 55, fixed=fixed) < TOL
    run = System.of(dataclasses.replace(system, initial=dict(model.initial))).simulate(t=10.0, dt=0.5, dataframe=False)
    assert run.complete
    energy = run["total_energy"]
    assert np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    momentum = run["r"] ** 2 * run["a_dot"]  # m = 1
    assert np.ptp(momentum) < 1e-8


def test_known_system_under_scenes():
    from kronsub.model.scenes import derive_scene, select_scene

    q, M, h, V, knee, motor = sweep4.scene_reference()
    model = sweep4.loaded("scene_with_known.yaml")
    full = sweep4.derived("scene_with_known.yaml")
    assert "rho" not in {p.name for p in full.parameters}
    assert compare_explicit(full, (M, h, gradient_force(V, q, [a + b for a, b in zip(knee, motor)])), 58) < TOL
    assert compare_energies(full, kinetic(M, q), V, 58) < TOL
    cons = derive_scene(model, select_scene(model, "conservative"))
    names = {p.name for p in cons.parameters}
    assert not names & {"cr", "tm"}, names
    assert next(p for p in cons.parameters if p.name == "kt").value == sp.Rational(5, 2)
    assert compare_explicit(cons, (M, h, gradient_force(V, q)), 59) < TOL
    run = System.of(dataclasses.replace(cons, initial=dict(model.initial))).simulate(t=3.0, dt=0.5, dataframe=False)
    energy = run["total_energy"]
    assert run.complete and np.ptp(energy) < 1e-8 * max(1.0, np.max(np.abs(energy)))
    bare = derive_scene(model, select_scene(model, "bare"))  # the shaft and the known system's gravity
    kt, k0 = S("kt k0")
    assert compare_explicit(bare, (M, h, gradient_force(V.subs({kt: 0, k0: 0}), q)), 60) < TOL


def test_nested_scene_numpy_module(tmp_path):
    import importlib.util

    result = CliRunner().invoke(main, ["codegen", str(sweep5.HERE / "nested_scenes.yaml"), "--scene", "quiet",
                                       "--lang", "python", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    spec = importlib.util.spec_from_file_location("sweep5_nested_quiet", tmp_path / "nested_scenes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert not {"cp", "tm"} & set(mod.PARAMETERS), mod.PARAMETERS  # only the switched-off effects use them
    values = sweep5.quiet_values()
    param = np.array([float(values[n]) for n in mod.PARAMETERS])
    fM, fh, ff, fT, fV = sweep5.hand_numbers(sweep5.nested_reference(hinges=False, motor=False), values)
    pairs = []
    for tt, y in sweep5.nested_states(511):
        q, qd = y[:5], y[5:]
        M, h, f = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        pairs += [(mod.mass_matrix(q, param), M), (mod.velocity_terms(q, qd, param), h.ravel()),
                  (mod.forces(tt, q, qd, param), f.ravel()),
                  (np.asarray(mod.rhs(tt, y, param))[5:], np.linalg.solve(M, f.ravel() - h.ravel())),
                  (np.array([mod.kinetic_energy(y, param), mod.potential_energy(tt, y, param)]),
                   np.array([fT(tt, *y), fV(tt, *y)], dtype=float))]
    assert worst(pairs) < TOL


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
@pytest.mark.parametrize("which", ["driven"])  # quiet: the numpy module above
def test_nested_scene_generated_c(tmp_path, which):
    from helpers.generated import header_order

    result = CliRunner().invoke(main, ["codegen", str(sweep5.HERE / "nested_scenes.yaml"), "--scene", which, "--lang", "c",
                                       "--prefix", "nq", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    lib = tmp_path / "libnested.so"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC",
                    str(tmp_path / "nested_scenes.c"), "-o", str(lib), "-lm"], check=True, capture_output=True)
    names, _ = header_order((tmp_path / "nested_scenes.h").read_text(), "NQ")
    if which == "quiet":
        values, ref = sweep5.quiet_values(), sweep5.nested_reference(hinges=False, motor=False)
        assert not {"cp", "tm"} & set(names), names
    else:  # gravity, the coupling, the shaft and the motor: no wall springs, no hinges
        values = {**sweep5.NESTED_VALUES, "k": 0, "kL": 0}
        ref = sweep5.nested_reference(hinges=False, motor=True)
        assert not {"cp", "k", "kL", "L0"} & set(names), names
    c = ctypes.CDLL(str(lib))
    D = ctypes.POINTER(ctypes.c_double)
    c.nq_rhs.argtypes = [ctypes.c_double, D, D, D]
    c.nq_forces.argtypes = [ctypes.c_double, D, D, D, D]
    ptr = lambda a: a.ctypes.data_as(D)  # noqa: E731
    param = np.array([float(values[n]) for n in names])
    fM, fh, ff, _, _ = sweep5.hand_numbers(ref, values)
    pairs = []
    for tt, y in sweep5.nested_states(512):
        q, qd = y[:5].copy(), y[5:].copy()
        M, h, f = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        Mc, fc, ydot = np.zeros(25), np.zeros(5), np.zeros(10)
        c.nq_mass_matrix(ptr(q), ptr(param), ptr(Mc))
        c.nq_forces(tt, ptr(q), ptr(qd), ptr(param), ptr(fc))
        assert c.nq_rhs(tt, ptr(y), ptr(param), ptr(ydot)) == 0
        pairs += [(Mc.reshape(5, 5), M), (fc, f.ravel()), (ydot[5:], np.linalg.solve(M, f.ravel() - h.ravel()))]
    assert worst(pairs) < TOL


def test_nested_scene_run_and_placed_points(tmp_path):
    """`simulate --scene driven` (its t_end, dt and outputs): every row against the hand
    equations integrated here (scipy, tight tolerances), and the points of the placed nested
    copies (a line point on the plane's x axis) at the row's state."""
    from scipy.integrate import solve_ivp

    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(sweep5.HERE / "nested_scenes.yaml"), "--scene", "driven",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#", deletechars="")
    values = {**sweep5.NESTED_VALUES, "k": 0, "kL": 0}
    fM, fh, ff, fT, fV = sweep5.hand_numbers(sweep5.nested_reference(hinges=False, motor=True), values)

    def rhs(tt, y):
        M = np.array(fM(tt, *y), dtype=float)
        return np.concatenate([y[5:], np.linalg.solve(M, (np.array(ff(tt, *y), dtype=float)
                                                          - np.array(fh(tt, *y), dtype=float)).ravel())])

    y0 = [0.5, 0.2, 0.4, -0.1, 0, 0, 0, 0, 0, 0]
    sol = solve_ivp(rhs, (0, 0.5), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=np.linspace(0, 0.5, 6))
    names = ["s1", "th1", "s2", "th2", "f", "s1_dot", "th1_dot", "s2_dot", "th2_dot", "f_dot"]
    assert np.allclose(table["t"], sol.t)
    ours = np.column_stack([table[n] for n in names])
    assert np.allclose(ours, sol.y.T, rtol=1e-8, atol=1e-8)
    l, d = values["l"], values["d"]
    s1, th1, s2, th2 = (table[n] for n in ("s1", "th1", "s2", "th2"))
    points = {"pair.right.pole.tip": (d + s2 + l * np.sin(th2), -l * np.cos(th2)),
              "pair.left.pole.centre": (s1 + l / 2 * np.sin(th1), -l / 2 * np.cos(th1)),
              "pair.right.cart.centre": (d + s2, 0 * s2)}
    for name, (px, py) in points.items():
        assert np.allclose(table[f"{name}.x"], px, atol=1e-12) and np.allclose(table[f"{name}.y"], py, atol=1e-12), name
    energy = [(fT(tt, *y), fV(tt, *y)) for tt, y in zip(sol.t, sol.y.T)]
    ours = np.column_stack([table["kinetic_energy"], table["potential_energy"]])
    assert np.allclose(ours, energy, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("which, damper, swirl", [("undamped", False, True), ("free", False, False)])
def test_elastic_spherical_pendulum_scenes(which, damper, swirl):
    """A scene's equations are the full ones with its switched-off effects' parameters at zero
    (the hand ones with c = 0, and P = 0 for `free`), and they no longer contain them."""
    q, T, V, Q = sweep6.elastic_reference(damper, swirl)
    system = sweep6.scene("elastic_spherical_pendulum.yaml", which)
    gone = {"c"} if swirl else {"c", "P", "w"}
    used = {s.name for e in (system.mass_matrix, system.velocity_terms, system.forces) for s in e.free_symbols}
    assert not gone & used and not gone & {p.name for p in system.parameters}
    assert compare_explicit(system, lagrange(T, V, q, Q), 603, fixed=sweep6.positive_r) < TOL
    full = sweep6.derived("elastic_spherical_pendulum.yaml")
    zero = {p.symbol: 0 for p in full.parameters if p.name in ({"c"} if swirl else {"c", "P"})}
    for ours, theirs in ((system.mass_matrix, full.mass_matrix), (system.velocity_terms, full.velocity_terms),
                         (system.forces, full.forces.xreplace(zero))):
        assert sp.expand(ours - theirs) == sp.zeros(*ours.shape)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_elastic_spherical_pendulum_scene_generated_c(tmp_path):
    """`codegen --scene undamped --lang c`, compiled with warnings as errors: no slot for the
    damper's ``c``; mass matrix, forces and accelerations against the hand equations."""
    from helpers.generated import header_order

    result = CliRunner().invoke(main, ["codegen", str(sweep6.HERE / "elastic_spherical_pendulum.yaml"), "--scene",
                                       "undamped", "--lang", "c", "--prefix", "esp", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    lib = tmp_path / "libesp.so"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC",
                    str(tmp_path / "elastic_spherical_pendulum.c"), "-o", str(lib), "-lm"], check=True,
                   capture_output=True)
    names, _ = header_order((tmp_path / "elastic_spherical_pendulum.h").read_text(), "ESP")
    assert "c" not in names and {"P", "w"} <= set(names)
    q, T, V, Q = sweep6.elastic_reference(damper=False)
    M, h, f = lagrange(T, V, q, Q)
    values = {"m": 0.7, "k": 30, "l0": 0.9, "P": 0.5, "w": 1.7, "g": 9.81}  # the model's values
    sub = {s: values[s.name] for e in (M, h, f) for s in e.free_symbols if s.name in values}
    fM, fh, ff = (sp.lambdify([t, *q, *dots(q)], e.xreplace(sub), "numpy") for e in (M, h, f))
    lib = ctypes.CDLL(str(lib))
    D = ctypes.POINTER(ctypes.c_double)
    lib.esp_rhs.argtypes = [ctypes.c_double, D, D, D]
    lib.esp_forces.argtypes = [ctypes.c_double, D, D, D, D]
    ptr = lambda a: a.ctypes.data_as(D)  # noqa: E731
    param = np.array([float(values[n]) for n in names])
    rng = np.random.default_rng(621)
    pairs = []
    for _ in range(6):
        tt, y = rng.uniform(0, 3), rng.uniform(-2, 2, 6)
        y[0], y[1] = rng.uniform(0.3, 2), rng.uniform(0.2, 2.9)
        qv, qdv = y[:3].copy(), y[3:].copy()
        Mr, hr, fr = (np.array(fn(tt, *y), dtype=float) for fn in (fM, fh, ff))
        Mc, fc, ydot = np.zeros(9), np.zeros(3), np.zeros(6)
        lib.esp_mass_matrix(ptr(qv), ptr(param), ptr(Mc))
        lib.esp_forces(tt, ptr(qv), ptr(qdv), ptr(param), ptr(fc))
        assert lib.esp_rhs(tt, ptr(y), ptr(param), ptr(ydot)) == 0
        pairs += [(Mc.reshape(3, 3), Mr), (fc, fr.ravel()), (ydot[3:], np.linalg.solve(Mr, fr.ravel() - hr.ravel()))]
    assert worst(pairs) < TOL


def test_ring_free_scene_keeps_energy_and_angular_momentum(tmp_path):
    """`simulate --scene free`: the energies in the CSV are the hand ``T`` and ``V`` of each row,
    and the total energy and ``sum m_i R^2 u_i_dot`` (the springs are central in the ring's
    plane) stay constant."""
    out = tmp_path / "ring.csv"
    result = CliRunner().invoke(main, ["simulate", str(sweep6.HERE / "bead_ring.yaml"), "--scene", "free", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    assert len(table) == 7  # the scene's t_end and dt
    u, T, V, _ = sweep6.ring_reference(damper=False)
    values = {s: sweep6.RING[s.name] for s in (T + V).free_symbols if s.name in sweep6.RING}
    fT, fV = (sp.lambdify([*u, *dots(u)], e.xreplace(values), "numpy") for e in (T, V))
    state = [table[n] for n in ("u1", "u2", "u3", "u4", "u1_dot", "u2_dot", "u3_dot", "u4_dot")]
    assert np.allclose(table["kinetic_energy"], fT(*state), rtol=1e-12, atol=1e-12)
    assert np.allclose(table["potential_energy"], fV(*state), rtol=1e-12, atol=1e-12)
    energy = table["total_energy"]
    momentum = sum(sweep6.RING[f"m{i}"] * sweep6.RING["R"] ** 2 * table[f"u{i}_dot"] for i in range(1, 5))
    assert np.max(np.abs(energy - energy[0])) < 1e-7 and np.max(np.abs(momentum - momentum[0])) < 1e-7
    assert abs(momentum[0] - (1.0 * 2.0 - 0.8) * 0.25) < 1e-12  # the initial velocities


def test_swinging_atwood_free_scene_keeps_energy(tmp_path):
    """`simulate --scene free` (gauss4, fixed step 0.01): the hand energy of every row is the first's."""
    q, T, V, _ = sweep6.atwood_reference(rope=False)
    values = {s: v for s, v in zip(S("m M L g"), (1.0, 1.3, 3, 9.81))}  # the model's values
    table, energy = sweep6.free_run(tmp_path, "swinging_atwood.yaml", q, T + V, values)
    assert len(table) == 201 and np.min(table["r"]) > 0.3
    assert np.allclose(table["total_energy"], energy, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(energy - energy[0])) < 1e-6


def test_charge_free_scene_keeps_energy_and_canonical_angular_momentum(tmp_path):
    q, T, V, _ = sweep6.charge_reference(drag=False)
    values = dict(zip(S("m mu eps b"), (1.0, 4, 0.5, 0.7)))  # the model's values
    table, energy = sweep6.free_run(tmp_path, "charge_in_central_field.yaml", q, T + V, values)
    rho2 = (table["r"] * np.sin(table["th"])) ** 2
    momentum = 1.0 * rho2 * table["ph_dot"] + 0.7 * rho2 / 2
    assert len(table) == 9 and np.allclose(table["total_energy"], energy, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(energy - energy[0])) < 1e-7 and np.max(np.abs(momentum - momentum[0])) < 1e-7
