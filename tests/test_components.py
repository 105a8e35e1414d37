"""Property tests of every registered library component.

Every test that is parametrised over ``sorted(REGISTRY)`` runs automatically
for a newly registered component type. The kinetic-energy test recomputes
``T`` from the component's mass distribution (``bodies()``) independently of
its declared metric, so a metric that does not match its bodies fails there.
"""
from __future__ import annotations

import inspect
import math

import numpy as np
import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from kronsub.components import REGISTRY
from kronsub.components.base import Component
from kronsub.components.spatial import SEQUENCES, euler_rates, euler_rotation
from kronsub.core.primitive import part_from_component
from kronsub.core.symbols import acceleration_symbol, symbol, velocity_symbol

TYPES = sorted(REGISTRY)
MECHANICAL = [name for name in TYPES if REGISTRY[name].__module__ != "kronsub.components.electrical"]
"""The types with a mass distribution; circuit branches (no bodies, a metric that may be zero:
a branch without inductance) have their own property tests in tests/test_electrical_components.py."""

# -- building components like the loader does --------------------------------

INERTIA_DIAGONAL = ("Ixx", "Iyy", "Izz")
INERTIA_PRODUCTS = ("Ixy", "Iyz", "Ixz")

# Coordinate ranges where a component's metric must be positive definite;
# anything not listed ranges over [-10, 10].
COORDINATE_RANGES = {
    ("particle_polar", "r"): (0.1, 10.0),
    ("particle_spherical", "r"): (0.1, 10.0),
    ("particle_spherical", "theta"): (1e-3, math.pi - 1e-3),
    ("rigid_body3d", "theta"): (-(math.pi / 2 - 0.1), math.pi / 2 - 0.1),
}
DEFAULT_COORDINATE_RANGE = (-10.0, 10.0)
# Parameters that may take any sign; every other parameter is positive.
SIGNED_PARAMETERS = {"pivot_x", "pivot_y"}


def coordinate_symbols(cls) -> dict[str, sympy.Symbol]:
    """Local coordinate name -> a real symbol, prefixed so it never clashes with a parameter."""
    return {local: symbol(f"q_{local}") for local in cls.coordinates}


def evaluate_default(spec, params):
    """A parameter's default: an expression (library-internal string) in the earlier parameters."""
    value = sympy.sympify(spec.default, locals=dict(params))
    unknown = {s.name for s in value.free_symbols} - {s.name for v in params.values()
                                                       for s in sympy.sympify(v).free_symbols}
    assert not unknown, f"default {spec.default!r} of {spec.name} names unknown parameters {unknown}"
    return value


def build(cls, use_defaults=False) -> Component:
    """An instance of ``cls`` with symbolic parameters (named like the parameters).

    With ``use_defaults`` every parameter that has a default takes it, evaluated
    from the parameters before it, as the loader does.
    """
    params: dict[str, sympy.Expr] = {}
    for spec in cls.parameters:
        if use_defaults and spec.default is not None:
            params[spec.name] = evaluate_default(spec, params)
        else:
            params[spec.name] = symbol(spec.name)
    return cls(x=coordinate_symbols(cls), p=params)


def symbolic_instances():
    """(type, use_defaults) pairs: all parameters free, and defaults where a component has any."""
    out = []
    for name in TYPES:
        out.append(pytest.param(name, False, id=f"{name}-given"))
        if any(spec.default is not None for spec in REGISTRY[name].parameters):
            out.append(pytest.param(name, True, id=f"{name}-defaults"))
    return out


SYMBOLIC = symbolic_instances()


def kinetic_energy_from_bodies(component: Component) -> sympy.Expr:
    """``T`` from the mass distribution alone: 1/2 m v.v + 1/2 omega^T I omega per body."""
    coords = component.coordinate_symbols
    vels = [velocity_symbol(q) for q in coords]

    def rate(expr):
        return sum((sympy.diff(expr, q) * v for q, v in zip(coords, vels)), sympy.Integer(0))

    total = sympy.Integer(0)
    for body in component.bodies():
        v = sympy.Matrix([rate(c) for c in body.centre])
        total += body.mass * (v.T * v)[0, 0] / 2
        if body.rotation is None:
            assert body.inertia is None or body.inertia.is_zero_matrix
            continue
        R = sympy.Matrix(body.rotation)
        S = R.T * R.applyfunc(rate)
        if R.shape == (2, 2):
            omega = sympy.Matrix([S[1, 0]])
        elif R.shape == (3, 3):
            omega = sympy.Matrix([S[2, 1], S[0, 2], S[1, 0]])
        else:  # pragma: no cover - a new kind of body
            raise AssertionError(f"unexpected rotation shape {R.shape}")
        assert body.inertia is not None and body.inertia.shape == (omega.rows, omega.rows)
        total += (omega.T * body.inertia * omega)[0, 0] / 2
    return total


