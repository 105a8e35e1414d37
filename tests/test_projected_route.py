"""The projection kept at run time in the generated C (emitters/projected.py).

Independent routes: the projected C's ``Mbar``, ``hbar``, ``fbar`` against the derived symbolic
expressions, and every right-hand side (``[q; qdot]``, the circle state, the canonical form)
against the expanded C of the same model, at random states; energy over a run of the projected
right-hand side; the choice by size leaving smaller models' code as it was.
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import sympy
from scipy.integrate import solve_ivp

import kronsub
from conftest import MODELS
from kronsub.emitters.code import emit_c
from kronsub.emitters.projected import PROJECTED_FROM, applies, projected_by_size
from kronsub.errors import KronsubError

sys.path.insert(0, str(MODELS / "chain"))
from generate import chain_yaml  # noqa: E402
from generate_spatial import spatial_chain_yaml  # noqa: E402

needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O2"]
DOUBLE = ctypes.c_double


def _library(system, route, folder, **options):
    folder.mkdir()
    generated = emit_c(system, "model", route=route, **options)
    for g in generated:
        (folder / g.name).write_text(g.text)
    sources = [g.name for g in generated if g.name.endswith(".c")]
    subprocess.run(["gcc", *CFLAGS, "-fPIC", "-shared", *sources, "-o", "lib.so", "-lm"], cwd=folder, check=True,
                   capture_output=True, text=True)
    lib = ctypes.CDLL(str(folder / "lib.so"))
    for name in ("ks_kinetic_energy", "ks_potential_energy"):
        getattr(lib, name).restype = DOUBLE
    return lib


def _array(values):
    return (DOUBLE * len(values))(*values)


def _evaluate(lib, n, t, y, param) -> dict:
    """Every function of the generated C that the projection computes, at one state."""
    yc, pc, qd = _array(y), _array(param), _array(y[n:])
    out = {name: (DOUBLE * size)() for name, size in (("M", n * n), ("h", n), ("f", n), ("rhs", 2 * n),
                                                      ("canonical", 2 * n), ("momentum", 2 * n))}
    lib.ks_mass_matrix(yc, pc, out["M"])
    lib.ks_velocity_terms(yc, qd, pc, out["h"])
    lib.ks_forces(DOUBLE(t), yc, qd, pc, out["f"])
    assert lib.ks_rhs(DOUBLE(t), yc, pc, out["rhs"]) == 0
    lib.ks_momentum(yc, pc, out["momentum"])
    assert lib.ks_rhs_canonical(DOUBLE(t), out["momentum"], pc, out["canonical"]) == 0
    values = {name: np.array(v[:]) for name, v in out.items()}
    nc = lib.ks_ncircle()
    if nc:
        z, zdot = (DOUBLE * (2 * n + 2 * nc))(), (DOUBLE * (2 * n + 2 * nc))()
        lib.ks_circle_state(yc, z)
        assert lib.ks_rhs_circle(DOUBLE(t), z, pc, zdot) == 0
        values["circle"] = np.array(zdot[:2 * n])
    return values


def _close(a, b, rtol=1e-12):
    """Equal to ``rtol`` relative to the largest entry of ``b``."""
    return np.allclose(a, b, rtol=rtol, atol=rtol * max(1.0, float(np.max(np.abs(b)))))


def _states(system, count, seed=3, around=False):
    """Random (t, y, param); ``around``: the model's own parameters each moved by up to 10 %
    (a machine's inductances are positive definite only near its values)."""
    rng = np.random.default_rng(seed)
    n = len(system.coordinates)
    values = np.array([float(p.value) for p in system.parameters])
    for _ in range(count):
        scale = rng.uniform(0.9, 1.1, len(values)) if around else rng.uniform(0.5, 1.5, len(values))
        yield rng.uniform(0, 2), rng.uniform(-1.0, 1.0, 2 * n), scale * values if around else scale


MODELS_PROJECTED = {  # name: the model
    "chain4": lambda: kronsub.load("chain4.yaml", text=chain_yaml(4)),
    # springs and dampers: f names x and xdot
    "chain5_hinges": lambda: kronsub.load("chain5_hinges.yaml", text=chain_yaml(5, hinges=True)),
    # rigid bodies: M(x) and h(x, xdot) of the primitive
    "spatial2": lambda: kronsub.load("spatial2.yaml", text=spatial_chain_yaml(2)),
    # inductances that turn with the rotor, a governor's sleeves, a cart, particles: M's entries
    # of x beside constant ones, entries of C that are constants, sums and products of bases
    **{path.stem: (lambda path=path: kronsub.load(path)) for path in (
        MODELS / "electrical" / "machine_pair.yaml", MODELS / "electrical" / "magnetic_suspension.yaml",
        MODELS / "examples" / "watt_governor.yaml", MODELS / "examples" / "cart_pole.yaml",
        MODELS / "examples" / "particle_on_sphere.yaml", MODELS / "hoffmann" / "three_particles.yaml")},
}


@needs_cc
@pytest.mark.parametrize("name", sorted(MODELS_PROJECTED))
def test_the_projected_c_computes_the_expanded_equations(name, tmp_path):
    """Mbar = C^T M C, hbar, fbar (9'), (D)-(F) at run time: the derived expressions' values,
    and every right-hand side the expanded C's, at random states."""
    system = MODELS_PROJECTED[name]().derive()
    assert applies(system)
    n = len(system.coordinates)
    projected = _library(system, "projected", tmp_path / "projected")
    expanded = _library(system, "expanded", tmp_path / "expanded")
    syms = [*system.coordinates, *system.velocities, *(p.symbol for p in system.parameters), sympy.Symbol("t", real=True)]
    symbolic = sympy.lambdify(syms, [system.mass_matrix, system.velocity_terms, system.forces], modules="numpy",
                              dummify=True)
    for t, y, param in _states(system, 20, around=name not in ("chain4", "chain5_hinges", "spatial2")):
        M, h, f = (np.array(v, float) for v in symbolic(*y, *param, t))
        got, want = _evaluate(projected, n, t, y, param), _evaluate(expanded, n, t, y, param)
        assert _close(got["M"].reshape(n, n), M) and _close(got["h"], h.ravel()) and _close(got["f"], f.ravel())
        assert _close(got["rhs"][n:], np.linalg.solve(M, f.ravel() - h.ravel()), 1e-11)
        # the projected C has no circle state where an angle is multiplied in M's entries (cos 2 theta)
        assert set(got) <= set(want) and set(want) - set(got) <= ({"circle"} if name == "machine_pair" else set())
        for key in got:
            assert _close(got[key], want[key], 1e-11), key


@needs_cc
def test_a_run_of_the_projected_right_hand_side_keeps_its_energy(tmp_path):
    system = kronsub.load("chain4.yaml", text=chain_yaml(4)).derive()
    lib = _library(system, "projected", tmp_path / "projected")
    param = _array([float(p.value) for p in system.parameters])
    n = len(system.coordinates)

    def rhs(t, y):
        out = (DOUBLE * (2 * n))()
        assert lib.ks_rhs(DOUBLE(t), _array(y), param, out) == 0
        return out[:]

    def energy(y):
        return lib.ks_kinetic_energy(_array(y), param) + lib.ks_potential_energy(DOUBLE(0.0), _array(y), param)

    y0 = [0.8, -0.4, 0.3, 1.0, 0.0, 0.5, -0.2, 0.0]
    run = solve_ivp(rhs, (0.0, 3.0), y0, method="DOP853", rtol=1e-11, atol=1e-11)
    assert run.success
    e0 = energy(y0)
    assert max(abs(energy(y) - e0) for y in run.y.T) < 1e-8 * max(1.0, abs(e0))


def test_the_route_is_chosen_by_size_and_smaller_models_keep_their_code():
    for path in ("hoffmann/system1.yaml", "examples/double_pendulum.yaml"):
        system = kronsub.load(MODELS / path).derive()
        assert [g.text for g in emit_c(system, "m")] == [g.text for g in emit_c(system, "m", route="expanded")]
    below = kronsub.load("below.yaml", text=chain_yaml(PROJECTED_FROM - 1)).derive()
    assert applies(below) and not projected_by_size(below)
    at = kronsub.load("at.yaml", text=chain_yaml(PROJECTED_FROM)).derive()
    assert projected_by_size(at) and "project_metric" in emit_c(at, "m")[1].text


def test_a_closed_loop_is_not_projected_at_run_time():
    system = kronsub.load(MODELS / "examples" / "four_bar.yaml").derive()
    assert not applies(system)
    with pytest.raises(KronsubError, match="closed loop"):
        emit_c(system, "m", route="projected")
    with pytest.raises(ValueError, match="route"):
        emit_c(system, "m", route="sideways")


def test_the_projected_code_is_the_same_under_any_hash_seed(tmp_path):
    script = ("import sys; sys.path.insert(0, sys.argv[1]); from generate import chain_yaml; import kronsub; "
              "from kronsub.emitters.code import emit_c; "
              "s = kronsub.load('c.yaml', text=chain_yaml(3, hinges=True)).derive(); "
              "sys.stdout.write(''.join(g.text for g in emit_c(s, 'm', route='projected')))")
    texts = []
    for seed in ("1", "777"):
        env = dict(os.environ, PYTHONHASHSEED=seed, KRONSUB_CACHE_DIR=str(tmp_path / seed))
        proc = subprocess.run([sys.executable, "-c", script, str(MODELS / "chain")], capture_output=True, env=env,
                              text=True)
        assert proc.returncode == 0, proc.stderr
        texts.append(proc.stdout)
    assert texts[0] == texts[1] and "project_metric" in texts[0]


@needs_cc
def test_a_simulation_of_a_model_at_the_threshold_keeps_its_energy():
    """The whole run (the library built with the projected route, the circle state, the
    energies from the projected Mbar) against the invariant T + V."""
    system = kronsub.load("at.yaml", text=chain_yaml(PROJECTED_FROM)).derive()
    assert projected_by_size(system)
    table = system.simulate(t=2.0, set={"q1": 0.9, "q3": -0.4})
    energy, potential = np.asarray(table["total_energy"]), np.asarray(table["potential_energy"])
    assert len(energy) > 100 and np.ptp(potential) > 1.0  # it moved
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(potential))


