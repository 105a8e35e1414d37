"""Exact solutions, to any number of digits with mpmath, of the linear spring chain and of the
pendulum released from rest (Jacobi's elliptic functions)."""
from __future__ import annotations

import mpmath


def spring_chain_exact(values, times, digits=30):
    """``y(t) = expm(A t) y0``, A = [[0, I], [-M^-1 K, 0]], K from the four springs by hand."""
    m1, m2, m3, k1, k2, k3, k4 = [mpmath.mpf(v) for v in values.parameters]
    with mpmath.workdps(digits + 10):
        K = mpmath.matrix([[k1 + k2, -k2, 0], [-k2, k2 + k3, -k3], [0, -k3, k3 + k4]])
        Minv = mpmath.diag([1 / m1, 1 / m2, 1 / m3])
        A = mpmath.zeros(6, 6)
        for i in range(3):
            A[i, 3 + i] = 1
        B = -Minv * K
        for i in range(3):
            for j in range(3):
                A[3 + i, j] = B[i, j]
        y0 = mpmath.matrix([mpmath.mpf(v) for v in values.y0])
        return [[v for v in mpmath.expm(A * mpmath.mpf(t)) * y0] for t in times]


def pendulum_exact(values, times, digits=30):
    """Released from rest at q0: ``q = 2 asin(k sn(K - w t | k^2))``, ``qdot = -2 k w cn(K - w t | k^2)``,
    ``k = sin(q0 / 2)``, ``w = sqrt(g / l)``."""
    m, l, g = [mpmath.mpf(v) for v in values.parameters]
    with mpmath.workdps(digits + 10):
        k = mpmath.sin(mpmath.mpf(values.y0[0]) / 2)
        w, K = mpmath.sqrt(g / l), mpmath.ellipk(k ** 2)
        out = []
        for t in times:
            u = K - w * mpmath.mpf(t)
            out.append([2 * mpmath.asin(k * mpmath.ellipfun("sn", u, m=k ** 2)),
                        -2 * k * w * mpmath.ellipfun("cn", u, m=k ** 2)])
        return out
