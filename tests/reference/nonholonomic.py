"""Independent derivations of non-holonomic systems: sympy.physics.mechanics' KanesMethod with
the same velocity constraints, and the hand-derived equations of a differential-drive robot."""
import numpy as np
import sympy
from sympy.physics import mechanics as me


def _disc_frames(names: str):
    """The disc's coordinates ``names`` (yaw, lean, spin first) and speeds ``u_<name>``, the ground
    frame N, the lean frame L (yaw about N.z, lean about its x), the disc R (spin about L.y) with
    its angular velocity in the speeds, and a fixed origin O."""
    q = me.dynamicsymbols(names)
    u = me.dynamicsymbols(" ".join(f"u_{name}" for name in names.split()))
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q[0], N.z])
    L = Y.orientnew("L", "Axis", [q[1], Y.x])
    R = L.orientnew("R", "Axis", [q[2], L.y])
    R.set_ang_vel(N, u[0] * N.z + u[1] * L.x + u[2] * L.y)
    O = me.Point("O")
    O.set_vel(N, 0)
    return q, u, N, L, R, O


def rolling_disc_kane(m, g, r):
    """The thin uniform disc rolling on the plane z = 0: q = (yaw, lean, spin, x, y) with (x, y)
    the contact point, u = qdot, the contact's speeds dependent. Returns ``(q, u, kane, centre)``
    with ``centre`` the mass centre's position in N (x, y, z) as expressions of q."""
    q, u, N, L, R, O = _disc_frames("yaw lean spin x y")
    contact = O.locatenew("C", q[3] * N.x + q[4] * N.y)
    centre = contact.locatenew("G", r * L.z)
    position = centre.pos_from(O)
    centre.set_vel(N, position.dt(N).subs({qi.diff(): ui for qi, ui in zip(q, u)}))
    point = centre.locatenew("P", -r * L.z)
    slip = centre.vel(N) + R.ang_vel_in(N).cross(point.pos_from(centre))
    disc = me.RigidBody("disc", centre, R, m, (me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), centre))
    kane = me.KanesMethod(N, q_ind=q, u_ind=u[:3], u_dependent=u[3:],
                          kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)],
                          velocity_constraints=[slip.dot(N.x), slip.dot(N.y)])
    kane.kanes_equations([disc], [(centre, -m * g * N.z)])
    return q, u, kane, [position.dot(N.x), position.dot(N.y), position.dot(N.z)]


def rolling_disc_height_kane(m, g, r):
    """The disc of :func:`rolling_disc_kane` with its centre's height a coordinate ``z`` held by the
    configuration constraint ``z - r cos(lean) = 0``: q = (yaw, lean, spin, x, y, z), u = qdot,
    the rates of yaw, lean and spin independent; the three components of the contact point's
    velocity are the velocity constraints (the vertical one is the configuration constraint's
    rate). Returns ``(q, u, kane, dependent)``, ``dependent`` the speeds of x, y, z as
    expressions of q and the independent speeds."""
    q, u, N, L, R, O = _disc_frames("yaw lean spin x y z")
    below = O.locatenew("B", q[3] * N.x + q[4] * N.y + (q[5] - r * sympy.cos(q[1])) * N.z)
    centre = below.locatenew("G", r * L.z)  # on the constraint, `below` is the contact point
    position = centre.pos_from(O)
    centre.set_vel(N, position.dt(N).subs({qi.diff(): ui for qi, ui in zip(q, u)}))
    point = centre.locatenew("P", -r * L.z)
    slip = centre.vel(N) + R.ang_vel_in(N).cross(point.pos_from(centre))
    constraints = [slip.dot(N.x), slip.dot(N.y), slip.dot(N.z)]
    disc = me.RigidBody("disc", centre, R, m, (me.inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), centre))
    kane = me.KanesMethod(N, q_ind=q[:5], u_ind=u[:3], kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)],
                          q_dependent=q[5:], configuration_constraints=[q[5] - r * sympy.cos(q[1])],
                          u_dependent=u[3:], velocity_constraints=constraints)
    kane.kanes_equations([disc], [(centre, -m * g * N.z)])
    solved = sympy.solve(constraints, u[3:], dict=True)[0]
    return q, u, kane, [solved[v] for v in u[3:]]


