"""Joints in space: point_on_line and slider give two equations (a point on a line in 3-D).

Each against the parametric form of the same line with the same generalized coordinates
(an explicit connection giving the dependent coordinates), at random states: Mbar, hbar,
fbar and T. The fixed line is oblique (no axis-aligned shortcut); the moving line turns
with a coordinate; the slider's line is fixed in a rigid_body3d turning in space.
"""
from __future__ import annotations

import numpy as np
import pytest

import kronsub
from kronsub.errors import ModelError
from helpers import implicit_numeric

BEAD = """name: bead in space
parameters: {m: 0.7, g: 9.81, k: 1.3}
components:
  bead: {type: particle3d, parameters: {mass: m}, coordinates: [bx, by, bz]}
"""

FIXED = BEAD + """coordinates: [bx]
effects:
  gravity: {type: gravity, g: g, direction: [0, 0, -1]}
  spring: {type: spring, between: [bead.centre, [0.3, -0.2, 0.5]], stiffness: k}
"""

CASES = {
    "fixed line": (
        FIXED + "constraints:\n  s: {point_on_line: {point: bead.centre, through: [1, 2, -1], direction: [1, -2, 2]}}\n"
        "initial: {bx: 0.5, by: 3, bz: -2}\n",
        FIXED + "connection:\n  by: 2 - 2*(bx - 1)\n  bz: -1 + 2*(bx - 1)\n",
        ["by", "bz"], lambda q: [2 - 2 * (q[0] - 1), -1 + 2 * (q[0] - 1)], [(0.2, 1.2)]),
}

MOVING_HEAD = """name: bead on a turning line
parameters: {m: 0.7, M: 1.1, L: 0.9, g: 9.81}
components:
  arm: {type: flywheel, parameters: {inertia: M}, coordinates: [a]}
  bead: {type: particle3d, parameters: {mass: m}, coordinates: [bx, by, bz]}
coordinates: [a, bx]
effects:
  gravity: {type: gravity, g: g, direction: [0, 0, -1]}
"""
# the line through (0, 0, L) along (1, tan a, 1/2) turns about the vertical with a
CASES["moving line"] = (
    MOVING_HEAD + "constraints:\n  s: {point_on_line: {point: bead.centre, through: [0, 0, L], "
    "direction: [cos(a), sin(a), cos(a)/2]}}\ninitial: {a: 0.3, bx: 0.6, by: 0.2, bz: 1.2}\n",
    MOVING_HEAD + "connection:\n  by: bx*sin(a)/cos(a)\n  bz: L + bx/2\n",
    ["by", "bz"], lambda q: [q[1] * np.tan(q[0]), 0.9 + q[1] / 2], [(0.1, 0.6), (0.3, 1.0)])

BODY_HEAD = """name: bead on a body in space
parameters: {m: 0.7, M: 1.1, g: 9.81, A: 0.3, B: 0.4, C: 0.5}
components:
  body: {type: rigid_body3d, parameters: {mass: M, Ixx: A, Iyy: B, Izz: C},
         coordinates: [x, y, z, psi, theta, phi]}
  bead: {type: particle3d, parameters: {mass: m}, coordinates: [bx, by, bz]}
coordinates: [x, y, z, psi, theta, phi, bx]
effects:
  gravity: {type: gravity, g: g, direction: [0, 0, -1]}
"""
# the body's x axis through its centre: bead = centre + u R e_x, R e_x = (cos psi cos theta,
# sin psi cos theta, -sin theta), so by = y + tan(psi) (bx - x), bz = z - tan(theta)/cos(psi) (bx - x)
CASES["slider on a rigid_body3d"] = (
    BODY_HEAD + "constraints:\n  s: {slider: {point: bead.centre, body: body}}\n"
    "initial: {psi: 0.2, theta: 0.3, phi: 0.1, bx: 0.5, by: 0.1, bz: -0.15}\n",
    BODY_HEAD + "connection:\n  by: y + sin(psi)/cos(psi)*(bx - x)\n"
    "  bz: z - sin(theta)/(cos(theta)*cos(psi))*(bx - x)\n",
    ["by", "bz"], lambda q: [q[1] + np.tan(q[3]) * (q[6] - q[0]), q[2] - np.tan(q[4]) / np.cos(q[3]) * (q[6] - q[0])],
    [(-0.5, 0.5), (-0.5, 0.5), (-0.5, 0.5), (-0.6, 0.6), (-0.6, 0.6), (-1, 1), (-0.5, 0.5)])


@pytest.mark.parametrize("case", sorted(CASES))
def test_line_in_space_equals_the_parametric_form(tmp_path, case):
    implicit_text, explicit_text, dependent, solved, ranges = CASES[case]
    (tmp_path / "implicit.yaml").write_text(implicit_text)
    (tmp_path / "explicit.yaml").write_text(explicit_text)
    implicit = kronsub.load(tmp_path / "implicit.yaml").derive()
    explicit = kronsub.load(tmp_path / "explicit.yaml").derive()
    imp = implicit.implicit
    assert [d.name for d in imp.dependent] == dependent
    assert [c.name for c in imp.constraints] == ["s.1", "s.2"]  # two equations in space
    assert implicit.coordinates == explicit.coordinates
    params = {p.name: float(p.value) for p in implicit.parameters}
    a_at, b_at = implicit_numeric(explicit, params), implicit_numeric(implicit, params)
    rng = np.random.default_rng(31)
    for _ in range(10):
        q = np.array([rng.uniform(*r) for r in ranges])
        qd = rng.uniform(-1.5, 1.5, len(q))
        guess = np.array(solved(q)) + rng.uniform(-0.05, 0.05, 2)
        for x, y, what in zip(a_at(q, qd), b_at(q, qd, guess=guess), ("M", "h", "f", "T")):
            assert np.allclose(x, y, rtol=1e-10, atol=1e-10), (case, what, x, y)


def test_slider_direction_must_match_the_body(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(BODY_HEAD + "constraints:\n  s: {slider: {point: bead.centre, body: body, direction: [1, 0]}}\n")
    with pytest.raises(ModelError) as info:
        kronsub.load(path)
    assert "direction of slider 's' needs 3 entries" in str(info.value)
