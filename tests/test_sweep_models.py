"""Robustness sweep: models kronsub was not built around (tests/models/sweep/), each checked
against an independent derivation written here in plain sympy, never with kronsub.

* Explicit models: ``M``, ``h``, ``f`` of ``M qddot + h = f`` from the geometry, either by
  Lagrange's equations of a hand-written ``T`` and ``V`` or by virtual power over the
  bodies (``M = sum m Jv^T Jv + Jw^T I Jw``, ``h = sum m Jv^T a0 + Jw^T (I alpha0 + w x I w)``,
  ``a0``, ``alpha0`` the accelerations at ``qddot = 0``), plus generalized forces by virtual
  work for the non-conservative effects. Compared with kronsub's ``Mbar``, ``hbar``, ``fbar``
  at random states and randomly perturbed parameters.
* Closed loops: Lagrange multipliers on the full coordinates ``y``
  (``[M G^T; G 0] [yddot; -mu] = [f - h; -Gdot ydot]``), the dependent coordinates by Newton's
  method and the dependent velocities from ``G ydot = 0``; compared with kronsub's projected
  ``Mbar``, ``hbar``, ``fbar`` and its accelerations (numpy module and compiled C).

"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import kronsub
from helpers import Rx, Ry, Rz
from kronsub.errors import ModelError

SWEEP = Path(__file__).resolve().parent / "models" / "sweep"
t = sp.Symbol("t")
S = sp.symbols
TOL = 1e-10


# ------------------------------------------------------------------------------------------
# Independent reference: Lagrange's equations, virtual power, constrained solve
# ------------------------------------------------------------------------------------------

def dots(q):
    return [sp.Symbol(f"{s.name}_dot") for s in q]


def lagrange(T, V, q, Q):
    """``M, h, f`` of ``d/dt dT/dqdot - dT/dq = -dV/dq + Q`` with ``T(q, qdot, t)``."""
    qd, n = dots(q), len(q)
    M = sp.Matrix(n, n, lambda i, j: sp.diff(T, qd[i], qd[j]))
    h = sp.Matrix([sum(sp.diff(T, qd[i], q[j]) * qd[j] for j in range(n)) + sp.diff(T, qd[i], t)
                   - sp.diff(T, q[i]) for i in range(n)])
    f = sp.Matrix([-sp.diff(V, q[i]) + Q[i] for i in range(n)])
    return M, h, f


def vee(W):
    return sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])


def virtual_power(bodies, q):
    """``M, h`` summed over bodies: ``(m, p)`` particles, ``(m, p, angle, I)`` planar bodies,
    ``(m, p, R, I3)`` bodies in space (``R`` world from body); ``p``, ``angle``, ``R`` in ``q``, ``t``."""
    qd, n = dots(q), len(q)
    Qd = sp.Matrix(qd)
    M, h = sp.zeros(n, n), sp.zeros(n, 1)

    def rate(e):
        return e.jacobian(q) * Qd + e.diff(t)

    for body in bodies:
        m, p = body[0], sp.Matrix(body[1])
        Jv, v = p.jacobian(q), rate(p)
        M += m * Jv.T * Jv
        h += m * Jv.T * rate(v)
        if len(body) == 4 and not isinstance(body[2], sp.MatrixBase):
            w = rate(sp.Matrix([body[2]]))
            Jw = w.jacobian(qd)
            M += body[3] * Jw.T * Jw
            h += body[3] * Jw.T * rate(w)
        elif len(body) == 4:
            R, inertia = body[2], body[3]
            Rd = sum((R.diff(x) * xd for x, xd in zip(q, qd)), R.diff(t))
            wb = vee(R.T * Rd)
            Jw = wb.jacobian(qd)
            M += Jw.T * inertia * Jw
            h += Jw.T * (inertia * rate(wb) + wb.cross(inertia * wb))
    return M, h


def rate_of(e, q):
    return sum((e.diff(x) * xd for x, xd in zip(q, dots(q))), e.diff(t))


def world_angular_velocity(R, q):
    return vee(rate_of(R, q) * R.T)


def _evaluator(exprs, names):
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
    ours, theirs = _evaluator(list(ours), names), _evaluator(list(theirs), names)
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


@lru_cache(maxsize=None)
def derived(name):
    return kronsub.load(SWEEP / name).derive()


class Constrained:
    """``M(y) yddot + h = f + G^T mu``, ``g(y) = 0`` on the full coordinates ``y``."""

    def __init__(self, y, M, h, f, g, independent, params):
        self.y, yd = list(y), dots(y)
        G = sp.Matrix(g).jacobian(y)
        Gdot_yd = (G * sp.Matrix(yd)).jacobian(y) * sp.Matrix(yd)
        self.ind = [self.y.index(s) for s in independent]
        self.dep = [i for i in range(len(y)) if i not in self.ind]
        args = [t, *self.y, *yd, *params]
        self.params = [p.name for p in params]
        fn = lambda e: sp.lambdify(args, e, "numpy", cse=True)  # noqa: E731
        self.fM, self.fh, self.ff, self.fg, self.fG, self.fGd = map(fn, (M, h, f, sp.Matrix(g), G, Gdot_yd))

    def consistent(self, q_ind, u_ind, guess, pv):
        """``y`` on the constraints (Newton from ``guess``, the independent ones held) and ``ydot``."""
        yv = np.array(guess, dtype=float)
        yv[self.ind] = q_ind
        zero = np.zeros(len(yv))
        for _ in range(100):
            r = np.array(self.fg(0.0, *yv, *zero, *pv), dtype=float).ravel()
            G = np.array(self.fG(0.0, *yv, *zero, *pv), dtype=float)
            step = np.linalg.solve(G[:, self.dep], -r)
            yv[self.dep] += step
            if np.max(np.abs(step)) < 1e-15:
                break
        assert np.max(np.abs(np.array(self.fg(0.0, *yv, *zero, *pv), dtype=float))) < 1e-12
        G = np.array(self.fG(0.0, *yv, *zero, *pv), dtype=float)
        ydv = np.zeros(len(yv))
        ydv[self.ind] = u_ind
        ydv[self.dep] = np.linalg.solve(G[:, self.dep], -G[:, self.ind] @ np.asarray(u_ind, dtype=float))
        return yv, ydv

    def evaluate(self, tt, yv, ydv, pv):
        """``Mbar, hbar, fbar`` in the independent coordinates and their accelerations from the
        multiplier solve (which never forms ``C``)."""
        a = (tt, *yv, *ydv, *pv)
        M = np.array(self.fM(*a), dtype=float)
        h = np.array(self.fh(*a), dtype=float).ravel()
        f = np.array(self.ff(*a), dtype=float).ravel()
        G = np.array(self.fG(*a), dtype=float)
        Gdy = np.array(self.fGd(*a), dtype=float).ravel()
        n, nc = len(yv), G.shape[0]
        K = np.block([[M, G.T], [G, np.zeros((nc, nc))]])
        acc = np.linalg.solve(K, np.concatenate([f - h, -Gdy]))[self.ind]
        C = np.zeros((n, len(self.ind)))
        C[self.ind, range(len(self.ind))] = 1
        C[self.dep, :] = -np.linalg.solve(G[:, self.dep], G[:, self.ind])
        gamma = np.zeros(n)
        gamma[self.dep] = -np.linalg.solve(G[:, self.dep], Gdy)
        return C.T @ M @ C, C.T @ (M @ gamma + h), C.T @ f, acc


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


# ------------------------------------------------------------------------------------------
# Explicit models
# ------------------------------------------------------------------------------------------

def test_spring_pendulum():
    r, q, rd, qd = S("r q r_dot q_dot")
    m, k, L0, c, cd, F0, w, g = S("m k L0 c cd F0 w g")
    x, y = r * sp.sin(q), -r * sp.cos(q)
    v = sp.Matrix([x, y]).jacobian([r, q]) * sp.Matrix([rd, qd])
    T = m * v.dot(v) / 2
    V = m * g * y + k * (r - L0) ** 2 / 2  # r > 0: the rod's length
    F = -cd * v + sp.Matrix([F0 * sp.sin(w * t), 0])
    Q = [F.dot(sp.Matrix([x, y]).diff(a)) - c * rd * int(a == r) for a in (r, q)]
    err = compare_explicit(derived("spring_pendulum.yaml"), lagrange(T, V, [r, q], Q), 1,
                           fixed=lambda rng: {"r": rng.uniform(0.3, 2)})
    assert err < TOL


@pytest.mark.parametrize("name, key", [("shaken_pendulum.yaml", "pivot_x"), ("growing_mass.yaml", "mass")])
def test_component_parameters_in_t_are_refused(name, key):
    """A component's equations are those of constant parameters: a pivot or a mass given in t
    would lose the inertial terms of the motion it prescribes (a shaken pivot's
    m L/2 (xp'' cos q + yp'' sin q), a growing mass's mdot xdot), so it is refused, where written."""
    path = SWEEP / name
    with pytest.raises(ModelError) as info:
        kronsub.load(path, cache=False)
    text = str(info.value)
    line = next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if f"{key}: " in ln)
    assert f"{path.name}:{line}:" in text and f"parameter '{key}'" in text and "depends on t" in text
    assert "hint:" in text