def _tree_sums(nodes, weight):
    """Each node's sum along its path from node 0 (the empty sum): ``weight(node)`` per step."""
    sums = [0.0]
    for i, node in enumerate(nodes[1:], start=1):
        sums.append(sums[node[0]] + weight(node))
    return sums


def test_the_trees_of_shared_parts_sum_what_the_rows_and_columns_hold():
    """``Cdot xbardot`` row by row and ``C^T w`` column by column over the trees of their shared
    parts equal the plain sums over a random sparse ``C`` whose columns repeat values down rows."""
    from kronsub.emitters.projected import _column_tree, _row_tree

    rng = np.random.default_rng(7)
    for _ in range(20):
        n, nx = int(rng.integers(1, 7)), int(rng.integers(1, 12))
        rows = [tuple((j, int(rng.integers(0, 2 * n))) for j in range(n) if rng.random() < 0.6) for _ in range(nx)]
        values, qd, w = rng.normal(size=2 * n), rng.normal(size=n), rng.normal(size=nx)
        nodes, ends = _row_tree(rows)
        sums = _tree_sums(nodes, lambda node: values[node[1]] * qd[node[2]])
        for a, row in enumerate(rows):
            assert sums[ends[a]] == pytest.approx(sum(values[u] * qd[j] for j, u in row), abs=1e-12)
        nodes, terms = _column_tree(rows, n)
        sums = _tree_sums(nodes, lambda node: w[node[1]])
        got = np.zeros(n)
        for column, value, node in terms:
            got[column] += values[value] * sums[node]
        want = np.zeros(n)
        for a, row in enumerate(rows):
            for j, u in row:
                want[j] += values[u] * w[a]
        assert np.allclose(got, want, atol=1e-12)


