"""Equations of motion by hand, in plain sympy (never with kronsub): Lagrange's equations of a
hand-written ``T`` and ``V``, virtual power over the bodies, and Lagrange multipliers on the full
coordinates for closed loops.

* Explicit: ``M``, ``h``, ``f`` of ``M qddot + h = f`` from the geometry, by :func:`lagrange`, or by
  :func:`virtual_power` (``M = sum m Jv^T Jv + Jw^T I Jw``, ``h = sum m Jv^T a0 + Jw^T (I alpha0 +
  w x I w)``, ``a0``, ``alpha0`` the accelerations at ``qddot = 0``), plus generalized forces by
  virtual work for the non-conservative effects.
* Closed loops (:class:`Constrained`): ``[M G^T; G 0] [yddot; -mu] = [f - h; -Gdot ydot]`` on the
  full coordinates ``y``, the dependent coordinates by Newton's method and the dependent velocities
  from ``G ydot = 0``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp


t = sp.Symbol("t")


S = sp.symbols


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


def down(a):
    return sp.Matrix([sp.sin(a), -sp.cos(a)])


def kinetic(M, q):
    qd = sp.Matrix(dots(q))
    return (qd.T * M * qd)[0, 0] / 2


def gradient_force(V, q, extra=None):
    return sp.Matrix([-V.diff(a) + (extra[i] if extra is not None else 0) for i, a in enumerate(q)])


def damper_rows(c, length, q):
    return [-c * rate_of(length, q) * length.diff(a) for a in q]


def norm(v):
    return sp.sqrt(v.dot(v))


def spring_V(k, p, q, length=0):
    return k * (norm(p - q) - length) ** 2 / 2


def work_rows(F, p, q):
    return [F.dot(p.diff(a)) for a in q]


def add(*rows):
    return [sum(r) for r in zip(*rows)]


R = sp.Rational