def sleigh_and_beads_kane(m, I, a, mp, mq, L, c):
    """tests/models/nonholonomic/sleigh_and_beads.yaml by Kane's method: the Chaplygin sleigh (mass
    centre (x, y), heading theta, knife edge a behind the centre) and two beads on their wires
    ``py + c py^3 = L sin(px/L)``, ``qy + c qy^3 = L cos(qx/L)`` written each on its own;
    q = (x, y, theta, px, qx, py, qy), u = qdot, the rates of x, theta, px, qx independent.
    Returns ``(q, u, kane, dependent)``, ``dependent`` the other speeds as expressions."""
    q = me.dynamicsymbols("x y theta px qx py qy")
    u = me.dynamicsymbols("u_x u_theta u_px u_qx u_y u_py u_qy")
    rate = {q[0]: u[0], q[2]: u[1], q[3]: u[2], q[4]: u[3], q[1]: u[4], q[5]: u[5], q[6]: u[6]}
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [q[2], N.z])
    B.set_ang_vel(N, u[1] * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    centre = O.locatenew("G", q[0] * N.x + q[1] * N.y)
    centre.set_vel(N, u[0] * N.x + u[4] * N.y)
    edge = centre.locatenew("E", -a * B.x)
    edge.v2pt_theory(centre, N, B)
    P = O.locatenew("P", q[3] * N.x + q[5] * N.y)
    P.set_vel(N, u[2] * N.x + u[5] * N.y)
    Q = O.locatenew("Q", q[4] * N.x + q[6] * N.y)
    Q.set_vel(N, u[3] * N.x + u[6] * N.y)
    wires = [q[5] + c * q[5] ** 3 - L * sympy.sin(q[3] / L), q[6] + c * q[6] ** 3 - L * sympy.cos(q[4] / L)]
    rates = {qi.diff(): v for qi, v in rate.items()}
    constraints = [edge.vel(N).dot(B.y)] + [w.diff(me.dynamicsymbols._t).subs(rates) for w in wires]
    bodies = [me.RigidBody("sleigh", centre, B, m, (me.inertia(B, 0, 0, I), centre)),
              me.Particle("p", P, mp), me.Particle("q", Q, mq)]
    kane = me.KanesMethod(N, q_ind=q[:5], u_ind=u[:4], kd_eqs=[qi.diff() - rate[qi] for qi in q],
                          q_dependent=q[5:], configuration_constraints=wires, u_dependent=u[4:],
                          velocity_constraints=constraints)
    kane.kanes_equations(bodies, [])
    solved = sympy.solve(constraints, u[4:], dict=True)[0]
    return q, u, kane, [solved[v] for v in u[4:]]


def kane_rates(kane, q, u, q_values, u_values, values) -> np.ndarray:
    """``udot`` of the independent speeds then the dependent ones, at a state."""
    at = {**dict(zip(q, q_values)), **dict(zip(u, u_values)), **values}
    M = np.array(kane.mass_matrix.subs(at).evalf(), dtype=float)
    F = np.array(kane.forcing.subs(at).evalf(), dtype=float)
    return np.linalg.solve(M, F).ravel()


def differential_drive_residual(m, Ic, J, R, b, d, tau_l, tau_r, phi_l_dot, phi_r_dot, phi_l_ddot, phi_r_ddot):
    """The robot's equations in the wheel speeds, from the textbook equations in the forward speed
    v of the axle's midpoint and the turning rate w (Newton-Euler on the chassis, the wheels'
    spin inertia J reflected through R):

        (m + 2 J / R^2) vdot - m d w^2 = (tau_r + tau_l) / R
        (Ic + m d^2 + 2 J b^2 / R^2) wdot + m d v w = b (tau_r - tau_l) / R

    carried to (phi_l_dot, phi_r_dot) by the transpose of d(v, w)/d(phi_l_dot, phi_r_dot)."""
    v, w = R * (phi_l_dot + phi_r_dot) / 2, R * (phi_r_dot - phi_l_dot) / (2 * b)
    vdot, wdot = R * (phi_l_ddot + phi_r_ddot) / 2, R * (phi_r_ddot - phi_l_ddot) / (2 * b)
    E = sympy.Matrix([(m + 2 * J / R**2) * vdot - m * d * w**2 - (tau_r + tau_l) / R,
                      (Ic + m * d**2 + 2 * J * b**2 / R**2) * wdot + m * d * v * w - b * (tau_r - tau_l) / R])
    jac = sympy.Matrix([[R / 2, R / 2], [-R / (2 * b), R / (2 * b)]])
    return jac.T * E
