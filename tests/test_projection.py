"""The projection core: multi-step equals one-step, (E) equals Lagrange's operator on Mbar."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy

import kronsub
import kronsub.errors
from conftest import MODELS, REJECTED_MODELS, every_model_file, explicit_model_paths
from kronsub.core.primitive import christoffel_terms
from kronsub.core.rheonomic import depends_on_time, project_frozen
from kronsub.core.trigpoly import TrigAlgebra

SYSTEM2_ONE_STEP = """
name: System II in one step
parameters:
  m1: 1
  m2: 1
  a1: 0.5
  a2: 0.5
  I1: 1/12
  I2: 1/12
  g: 9.81
  F: 0
  c: 0.6
components:
  upper: {type: pinned_rod, parameters: {mass: m1, length: 2*a1, inertia: I1}, coordinates: {angle: theta}}
  lower: {type: rod, parameters: {mass: m2, length: 2*a2, inertia: I2}, coordinates: {x: y, y: z, angle: phi}}
coordinates: [theta]
connection:
  phi: asin((c - a1*sin(theta))/a2)
  y: 2*a1*sin(theta) + a2*sin(asin((c - a1*sin(theta))/a2))
  z: -2*a1*cos(theta) - a2*cos(asin((c - a1*sin(theta))/a2))
effects:
  gravity: {type: gravity, g: g, direction: [0, -1]}
  push: {type: force, point: lower.centre, vector: [F, 0]}
