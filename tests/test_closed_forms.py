"""Closed forms of the dependent coordinates where the docs promise one (docs/model-format.md,
"a closed form of a dependent coordinate where one constraint is linear in it, in its sine or in
its cosine"): also when there are several constraints, solved one at a time (a pin in space, a
bead on a helix). Each closed form is checked against Newton's method on the constraints from
the branch of the initial configuration, at random states, and against the constraints."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import kronsub
from conftest import ROOT
from kronsub.core.constraints import NumericConstraints

PIN_IN_SPACE = """\
name: two beads pinned in space
parameters: {m1: 1.0, m2: 0.5, g: 9.81}
components:
  a: {type: particle3d, parameters: {mass: m1}, coordinates: [u, v, w]}
  b: {type: particle3d, parameters: {mass: m2}, coordinates: [x, y, z]}
coordinates: [u, v, w]
constraints:
  P: {pin: [a.centre, b.centre]}
effects:
  gravity: {type: gravity, g: g, direction: [0, 0, -1]}
initial: {u: 0.1, v: -0.2, w: 0.3}
"""

SPINNING_PIN = """\
name: a bead pinned to a point turning in space
parameters: {m: 1.0, r: 0.4, h: 0.3, g: 9.81}
components:
  wheel: {type: flywheel, parameters: {inertia: 0.1}, coordinates: [a]}
  bead: {type: particle3d, parameters: {mass: m}, coordinates: [x, y, z]}
coordinates: [a]
constraints:
  px: x - r*cos(a)
  py: y - r*sin(a)
  pz: z - h*a - x
effects:
  gravity: {type: gravity, g: g, direction: [0, 0, -1]}
initial: {a: 0.7, x: 0.3, y: 0.25, z: 0.5}
"""


def _system(tmp_path, source):
    """The derived system and the model's initial values by name."""
    path = ROOT / source if source.endswith(".yaml") else tmp_path / "m.yaml"
    if not source.endswith(".yaml"):
        path.write_text(source)
    model = kronsub.load(path)
    return model.derive(), {str(k): float(v) for k, v in dict(model.initial).items()}


@pytest.mark.parametrize("source", [PIN_IN_SPACE, SPINNING_PIN, "tests/models/sweep5/bead_on_helix.yaml"],
                         ids=["pin in space", "one solution put into the next", "helix"])
def test_several_constraints_solved_one_at_a_time_agree_with_newton(tmp_path, source):
    system, initial = _system(tmp_path, source)
    imp = system.implicit
    closed = dict(imp.closed_form)
    assert set(closed) == set(imp.dependent), "every dependent coordinate has a closed form"
    params = {p.symbol: p.value for p in system.parameters}
    q = list(imp.independent)
    forms = sympy.lambdify([q], [closed[d].xreplace(params) for d in imp.dependent])
    y = q + list(imp.dependent)
    numeric = NumericConstraints(imp.constraints, y, params)
    branch = dict(imp.branch)
    start = np.array([float(branch[s]) if s in branch else initial.get(s.name, 0.0) for s in y])
    rng = np.random.default_rng(3)
    n, k = len(q), len(imp.dependent)
    for _ in range(20):
        qv = start[:n] + rng.uniform(-0.2, 0.2, n)
        from_closed = np.array(forms(list(qv)), dtype=float)
        newton = numeric.solve(np.concatenate([qv, start[n:]]), range(n, n + k))[n:]
        np.testing.assert_allclose(from_closed, newton, rtol=1e-10, atol=1e-12)
        assert np.max(np.abs(numeric.residual(np.concatenate([qv, from_closed])))) < 1e-12


def test_the_docs_promise_what_is_done():
    text = " ".join((ROOT / "docs" / "model-format.md").read_text(encoding="utf-8").split())
    assert "one at a time" in text and "a pin in space" in text
