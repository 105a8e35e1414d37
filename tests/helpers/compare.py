"""kronsub's derived systems against hand derivations (tests/reference/) at random states, times and
randomly perturbed parameters: the largest relative difference, walks along closed loops kept on
one branch, and the accelerations of the compiled C and of the generated numpy module."""
from __future__ import annotations

import numpy as np
import sympy as sp

from reference.lagrange import dots, t


TOL = 1e-10


def evaluator(exprs, names):
    symbols = {s.name: s for e in exprs for s in e.free_symbols}
    unknown = set(symbols) - set(names)
    assert not unknown, f"unexpected symbols {sorted(unknown)}"
    used = [n for n in names if n in symbols]
    fns = [sp.lambdify([symbols[n] for n in used], e, "numpy", cse=True) for e in exprs]
    return lambda values: [np.array(fn(*[values[n] for n in used]), dtype=float) for fn in fns]


def compare_explicit(system, reference, seed, *, spread=3.0, jitter=0.3, states=10, fixed=None):
    """Largest relative difference of kronsub's ``Mbar, hbar, fbar`` from the reference's at random
    states, times and parameters (each parameter its model value times 1 +- ``jitter``)."""
    return largest_difference(system, [system.mass_matrix, system.velocity_terms, system.forces], list(reference),
                              seed, spread=spread, jitter=jitter, states=states, fixed=fixed)


def largest_difference(system, ours, theirs, seed, *, spread=3.0, jitter=0.3, states=10, fixed=None):
    """Largest relative difference of the expressions ``ours`` from ``theirs`` (pairwise) at random
    states, times and parameters of ``system``."""
    rng = np.random.default_rng(seed)
    params = {p.name: float(p.value) for p in system.parameters if p.value is not None}
    q = [s.name for s in system.coordinates] + [s.name for s in system.velocities]
    names = ["t", *q, *sorted(params)]
    ours, theirs = evaluator(list(ours), names), evaluator(list(theirs), names)
    worst = 0.0
    for _ in range(states):
        values = {n: v * (1 + jitter * rng.uniform(-1, 1)) for n, v in params.items()}
        values.update({n: rng.uniform(-spread, spread) for n in q})
        values["t"] = rng.uniform(0, 3)
        if fixed:
            values.update(fixed(rng))
        for a, b in zip(ours(values), theirs(values)):
            a = np.broadcast_to(a, b.shape)
            worst = max(worst, float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b)))))
    return worst


def walk_constrained(system, ref, start, guess, seed, step=0.25, states=10):
    """Pairs (kronsub, reference) of ``Mbar, hbar, fbar, accelerations (numpy), accelerations (C)``
    along a random walk of the independent coordinate from ``start`` (kept on one branch)."""
    num = system.numeric()
    pv = [num.parameters[name] for name in ref.params]
    rng = np.random.default_rng(seed)
    q, rows = float(start), []
    for _ in range(states):
        q += rng.uniform(-step, step)
        u, tt = rng.uniform(-3, 3), rng.uniform(0, 2)
        yv, ydv = ref.consistent([q], [u], guess, pv)
        guess = yv
        Mb, hb, fb, acc = ref.evaluate(tt, yv, ydv, pv)
        st = [q, u]
        kM, kh, kf = num.mass_matrix([q]), num.velocity_terms(st), num.forces(tt, st)
        projected = np.linalg.solve(kM, kf - kh)
        rows.append(((kM, Mb), (kh, hb), (kf, fb), (projected, acc), (num.rhs(tt, st)[1:], acc)))
    return rows


def worst(pairs):
    return max(float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b)))) for a, b in pairs)


def accelerations_agree(system, M, h, f, seed, *, states=5, spread=2.0, numpy_module=None):
    """kronsub's compiled right-hand side (and optionally a generated numpy module's) against
    ``M^-1 (f - h)`` of the reference at the model's parameter values."""
    num = system.numeric()
    q = [sp.Symbol(s.name) for s in system.coordinates]
    names = [p.name for p in system.parameters if p.name in num.parameters]
    args = [t, *q, *dots(q), *(sp.Symbol(n) for n in names)]
    fns = [sp.lambdify(args, sp.Matrix(e), "numpy") for e in (M, h, f)]
    pv = [num.parameters[n] for n in names]
    rng = np.random.default_rng(seed)
    n, pairs = len(q), []
    for _ in range(states):
        tt, y = rng.uniform(0, 3), rng.uniform(-spread, spread, 2 * n)
        Mr, hr, fr = (np.array(fn(tt, *y, *pv), dtype=float) for fn in fns)
        want = np.linalg.solve(Mr, fr.ravel() - hr.ravel())
        pairs.append((num.rhs(tt, y)[n:], want))
        if numpy_module is not None:
            slots = np.array([num.parameters[name] for name in numpy_module.PARAMETERS])
            pairs.append((np.asarray(numpy_module.rhs(tt, y, slots))[n:], want))
    return worst(pairs)


def walk_independent(system, ref, start, guess, seed, *, step=0.1, states=8):
    """Pairs (kronsub, reference) of ``Mbar, hbar, fbar`` and the accelerations (compiled C)
    along a random walk of several independent coordinates (kept on one branch)."""
    num = system.numeric()
    pv = [num.parameters[name] for name in ref.params]
    rng = np.random.default_rng(seed)
    q, pairs = np.array(start, dtype=float), []
    for _ in range(states):
        q = q + rng.uniform(-step, step, len(q))
        u, tt = rng.uniform(-2, 2, len(q)), rng.uniform(0, 2)
        yv, ydv = ref.consistent(q, u, guess, pv)
        guess = yv
        Mb, hb, fb, acc = ref.evaluate(tt, yv, ydv, pv)
        st = np.concatenate([q, u])
        pairs += [(num.mass_matrix(q), Mb), (num.velocity_terms(st), hb), (num.forces(tt, st), fb),
                  (num.rhs(tt, st)[len(q):], acc)]
    return pairs


def compare_energies(system, T, V, seed, *, spread=3.0, jitter=0.3, states=6, fixed=None):
    """Largest relative difference of kronsub's ``T`` (from ``Mbar``) and ``V`` from the hand ones."""
    return largest_difference(system, [system.kinetic_energy, system.potential_energy], [sp.sympify(T), sp.sympify(V)],
                              seed, spread=spread, jitter=jitter, states=states, fixed=fixed)


def same_roots(ours, theirs, tol: float) -> bool:
    """The two lists of eigenvalues equal to ``tol``, each matched to its nearest."""
    left = list(theirs)
    for e in ours:
        k = int(np.argmin([abs(e - t) for t in left]))
        if abs(e - left.pop(k)) > tol:
            return False
    return not left
