"""The Whipple bicycle of the benchmark (Meijaard, Papadopoulos, Ruina & Schwab, Proc. R. Soc. A
463 (2007) 1955-1982), built from kronsub's core: four placed rigid bodies, the front contact's
height as a configuration constraint, the two wheels' rolling as velocity constraints.

The rear frame takes a roll torque and the front frame a steer torque, the inputs ``T_roll``,
``T_steer``. Coordinates: the rear contact ``x, y`` on the ground, ``yaw``, ``roll`` and ``pitch`` of the rear
frame, the rear wheel's turn ``rear`` relative to it, the ``steer`` angle about the steer axis
and the front wheel's turn ``front``. Speeds: the roll, steer and rear wheel rates. Axes: X forward
at zero yaw, Y to the left, Z up (the paper's x, -y, -z); roll is positive leaning right as in
the paper, steer positive turning left (the paper's opposite). The rear frame's pitch is 0 in
the paper's reference configuration, where every point of Table 1 is given.

``python models/benchmarks/whipple_bicycle.py`` prints the eigenvalues of upright straight running
for v = 0 .. 10 m/s.

How the model-file route is to reach the same objects: each body a ``PlacedBody`` (mass, centre
and turns in the coordinates, inertia in its axes), the metric ``ProjectedMetric`` of the bodies'
``weights()`` and ``projection()`` stacked, gravity ``f = -dV/dx`` with ``V = g sum m c_z``, the
contact-height constraint under ``constraints:``, the rolling constraints the X and Y rows of
``point_velocity(wheel, contact) xdot``, and
``SteadyMotionRates(motion, values, inputs=(T_roll, T_steer)).linearize(point, keep=(roll, steer),
dependent=(pitch,))``.
"""
from __future__ import annotations

import sys

import sympy

from kronsub.core.nonholonomic_linearize import ConstrainedMotion, ProjectedMetric, SteadyMotionRates
from kronsub.core.rigid_bodies import PlacedBody, centre_height, point_velocity
from kronsub.core.symbols import symbol, velocity_symbol

# Table 1 of Meijaard et al. (2007), in the paper's axes (x forward, y right, z down; the
# products of inertia as the entries of the tensor there)
BENCHMARK = {
    "w": 1.02, "c": 0.08, "lam": "pi/10", "g": 9.81,
    "rR": 0.3, "mR": 2.0, "IRxx": 0.0603, "IRyy": 0.12,
    "xB": 0.3, "zB": -0.9, "mB": 85.0, "IBxx": 9.2, "IByy": 11.0, "IBzz": 2.8, "IBxz": 2.4,
    "xH": 0.9, "zH": -0.7, "mH": 4.0, "IHxx": 0.05892, "IHyy": 0.06, "IHzz": 0.00708, "IHxz": -0.00756,
    "rF": 0.35, "mF": 3.0, "IFxx": 0.1405, "IFyy": 0.28,
}
COORDINATES = ("x", "y", "yaw", "roll", "pitch", "rear", "steer", "front")
SPEEDS = ("roll", "steer", "rear")  # the speeds are these coordinates' rates
TORQUES = (symbol("T_roll"), symbol("T_steer"))  # inputs: on the rear frame about the roll axis, and steering


def parameters() -> dict[str, sympy.Symbol]:
    return {name: symbol(name) for name in BENCHMARK}


def benchmark_values() -> dict[sympy.Symbol, float]:
    """Table 1 as numbers, by symbol."""
    return {symbol(k): float(sympy.sympify(v).evalf(17)) if isinstance(v, str) else float(v)
            for k, v in BENCHMARK.items()}


def _turn(axis: str, angle) -> sympy.Matrix:
    return PlacedBody("", 0, (0, 0, 0), ((axis, angle),), sympy.eye(3)).rotation()


