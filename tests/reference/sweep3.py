"""The models of tests/models/sweep3/: their loaders and their hand derivations in plain sympy
(never with kronsub), for the tests by subject (tests/test_models_*.py).

The folder holds: known systems three levels deep, a known system reused twice and
placed, a closed loop inside a known system carrying a pendulum, pulleys and gear trains by
explicit connections, a planar body on spring-damper legs, a pendulum on a point of a
rolling body, a body on a Cardan joint with products of inertia, linear implicit
constraints (a rope over a pulley), a bead on a cone in spherical coordinates.

Each is checked against an independent derivation written here in plain sympy (never with
kronsub), with the helpers of tests/reference/lagrange.py: Lagrange's equations of a hand
``T`` and ``V``, virtual power over the bodies, and Lagrange multipliers on the full
coordinates for closed loops. ``Mbar``, ``hbar``, ``fbar`` (and ``T``, ``V``) at random states
and randomly perturbed parameters; for some, the accelerations of the compiled C and of the
generated numpy module.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import sympy as sp
from click.testing import CliRunner

import kronsub
from helpers import generated_numpy_module
from helpers.compare import worst
from kronsub.cli import main
from reference.lagrange import Constrained, dots, down, rate_of, S, t, virtual_power

HERE = Path(__file__).resolve().parent.parent / "models" / "sweep3"


@lru_cache(maxsize=None)
def derived(name):
    return kronsub.load(HERE / name).derive(scene=False)  # the whole model, also of a model with one scene


def numpy_module(tmp_path, name):
    return generated_numpy_module(tmp_path, HERE / name)


def cart_pendulum_parts(x, th, origin=(0, 0), mb_factor=1):
    """Bodies and potential of cart_pendulum.yaml (itself sprung_cart.yaml plus a rod and a bob)."""
    mc, mp, L, mb, g = S("mc mp L mb g")
    cart = sp.Matrix([x + origin[0], origin[1]])
    rod = cart + L / 2 * down(th)
    bob = cart + L * down(th)
    bodies = [(mc, cart), (mp, rod, th, mp * L ** 2 / 10), (mb_factor * mb, bob)]
    V = g * (mp * rod[1] + mb_factor * mb * bob[1])
    return bodies, V, cart, bob


def sprung_cart_force(x, q, push=True):
    """The wall spring (rest length l0 from x = -w), damper and push of sprung_cart.yaml: ``-dV``
    is the caller's, the potential is returned with the non-conservative forces."""
    k, l0, w, c, P, om = S("k l0 w c P om")
    V = k * (x + w - l0) ** 2 / 2  # the cart stays right of the wall
    Q = sp.Matrix([(-c * rate_of(x, q) + (P * sp.cos(om * t) if push else 0)) * x.diff(a) for a in q])
    return V, Q


@lru_cache(maxsize=None)
def cart_pendulum_reference():
    x, th = q = list(S("x th"))
    cp = S("cp")
    bodies, V, _, _ = cart_pendulum_parts(x, th)
    M, h = virtual_power(bodies, q)
    Vs, Q = sprung_cart_force(x, q)
    V = V + Vs
    f = sp.Matrix([-V.diff(a) + Q[i] - cp * dots(q)[1] * int(a == th) for i, a in enumerate(q)])
    return q, M, h, f, V


@lru_cache(maxsize=None)
def two_cart_reference():
    """cart_pendulum.yaml twice (renamed, the right one placed at (d, 0) with a heavier bob and
    no push), joined by a spring of rest length d and a damper, the right bob shoved."""
    x1, th1, x2, th2 = q = list(S("x1 th1 x2 th2"))
    d, kc, cc, Q0, cp = S("d kc cc Q cp")
    b1, V1, cart1, _ = cart_pendulum_parts(x1, th1)
    b2, V2, cart2, bob2 = cart_pendulum_parts(x2, th2, origin=(d, 0), mb_factor=2)
    M, h = virtual_power(b1 + b2, q)
    Vs1, Q1 = sprung_cart_force(x1, q)
    Vs2, Q2 = sprung_cart_force(x2, q, push=False)  # the right copy's own wall is at x2 = -w
    gap = cart2[0] - cart1[0]  # > 0: the right cart stays right of the left one
    V = V1 + V2 + Vs1 + Vs2 + kc * (gap - d) ** 2 / 2
    shove = Q0 * sp.Matrix([1, 2]) / sp.sqrt(5)
    f = sp.Matrix([-V.diff(a) + Q1[i] + Q2[i] - cc * rate_of(gap, q) * gap.diff(a) + shove.dot(bob2.diff(a))
                   - cp * dots(q)[i] * int(a in (th1, th2)) for i, a in enumerate(q)])
    return q, M, h, f, V