def kinetic_energy_from_metric(component: Component) -> sympy.Expr:
    xdot = sympy.Matrix([velocity_symbol(q) for q in component.coordinate_symbols])
    return (xdot.T * sympy.Matrix(component.metric()) * xdot)[0, 0] / 2


def random_state(component: Component, rng, extra=()):
    """Random values for every free symbol: coordinates in their valid ranges, the rest in [0.3, 1.7]."""
    ranges = {component.x[local]: COORDINATE_RANGES.get((component.type_name, local), DEFAULT_COORDINATE_RANGE)
              for local in component.coordinates}
    names = set(extra)
    for expr in list(component.p.values()) + list(component.metric()):
        names |= sympy.sympify(expr).free_symbols
    names |= set(ranges)
    state = {}
    for s in sorted(names, key=lambda s: s.name):
        lo, hi = ranges.get(s, (0.3, 1.7))
        state[s] = float(rng.uniform(lo, hi))
    return state


def numeric(expr, state) -> float:
    return float(sympy.sympify(expr).xreplace(state).evalf(30))


def close(a: float, b: float, rel=1e-12) -> bool:
    return abs(a - b) <= rel * max(1.0, abs(a), abs(b))


# -- 1. symmetry ---------------------------------------------------------------

@pytest.mark.parametrize("type_name, use_defaults", SYMBOLIC)
def test_metric_is_square_and_symmetric(type_name, use_defaults):
    component = build(REGISTRY[type_name], use_defaults=use_defaults)
    M = sympy.Matrix(component.metric())
    n = len(component.coordinates)
    assert M.shape == (n, n)
    asym = (M - M.T).applyfunc(sympy.simplify)
    assert asym == sympy.zeros(n, n), f"{type_name}: metric not symmetric, M - M.T = {asym}"


# -- 2. positive definiteness -------------------------------------------------

def rotation_from_quaternion(w, x, y, z) -> np.ndarray:
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


POSITIVE = st.floats(0.1, 10.0, allow_nan=False, allow_infinity=False)


def draw_parameters(draw, cls) -> dict[str, sympy.Expr]:
    """Valid numeric parameters for ``cls``; a parameter with a default sometimes takes it."""
    names = [spec.name for spec in cls.parameters]
    drawn: dict[str, float] = {}
    tensor = all(n in names for n in INERTIA_DIAGONAL + INERTIA_PRODUCTS)
    if tensor and draw(st.booleans(), label="rotated inertia tensor"):
        # a positive diagonal seen in rotated axes: positive definite with products
        principal = np.diag([draw(POSITIVE, label=f"principal {i}") for i in range(3)])
        quat = [draw(st.floats(-1.0, 1.0), label=f"q{i}") for i in range(4)]
        if sum(q * q for q in quat) < 1e-2:
            quat = [1.0, 0.0, 0.0, 0.0]
        Q = rotation_from_quaternion(*quat)
        inertia = Q @ principal @ Q.T
        for name, (i, j) in zip(INERTIA_DIAGONAL + INERTIA_PRODUCTS,
                                [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]):
            drawn[name] = float(inertia[i, j])
    params: dict[str, sympy.Expr] = {}
    for spec in cls.parameters:
        if spec.name in drawn:
            params[spec.name] = sympy.Float(drawn[spec.name])
        elif spec.default is not None and (spec.name in INERTIA_PRODUCTS
                                           or draw(st.booleans(), label=f"default {spec.name}")):
            params[spec.name] = evaluate_default(spec, params)
        elif spec.name in SIGNED_PARAMETERS:
            params[spec.name] = sympy.Float(draw(st.floats(-10.0, 10.0), label=spec.name))
        else:
            params[spec.name] = sympy.Float(draw(POSITIVE, label=spec.name))
    return params


@pytest.mark.parametrize("type_name", MECHANICAL)
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_metric_positive_definite(type_name, data):
    cls = REGISTRY[type_name]
    params = draw_parameters(data.draw, cls)
    component = cls(x=coordinate_symbols(cls), p=params)
    state = {}
    for local in cls.coordinates:
        lo, hi = COORDINATE_RANGES.get((type_name, local), DEFAULT_COORDINATE_RANGE)
        state[component.x[local]] = data.draw(st.floats(lo, hi), label=local)
    M = sympy.Matrix(component.metric()).xreplace({k: sympy.Float(v) for k, v in state.items()})
    assert not M.free_symbols, f"{type_name}: metric has unbound symbols {M.free_symbols}"
    A = np.array(M.evalf(), dtype=float)
    eig = np.linalg.eigvalsh((A + A.T) / 2)
    assert np.all(eig > 0), f"{type_name}: metric not positive definite at {state}, {params}: eigenvalues {eig}"