def whipple_bicycle() -> ConstrainedMotion:
    """The benchmark bicycle as a :class:`ConstrainedMotion` in its parameters' symbols."""
    p = parameters()
    x, y, yaw, roll, pitch, rear, steer, front = q = tuple(symbol(n) for n in COORDINATES)
    flip = sympy.diag(1, -1, -1)  # the paper's axes to ours

    def tensor(xx, yy, zz, xz):
        return flip * sympy.Matrix([[xx, 0, xz], [0, yy, 0], [xz, 0, zz]]) * flip

    frame_turns = (("Z", yaw), ("X", roll), ("Y", pitch))
    head_turns = frame_turns + (("Y", -p["lam"]), ("Z", steer))  # the front frame's axes: z along the steer axis
    frame = sympy.eye(3)
    for axis, angle in frame_turns:
        frame = frame * _turn(axis, angle)
    contact = sympy.Matrix([x, y, 0])
    rear_centre = contact + _turn("Z", yaw) * _turn("X", roll) * sympy.Matrix([0, 0, p["rR"]])

    def on_frame(px, pz):  # a point of the rear frame given in the paper's reference configuration
        return rear_centre + frame * sympy.Matrix([px, 0, -pz - p["rR"]])

    # a point of the front frame: turned by the steer about the axis through (w + c, 0, 0)
    axis_foot = sympy.Matrix([p["w"] + p["c"], 0, -p["rR"]])
    steering = _turn("Y", -p["lam"]) * _turn("Z", steer) * _turn("Y", p["lam"])

    def on_fork(px, pz):
        return rear_centre + frame * (axis_foot + steering * (sympy.Matrix([px, 0, -pz - p["rR"]]) - axis_foot))

    tilt = _turn("Y", p["lam"])
    head_inertia = tilt * tensor(p["IHxx"], p["IHyy"], p["IHzz"], p["IHxz"]) * tilt.T  # in the front frame's axes
    front_centre = on_fork(p["w"], -p["rF"])
    bodies = (
        PlacedBody("rear_wheel", p["mR"], tuple(rear_centre), frame_turns + (("Y", rear),),
                   sympy.diag(p["IRxx"], p["IRyy"], p["IRxx"])),
        PlacedBody("rear_frame", p["mB"], tuple(on_frame(p["xB"], p["zB"])), frame_turns,
                   tensor(p["IBxx"], p["IByy"], p["IBzz"], p["IBxz"])),
        PlacedBody("front_frame", p["mH"], tuple(on_fork(p["xH"], p["zH"])), head_turns, head_inertia),
        PlacedBody("front_wheel", p["mF"], tuple(front_centre), head_turns + (("Y", front),),
                   sympy.diag(p["IFxx"], p["IFyy"], p["IFxx"])),
    )
    # the front contact: the wheel's lowest point, below the centre in the wheel's plane
    axle = bodies[3].rotation() * sympy.Matrix([0, 1, 0])
    down = sympy.sqrt(1 - axle[2] ** 2)
    front_contact = front_centre - p["rF"] * (sympy.Matrix([0, 0, 1]) - axle[2] * axle) / down
    height = sympy.expand(front_centre[2]) - p["rF"] * down
    xdot = sympy.Matrix([velocity_symbol(s) for s in q])
    rolling = []
    for wheel, where in ((bodies[0], contact), (bodies[3], front_contact)):
        slip = point_velocity(wheel, tuple(where), q) * xdot
        rolling += [slip[0], slip[1]]
    V = p["g"] * centre_height(bodies)
    torques = {roll: TORQUES[0], steer: TORQUES[1]}  # the paper's roll and steer torques (steer's sign ours)
    force = sympy.Matrix([-sympy.diff(V, s) + torques.get(s, 0) for s in q])
    metric = ProjectedMetric(sympy.diag(*[b.weights() for b in bodies]),
                             sympy.Matrix.vstack(*[b.projection(q) for b in bodies]))
    speeds = {velocity_symbol(symbol(n)): velocity_symbol(symbol(n)) for n in SPEEDS}
    return ConstrainedMotion(q, metric, force, speeds, tuple(rolling), (height,))


def upright(v: float, values=None) -> dict:
    """Straight upright running at speed ``v``: every coordinate 0, the rear wheel turning at ``v / rR``."""
    values = values or benchmark_values()
    return {velocity_symbol(symbol("rear")): v / values[symbol("rR")]}


def linearized(rates: SteadyMotionRates, v: float):
    """The linearisation about upright running at ``v``, in ``[roll, steer, their rates, rear wheel rate]``."""
    return rates.linearize(upright(v), keep=(symbol("roll"), symbol("steer")), dependent=(symbol("pitch"),))


def rates_of(values=None) -> SteadyMotionRates:
    """The bicycle's rates at Table 1's values (or ``values``), the torques its inputs."""
    return SteadyMotionRates(whipple_bicycle(), values or benchmark_values(), TORQUES)


def main() -> int:
    rates = rates_of()
    for v in range(11):
        lin = linearized(rates, float(v))
        shown = sorted(lin.eigenvalues, key=lambda e: (e.real, e.imag))
        print(f"v = {v:2d}: " + "  ".join(f"{e.real:+.14f}{e.imag:+.14f}j" for e in shown))
    return 0


if __name__ == "__main__":
    sys.exit(main())