def test_spherical_pendulum_along_minus_y():
    th, ph = S("th ph")
    m, L, k, l0, c, P, g = S("m L k l0 c P g")
    q = [th, ph]
    p = sp.Matrix([L * sp.sin(th) * sp.cos(ph), -L * sp.cos(th), L * sp.sin(th) * sp.sin(ph)])
    v = p.jacobian(q) * sp.Matrix(dots(q))
    T = m * v.dot(v) / 2
    anchor = sp.Matrix([sp.Rational(3, 10), -sp.Rational(9, 10), sp.Rational(1, 10)])
    wall = sp.Matrix([0, sp.Rational(1, 5), -sp.Rational(1, 2)])
    V = m * g * p[1] + k * (sp.sqrt((p - anchor).dot(p - anchor)) - l0) ** 2 / 2
    length = sp.sqrt((p - wall).dot(p - wall))
    Q = [-c * rate_of(length, q) * length.diff(a) + P * p[2].diff(a) for a in q]
    assert compare_explicit(derived("spherical_pendulum.yaml"), lagrange(T, V, q, Q), 4) < TOL


def test_sideways_top_zxz():
    psi, th, phi = S("psi theta phi")
    m, h, A, B, C, D, E, tau, cs, g = S("m h A B C D E tau cs g")
    q = [psi, th, phi]
    R = Rz(psi) * Rx(th) * Rz(phi)
    centre = R * sp.Matrix([0, 0, h])
    M, hh = virtual_power([(m, centre, R, sp.Matrix([[A, 0, D], [0, B, E], [D, E, C]]))], q)
    omega = world_angular_velocity(R, q)
    torque = sp.Matrix([0, tau, tau / 2])
    f = sp.Matrix([-(m * g * centre[1]).diff(a) + torque.dot(omega.diff(ad)) - cs * ad * int(a == phi)
                   for a, ad in zip(q, dots(q))])
    assert compare_explicit(derived("sideways_top.yaml"), (M, hh, f), 5) < TOL


