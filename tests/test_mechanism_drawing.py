"""The drawing of a mechanism (simulation/mechanism.py): which shapes, and where, checked
against positions computed by hand from the trajectory's coordinates."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

from conftest import MODELS
from kronsub.model.loader import load_model
from kronsub.simulation.mechanism import KINDS, coincident, describe, from_points, place
from kronsub.simulation.run import simulate
from kronsub.simulation.values import parse_assignments, resolve

DRAWING = MODELS.parent / "tests" / "models" / "drawing"


def run(path, t_end=0.3, dt=0.05):
    model = load_model(path)
    system = model.derive()
    values = resolve(system, dict(model.initial), parse_assignments(()))
    traj = simulate(system, values, t_end, dt, "dop853")
    param = np.array(values.parameters)
    return system, traj, {p.name: float(v) for p, v in zip(system.parameters, param)}, \
        place(describe(model, system), system, traj, param)


def column(system, traj, name):
    names = [q.name for q in system.coordinates]
    if name in names:
        return traj.y[:, names.index(name)]
    return traj.dependent[:, [d.name for d in system.implicit.dependent].index(name)]


def only(shapes, kind, label):
    (found,) = [s for s in shapes if s.kind == kind and s.label == label]
    return found


def test_planar_shapes_are_where_the_coordinates_put_them():
    system, traj, p, shapes = run(DRAWING / "planar.yaml")
    assert len(traj.t) == 7 and all(s.places.shape[0] == 7 for s in shapes)
    assert {s.kind for s in shapes} <= set(KINDS)
    wx, wy, wa, th, bx, by = (column(system, traj, n) for n in ("wx", "wy", "wa", "th", "bx", "by"))
    R, L = p["R"], p["L"]
    centre = np.column_stack([wx, wy])
    rim = centre + R * np.column_stack([np.cos(wa), np.sin(wa)])
    tip = np.column_stack([1 + L * np.sin(th), -L * np.cos(th)])
    along = np.column_stack([np.sin(th), -np.cos(th)])  # the rod's axis, from its pivot to its tip
    fixed = np.broadcast_to([0.0, 1.0], centre.shape)

    def same(shape, *expected):
        assert np.allclose(shape.places, np.stack(expected, axis=1), rtol=0, atol=1e-12), shape

    same(only(shapes, "disc", "wheel"), centre, rim)  # a circle through the rim: the mark shows its angle
    same(only(shapes, "spring", "spring"), centre, fixed)
    same(only(shapes, "wall", "spring"), fixed, centre)  # the fixed end of the spring is a wall
    same(only(shapes, "damper", "damper"), centre, tip)
    pivot = only(shapes, "pivot", "arm.pivot")
    assert pivot.fixed and np.allclose(pivot.places[0, 0], [1.0, 0.0])
    same(only(shapes, "link", "arm"), np.broadcast_to([1.0, 0.0], centre.shape), (tip + [1.0, 0.0]) / 2, tip)
    rail = only(shapes, "rail", "on_arm")  # the slider's line, fixed in the rod: through its centre along its axis
    assert not rail.fixed
    same(rail, (tip + [1.0, 0.0]) / 2, (tip + [1.0, 0.0]) / 2 + along)
    block = only(shapes, "block", "on_arm")
    same(block, np.column_stack([bx, by]))
    # the bead is on the rod's line at every row (the constraint, seen in the drawing)
    offset = block.places[:, 0] - rail.places[:, 0]
    assert np.allclose(offset[:, 0] * along[:, 1] - offset[:, 1] * along[:, 0], 0, atol=1e-8)
    assert not [s for s in shapes if s.kind == "pivot" and s.label != "arm.pivot"]
    fa, cx = column(system, traj, "fa"), column(system, traj, "cx")
    same(only(shapes, "dial", "fly"), np.column_stack([np.cos(fa), np.sin(fa)]))  # the flywheel's angle
    same(only(shapes, "block", "cart"), np.column_stack([cx, np.zeros_like(cx)]))  # on the x axis
    rail = only(shapes, "rail", "cart")
    assert rail.fixed and np.allclose(rail.places[0], [[0.0, 0.0], [1.0, 0.0]])
    assert np.ptp(fa) > 0.5 and np.ptp(cx) > 0.1


def test_a_body_in_space_shows_its_axes():
    system, traj, _, shapes = run(DRAWING / "top.yaml")
    axes = only(shapes, "axes", "top")
    x, y, z, psi, theta, phi = (column(system, traj, n) for n in ("x", "y", "z", "psi", "theta", "phi"))
    for k in range(len(traj.t)):  # Z-Y-X: R = Rz(psi) Ry(theta) Rx(phi), its columns the body axes
        cz, sz, cy, sy, cx, sx = (np.cos(psi[k]), np.sin(psi[k]), np.cos(theta[k]), np.sin(theta[k]),
                                  np.cos(phi[k]), np.sin(phi[k]))
        rotation = (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
                    @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))
        centre = np.array([x[k], y[k], z[k]])
        assert np.allclose(axes.places[k, 0], centre, atol=1e-12)
        assert np.allclose(axes.places[k, 1:] - centre, rotation.T, atol=1e-12)
    assert np.ptp(psi) > 0.1  # it turned


def test_points_that_meet_are_one_joint_and_fixed_ones_a_pivot():
    system, traj, _, shapes = run(MODELS / "examples" / "four_bar.yaml", t_end=0.2)
    joints = [s for s in shapes if s.kind == "joint"]
    # crank.tip = coupler's upper end (pivot: crank.tip), and the pin B of coupler.tip and rocker.tip
    assert sorted(s.label for s in joints) == ["B", "crank.tip = coupler.pivot"]
    pivots = sorted(tuple(np.round(s.places[0, 0], 12)) for s in shapes if s.kind == "pivot")
    d = next(p.value for p in system.parameters if p.name == "d")
    assert pivots == [(0.0, 0.0), (float(d), 0.0)]


def test_points_of_a_csv_and_their_coincidences():
    t = np.linspace(0, 1, 5)
    a = np.column_stack([np.cos(t), np.sin(t)])
    names = ["rod.a.x", "rod.a.y", "rod.b.x", "rod.b.y", "bob.centre.x", "bob.centre.y"]
    shapes = from_points(names, np.column_stack([np.zeros_like(a), a, a]))
    assert [(s.kind, s.label) for s in shapes] == [("link", "rod"), ("mass", "bob"), ("pivot", "rod.a")]
    groups = coincident(["rod.a", "rod.b", "bob.centre"], np.stack([np.zeros_like(a), a, a], axis=1), 1.0)
    assert groups == [[0], [1, 2]]


def test_a_gif_of_the_shapes_has_its_frames_and_size(tmp_path):
    Image = pytest.importorskip("PIL.Image")
    from kronsub.simulation.animate import animate

    _, traj, _, shapes = run(DRAWING / "planar.yaml", t_end=0.2)
    gif = tmp_path / "planar.gif"
    frames = animate(traj.t, shapes, gif, fps=20, size=120, progress=False)
    with Image.open(gif) as image:
        assert image.n_frames == frames == 5 and image.size == (120, 120)


def test_every_component_type_is_drawn():
    """Each type of the library with a mass distribution has named points (its links or dot) or
    a drawing of its own; circuit branches (no bodies, docs/electrical.md) have no picture."""
    from kronsub.components import REGISTRY
    from kronsub.simulation.mechanism import BY_TYPE

    assert set(BY_TYPE) <= set(REGISTRY)
    for name, cls in REGISTRY.items():
        x = {c: sympy.Symbol(c) for c in cls.coordinates}
        p = {spec.name: sympy.Integer(1) for spec in cls.parameters}
        component = cls(x=x, p=p)
        if not component.bodies():
            continue
        assert name in BY_TYPE or component.points(), name


def test_every_kind_has_a_drawing():
    from kronsub.simulation import animate

    assert all(callable(getattr(animate._Canvas, f"_{kind}", None)) for kind in KINDS)
