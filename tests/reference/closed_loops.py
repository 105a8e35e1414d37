"""Closed-loop mechanisms derived WITHOUT kronsub: sympy.physics.mechanics' KanesMethod with
configuration constraints (dependent coordinates and speeds).

Each builder gives frames, points, bodies, loads and the loop-closure equations; the
reference then evaluates, at a consistent state (dependent coordinates by Newton from a
guess, dependent speeds from the velocity constraints), the generalized active forces
``Fr`` for the independent speeds (kronsub's ``fbar``), the kinetic energy (``Mbar``) and
the accelerations of the independent coordinates (with ``Mbar`` and ``fbar``, ``hbar``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy
from sympy import Symbol
from sympy.physics.mechanics import KanesMethod, Particle, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia
from sympy.physics.mechanics import kinetic_energy as kinetic

from .mechanics import to_plain

T = dynamicsymbols._t


@dataclass
class ClosedLoop:
    independent: list[str]
    dependent: list[str]
    parameters: list[sympy.Symbol]
    functions: dict  # numeric functions, see build()

    def state(self, q_ind, u_ind, guess, params):
        """Consistent ``q = [q_ind; q_dep]`` and ``u = [u_ind; u_dep]``."""
        p = [params[s.name] for s in self.parameters]
        qd = np.array(guess, dtype=float)
        for _ in range(60):
            q = np.concatenate([q_ind, qd])
            r = np.array(self.functions["loop"](q, p), dtype=float).ravel()
            J = np.array(self.functions["loop_jac"](q, p), dtype=float)
            step = np.linalg.solve(J, -r)
            qd = qd + step
            if np.max(np.abs(step)) < 1e-15 + 1e-13 * np.max(np.abs(qd)):
                break
        q = np.concatenate([q_ind, qd])
        A = np.array(self.functions["vel_dep"](q, p), dtype=float)
        B = np.array(self.functions["vel_ind"](q, p), dtype=float)
        ud = np.linalg.solve(A, -B @ np.asarray(u_ind, dtype=float))
        return q, np.concatenate([np.asarray(u_ind, dtype=float), ud])

    def evaluate(self, q, u, params):
        """``(Fr, T, qddot_ind)`` at a consistent state."""
        p = [params[s.name] for s in self.parameters]
        fr = np.array(self.functions["fr"](q, u, p), dtype=float).ravel()
        Tk = float(self.functions["T"](q, u, p))
        M = np.array(self.functions["M"](q, u, p), dtype=float)
        F = np.array(self.functions["F"](q, u, p), dtype=float).ravel()
        acc = np.linalg.solve(M, F)
        return fr, Tk, acc[: len(self.independent)]


def _reference(ind, dep, params, build):
    q_ind = [dynamicsymbols(n) for n in ind]
    q_dep = [dynamicsymbols(n) for n in dep]
    u_ind = [dynamicsymbols(f"{n}_dot") for n in ind]
    u_dep = [dynamicsymbols(f"{n}_dot") for n in dep]
    q, u = q_ind + q_dep, u_ind + u_dep
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    bodies, loads, loop = build(dict(zip(ind + dep, q)), N, O)
    kd = [qi.diff(T) - ui for qi, ui in zip(q, u)]
    qdot_to_u = {qi.diff(T): ui for qi, ui in zip(q, u)}
    vel = [sympy.diff(c, T).xreplace(qdot_to_u) for c in loop]
    kane = KanesMethod(N, q_ind=q_ind, u_ind=u_ind, kd_eqs=kd, q_dependent=q_dep,
                       configuration_constraints=loop, u_dependent=u_dep, velocity_constraints=vel)
    fr, _ = kane.kanes_equations(bodies, loads)
    plain_q = [Symbol(n) for n in ind + dep]
    plain_u = [Symbol(f"{n}_dot") for n in ind + dep]

    def conv(e):
        return to_plain(e, q, u)

    loop_p = sympy.Matrix([conv(c) for c in loop])
    vel_p = sympy.Matrix([conv(c) for c in vel])
    functions = {
        "loop": sympy.lambdify([plain_q, params], loop_p, "numpy"),
        "loop_jac": sympy.lambdify([plain_q, params], loop_p.jacobian(plain_q[len(ind):]), "numpy"),
        "vel_dep": sympy.lambdify([plain_q, params], vel_p.jacobian(plain_u[len(ind):]), "numpy"),
        "vel_ind": sympy.lambdify([plain_q, params], vel_p.jacobian(plain_u[: len(ind)]), "numpy"),
        "fr": sympy.lambdify([plain_q, plain_u, params], conv(fr), "numpy"),
        "T": sympy.lambdify([plain_q, plain_u, params], conv(kinetic(N, *bodies)), "numpy"),
        "M": sympy.lambdify([plain_q, plain_u, params], conv(kane.mass_matrix), "numpy"),
        "F": sympy.lambdify([plain_q, plain_u, params], conv(kane.forcing), "numpy"),
    }
    return ClosedLoop(list(ind), list(dep), list(params), functions)


def _rod(name, frame, centre, mass, izz):
    return RigidBody(name, centre, frame, mass, (inertia(frame, 0, 0, izz), centre))


def _pinned(name, N, pivot, angle, mass, length, izz=None):
    """A rod hanging from ``pivot`` at ``angle`` from the downward vertical: (body, centre, tip)."""
    F = N.orientnew(f"F_{name}", "Axis", (angle, N.z))
    G = pivot.locatenew(f"G_{name}", -(length / 2) * F.y)
    tip = pivot.locatenew(f"P_{name}", -length * F.y)
    for pt in (G, tip):
        pt.v2pt_theory(pivot, N, F)
    body = _rod(name, F, G, mass, izz if izz is not None else mass * length**2 / 12)
    return body, G, tip, F


def four_bar():
    m1, m2, m3, l1, l2, l3, d, g, tau = sympy.symbols("m1 m2 m3 l1 l2 l3 d g tau")

    def build(q, N, O):
        crank, G1, P1, A = _pinned("crank", N, O, q["theta1"], m1, l1)
        coupler, G2, P2, _ = _pinned("coupler", N, P1, q["theta2"], m2, l2)
        D = O.locatenew("D", d * N.x)
        D.set_vel(N, 0)
        rocker, G3, P3, _ = _pinned("rocker", N, D, q["theta3"], m3, l3)
        loads = [(G1, -m1 * g * N.y), (G2, -m2 * g * N.y), (G3, -m3 * g * N.y), (A, tau * N.z)]
        gap = P2.pos_from(O) - P3.pos_from(O)
        return [crank, coupler, rocker], loads, [gap.dot(N.x), gap.dot(N.y)]

    return _reference(["theta1"], ["theta2", "theta3"], [m1, m2, m3, l1, l2, l3, d, g, tau], build)


def slider_crank():
    m1, m2, mp, J, r, L, g, P = sympy.symbols("m1 m2 mp J r L g P")

    def build(q, N, O):
        crank, G1, P1, A = _pinned("crank", N, O, q["theta"], m1, r)
        W = N.orientnew("W", "Axis", (q["theta"], N.z))
        wheel = RigidBody("wheel", O, W, 0, (inertia(W, 0, 0, J), O))
        rod, G2, P2, _ = _pinned("rod", N, P1, q["psi"], m2, L)
        S = O.locatenew("S", q["s"] * N.x)
        S.set_vel(N, q["s"].diff(T) * N.x)
        piston = Particle("piston", S, mp)
        loads = [(G1, -m1 * g * N.y), (G2, -m2 * g * N.y), (S, -P * N.x)]
        gap = P2.pos_from(O) - S.pos_from(O)
        return [crank, wheel, rod, piston], loads, [gap.dot(N.x), gap.dot(N.y)]

    return _reference(["theta"], ["psi", "s"], [m1, m2, mp, J, r, L, g, P], build)


def system3():
    """Two of Hoffmann's System I, hanging from O and from D = (2d, 0), their free ends pinned."""
    m1, m2, a1, a2, I1, I2, g, F, d = sympy.symbols("m1 m2 a1 a2 I1 I2 g F d")

    def build(q, N, O):
        bodies, loads, ends = [], [], []
        D = O.locatenew("D", 2 * d * N.x)
        D.set_vel(N, 0)
        for side, pivot in (("1", O), ("2", D)):
            up, G1, A, _ = _pinned(f"up{side}", N, pivot, q[f"theta{side}"], m1, 2 * a1, I1)
            low, G2, B, _ = _pinned(f"low{side}", N, A, q[f"phi{side}"], m2, 2 * a2, I2)
            bodies += [up, low]
            loads += [(G1, -m1 * g * N.y), (G2, -m2 * g * N.y), (G2, F * N.x)]
            ends.append(B)
        gap = ends[0].pos_from(O) - ends[1].pos_from(O)
        return bodies, loads, [gap.dot(N.x), gap.dot(N.y)]

    return _reference(["theta1", "theta2"], ["phi1", "phi2"], [m1, m2, a1, a2, I1, I2, g, F, d], build)


def system2():
    """Hoffmann's System II with phi dependent through (25) itself (not the closed form (26))."""
    m1, m2, a1, a2, I1, I2, g, F, c = sympy.symbols("m1 m2 a1 a2 I1 I2 g F c")

    def build(q, N, O):
        up, G1, A, _ = _pinned("up", N, O, q["theta"], m1, 2 * a1, I1)
        low, G2, B, _ = _pinned("low", N, A, q["phi"], m2, 2 * a2, I2)
        loads = [(G1, -m1 * g * N.y), (G2, -m2 * g * N.y), (G2, F * N.x)]
        return [up, low], loads, [B.pos_from(O).dot(N.x) - 2 * c]

    return _reference(["theta"], ["phi"], [m1, m2, a1, a2, I1, I2, g, F, c], build)


__all__ = ["four_bar", "slider_crank", "system3", "system2"]