def test_disc_on_seesaw():
    beta, s = S("beta s")
    M_, L, m, R, J, kb, cr, u, g = S("M L m R J kb cr u g")
    q = [beta, s]
    along, normal = sp.Matrix([sp.cos(beta), sp.sin(beta)]), sp.Matrix([-sp.sin(beta), sp.cos(beta)])
    centre = s * along + R * normal
    roll = beta - s / R  # no slip on the turning beam
    M, h = virtual_power([(M_, [0, 0], beta, M_ * L ** 2 / 12), (m, centre, roll, J)], q)
    V = m * g * centre[1] + kb * (beta - sp.Rational(1, 20)) ** 2 / 2
    relative = roll - beta
    f = sp.Matrix([-V.diff(a) + u * int(a == beta) - cr * rate_of(relative, q) * relative.diff(a) for a in q])
    assert compare_explicit(derived("disc_on_seesaw.yaml"), (M, h, f), 6, spread=2) < TOL


def test_double_pendulum_driven():
    q1, q2 = S("q1 q2")
    m1, m2, L1, L2, I2, px, py, k, c1, c2, tau1, tau2, w, P, g = S("m1 m2 L1 L2 I2 px py k c1 c2 tau1 tau2 w P g")
    q = [q1, q2]
    q1d, q2d = dots(q)
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    pivot = sp.Matrix([px, py])
    c1p, elbow = pivot + L1 / 2 * down(q1), pivot + L1 * down(q1)
    c2p = elbow + L2 / 2 * down(q2)
    hook = c2p + L2 / 4 * down(q2) + sp.Rational(1, 20) * sp.Matrix([sp.cos(q2), sp.sin(q2)])
    M, h = virtual_power([(m1, c1p, q1, m1 * L1 ** 2 / 12), (m2, c2p, q2, I2)], q)
    V = g * (m1 * c1p[1] + m2 * c2p[1]) + k * (q2 - q1 - sp.Rational(1, 5)) ** 2 / 2
    F = P * sp.Matrix([3, -4]) / 5
    f = sp.Matrix([-V.diff(a) + tau1 * int(a == q1) + tau2 * sp.cos(w * t) * int(a == q2) + F.dot(hook.diff(a))
                   - c1 * q1d * int(a == q1) - c2 * (q2d - q1d) * (q2 - q1).diff(a) for a in q])
    assert compare_explicit(derived("double_pendulum_driven.yaml"), (M, h, f), 7) < TOL