def test_a_chain_s_projection_keeps_its_structure():
    """The 20-link chain: the trees grow with the links, not with C's entries (about n^2); each
    entry of Mbar off the diagonal is one weight times cos q_j cos q_k + sin q_j sin q_k, and each on
    it a weight alone (cos^2 + sin^2 = 1, the rod's own inertia added to the same weight)."""
    from kronsub.emitters.numeric import prepare

    n = 20
    pj = prepare(kronsub.load("chain20.yaml", text=chain_yaml(n)).derive(), route="projected").projected
    assert sum(len(row) for row in pj.c_rows) > n * n
    assert len(pj.row_nodes) <= 5 * n + 1 and len(pj.column_nodes) <= 5 * n + 1
    for upper, lower, groups, terms in pj.entries:
        assert not terms
        ((_, products),) = groups
        assert products == ((),) if upper == lower else [len(p) for p in products] == [2, 2]


@needs_cc
def test_mbar_in_a_file_of_its_own_computes_the_same_bits(tmp_path):
    """A run's library compiles the projection's Mbar in its own file beside model.c
    (``metric_apart``): the same right-hand sides, bit for bit, as the one file of ``codegen``."""
    system = kronsub.load("chain12.yaml", text=chain_yaml(12)).derive()
    names = [g.name for g in emit_c(system, "model", metric_apart=True)]
    assert names == ["model.h", "model.c", "model_metric.c"]
    one = _library(system, "auto", tmp_path / "one")
    apart = _library(system, "auto", tmp_path / "apart", metric_apart=True)
    n = len(system.coordinates)
    for t, y, param in _states(system, 5):
        got, want = _evaluate(apart, n, t, y, param), _evaluate(one, n, t, y, param)
        assert set(got) == set(want) and all(np.array_equal(got[k], want[k]) for k in want)


