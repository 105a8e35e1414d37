"""The drawing of a mechanism: which shapes, and where they are at each row of a run.

What a sketch of a mechanism shows is read off the model, never from one bundled example:
the components' types (a rod is a bar between its ends, a disc a circle with a mark at its
``rim``, a flywheel a dial turning with its angle, a particle on a line a block on a rail, a
rigid body its body axes), the named points that stay put (a fixed pivot on the hatched
ground), the effects that act between two points (a spring as a zigzag, a damper as a
dashpot, a wall where one end is a fixed place) and the joints of ``constraints:`` (a pin
as a joint mark, or a pivot when one side is a fixed place; ``point_on_line`` and ``slider``
as a block on its line). Named points that coincide throughout the run are one joint.

A :class:`Shape` holds world positions (``places``, one row per row of the run); the
renderer (:mod:`kronsub.simulation.animate`) projects them to the drawing plane.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy

from ..components.base import in_world
from ..core.symbols import TIME
from ..effects.elements import Damper, Spring

KINDS = {
    "link": "segments from the first place to each of the others (a rod, a body's points)",
    "disc": "a circle about the first place through the second, with a mark to it (its angle)",
    "dial": "a flywheel: a circle apart from the world with a mark at the angle of (cos a, sin a)",
    "mass": "a particle: a dot",
    "block": "a point held on a line: a block (a slider, a particle on its rail)",
    "axes": "a body's axes: from its centre (first place) along each unit vector that follows",
    "spring": "a zigzag between the two places",
    "damper": "a dashpot between the two places",
    "pivot": "a fixed pivot: a triangle on hatched ground",
    "wall": "a wall at the first place, across the direction to the second",
    "rail": "a line through the first place towards the second, hatched when fixed",
    "joint": "named points that coincide: one ring",
}
"""The shapes a drawing is made of, and what their ``places`` are."""

COINCIDENT = 1e-6
"""Relative distance (to the drawing's extent) under which named points are one throughout a run."""


@dataclass(frozen=True)
class Shape:
    """One thing drawn: ``kind`` (:data:`KINDS`), what it draws (``label``), and its world
    ``places`` per row of the run (rows x places x world axes); a ``fixed`` shape does not move
    (drawn once, from its first row)."""

    kind: str
    label: str
    places: np.ndarray
    fixed: bool = False


@dataclass(frozen=True)
class Sketch:
    """A :class:`Shape` before the run: its places as expressions in the model's coordinates ``y``."""

    kind: str
    label: str
    places: tuple[tuple, ...]


def _disc(part, points):
    return [Sketch("disc", part.name, (points[f"{part.name}.centre"], points[f"{part.name}.rim"]))]


def _dial(part, points):
    R = part.bodies[0].rotation
    return [Sketch("dial", part.name, ((R[0, 0], R[1, 0]),))]


def _on_rail(part, points):
    """A particle on a line: a block on the world x axis."""
    zero, one = sympy.Integer(0), sympy.Integer(1)
    return [Sketch("block", part.name, (points[f"{part.name}.centre"],)), Sketch("rail", part.name, ((zero,), (one,)))]


def _body_axes(part, points):
    """A body known by its centre: its axes show its angle (in space, its orientation)."""
    body = part.bodies[0]
    R = body.rotation
    return [Sketch("axes", part.name, (tuple(body.centre),) + tuple(
        tuple(body.centre[i] + R[i, j] for i in range(R.rows)) for j in range(R.cols)))]


BY_TYPE = {"disc": _disc, "flywheel": _dial, "particle1d": _on_rail, "planar_body": _body_axes,
           "rigid_body3d": _body_axes, "turned_body": _body_axes}
"""What a component type adds to the links of its named points (``components.REGISTRY``
names); a type not listed (a particle, a rod, a known system) is its links, or a dot for a
lone point."""


def _part_shapes(part, points: dict) -> list[Sketch]:
    """The shapes of one part: a star of links over the named points of each of its bodies
    (the label up to its last dot: the part, or a component of a known system), and what
    its type adds (:data:`BY_TYPE`)."""
    own = [label for label in points if label.startswith(part.name + ".")]
    bodies: dict[str, list[str]] = {}
    for label in own:
        bodies.setdefault(label.rpartition(".")[0], []).append(label)
    shapes = [Sketch("link", body, tuple(points[label] for label in labels))
              for body, labels in bodies.items() if len(labels) > 1]
    if part.type_name in BY_TYPE:
        return shapes + BY_TYPE[part.type_name](part, points)
    return shapes + [Sketch("mass", body, (points[labels[0]],)) for body, labels in bodies.items() if len(labels) == 1]


def _effect_shapes(effect, points: dict) -> list[Sketch]:
    """A spring or damper between its ends; a wall at an end that is a fixed place."""
    if not isinstance(effect, (Spring, Damper)):
        return []
    ends = [points[e] if isinstance(e, str) else tuple(e) for e in effect.ends]
    shapes = [Sketch("spring" if isinstance(effect, Spring) else "damper", effect.name, tuple(ends))]
    for k, end in enumerate(effect.ends):
        if not isinstance(end, str):
            shapes.append(Sketch("wall", effect.name, (ends[k], ends[1 - k])))
    return shapes


def _joint_shapes(joint) -> list[Sketch]:
    """A pin as a joint (drawn where its points meet, or as a pivot at a fixed place); a line
    joint as its rail and the block on it."""
    if joint.kind == "pin":
        return [Sketch("joint", joint.name, (joint.point, joint.other))]
    ahead = tuple(a + b for a, b in zip(in_world(joint.other, len(joint.direction)), joint.direction))
    return [Sketch("rail", joint.name, (joint.other, ahead)), Sketch("block", joint.name, (joint.point,))]


def describe(model, system) -> list[Sketch]:
    """The sketches of a loaded model (:class:`kronsub.model.model.Model`) as derived in
    ``system`` (its scene: the effects it switches on), in the model's coordinates ``y``."""
    connection = dict(model.connection)
    points = {label: tuple(sympy.sympify(c).xreplace(connection) for c in place)
              for label, place in model.primitive.points().items()}
    sketches = []
    for part in model.primitive.parts:
        sketches += _part_shapes(part, points)
    for effect in model.effects:
        if effect.name in system.effect_forces:
            sketches += _effect_shapes(effect, points)
    for joint in model.joints:
        sketches += _joint_shapes(joint)

    def moved(sketch):
        return Sketch(sketch.kind, sketch.label, tuple(tuple(sympy.sympify(c).xreplace(connection) for c in place)
                                                       for place in sketch.places))

    sketches = [moved(s) for s in sketches]
    for label, place in points.items():  # a point fixed in the world is a pivot; moving ones may meet
        sketches.append(Sketch("named" if _moves(place, system) else "pivot", label, (place,)))
    return sketches


def _coordinates(system) -> tuple:
    dependent = system.implicit.dependent if system.implicit is not None else ()
    return tuple(system.coordinates) + tuple(dependent)


def _moves(place, system) -> bool:
    """Whether a place depends on the coordinates or on the time (a driven point)."""
    symbols = set().union(*(sympy.sympify(c).free_symbols for c in place))
    return bool(symbols & (set(_coordinates(system)) | {TIME}))


def place(sketches: list[Sketch], system, traj, param) -> list[Shape]:
    """The shapes at each row of the run ``traj`` (parameter values ``param`` in the order of
    ``system.parameters``): every place evaluated, in the world of the largest dimension."""
    coords = _coordinates(system)
    rows = len(traj.t)
    columns = [traj.y[:, i] for i in range(len(system.coordinates))]
    if system.implicit is not None:
        dependent = traj.dependent if traj.dependent is not None else np.full((rows, len(coords) - len(columns)), np.nan)
        columns += [dependent[:, i] for i in range(dependent.shape[1])]
    symbols = list(coords) + [TIME] + [p.symbol for p in system.parameters]
    values = columns + [np.asarray(traj.t, dtype=float)] + [np.full(rows, float(v)) for v in param]
    flat = [sympy.sympify(c) for s in sketches for pl in s.places for c in pl]
    evaluate = sympy.lambdify(symbols, flat, "numpy")
    numbers = [np.broadcast_to(np.asarray(v, dtype=float), (rows,)) for v in evaluate(*values)] if flat else []
    dimension = max([len(pl) for s in sketches for pl in s.places] + [2])
    shapes, k = [], 0
    for s in sketches:
        out = np.zeros((rows, len(s.places), dimension))
        for j, pl in enumerate(s.places):
            for axis in range(len(pl)):
                out[:, j, axis] = numbers[k]
                k += 1
        still = [j for j, pl in enumerate(s.places) if not _moves(pl, system)]
        if s.kind == "joint" and still:  # a pin to a fixed place: a pivot there
            shapes.append(Shape("pivot", s.label, out[:, still[0]:still[0] + 1], True))
            continue
        if s.kind == "joint":
            out = out[:, :1]
        fixed = s.kind in ("pivot", "wall") or (s.kind == "rail" and len(still) == len(s.places))
        shapes.append(Shape(s.kind, s.label, out, fixed))
    return _tidy(shapes)


def _tidy(shapes: list[Shape]) -> list[Shape]:
    """Named points that coincide throughout the run (hidden ``named`` shapes) become one joint;
    a fixed shape, or a joint, drawn once where several are alike."""
    named = [s for s in shapes if s.kind == "named"]
    out = [s for s in shapes if s.kind != "named"]
    if named:
        paths = np.concatenate([s.places for s in named], axis=1)
        scale = float(np.ptp(paths.reshape(-1, paths.shape[2]), axis=0).max(initial=0.0)) or 1.0
        for group in coincident([s.label for s in named], paths, scale):
            parts = {named[j].label.rpartition(".")[0] for j in group}
            if len(parts) > 1:
                out.append(Shape("joint", " = ".join(named[j].label for j in group), paths[:, group[0]:group[0] + 1]))
    seen = [s.places.reshape(-1, s.places.shape[-1]) for s in out if s.kind != "dial"]
    scale = float(np.ptp(np.vstack(seen), axis=0).max(initial=0.0)) if seen else 0.0
    kept: list[Shape] = []
    for s in out:
        if (s.fixed or s.kind == "joint") and any(
                k.kind == s.kind and k.places.shape == s.places.shape
                and np.allclose(k.places, s.places, rtol=0, atol=COINCIDENT * scale) for k in kept):
            continue
        kept.append(s)
    return kept


def coincident(labels: list[str], paths: np.ndarray, scale: float) -> list[list[int]]:
    """Groups of named points (``paths``: rows x points x axes) that are one point throughout
    the run: within :data:`COINCIDENT` of ``scale`` at every row; each group in first-seen order."""
    groups: list[list[int]] = []
    tolerance = COINCIDENT * max(scale, 1e-300)
    for j in range(len(labels)):
        for group in groups:
            if np.max(np.abs(paths[:, j] - paths[:, group[0]]), initial=0.0) <= tolerance:
                group.append(j)
                break
        else:
            groups.append([j])
    return groups


def from_points(names: list[str], values: np.ndarray) -> list[Shape]:
    """Shapes from a trajectory's point columns alone (``label.x``, ``label.y``...): a star of
    links per component (the label up to its last dot), a disc where a component has a
    ``centre`` and a ``rim``, a dot for a lone point, a pivot where a point never moves."""
    columns: dict[str, list[int]] = {}
    for j, name in enumerate(names):
        label, _, axis = name.rpartition(".")
        if axis in ("x", "y", "z") and label:
            columns.setdefault(label, []).append(j)
    if not columns:
        return []
    dimension = max(len(c) for c in columns.values())
    paths = {label: np.column_stack([values[:, c] for c in cols] + [np.zeros(len(values))] * (dimension - len(cols)))
             for label, cols in columns.items()}
    groups: dict[str, list[str]] = {}
    for label in paths:
        groups.setdefault(label.rpartition(".")[0] or label, []).append(label)
    shapes = []
    for group, labels in groups.items():
        stacked = np.stack([paths[label] for label in labels], axis=1)
        if len(labels) > 1:
            shapes.append(Shape("link", group, stacked))
        else:
            shapes.append(Shape("mass", group, stacked))
        if f"{group}.centre" in labels and f"{group}.rim" in labels:
            shapes.append(Shape("disc", group, np.stack([paths[f"{group}.centre"], paths[f"{group}.rim"]], axis=1)))
    for label, path in paths.items():
        if np.ptp(path, axis=0).max(initial=0.0) == 0.0:
            shapes.append(Shape("pivot", label, path[:, None, :], True))
    return _tidy(shapes)


__all__ = ["BY_TYPE", "COINCIDENT", "KINDS", "Shape", "Sketch", "coincident", "describe", "from_points", "place"]