def test_coupled_spring_pendulums_known_systems():
    r1, q1, r2, q2 = S("r1 q1 r2 q2")
    m, m2, d, e, kc, k, L0, c, cd, F0, w, g = S("m m2 d e kc k L0 c cd F0 w g")
    q = [r1, q1, r2, q2]
    b1 = sp.Matrix([r1 * sp.sin(q1), -r1 * sp.cos(q1)])
    b2 = sp.Matrix([d + r2 * sp.sin(q2), e - r2 * sp.cos(q2)])
    M, h = virtual_power([(m, b1), (m2, b2)], q)
    gap = b2 - b1
    V = (g * (m * b1[1] + m2 * b2[1]) + k * (r1 - L0) ** 2 / 2 + (2 * k + 1) * (r2 - L0) ** 2 / 2
         + kc * (sp.sqrt(gap.dot(gap)) - d) ** 2 / 2)
    r1d, _, r2d, _ = dots(q)
    F1 = -cd * rate_of(b1, q) + sp.Matrix([F0 * sp.sin(w * t), 0])
    F2 = -cd * rate_of(b2, q)  # the right one's push is overridden to F0 = 0
    f = sp.Matrix([-V.diff(a) + F1.dot(b1.diff(a)) + F2.dot(b2.diff(a)) - c * r1d * int(a == r1)
                   - c * r2d * int(a == r2) for a in q])
    err = compare_explicit(derived("coupled_spring_pendulums.yaml"), (M, h, f), 8,
                           fixed=lambda rng: {"r1": rng.uniform(0.3, 2), "r2": rng.uniform(0.3, 2)})
    assert err < TOL


def test_bead_on_hoop():
    psi, al = S("psi al")
    J, m, R, tau, b, cb, eps, kz, g = S("J m R tau b cb eps kz g")
    q = [psi, al]
    psid, ald = dots(q)
    p = sp.Matrix([R * sp.sin(al) * sp.cos(psi), R * sp.sin(al) * sp.sin(psi), -R * sp.cos(al)])
    v = p.jacobian(q) * sp.Matrix([psid, ald])
    T = J * psid ** 2 / 2 + m * v.dot(v) / 2
    V = m * g * p[2] + eps * p[0] * p[2] + kz * p[2] ** 4
    assert compare_explicit(derived("bead_on_hoop.yaml"), lagrange(T, V, q, [tau - b * psid, -cb * ald]), 9) < TOL