# -- 3. kinetic energy from the mass distribution ------------------------------

@pytest.mark.parametrize("type_name, use_defaults", [p for p in SYMBOLIC if p.values[0] in MECHANICAL])
def test_metric_matches_kinetic_energy_of_bodies(type_name, use_defaults):
    component = build(REGISTRY[type_name], use_defaults=use_defaults)
    assert component.bodies(), f"{type_name}: declares no bodies (no mass distribution)"
    t_bodies = kinetic_energy_from_bodies(component)
    t_metric = kinetic_energy_from_metric(component)
    rng = np.random.default_rng(sum(map(ord, type_name)))
    vels = [velocity_symbol(q) for q in component.coordinate_symbols]
    for _ in range(20):
        state = random_state(component, rng)
        state.update({v: float(rng.uniform(-2, 2)) for v in vels})
        a, b = numeric(t_bodies, state), numeric(t_metric, state)
        assert close(a, b), (f"{type_name}: metric kinetic energy {b!r} != kinetic energy of its bodies "
                             f"{a!r} at {state}\n  from bodies: {t_bodies}\n  from metric: {t_metric}")
    if len(component.coordinates) <= 3:  # exact check where simplify is quick
        diff = sympy.simplify(sympy.expand(t_bodies - t_metric))
        assert diff == 0, f"{type_name}: T(bodies) - T(metric) = {diff}"


# -- 4. velocity terms satisfy Lagrange's operator ------------------------------

@pytest.mark.parametrize("type_name, use_defaults", SYMBOLIC)
def test_velocity_terms_satisfy_lagrange(type_name, use_defaults):
    component = build(REGISTRY[type_name], use_defaults=use_defaults)
    part = part_from_component("c", component)
    coords = list(component.coordinate_symbols)
    vels = [velocity_symbol(q) for q in coords]
    accs = [acceleration_symbol(q) for q in coords]
    assert list(part.coordinates) == coords and list(part.velocities) == vels
    n = len(coords)
    assert part.velocity_terms.shape == (n, 1)
    T = kinetic_energy_from_metric(component)
    lhs = []
    for a in range(n):
        p_a = sympy.diff(T, vels[a])
        dt = sum((sympy.diff(p_a, q) * v for q, v in zip(coords, vels)), sympy.Integer(0)) \
            + sum((sympy.diff(p_a, v) * w for v, w in zip(vels, accs)), sympy.Integer(0))
        lhs.append(dt - sympy.diff(T, coords[a]))
    rhs = part.metric * sympy.Matrix(accs) + part.velocity_terms
    rng = np.random.default_rng(1 + sum(map(ord, type_name)))
    for _ in range(20):
        state = random_state(component, rng)
        state.update({v: float(rng.uniform(-2, 2)) for v in vels})
        state.update({w: float(rng.uniform(-2, 2)) for w in accs})
        for a in range(n):
            x, y = numeric(lhs[a], state), numeric(rhs[a], state)
            assert close(x, y), (f"{type_name}: Lagrange's operator {x!r} != M xddot + h {y!r} "
                                 f"in row {a} at {state}")


# -- 5. named points -------------------------------------------------------------

@pytest.mark.parametrize("type_name, use_defaults", SYMBOLIC)
def test_points(type_name, use_defaults):
    component = build(REGISTRY[type_name], use_defaults=use_defaults)
    points = component.points()
    if component.dimension == 0:
        assert points == {}, f"{type_name}: dimension 0 but has points {sorted(points)}"
    allowed = set(component.coordinate_symbols)
    for value in component.p.values():
        allowed |= sympy.sympify(value).free_symbols
    for name, position in points.items():
        assert len(position) == component.dimension, \
            f"{type_name}.{name}: {len(position)} entries, dimension {component.dimension}"
        stray = set().union(*(sympy.sympify(c).free_symbols for c in position)) - allowed
        assert not stray, f"{type_name}.{name}: depends on unknown symbols {stray}"
    bodies = component.bodies()
    if not bodies:
        return
    centre = tuple(sympy.sympify(c) for c in bodies[0].centre)
    moving = any(c.has(*component.coordinate_symbols) for c in centre)
    if moving:
        assert "centre" in points, f"{type_name}: moving mass centre but no 'centre' point"
    if "centre" in points:
        assert len(points["centre"]) == len(centre)
        for p, c in zip(points["centre"], centre):
            assert sympy.simplify(p - c) == 0, f"{type_name}: point centre {points['centre']} != body centre {centre}"


