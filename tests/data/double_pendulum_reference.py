#!/usr/bin/env python
"""Recompute ``double_pendulum_rods.json``: the benchmark double pendulum at t = 10, 40 digits.

Independent of kronsub: the equations come from the Lagrangian written out by hand below, and
the integrator is this file's own Gragg-Bulirsch-Stoer extrapolation in mpmath, run from the
exact inputs (angles 2 pi/3 and -pi/18 at rest, g = 981/100, I = m l^2 / 12) with two settings
(stages and tolerance); their largest difference is recorded as the estimated error, and, when
the shared reference file is at hand, the largest difference from it.

Two uniform rods of mass m = 1 and length l = 1 (half length a = 1/2), the upper pinned at its
end, absolute angles q1, q2 from the downward vertical. With the centres
c1 = a (sin q1, -cos q1), c2 = 2a (sin q1, -cos q1) + a (sin q2, -cos q2):

    T = 1/2 (I + m a^2) u1^2 + 1/2 I u2^2 + 1/2 m |c2'|^2,
    |c2'|^2 = 4 a^2 u1^2 + a^2 u2^2 + 4 a^2 u1 u2 cos(q1 - q2),
    V = -m g a cos q1 - m g (2 a cos q1 + a cos q2),

so with d = q2 - q1 the equations M u' = r are

    M = [[I + 5 m a^2, 2 m a^2 cos d], [2 m a^2 cos d, I + m a^2]],
    r = [ 2 m a^2 u2^2 sin d - 3 m g a sin q1,  -2 m a^2 u1^2 sin d - m g a sin q2].

Usage: python tests/data/double_pendulum_reference.py [--digits 40] [--shared PATH]
(about twenty minutes on one core).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import mpmath

HERE = Path(__file__).resolve().parent
OUT = HERE / "double_pendulum_rods.json"
SHARED = HERE.parent.parent.parent / "shared" / "reference" / "double-pendulum-rods.json"


def rhs(y, m, a, I, g):
    q1, q2, u1, u2 = y
    d = q2 - q1
    s, c = mpmath.sin(d), mpmath.cos(d)
    M11, M12, M22 = I + 5 * m * a * a, 2 * m * a * a * c, I + m * a * a
    r1 = 2 * m * a * a * u2 * u2 * s - 3 * m * g * a * mpmath.sin(q1)
    r2 = -2 * m * a * a * u1 * u1 * s - m * g * a * mpmath.sin(q2)
    det = M11 * M22 - M12 * M12  # Cramer's rule
    return [u1, u2, (r1 * M22 - r2 * M12) / det, (M11 * r2 - M12 * r1) / det]


def gbs(f, y, t_end, stages, tol):
    """Gragg-Bulirsch-Stoer with the sequence 2, 4, 6, ... and a simple step control."""
    t, h = mpmath.mpf(0), mpmath.mpf("0.02")
    while t < t_end:
        h = min(h, t_end - t)
        f0 = f(y)
        T = []
        for j in range(stages):
            n = 2 * (j + 1)
            hh = h / n
            z0, z1 = y, [a + hh * b for a, b in zip(y, f0)]
            for _ in range(n - 1):
                z0, z1 = z1, [a + 2 * hh * b for a, b in zip(z0, f(z1))]
            row = [z1]
            for k in range(1, j + 1):
                r = (mpmath.mpf(j + 1) / (j + 1 - k)) ** 2 - 1
                row.append([a + (a - b) / r for a, b in zip(row[k - 1], T[j - 1][k - 1])])
            T.append(row)
        err = max(abs(a - b) for a, b in zip(T[-1][-1], T[-1][-2])) / max(1, max(abs(v) for v in y))
        if err <= tol:
            t, y = t + h, T[-1][-1]
        h *= min(3, max(mpmath.mpf("0.3"), 0.9 * (tol / max(err, tol * 1e-30)) ** (mpmath.mpf(1) / (2 * stages - 1))))
    return y


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--digits", type=int, default=40)
    parser.add_argument("--shared", type=Path, default=SHARED)
    args = parser.parse_args(argv)
    mpmath.mp.dps = args.digits + 15
    m, a = mpmath.mpf(1), mpmath.mpf(1) / 2
    I, g = m * (2 * a) ** 2 / 12, mpmath.mpf(981) / 100
    y0 = [2 * mpmath.pi / 3, -mpmath.pi / 18, mpmath.mpf(0), mpmath.mpf(0)]
    f = lambda y: rhs(y, m, a, I, g)  # noqa: E731
    runs = []
    for stages, extra in ((args.digits // 2 + 2, 4), (args.digits // 2 + 6, 8)):
        runs.append(gbs(f, y0, mpmath.mpf(10), stages, mpmath.mpf(10) ** -(args.digits + extra)))
        print(f"{stages} stages: {[mpmath.nstr(v, args.digits) for v in runs[-1]]}", file=sys.stderr)
    best = runs[-1]
    spread = max(abs(a - b) for a, b in zip(*runs))
    names = ("q1", "q2", "u1", "u2")
    data = {
        "problem": "Double pendulum of two uniform rods (mass 1, length 1, I = 1/12), g = 981/100, absolute "
                   "angles q1, q2 from the downward vertical, speeds u1, u2; models/hoffmann/system1.yaml "
                   "with theta = q1, phi = q2.",
        "initial_state": {"q1": "2*pi/3", "q2": "-pi/18", "u1": "0", "u2": "0"},
        "t_end": 10,
        "state_at_t_end": {k: mpmath.nstr(v, args.digits + 2) for k, v in zip(names, best)},
        "estimated_error": mpmath.nstr(spread, 3),
        "how": f"tests/data/double_pendulum_reference.py: hand Lagrangian, Gragg-Bulirsch-Stoer in mpmath at "
               f"{mpmath.mp.dps} digits, two settings agreeing to {mpmath.nstr(spread, 3)}.",
    }
    if args.shared.exists():
        shared = json.loads(args.shared.read_text())["state_at_t_end"]
        diff = max(abs(mpmath.mpf(shared[k]) - v) for k, v in zip(names, best))
        data["checked"] = f"agrees with the shared reference double-pendulum-rods.json to {mpmath.nstr(diff, 3)}"
    OUT.write_text(json.dumps(data, indent=2) + "\n")
    print(json.dumps(data, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
