"""The rolling disc by ``sympy.physics.mechanics`` alone: ``KanesMethod`` with its two rolling
constraints (the contact point's velocities dependent) and its ``linearize``, which takes the
dependent speeds along (Peterson, Gede & Hubbard 2014). Plain symbols at the boundary:
coordinates ``yaw, lean, spin, x, y``, parameters ``m, g, r``."""
from __future__ import annotations

import numpy as np
import sympy
from sympy.physics import mechanics as me

NAMES = ("yaw", "lean", "spin", "x", "y")


class KaneDisc:
    """A uniform thin disc (axial inertia ``m r^2/2``, diametral ``m r^2/4``) rolling on a
    plane; ``q = qdot`` for all five coordinates, the speeds of ``x``, ``y`` dependent."""

    def __init__(self):
        self.m, self.g, self.r = sympy.symbols("m g r")
        m, g, r = self.m, self.g, self.r
        q = self.q = me.dynamicsymbols("q1:6")
        u = self.u = me.dynamicsymbols("u1:6")
        N = me.ReferenceFrame("N")
        Yf = N.orientnew("Y", "Axis", [q[0], N.z])
        L = Yf.orientnew("L", "Axis", [q[1], Yf.x])
        R = L.orientnew("R", "Axis", [q[2], L.y])
        R.set_ang_vel(N, u[0] * N.z + u[1] * Yf.x + u[2] * L.y)
        contact = me.Point("C")
        contact.set_vel(N, u[3] * N.x + u[4] * N.y)
        centre = contact.locatenew("G", r * L.z)
        centre.set_vel(N, contact.vel(N) + (u[0] * N.z + u[1] * Yf.x).cross(r * L.z))
        slip = centre.vel(N) + R.ang_vel_in(N).cross(-r * L.z)
        disc = me.RigidBody("disc", centre, R, m, (me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), centre))
        self.kane = me.KanesMethod(N, q_ind=q, u_ind=u[:3], u_dependent=u[3:],
                                   kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)],
                                   velocity_constraints=[slip.dot(N.x), slip.dot(N.y)])
        self.kane.kanes_equations([disc], [(centre, -m * g * N.z)])
        self._slip = sympy.Matrix([slip.dot(N.x), slip.dot(N.y)])
        ud = [ui.diff() for ui in u]
        self._ud = ud
        t = me.dynamicsymbols._t
        self._accel = sympy.symbols("a1:6")
        self._slip_rate = self._slip.diff(t).subs({qi.diff(): ui for qi, ui in zip(q, u)}).xreplace(
            dict(zip(ud, self._accel)))

    def numbers(self, values):
        return {self.m: values["m"], self.g: values["g"], self.r: values["r"]}

    def linearized(self, coordinates, speeds, values) -> np.ndarray:
        """``A`` in ``[q; yaw rate, lean rate, spin rate]`` at the state (not necessarily steady)."""
        numbers = self.numbers(values)
        at = {**dict(zip(self.q, coordinates)), **dict(zip(self.u[:3], speeds)), **numbers}
        # the dependent speeds from the constraints, the accelerations from Kane's equations
        dep = sympy.Matrix(self._slip.subs(at)).jacobian(self.u[3:])
        rest = sympy.Matrix(self._slip.subs(at)).subs({ui: 0 for ui in self.u[3:]})
        u_dep = [float(e) for e in dep.LUsolve(-rest)]
        at.update(dict(zip(self.u[3:], u_dep)))
        M = np.array(self.kane.mass_matrix_full.subs(at).evalf(), dtype=float)
        F = np.array(self.kane.forcing_full.subs(at).evalf(), dtype=float).ravel()
        rates = np.linalg.solve(M, F)
        op = dict(at)
        op.update({d: float(v) for d, v in zip(self._ud[:3], rates[5:])})
        # the acceleration constraints (the rolling constraints' rates) give the dependent udot
        rate = sympy.Matrix(self._slip_rate.subs(at).subs(dict(zip(self._accel[:3], rates[5:]))))
        dependent = rate.jacobian(self._accel[3:]).LUsolve(-rate.subs({a: 0 for a in self._accel[3:]}))
        op.update({d: float(v) for d, v in zip(self._ud[3:], dependent)})
        A, _, _ = self.kane.linearize(A_and_B=True, op_point=op, simplify=False)
        return np.array(A.subs(numbers).evalf(), dtype=float)