def test_box_on_springs_3d():
    x, y, z, psi, th, phi = q = list(S("x y z psi theta phi"))
    m, A, B, C, k, l0, g = S("m A B C k l0 g")
    cz, sz, cy, sy, cx, sx = sp.cos(psi), sp.sin(psi), sp.cos(th), sp.sin(th), sp.cos(phi), sp.sin(phi)
    R = (sp.Matrix([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) * sp.Matrix([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
         * sp.Matrix([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))
    centre = sp.Matrix([x, y, z])
    M, h = virtual_power([(m, centre, R, sp.diag(A, B, C))], q)
    V = m * g * z
    for offset, anchor in (([-0.2, 0.1, 0.05], [-0.3, 0, 1]), ([0.2, -0.1, 0.05], [0.3, 0, 1])):
        d = centre + R * sp.Matrix([sp.nsimplify(v) for v in offset]) - sp.Matrix([sp.nsimplify(v) for v in anchor])
        V += k * (sp.sqrt(d.dot(d)) - l0) ** 2 / 2
    f = sp.Matrix([-V.diff(a) for a in q])
    assert compare_explicit(derived("box_on_springs_3d.yaml"), (M, h, f), 10, spread=1) < TOL


# ------------------------------------------------------------------------------------------
# Closed loops
# ------------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def slider_crank_reference():
    th, rx, ry, ra, px, py = y = list(S("theta rx ry ra px py"))
    m1, m2, mp, r, L, e, k, l0, c, tau, g = params = S("m1 m2 mp r L e k l0 c tau g")
    M = sp.diag(m1 * r ** 2 / 3, m2, m2, m2 * L ** 2 / 12, mp, mp)
    tip = sp.Matrix([r * sp.sin(th), -r * sp.cos(th)])
    axis = L / 2 * sp.Matrix([sp.cos(ra), sp.sin(ra)])
    piston = sp.Matrix([px, py])
    g_ = [*(tip - (sp.Matrix([rx, ry]) - axis)), *(sp.Matrix([rx, ry]) + axis - piston), py - e]
    gap = piston - sp.Matrix([sp.Rational(13, 10), e])
    length = sp.sqrt(gap.dot(gap))
    V = g * (-m1 * r / 2 * sp.cos(th) + m2 * ry + mp * py) + k * (length - l0) ** 2 / 2
    f = sp.Matrix([-V.diff(a) - c * rate_of(length, y) * length.diff(a) + tau * int(a == th) for a in y])
    return Constrained(y, M, sp.zeros(6, 1), f, g_, [th], params)


@lru_cache(maxsize=None)
def slider_crank_rows():
    return walk_constrained(derived("offset_slider_crank.yaml"), slider_crank_reference(), 0.5,
                            [0.5, 0.44, -0.14, 0.11, 0.79, -0.1], 11)


def test_offset_slider_crank_projection():
    rows = slider_crank_rows()
    assert worst(p for row in rows for p in row[:4]) < TOL


def test_offset_slider_crank_compiled_rhs():
    rows = slider_crank_rows()
    assert worst(row[4] for row in rows) < TOL


@lru_cache(maxsize=None)
def four_bar_rows():
    a1, cx, cy, a2, a3 = y = list(S("a1 cx cy a2 a3"))
    m1, m2, m3, l1, l2, l3, d, h, k, c, g = params = S("m1 m2 m3 l1 l2 l3 d h k c g")
    M = sp.diag(m1 * l1 ** 2 / 3, m2, m2, m2 * l2 ** 2 / 12, m3 * l3 ** 2 / 3)
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    half = l2 / 2 * sp.Matrix([sp.cos(a2), sp.sin(a2)])
    centre, D = sp.Matrix([cx, cy]), sp.Matrix([d, h])
    g_ = [*(l1 * down(a1) - (centre - half)), *(centre + half - (D + l3 * down(a3)))]
    V = g * (-m1 * l1 / 2 * sp.cos(a1) + m2 * cy + m3 * (h - l3 / 2 * sp.cos(a3))) + k * (a3 + sp.Rational(1, 5)) ** 2 / 2
    f = sp.Matrix([-V.diff(a) - c * dots(y)[0] * int(a == a1) for a in y])
    system = derived("four_bar_free_coupler.yaml")
    assert [s.name for s in system.coordinates] == ["a1"]  # coordinates: auto
    ref = Constrained(y, M, sp.zeros(5, 1), f, g_, [a1], params)
    return walk_constrained(system, ref, 2.0, [2.0, 0.73, -0.23, -0.69, 0.36], 12, step=0.2)


def test_four_bar_free_coupler_projection():
    rows = four_bar_rows()
    assert worst(p for row in rows for p in row[:4]) < TOL


def test_four_bar_free_coupler_compiled_rhs():
    rows = four_bar_rows()
    assert worst(row[4] for row in rows) < TOL


def test_four_bar_free_coupler_conserves_energy():
    run = derived("four_bar_free_coupler.yaml").simulate(t=1.5, dt=0.5, set={"c": 0}, dataframe=False)
    energy = run["total_energy"]
    assert run.complete and np.max(np.abs(energy - energy[0])) < 1e-6 * np.max(np.abs(energy))


def test_geared_free_coupler_closed_loop_as_known_system():
    """four_bar_free_coupler.yaml as a known system (its 4 dependent coordinates and constraints
    brought along), driven through a gear: the full mechanism in (alpha, cx, cy, a2, a3), a1 = alpha/n."""
    al, cx, cy, a2, a3 = y = list(S("alpha cx cy a2 a3"))
    m1, m2, m3, l1, l2, l3, d, h, k, c, g, Jm, n, kk = params = S("m1 m2 m3 l1 l2 l3 d h k c g Jm n kk")
    a1 = al / n
    M = sp.diag(m1 * l1 ** 2 / 3 / n ** 2 + Jm, m2, m2, m2 * l2 ** 2 / 12, m3 * l3 ** 2 / 3)
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    half = l2 / 2 * sp.Matrix([sp.cos(a2), sp.sin(a2)])
    centre, rocker_tip = sp.Matrix([cx, cy]), sp.Matrix([d, h]) + l3 * down(a3)
    g_ = [*(l1 * down(a1) - (centre - half)), *(centre + half - rocker_tip)]
    gap = rocker_tip - sp.Matrix([sp.Rational(6, 5), 0])
    V = (g * (-m1 * l1 / 2 * sp.cos(a1) + m2 * cy + m3 * (h - l3 / 2 * sp.cos(a3)))
         + k * (a3 + sp.Rational(1, 5)) ** 2 / 2 + kk * gap.dot(gap) / 2)
    f = sp.Matrix([-V.diff(a) - c * dots(y)[0] / n ** 2 * int(a == al) for a in y])
    ref = Constrained(y, M, sp.zeros(5, 1), f, g_, [al], params)
    rows = walk_constrained(derived("geared_free_coupler.yaml"), ref, 6.0, [6.0, 0.66, -0.22, -0.82, 0.2], 13,
                            step=0.3)
    assert worst(p for row in rows for p in row[:4]) < TOL


@pytest.mark.skipif(not os.environ.get("KRONSUB_SWEEP_SLOW"), reason="kronsub takes 70-120 s to derive it "
                    "(inverse kinematics through atan2 and acos); KRONSUB_SWEEP_SLOW=1 runs it")
def test_arm_in_task_space():
    """Joint angles from the hand's position by atan2 and acos (elbow down) in the connection."""
    X, Y = q = list(S("X Y"))
    m1, m2, l1, l2, k, c, g = S("m1 m2 l1 l2 k c g")
    q2 = sp.acos((X ** 2 + Y ** 2 - l1 ** 2 - l2 ** 2) / (2 * l1 * l2))
    q1 = sp.atan2(Y, X) - sp.atan2(l2 * sp.sin(q2), l1 + l2 * sp.cos(q2))
    c1 = l1 / 2 * sp.Matrix([sp.cos(q1), sp.sin(q1)])
    c2 = l1 * sp.Matrix([sp.cos(q1), sp.sin(q1)]) + l2 / 2 * sp.Matrix([sp.cos(q1 + q2), sp.sin(q1 + q2)])
    M, h = virtual_power([(m1, c1, q1, m1 * l1 ** 2 / 12), (m2, c2, q1 + q2, m2 * l2 ** 2 / 12)], q)
    hand = sp.Matrix([X, Y]) - sp.Matrix([sp.Rational(7, 10), -sp.Rational(1, 5)])
    V = g * (m1 * c1[1] + m2 * c2[1]) + k * hand.dot(hand) / 2
    f = sp.Matrix([-V.diff(a) - c * rate_of(q2, q) * q2.diff(a) for a in q])

    def reachable(rng):
        r, a = rng.uniform(0.3, 1.0), rng.uniform(-3, 3)
        return {"X": r * np.cos(a), "Y": r * np.sin(a)}

    assert compare_explicit(derived("arm_in_task_space.yaml"), (M, h, f), 14, jitter=0.05, fixed=reachable) < TOL


def test_ball_joint_pendulum():
    """A 3-D pin to a fixed place makes the body a compound pendulum about it: compared with the
    explicit pendulum (centre = -R (0, 0, h)) by virtual power, Mbar, hbar, fbar and the
    accelerations of the compiled right-hand side."""
    a, b, c = q = list(S("a b c"))
    m, A, B, C, h, g = params = S("m A B C h g")

    R = Rx(a) * Ry(b) * Rz(c)
    centre = -R * sp.Matrix([0, 0, h])
    M, hh = virtual_power([(m, centre, R, sp.diag(A, B, C))], q)
    f = sp.Matrix([-(m * g * centre[2]).diff(u) for u in q])
    fns = [sp.lambdify([*q, *dots(q), *params], e, "numpy") for e in (M, hh, f)]
    num = derived("ball_joint_pendulum.yaml").numeric()
    pv = [num.parameters[s.name] for s in params]
    rng = np.random.default_rng(15)
    qv, pairs = np.array([0.3, 0.2, 0.1]), []
    for _ in range(10):
        qv = qv + rng.uniform(-0.2, 0.2, 3)  # a walk: the branch of the centre is followed
        uv = rng.uniform(-2, 2, 3)
        st = np.concatenate([qv, uv])
        Mr, hr, fr = (np.array(fn(*qv, *uv, *pv), dtype=float) for fn in fns)
        hr, fr = hr.ravel(), fr.ravel()
        pairs += [(num.mass_matrix(qv), Mr), (num.velocity_terms(st), hr), (num.forces(0.0, st), fr),
                  (num.rhs(0.0, st)[3:], np.linalg.solve(Mr, fr - hr))]
    assert worst(pairs) < TOL


def test_offset_slider_crank_reactions(tmp_path):
    """The multipliers of ``M yddot + h = f + G^T mu`` at the initial state (the first row)."""
    from click.testing import CliRunner

    from kronsub.cli import main

    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(SWEEP / "offset_slider_crank.yaml"), "--t", "0.1",
                                       "--dt", "0.1", "--reactions", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",")
    ref = slider_crank_reference()
    pv = [0.8, 0.5, 0.3, 0.2, 0.7, -0.1, 20, 0.3, 0.4, 0.5, 9.81]  # the model's values, in ref.params order
    row = table[0]
    yv, ydv = ref.consistent([row["theta"]], [row["theta_dot"]], [0.5, 0.44, -0.14, 0.11, 0.79, -0.1], pv)
    a = (row["t"], *yv, *ydv, *pv)
    M, f = np.array(ref.fM(*a), dtype=float), np.array(ref.ff(*a), dtype=float).ravel()
    G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
    K = np.block([[M, G.T], [G, np.zeros((5, 5))]])
    mu = -np.linalg.solve(K, np.concatenate([f, -Gdy]))[6:]  # M yddot + G^T (-mu) = f
    printed = [row[name] for name in ("mu_A_x", "mu_A_y", "mu_B_x", "mu_B_y", "mu_line")]
    assert np.allclose(printed, mu, rtol=1e-9, atol=1e-9)


def test_pendulum_on_wheel_rim():
    phi, th = q = list(S("phi th"))
    M_, R, m, L, tau, b, k, c, g = S("M R m L tau b k c g")
    phid, _ = dots(q)
    rim = R * sp.Matrix([sp.cos(phi), sp.sin(phi)])
    down = sp.Matrix([sp.sin(th), -sp.cos(th)])
    centre, tip = rim + L / 2 * down, rim + L * down
    M, h = virtual_power([(M_, [0, 0], phi, M_ * R ** 2 / 2), (m, centre, th, m * L ** 2 / 12)], q)
    V = m * g * centre[1] + k * (th - phi - sp.Rational(6, 5)) ** 2 / 2
    gap = tip - sp.Matrix([sp.Rational(1, 5), -sp.Rational(3, 2)])
    length = sp.sqrt(gap.dot(gap))
    f = sp.Matrix([-V.diff(a) + (tau - b * phid) * int(a == phi) - c * rate_of(length, q) * length.diff(a) for a in q])
    assert compare_explicit(derived("pendulum_on_wheel_rim.yaml"), (M, h, f), 16) < TOL


def test_quick_return_slider_joint():
    """A `slider` joint: the crank's tip on the slotted arm's axis, (tip x e_arm) = 0."""
    b, a = y = list(S("b a"))
    m1, L1, m2, r, d, tau, k, g = params = S("m1 L1 m2 r d tau k g")
    M = sp.diag(m2 * r ** 2 / 3, m1 * L1 ** 2 / 3)
    tip = sp.Matrix([r * sp.sin(b), -d - r * sp.cos(b)])
    along = sp.Matrix([sp.sin(a), -sp.cos(a)])
    V = g * (-m1 * L1 / 2 * sp.cos(a) + m2 * (-d - r / 2 * sp.cos(b))) + k * a ** 2 / 2
    f = sp.Matrix([-V.diff(v) + tau * int(v == b) for v in y])
    ref = Constrained(y, M, sp.zeros(2, 1), f, [tip[0] * along[1] - tip[1] * along[0]], [b], params)
    rows = walk_constrained(derived("quick_return.yaml"), ref, 0.8, [0.8, 0.3], 17, step=0.5)
    assert worst(p for row in rows for p in row) < TOL


def test_four_bar_rocker_flywheel():
    """A connection in a dependent coordinate (w = n theta3) beside the constraints."""
    t1, t2, t3 = y = list(S("theta1 theta2 theta3"))
    m1, m2, m3, l1, l2, l3, d, J, n, cw, tau, g = params = S("m1 m2 m3 l1 l2 l3 d J n cw tau g")
    down = lambda a: sp.Matrix([sp.sin(a), -sp.cos(a)])  # noqa: E731
    c1, tip1 = l1 / 2 * down(t1), l1 * down(t1)
    c2, tip2 = tip1 + l2 / 2 * down(t2), tip1 + l2 * down(t2)
    D = sp.Matrix([d, 0])
    c3, tip3 = D + l3 / 2 * down(t3), D + l3 * down(t3)
    M, h = virtual_power([(m1, c1, t1, m1 * l1 ** 2 / 12), (m2, c2, t2, m2 * l2 ** 2 / 12),
                          (m3, c3, t3, m3 * l3 ** 2 / 12), (0, [0, 0], n * t3, J)], y)
    V = g * (m1 * c1[1] + m2 * c2[1] + m3 * c3[1])
    f = sp.Matrix([-V.diff(a) + tau * int(a == t1) - cw * n ** 2 * dots(y)[2] * int(a == t3) for a in y])
    ref = Constrained(y, M, h, f, list(tip2 - tip3), [t1], params)
    rows = walk_constrained(derived("four_bar_rocker_flywheel.yaml"), ref, 2.0, [2.0, 0.34, -0.25], 18, step=0.3)
    assert worst(p for row in rows for p in row) < TOL


def test_double_spherical_pendulum():
    t1, p1, t2, p2 = q = list(S("t1 p1 t2 p2"))
    m1, m2, L1, L2, cd, g = S("m1 m2 L1 L2 cd g")

    def unit(th, ph):
        return sp.Matrix([sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), -sp.cos(th)])

    b1 = L1 * unit(t1, p1)
    b2 = b1 + L2 * unit(t2, p2)
    M, h = virtual_power([(m1, b1), (m2, b2)], q)
    V = g * (m1 * b1[2] + m2 * b2[2])
    f = sp.Matrix([-V.diff(a) - cd * rate_of(b2, q).dot(b2.diff(a)) for a in q])
    assert compare_explicit(derived("double_spherical_pendulum.yaml"), (M, h, f), 19) < TOL


def test_bead_on_turning_rod_moving_line():
    """point_on_line with a direction that turns with a coordinate; two independent coordinates."""
    a, x, y_ = y = list(S("a x y"))
    J, m, k, tau, g = params = S("J m k tau g")
    bead = sp.Matrix([x, y_])
    length = sp.sqrt(bead.dot(bead))
    V = m * g * y_ + k * (length - sp.Rational(1, 5)) ** 2 / 2
    f = sp.Matrix([-V.diff(v) + tau * int(v == a) for v in y])
    ref = Constrained(y, sp.diag(J, m, m), sp.zeros(3, 1), f, [x * sp.sin(a) - y_ * sp.cos(a)], [a, x], params)
    num = derived("bead_on_turning_rod.yaml").numeric()
    pv = [num.parameters[s.name] for s in params]
    rng = np.random.default_rng(20)
    pairs = []
    for _ in range(10):
        qa, qx = 0.3 + rng.uniform(-0.8, 0.8), rng.uniform(0.2, 1.0)
        ua, ux = rng.uniform(-2, 2, 2)
        yv, ydv = ref.consistent([qa, qx], [ua, ux], [qa, qx, qx * np.tan(qa)], pv)
        Mb, hb, fb, acc = ref.evaluate(0.0, yv, ydv, pv)
        st = [qa, qx, ua, ux]
        pairs += [(num.mass_matrix([qa, qx]), Mb), (num.velocity_terms(st), hb), (num.forces(0.0, st), fb),
                  (num.rhs(0.0, st)[2:], acc)]
    assert worst(pairs) < TOL


@pytest.mark.parametrize("fmt", ["markdown", "json", "latex"])
def test_offset_slider_crank_reactions_printed_as_their_linear_system(fmt):
    """Five dependent coordinates: `derive --reactions` prints the multipliers' linear system
    G_d^T mu = r row by row (no closed-form inverse, no placeholder names)."""
    from click.testing import CliRunner

    from kronsub.cli import main

    result = CliRunner().invoke(main, ["derive", str(SWEEP / "offset_slider_crank.yaml"), "--reactions",
                                       "--format", fmt])
    assert result.exit_code == 0, result.output
    assert "G_d^-T" not in result.output and "linear system" in result.output
    names = ("\\mu_{A x}", "\\mu_{B y}", "\\mu_{line}") if fmt == "latex" else ("mu_A_x", "mu_B_y", "mu_line")
    assert all(name in result.output for name in names), result.output[-2000:]


def test_auto_branch_holds_the_initial_independent_coordinates():
    """`coordinates: auto`: the branch printed "at the initial configuration" satisfies the
    constraints with the independent coordinate at its initial value (the search over every
    coordinate once left the crank at 1.89 for an initial 2.0)."""
    model = kronsub.load(SWEEP / "four_bar_free_coupler.yaml", cache=False)
    system = model.derive(cache=False)
    imp = system.implicit
    values = {p.symbol: p.value for p in system.parameters}
    point = {**{q: model.initial[q] for q in imp.independent}, **dict(imp.branch)}
    residual = [float(c.expression.xreplace(point).xreplace(values)) for c in imp.constraints]
    assert max(abs(r) for r in residual) < 1e-10, residual
