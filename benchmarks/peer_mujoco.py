"""MuJoCo as a peer in table b of ``benchmarks/simulate.py``: its Euler and RK4 integrators on the
double pendulum of two uniform rods (System I with its defaults), at several fixed steps.

The model is written as MJCF from System I's parameter values: two bodies in a chain, each a rod
of mass ``m``, length ``2a`` and inertia ``I`` about its midpoint given exactly by ``<inertial>``
(``inertiafromgeom="false"``, no geoms, so nothing else adds mass), hinged about the horizontal
axis ``-y`` (so that a positive angle swings the rod towards +x, System I's ``y``), gravity ``g``
along -z; contacts disabled, no damping, armature, friction loss or limits. MuJoCo's hinge
angles are relative, System I's absolute (from the downward vertical):

    theta = q1,   phi = q1 + q2,   and likewise for the velocities.

Before timing, :func:`check` confirms that the two describe the same mechanism: MuJoCo's mass
matrix and accelerations at a moving state against kronsub's ``Mbar`` and ``Mbar^-1 (fbar -
hbar)`` (mapped through the relative angles), and MuJoCo's RK4 against kronsub's ``dop853`` at
tolerance 1e-13 over one second at several steps, where its error must fall as ``h^4``.

Timing: ``mj_step(model, data, nstep=N)`` runs the ``N`` steps to t_end in C; the state is reset
before each run, outside the timed call. Min and median of repeats.
"""
from __future__ import annotations

import math
import statistics
import time

import numpy as np

NAMES = ("m1", "m2", "a1", "a2", "I1", "I2", "g", "F")
EULER_STEPS = (1e-3, 1e-4, 1e-5)
RK4_STEPS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)


def mjcf(values: dict, h: float, integrator: str) -> str:
    """System I's double pendulum as MJCF (``values``: System I's parameters by name)."""
    if values["F"] != 0:
        raise ValueError("the MuJoCo peer models gravity alone: System I's F must be 0")
    v = {k: repr(float(values[k])) for k in NAMES}
    length1 = repr(2 * float(values["a1"]))
    tiny = "1e-9"  # the rods' inertia about their own axis (no motion about it in the plane)

    def rod(mass, a, inertia):
        return f'<inertial pos="0 0 -{a}" mass="{mass}" diaginertia="{inertia} {inertia} {tiny}"/>'

    hinge = 'type="hinge" axis="0 -1 0" damping="0" armature="0" frictionloss="0" limited="false"'
    return f"""<mujoco model="double pendulum of two uniform rods">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="{h!r}" integrator="{integrator}" gravity="0 0 -{v['g']}">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="upper" pos="0 0 0">
      <joint name="theta" {hinge}/>
      {rod(v['m1'], v['a1'], v['I1'])}
      <body name="lower" pos="0 0 -{length1}">
        <joint name="phi_minus_theta" {hinge}/>
        {rod(v['m2'], v['a2'], v['I2'])}
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def to_relative(y) -> tuple[np.ndarray, np.ndarray]:
    """System I's ``[theta, phi, theta_dot, phi_dot]`` -> MuJoCo's ``qpos``, ``qvel``."""
    theta, phi, theta_dot, phi_dot = map(float, y)
    return np.array([theta, phi - theta]), np.array([theta_dot, phi_dot - theta_dot])


def to_absolute(qpos, qvel) -> np.ndarray:
    """MuJoCo's relative angles -> System I's ``[theta, phi, theta_dot, phi_dot]``."""
    return np.array([qpos[0], qpos[0] + qpos[1], qvel[0], qvel[0] + qvel[1]])


class Pendulum:
    """The MJCF compiled for one integrator and step, and runs of it from System I's state."""

    def __init__(self, values: dict, h: float, integrator: str):
        import mujoco

        self.mujoco, self.h = mujoco, h
        self.model = mujoco.MjModel.from_xml_string(mjcf(values, h, integrator))
        self.data = mujoco.MjData(self.model)

    def reset(self, y0) -> None:
        self.mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:], self.data.qvel[:] = to_relative(y0)

    def run(self, y0, t_end: float) -> tuple[np.ndarray, float, int]:
        """(state at t_end in System I's coordinates, seconds of the stepping alone, steps)."""
        steps = round(t_end / self.h)
        if abs(steps * self.h - t_end) > 1e-9 * t_end:
            raise ValueError(f"t_end {t_end} is not a whole number of steps {self.h}")
        self.reset(y0)
        t0 = time.perf_counter()
        self.mujoco.mj_step(self.model, self.data, nstep=steps)
        seconds = time.perf_counter() - t0
        return to_absolute(self.data.qpos, self.data.qvel), seconds, steps

    def mass_and_acceleration(self, y) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo's joint-space mass matrix and accelerations at ``y`` (relative angles)."""
        self.reset(y)
        self.mujoco.mj_forward(self.model, self.data)
        M = np.zeros((self.model.nv, self.model.nv))
        try:
            self.mujoco.mj_fullM(self.model, self.data, M)  # MuJoCo 4
        except TypeError:
            self.mujoco.mj_fullM(self.model, M, self.data.qM)  # MuJoCo 3
        return M, self.data.qacc.copy()


# the relative angles are q_rel = T^-1 q_abs: M_rel = T^T M_abs T, qddot_abs = T qddot_rel
T_REL = np.array([[1.0, 0.0], [1.0, 1.0]])