"""

ALL_MODELS = explicit_model_paths()


def _lambdified(system):
    exprs = [system.mass_matrix, system.velocity_terms, system.forces]
    syms = sorted(set().union(*(e.free_symbols for e in exprs)), key=lambda s: s.name)
    return syms, sympy.lambdify(syms, exprs, modules="numpy")


def test_two_steps_equal_one_step(tmp_path: Path):
    """Footnote 3: the transition in several steps yields the result of one step."""
    two = kronsub.load(MODELS / "hoffmann" / "system2.yaml").derive()
    path = tmp_path / "one.yaml"
    path.write_text(SYSTEM2_ONE_STEP)
    one = kronsub.load(path).derive()
    syms_a, fa = _lambdified(two)
    syms_b, fb = _lambdified(one)
    names = sorted({s.name for s in syms_a} | {s.name for s in syms_b})
    rng = np.random.default_rng(3)
    for _ in range(20):
        vals = {n: rng.uniform(0.4, 1.2) for n in names}
        vals["c"] = rng.uniform(0.0, 0.3)
        vals["theta"] = rng.uniform(-0.4, 0.4)
        vals["theta_dot"] = rng.uniform(-2, 2)
        a = fa(*[vals[s.name] for s in syms_a])
        b = fb(*[vals[s.name] for s in syms_b])
        for x, y in zip(a, b):
            assert np.allclose(np.array(x, float), np.array(y, float), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("path", ALL_MODELS)
def test_velocity_terms_are_lagranges_operator_on_mbar(path):
    """(E) = C^T(M Cdot xbardot + h) must equal the Christoffel form of Mbar (Synge's (A)); for a
    connection in t, its part with t held fixed does (the drive's terms are checked against
    hand Lagrangians in test_prescribed_models.py)."""
    system = kronsub.load(MODELS / path).derive()
    want = christoffel_terms(system.mass_matrix, system.coordinates, system.velocities)
    tr = system.transition
    if tr is not None and depends_on_time(dict(tr.connection)):
        want = want + system.velocity_terms - project_frozen(tr.primitive_coordinates, tr.primitive_metric,
                                                             tr.primitive_velocity_terms, dict(tr.connection),
                                                             system.coordinates)
    syms = sorted(system.velocity_terms.free_symbols | want.free_symbols, key=lambda s: s.name)
    f = sympy.lambdify(syms, [system.velocity_terms, want], modules="numpy")
    rng = np.random.default_rng(11)
    for _ in range(10):
        vals = {s.name: rng.uniform(0.3, 1.0) for s in syms}
        if "c" in vals:  # keep System II's subspace (26) real
            vals.update(c=0.1, a1=rng.uniform(0.3, 0.5), a2=rng.uniform(0.9, 1.0))
        got, expected = (np.array(m, dtype=float).ravel() for m in f(*[vals[s.name] for s in syms]))
        assert np.allclose(got, expected, rtol=1e-10, atol=1e-10), (path, got, expected)


def test_known_system_reused_as_component_keeps_its_effects():
    sys1 = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    sys2 = kronsub.load(MODELS / "hoffmann" / "system2.yaml").derive()
    assert set(sys2.effect_forces) == {f"sys1.{name}" for name in sys1.effect_forces}


def test_trig_algebra_collapses_angle_sums():
    a, b = sympy.symbols("a b", real=True)
    alg = TrigAlgebra([a, b])
    p = alg.from_expr(sympy.cos(a) * sympy.cos(b) + sympy.sin(a) * sympy.sin(b))
    assert alg.to_expr(p) == sympy.cos(a - b)
    q = alg.from_expr(sympy.sin(a) ** 2 + sympy.cos(a) ** 2)
    assert alg.to_expr(q) == 1
    r = alg.from_expr(2 * sympy.sin(a) * sympy.cos(a))
    assert alg.to_expr(r) == sympy.sin(2 * a)


def test_trig_algebra_derivative_matches_sympy():
    a, b, k = sympy.symbols("a b k", real=True)
    alg = TrigAlgebra([a, b])
    expr = k * sympy.cos(a - 2 * b) * sympy.sin(b) ** 2 + sympy.sqrt(1 + sympy.sin(a) ** 2) * a
    for i, q in enumerate((a, b)):
        got = alg.to_expr(alg.diff(alg.from_expr(expr), i))
        want = sympy.diff(expr, q)
        for va, vb in ((0.3, -1.1), (1.7, 0.4)):
            vals = {a: va, b: vb, k: 1.3}
            assert abs(float(got.xreplace(vals)) - float(want.xreplace(vals))) < 1e-12


def test_points_fixed_in_a_body_take_forces(tmp_path):
    """A force F at 3L/4 from the pivot of a pinned rod: generalized force 3 F L cos(q) / 4."""
    path = tmp_path / "m.yaml"
    path.write_text("name: p\nparameters: {m: 1, L: 1, F: 1}\ncomponents:\n  rod:\n    type: pinned_rod\n"
                    "    parameters: {mass: m, length: L}\n    coordinates: [q]\n    points: {quarter: [L/4, 0]}\n"
                    "coordinates: [q]\neffects:\n  push: {type: force, point: rod.quarter, vector: [F, 0]}\n")
    system = kronsub.load(path).derive()
    F, L, q = (sympy.Symbol(n, real=True) for n in ("F", "L", "q"))
    assert sympy.simplify(system.forces[0] - 3 * F * L * sympy.cos(q) / 4) == 0
    assert "rod.quarter" in system.points


def test_system1_rod_ends_are_the_hinge_and_the_free_end():
    """System I's lower rod, `axis: down`: its end a is the upper rod's tip A' (2 a1 from O),
    its end b lies 2 a2 further along the angle phi from the downward vertical (Fig. 1)."""
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    a1, a2, theta, phi = (sympy.Symbol(n, real=True) for n in ("a1", "a2", "theta", "phi"))
    tip = (2 * a1 * sympy.sin(theta), -2 * a1 * sympy.cos(theta))
    end = (tip[0] + 2 * a2 * sympy.sin(phi), tip[1] - 2 * a2 * sympy.cos(phi))
    for name, where in (("lower.a", tip), ("lower.hinge", tip), ("lower.b", end), ("lower.end", end)):
        assert all(sympy.simplify(u - v) == 0 for u, v in zip(system.points[name], where)), name


def test_points_need_a_rigid_body(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text("name: p\nparameters: {m: 1}\ncomponents:\n  p:\n    type: particle2d\n"
                    "    parameters: {mass: m}\n    points: {q: [1, 0]}\ncoordinates: [p_x, p_y]\n")
    with pytest.raises(kronsub.errors.ModelError, match="not a rigid body"):
        kronsub.load(path)


@pytest.mark.parametrize("placed, extra, reused", [
    ("", "", True),
    ("", "effects:\n  kick: {type: force, point: arm.lower.end, vector: [1, 0]}\n", True),
    ("", "effects:\n  tie: {type: spring, between: [arm.lower.end, [0, -1]], stiffness: 3}\n", False),
    (", origin: [0.5, 2]", "", False),  # moved: its gravity's potential changes
])
def test_a_known_system_reused_as_it_is_keeps_its_potential(tmp_path, placed, extra, reused):
    """A model on a known system's own coordinates takes the potential the known system's
    derivation compacted (subspace.assemble, ``known``): exactly what compacting the same sum
    again gives; with an effect that adds a potential, or the system moved, it is compacted anew."""
    from kronsub.core.simplify import compact

    arm = tmp_path / "arm.yaml"
    arm.write_text((MODELS / "hoffmann" / "system1.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    top = tmp_path / "top.yaml"
    top.write_text("name: arm again\ncomponents:\n  arm: {model: arm.yaml" + placed + "}\ncoordinates: [theta, phi]\n"
                   + extra, encoding="utf-8")
    model = kronsub.load(top, cache=False)
    system = model.derive(cache=False)
    part = model.primitive.parts[0]
    algebra = TrigAlgebra(system.coordinates)
    again = compact(algebra, algebra.from_expr(sympy.Add(*system.effect_potentials.values())))
    assert sympy.srepr(system.potential_energy) == sympy.srepr(again)
    assert (system.potential_energy is part.assembled_potential[2]) == reused


def test_a_subspace_that_only_renames_is_known_to_have_full_rank(tmp_path):
    """``Subspace.only_renames``: C a permutation (the rank check is skipped for it), and not
    for a connection that mixes coordinates."""
    from kronsub.core.subspace import Subspace

    arm = tmp_path / "arm.yaml"
    arm.write_text((MODELS / "hoffmann" / "system1.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    for coords, expected in (("[theta, phi]", True), ("[phi, theta]", True)):
        top = tmp_path / "top.yaml"
        top.write_text(f"name: again\ncomponents:\n  arm: {{model: arm.yaml}}\ncoordinates: {coords}\n",
                       encoding="utf-8")
        model = kronsub.load(top, cache=False)
        assert Subspace(model.primitive, model.coordinates, model.connection).only_renames(model.primitive) \
            is expected
    model = kronsub.load(MODELS / "hoffmann" / "system1.yaml", cache=False)
    assert not Subspace(model.primitive, model.coordinates, model.connection).only_renames(model.primitive)


@pytest.mark.parametrize("renamed, coords", [("", "[theta, phi]"), ("", "[phi, theta]"),
                                             (", coordinates: {theta: a, phi: b}", "[b, a]")])
def test_a_renaming_writes_c_and_the_velocities_without_the_algebra(tmp_path, renamed, coords):
    """A subspace that only renames (a known system reused, its coordinates permuted or named
    anew) writes ``C`` as ones and zeros and each velocity's image as the new coordinate's
    velocity, without building ``C`` in the algebra: both equal what the algebra makes of them,
    and ``C`` is built only when something asks for it."""
    from kronsub.core import canonical
    from kronsub.core.simplify import compact
    from kronsub.core.subspace import Subspace
    from kronsub.core.symbols import velocity_symbol

    arm = tmp_path / "arm.yaml"
    arm.write_text((MODELS / "hoffmann" / "system1.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    top = tmp_path / "top.yaml"
    top.write_text(f"name: again\ncomponents:\n  arm: {{model: arm.yaml{renamed}}}\ncoordinates: {coords}\n",
                   encoding="utf-8")
    model = kronsub.load(top, cache=False)
    sub = Subspace(model.primitive, model.coordinates, model.connection)
    fast, substitution = sub.transformation(model.primitive), dict(sub.substitution)
    assert "C" not in sub.__dict__  # nothing above needed the algebra's C
    assert sub.is_identity == (not renamed and coords == "[theta, phi]")
    slow = canonical.matrix(len(sub.x), sub.n, [compact(sub.algebra, c) for row in sub.C for c in row])
    assert fast == slow and sorted(fast) == [0, 0, 1, 1]
    for a, (x, v) in enumerate(zip(sub.x, sub.velocities)):
        image = sub.algebra.to_expr(sub.velocity[a])
        assert substitution.get(v, v) == image == velocity_symbol(model.connection[x])
    system = model.derive(cache=False)
    order = [list(model.coordinates).index(model.connection[x]) for x in sub.x]
    original = kronsub.load(MODELS / "hoffmann" / "system1.yaml", cache=False).derive(cache=False)
    rename = {old: model.connection[x] for old, x in zip(original.coordinates, sub.x)}
    rename.update({velocity_symbol(old): velocity_symbol(new) for old, new in list(rename.items())})
    for i in range(2):
        for j in range(2):
            assert system.mass_matrix[order[i], order[j]] == original.mass_matrix[i, j].xreplace(rename)
        assert system.velocity_terms[order[i]] == original.velocity_terms[i].xreplace(rename)


def test_the_gradient_is_diff_along_each_coordinate():
    """`TrigAlgebra.gradient` (one pass over the terms) builds the very polynomials `diff` does,
    term for term and in the same order, through atoms that depend on the coordinates too."""
    a, b, c, k = sympy.symbols("a b c k", real=True)
    alg = TrigAlgebra([a, b, c])
    exprs = [k * sympy.cos(a - 2 * b) * sympy.sin(b) ** 2 + sympy.sqrt(1 + sympy.sin(a) ** 2) * a,
             sympy.cos(a + b + c) * sympy.sin(a - c) * k ** 2 - sympy.sin(2 * c) / k,
             sympy.asin(k * sympy.sin(a)) * sympy.cos(b) + sympy.cos(a) ** 3, k]
    for expr in exprs:
        p = alg.from_expr(expr)
        gradient = alg.gradient(p)
        for j in range(3):
            want = alg.diff(p, j)
            assert [(key, list(coef.items())) for key, coef in gradient[j].terms.items()] == \
                [(key, list(coef.items())) for key, coef in want.terms.items()]


@pytest.mark.parametrize("path", ALL_MODELS)
def test_points_and_bodies_placed_when_read_are_those_placed_at_once(path):
    """A derived system places its points and bodies when they are first read (PlacedPoints,
    PlacedBodies); each is the one ``x -> x(xbar)`` gives at once (`Subspace.moved`)."""
    from kronsub.components.base import in_world
    from kronsub.core.primitive import body_label
    from kronsub.core.subspace import Subspace, world_dimension

    model = kronsub.load(MODELS / path, cache=False)
    system = model.derive(cache=False, scene=False)  # the whole model: a scene keeps the points it uses
    sub = Subspace(model.primitive, model.coordinates, model.connection)
    dimension = world_dimension(model.primitive)

    def at_once(pos):
        moved = tuple(sub.moved(c) for c in pos)
        return in_world(moved, dimension) if dimension == 2 else moved

    points = {f"{part.name}.{label}": at_once(pos) for part in model.primitive.parts
              for label, pos in part.points.items()}
    assert list(system.points) == list(points)
    assert {k: sympy.srepr(v) for k, v in system.points.items()} == {k: sympy.srepr(v) for k, v in points.items()}
    bodies = [(body_label(part, b), sympy.srepr(b.mass), sympy.srepr(at_once(b.centre)),
               sympy.srepr(None if b.rotation is None else b.rotation.applyfunc(sub.moved)), sympy.srepr(b.inertia))
              for part in model.primitive.parts for b in part.bodies]
    assert [(b.name, sympy.srepr(b.mass), sympy.srepr(b.centre), sympy.srepr(b.rotation), sympy.srepr(b.inertia))
            for b in system.bodies] == bodies
    assert len(system.bodies) == len(bodies) and tuple(system.bodies) == system.bodies[:]
    if bodies:
        assert system.bodies[-1] == tuple(system.bodies)[-1]


def test_a_derivation_places_no_point_and_no_body(tmp_path):
    """``Mbar``, ``hbar`` and ``fbar`` need no point and no body: a chain's are placed only when
    read (the link ends are sums over every link above; a rod's rotation costs sympy
    milliseconds), and then once."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_chain", MODELS / "chain" / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    path = tmp_path / "chain6.yaml"
    path.write_text(gen.chain_yaml(6), encoding="utf-8")
    model = kronsub.load(path, cache=False)
    system = model.derive(cache=False)
    assert not system.points._placed and not system.bodies._placed
    assert all(part.points._all is None for part in model.primitive.parts)  # nor built (ComponentPoints)
    assert system.mass_matrix.shape == (6, 6)
    first = system.points["rod6.b"]
    assert system.points["rod6.b"] is first and len(system.points._placed) == 1
    assert [part.name for part in model.primitive.parts if part.points._all is not None] == ["rod6"]
    assert system.bodies[5] is system.bodies[5] and set(system.bodies._placed) == {5}


EVERY_MODEL_FILE = [str(p.relative_to(MODELS.parent)) for p in every_model_file()]


@pytest.mark.parametrize("path", sorted(REJECTED_MODELS))
def test_the_model_files_left_out_of_every_model_file_are_rejected(path):
    with pytest.raises(kronsub.errors.ModelError):
        kronsub.load(MODELS.parent / path)


@pytest.mark.parametrize("path", EVERY_MODEL_FILE)
def test_points_built_when_read_are_those_built_at_once(path):
    """A component's points are built when first read (`ComponentPoints`): the very points
    `Component.all_points` builds, in its order, with no symbol `ComponentPoints.symbols` does
    not name; the primitive's (`PrimitivePoints`) are the same read one by one or listed."""
    from kronsub.components.base import ComponentPoints
    from kronsub.core.symbols import free_symbols_of

    model = kronsub.load(MODELS.parent / path)
    parts = model.primitive.parts
    for part in parts:
        if isinstance(part.points, ComponentPoints):
            at_once = part.points._component.all_points()
            assert list(part.points) == list(at_once)
            assert {k: sympy.srepr(v) for k, v in part.points.items()} == {k: sympy.srepr(v) for k, v in at_once.items()}
            assert free_symbols_of([c for pos in at_once.values() for c in pos]) <= part.points.symbols()
    listed = {f"{part.name}.{label}": pos for part in parts for label, pos in part.points.items()}
    one_by_one = model.primitive.points()
    assert {label: one_by_one[label] for label in listed} == listed and one_by_one._all is None
    assert list(one_by_one) == list(listed) and len(one_by_one) == len(listed)
    assert "no.such.point" not in one_by_one and f"{parts[0].name}.no_such_point" not in one_by_one