# -- 6. class metadata -----------------------------------------------------------

@pytest.mark.parametrize("type_name", TYPES)
def test_class_metadata(type_name):
    cls = REGISTRY[type_name]
    assert issubclass(cls, Component)
    assert cls.type_name == type_name and type_name.strip()
    assert cls.summary.strip(), f"{type_name}: empty summary"
    assert cls.coordinates and len(set(cls.coordinates)) == len(cls.coordinates), \
        f"{type_name}: coordinates {cls.coordinates!r} empty or repeated"
    assert all(isinstance(c, str) and c for c in cls.coordinates)
    names = [spec.name for spec in cls.parameters]
    assert len(set(names)) == len(names), f"{type_name}: repeated parameter names {names}"
    assert not set(names) & set(cls.coordinates), f"{type_name}: a parameter is named like a coordinate"
    assert all(spec.description.strip() for spec in cls.parameters)
    # the class's own docstring, or one inherited from a component-specific base
    # (particle1d/2d/3d share _Cartesian's); the generic Component docstring does not count
    doc = inspect.getdoc(cls)
    assert doc and doc.strip() and doc != inspect.getdoc(Component), f"{type_name}: no docstring"


# -- exact facts -------------------------------------------------------------------

def S(names: str):
    return [symbol(n) for n in names.split()]


def test_pinned_rod_metric_is_first_entry_of_16():
    m, L, I, px, py = S("mass length inertia pivot_x pivot_y")
    rod = build(REGISTRY["pinned_rod"])
    assert sympy.simplify(rod.metric()[0, 0] - (I + m * (L / 2) ** 2)) == 0
    assert rod.metric().shape == (1, 1)
    # with the default inertia m L^2/12 the metric is m L^2/3 about the pivot
    rod = build(REGISTRY["pinned_rod"], use_defaults=True)
    assert sympy.simplify(rod.metric()[0, 0] - m * L**2 / 3) == 0
    assert rod.p["pivot_x"] == 0 and rod.p["pivot_y"] == 0


def test_rod_default_inertia():
    m, L = S("mass length")
    rod = build(REGISTRY["rod"], use_defaults=True)
    assert sympy.simplify(rod.p["inertia"] - m * L**2 / 12) == 0
    assert sympy.simplify(rod.metric()[2, 2] - m * L**2 / 12) == 0
    assert sympy.simplify(rod.bodies()[0].inertia[0, 0] - m * L**2 / 12) == 0


def test_disc_default_inertia():
    m, r = S("mass radius")
    disc = build(REGISTRY["disc"], use_defaults=True)
    assert sympy.simplify(disc.p["inertia"] - m * r**2 / 2) == 0
    assert sympy.simplify(disc.metric()[2, 2] - m * r**2 / 2) == 0


def test_particle_spherical_metric():
    (m,) = S("mass")
    component = build(REGISTRY["particle_spherical"])
    r, th = component.x["r"], component.x["theta"]
    expected = sympy.diag(m, m * r**2, m * r**2 * sympy.sin(th) ** 2)
    assert (sympy.Matrix(component.metric()) - expected).applyfunc(sympy.simplify) == sympy.zeros(3, 3)


def test_registry_covers_library():
    assert {"particle1d", "particle2d", "particle3d", "particle_polar", "particle_spherical",
            "planar_body", "rod", "disc", "pinned_rod", "flywheel", "rigid_body3d"} <= set(REGISTRY)


@pytest.mark.parametrize("sequence", SEQUENCES)
def test_euler_rates_give_the_body_angular_velocity_of_every_sequence(sequence):
    """``E qdot = (R^T Rdot)^vee`` for each of the twelve sequences, with ``R`` differentiated
    along a path (numerically, at random angles and rates)."""
    t = sympy.Symbol("t")
    rng = np.random.default_rng(len(sequence) + sum(map(ord, sequence)))
    angles0, rates = rng.uniform(-1.2, 1.2, 3), rng.uniform(-2, 2, 3)
    path = [a + r * t for a, r in zip(angles0, rates)]
    R = euler_rotation(sequence, *path)
    W = (R.T * R.diff(t)).subs(t, 0)
    omega = np.array([W[2, 1], W[0, 2], W[1, 0]], dtype=float)
    E = np.array(euler_rates(sequence, *path[1:]).subs(t, 0), dtype=float)
    assert np.allclose(E @ rates, omega, atol=1e-12)
    assert np.allclose(np.array(W + W.T, dtype=float), 0, atol=1e-12)