@lru_cache(maxsize=None)
def five_bar_reference():
    """System III (two System I's pinned at B: four coordinates, two constraints) with a rod
    hung from the left lower rod's centre, tied to it by a torsional spring; B_left - B_right = 0."""
    y, M, h, f, g_, params, _ = five_bar_pieces()
    return Constrained(y, M, h, f, g_, y[:3], params)


def five_bar_pieces():
    """``y``, ``M``, ``h``, ``f``, ``g``, the parameters and the hung rod's tip."""
    t1, t2, ps, p1, p2 = y = list(S("theta1 theta2 psi phi1 phi2"))
    m1, m2, a1, a2, I1, I2, g, F, d, mr, Lr, kr, tq = params = S("m1 m2 a1 a2 I1 I2 g F d mr Lr kr tq")
    bodies, V, Q, ends, centres = [], 0, sp.zeros(5, 1), [], []
    for th, ph, O in ((t1, p1, sp.Matrix([0, 0])), (t2, p2, sp.Matrix([2 * d, 0]))):
        c1, A = O + a1 * down(th), O + 2 * a1 * down(th)
        c2, B = A + a2 * down(ph), A + 2 * a2 * down(ph)
        bodies += [(m1, c1, th, I1), (m2, c2, ph, I2)]
        V += g * (m1 * c1[1] + m2 * c2[1])
        Q += sp.Matrix([F * c2[0].diff(a) for a in y])
        ends.append(B)
        centres.append(c2)
    ch = centres[0] + Lr / 2 * down(ps)  # hung from the left lower rod's centre (phi1 dependent)
    bodies.append((mr, ch, ps, mr * Lr ** 2 / 12))
    V += g * mr * ch[1] + kr * (ps - p1 - sp.Rational(1, 10)) ** 2 / 2
    M, h = virtual_power(bodies, y)
    f = sp.Matrix([-V.diff(a) + Q[i] + tq * int(a == t2) for i, a in enumerate(y)])
    return y, M, h, f, list(ends[0] - ends[1]), params, ch + Lr / 2 * down(ps)


def reactions_agree(tmp_path, name, ref, independent, guess, labels):
    """`simulate --reactions`: the multipliers of ``M yddot + h = f + G^T mu`` in every row
    against the reference's, solved at the row's state on the full coordinates."""
    out = tmp_path / "run.csv"
    result = CliRunner().invoke(main, ["simulate", str(HERE / name), "--t", "0.2", "--dt", "0.1", "--reactions",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = np.genfromtxt(out, names=True, delimiter=",", comments="#")
    values = {p.name: float(p.value) for p in derived(name).parameters}
    pv = [values[n] for n in ref.params]
    pairs = []
    for row in table:
        yv, ydv = ref.consistent([row[n] for n in independent], [row[f"{n}_dot"] for n in independent], guess, pv)
        a = (row["t"], *yv, *ydv, *pv)
        M, h, f = (np.array(fn(*a), dtype=float) for fn in (ref.fM, ref.fh, ref.ff))
        G, Gdy = np.array(ref.fG(*a), dtype=float), np.array(ref.fGd(*a), dtype=float).ravel()
        nc = G.shape[0]
        K = np.block([[M, G.T], [G, np.zeros((nc, nc))]])
        mu = -np.linalg.solve(K, np.concatenate([f.ravel() - h.ravel(), -Gdy]))[len(yv):]
        pairs.append((np.array([row[n] for n in labels]), mu))
    return worst(pairs)


@lru_cache(maxsize=None)
def blocks_reference():
    p, xA, yA, xB, yB = y = list(S("p xA yA xB yB"))
    mA, mB, J, r, al, bt, Ls, k, l0, c, g = params = S("mA mB J r al bt Ls k l0 c g")
    M = sp.diag(J, mA, mA, mB, mB)
    sA = -xA * sp.cos(al) - yA * sp.sin(al)  # distances from the apex along the faces
    sB = xB * sp.cos(bt) - yB * sp.sin(bt)
    g_ = [xA * sp.sin(al) - yA * sp.cos(al), xB * sp.sin(bt) + yB * sp.cos(bt), sA + sB - Ls,
          r * p + sA - sp.Rational(3, 5)]
    down_ = sp.Matrix([sp.Rational(1, 10), -1]) / sp.sqrt(sp.Rational(101, 100))
    foot = sp.Matrix([-sp.cos(al), -sp.sin(al)])
    gap = sp.Matrix([xA, yA]) - foot
    V = -g * down_.dot(mA * sp.Matrix([xA, yA]) + mB * sp.Matrix([xB, yB])) + k * (sp.sqrt(gap.dot(gap)) - l0) ** 2 / 2
    yd = dots(y)
    f = sp.Matrix([-V.diff(v) - c * yd[i] * int(v in (xB, yB)) for i, v in enumerate(y)])
    return Constrained(y, M, sp.zeros(5, 1), f, g_, [p], params)