def _mass_matrix(native, param, q) -> np.ndarray:
    """kronsub's ``Mbar`` at ``q`` from its kinetic energy ``T = 1/2 qdot^T Mbar qdot``, polarised:
    ``Mbar_ij = T(e_i + e_j) - T(e_i) - T(e_j)``."""
    n = len(q)

    def kinetic(u):
        return native.kinetic_energy(np.concatenate([q, u]), param)

    unit = np.eye(n)
    return np.array([[kinetic(unit[i] + unit[j]) - kinetic(unit[i]) - kinetic(unit[j]) for j in range(n)]
                     for i in range(n)])


def check(native, param, values: dict, y0) -> list[str]:
    """That MuJoCo's model is kronsub's System I: lines saying what was compared (raises when
    it is not). ``native``: kronsub's compiled System I."""
    pendulum = Pendulum(values, 1e-3, "RK4")
    rng = np.random.default_rng(9)
    worst_m = worst_a = 0.0
    for _ in range(5):
        y = np.concatenate([rng.uniform(-math.pi, math.pi, 2), rng.uniform(-3, 3, 2)])
        M_rel, acc_rel = pendulum.mass_and_acceleration(y)
        ydot = native.rhs(0.0, y, param)
        M_abs = _mass_matrix(native, param, y[:2])
        worst_m = max(worst_m, float(np.max(np.abs(T_REL.T @ M_abs @ T_REL - M_rel))))
        worst_a = max(worst_a, float(np.max(np.abs(T_REL @ acc_rel - ydot[2:]))))
    if worst_m > 1e-12 or worst_a > 1e-10:
        raise AssertionError(f"MuJoCo's model is not System I: mass matrices differ by {worst_m:.1e}, "
                             f"accelerations by {worst_a:.1e}")
    lines = [f"MuJoCo vs kronsub at 5 random states: mass matrix {worst_m:.1e}, accelerations {worst_a:.1e}"]
    _, Y, _ = native.integrate("dop853", 0.0, np.asarray(y0, dtype=float), 1.0, 1.0, param, rtol=1e-13, atol=1e-13)
    for integrator, steps, order, smallest in (("RK4", (2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4), 4, 1e-9),
                                               ("Euler", (2e-3, 1e-3, 5e-4), 1, 0.1)):
        errors = []
        for h in steps:
            final, _, _ = Pendulum(values, h, integrator).run(y0, 1.0)
            errors.append(float(np.max(np.abs(final - Y[-1]))))
        orders = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
        # the observed order tends to the method's as h falls (the last halving within 15 %)
        if not (abs(orders[-1] - order) < 0.15 * order and all(p > 0.75 * order for p in orders)
                and errors[-1] < smallest):
            raise AssertionError(f"MuJoCo's {integrator} does not converge to kronsub's dop853 at order {order}: "
                                 f"errors {errors} at h = {steps}")
        lines.append(f"MuJoCo {integrator} vs kronsub dop853 (tol 1e-13) at t = 1, h = {steps[0]:g} .. {steps[-1]:g}: "
                     "errors " + ", ".join(f"{e:.1e}" for e in errors)
                     + " (observed order " + ", ".join(f"{p:.2f}" for p in orders) + ")")
    return lines


def rows(values: dict, y0, t_end: float, repeats: int, quick: bool = False):
    """``(method, setting, min seconds, median seconds, final state, steps, f evals)`` for MuJoCo's
    Euler and RK4 at several steps; ``final`` in System I's coordinates. Each setting runs up to
    ``repeats`` times, at least 3 (1 with ``quick``), stopping once a time budget is spent."""
    import mujoco

    plan = [("Euler", h) for h in EULER_STEPS] + [("RK4", h) for h in RK4_STEPS]
    if quick:
        plan = [p for p in plan if p[1] >= 1e-4]
    least, budget = (1, 0.3) if quick else (3, 2.0)
    out = []
    for integrator, h in plan:
        pendulum = Pendulum(values, h, integrator)
        times, final, steps = [], None, 0
        while len(times) < max(least, 1) or (len(times) < repeats and sum(times) < budget):
            final, seconds, steps = pendulum.run(y0, t_end)
            times.append(seconds)
        out.append((f"MuJoCo {mujoco.__version__} {integrator}", f"h {h:g}", min(times), statistics.median(times),
                    final, steps, steps * (4 if integrator == "RK4" else 1)))
    return out


def table_rows(row, native, system, values, y0, t_end: float, repeats: int, quick: bool) -> None:
    """Print MuJoCo's rows with table b's ``row(method, setting, seconds, final, evals, note)``,
    or one line saying why not."""
    try:
        import mujoco  # noqa: F401
    except ImportError as exc:
        print(f"  {'MuJoCo':<22} not available ({exc}; pip install 'kronsub[bench]')")
        return
    named = {p.name: v for p, v in zip(system.parameters, values.parameters)}
    for line in check(native, np.array(values.parameters), named, y0):
        print(f"  {line}")
    for method, setting, best, median, final, steps, evals in rows(named, y0, t_end, repeats, quick):
        row(method, setting, best, final, evals, f"{steps} steps; median {1e3 * median:.3f} ms; mj_step(nstep) in C")