def _particles_yaml(n: int, coefficient, last: str = "") -> str:
    """``n`` particles on a line, ``x_i = sum_{j <= i} a_ij y_j`` (``coefficient(i, j)``: the
    text of ``a_ij``; ``last``: a term added to ``x_n``), springs between neighbours: a constant
    ``C`` of numbers alone but for ``last``."""
    lines = ["name: particles", "parameters:", "  k: {value: 3, unit: N/m}",
             *(f"  m{i}: {{value: {1 + i / 10}, unit: kg}}" for i in range(1, n + 1)), "components:",
             *(f"  p{i}: {{type: particle1d, parameters: {{mass: m{i}}}, coordinates: [x{i}]}}"
               for i in range(1, n + 1)),
             "coordinates: [" + ", ".join(f"y{i}" for i in range(1, n + 1)) + "]", "connection:",
             *(f"  x{i}: " + " + ".join(f"{coefficient(i, j)}*y{j}" for j in range(1, i + 1)) + (last if i == n else "")
               for i in range(1, n + 1)),
             "effects:",
             *(f"  s{i}: {{type: spring, between: [p{i}.centre, p{i + 1}.centre], stiffness: k}}" for i in range(1, n))]
    return "\n".join(lines) + "\n"


@needs_cc
def test_a_weight_past_the_double_range_is_written_as_c_reads_it(tmp_path):
    """Two of C's numbers whose product (a weight's coefficient, once per parameter set) is past
    the double range: the C still compiles, and its Mbar is the expanded C's (infinite where that
    one's is, equal elsewhere)."""
    import warnings

    text = _particles_yaml(PROJECTED_FROM, lambda i, j: "1e170" if j == 3 else "1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # C's columns differ by 1e170: a rank warning at a random state
        system = kronsub.load("big.yaml", text=text).derive()
    assert projected_by_size(system)
    n = len(system.coordinates)
    param = [float(p.value) for p in system.parameters]
    y = np.linspace(-0.5, 0.5, 2 * n)
    got, want = ((DOUBLE * (n * n))(), (DOUBLE * (n * n))())
    _library(system, "projected", tmp_path / "projected").ks_mass_matrix(_array(y), _array(param), got)
    _library(system, "expanded", tmp_path / "expanded").ks_mass_matrix(_array(y), _array(param), want)
    got, want = np.array(got[:]), np.array(want[:])
    assert np.isinf(want).any() and np.array_equal(np.isinf(got), np.isinf(want))
    finite = np.isfinite(want)
    assert _close(got[finite], want[finite])


@needs_cc
def test_an_angle_sum_in_c_compiles_and_projects(tmp_path):
    """An entry of C with the sine of a sum of coordinates (the primitive's code calls the guarded
    angle's helper, defined further down the file): the projected C compiles and computes the
    expanded C's right-hand sides."""
    text = _particles_yaml(PROJECTED_FROM, lambda i, j: "1", " + cos(y1 + y2)")
    system = kronsub.load("sum.yaml", text=text).derive()
    assert projected_by_size(system)
    n = len(system.coordinates)
    projected = _library(system, "projected", tmp_path / "projected")
    expanded = _library(system, "expanded", tmp_path / "expanded")
    for t, y, param in _states(system, 5, around=True):
        got, want = _evaluate(projected, n, t, y, param), _evaluate(expanded, n, t, y, param)
        assert {"M", "rhs", "canonical"} <= set(got) <= set(want)
        for key in got:
            assert _close(got[key], want[key], 1e-11), key
