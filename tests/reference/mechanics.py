"""Independent reference equations of motion derived with ``sympy.physics.mechanics``.

These references are deliberately derived WITHOUT kronsub: every system is built
from frames, points and bodies and handed to :class:`KanesMethod` (or
:class:`LagrangesMethod` for ``rod_chain(..., method="lagrange")``).  The project's
tests compare kronsub's derived ``M(q) qddot + h(q, qdot) = f(q, qdot, t)`` against
them.

Conventions of every :class:`Reference`
--------------------------------------
* ``coordinates``: generalized coordinate names, in order.
* All expressions use plain ``sympy.Symbol`` objects without assumptions:
  coordinates by name (``theta``), velocities ``<coordinate>_dot``
  (``theta_dot``), parameters by name (``m1``, ``g``...), time ``t``.
* ``mass_matrix``: M (n x n).
* ``velocity_terms``: h (n x 1), everything in the inertial side that is not
  ``M qddot`` (Coriolis/centrifugal terms), so that ``M qddot + h = f``.
* ``forces``: f (n x 1), the generalized applied forces: gravity, springs,
  dampers (velocity dependent but still applied forces), external forces.
* ``kinetic_energy``, ``potential_energy``: T and V (V covers only conservative
  loads, i.e. gravity here; the non-conservative part of f is
  ``f + grad_q V``).

Split used with Kane's method (``M u' = forcing``; ``forcing = f - h``):
``h = -forcing(no loads)``, ``f = forcing(all loads) - forcing(no loads)``.
Sign check by hand on a simple pendulum (mass m, length l, angle q from the
downward vertical): ``m l**2 q'' + m g l sin q = 0`` gives M = m l**2, h = 0,
f = -m g l sin q, which is what ``_kane_reference`` produces (see the tests).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

import numpy as np
import sympy
from sympy import Matrix, Symbol, asin, cos, sin
from sympy.physics.mechanics import (
    KanesMethod,
    LagrangesMethod,
    Lagrangian,
    Particle,
    Point,
    ReferenceFrame,
    RigidBody,
    dynamicsymbols,
    inertia,
    kinetic_energy,
)

__all__ = [
    "Reference",
    "RawDerivation",
    "numeric",
    "system1",
    "system2",
    "double_pendulum",
    "cart_pole",
    "particle_on_sphere",
    "watt_governor",
    "rod_chain",
    "rod_chain_raw",
    "three_particles",
    "to_plain",
    "linearized",
]

T_SYMBOL = dynamicsymbols._t  # == sympy.Symbol("t")


# --------------------------------------------------------------------------
# Result types
# --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Reference:
    """Reference equations ``M qddot + h = f`` in plain symbols."""

    coordinates: tuple[str, ...]
    mass_matrix: Matrix
    velocity_terms: Matrix
    forces: Matrix
    kinetic_energy: sympy.Expr
    potential_energy: sympy.Expr
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def velocities(self) -> tuple[str, ...]:
        return tuple(f"{c}_dot" for c in self.coordinates)

    @property
    def q(self) -> Matrix:
        return Matrix([Symbol(c) for c in self.coordinates])

    @property
    def qdot(self) -> Matrix:
        return Matrix([Symbol(v) for v in self.velocities])


@dataclass(frozen=True, eq=False)
class RawDerivation:
    """Unsimplified output of a mechanics derivation (``M * q'' = forcing``).

    ``mass_matrix`` and ``forcing`` are exactly as sympy.physics.mechanics
    returns them (in dynamicsymbols); ``seconds`` is the wall time spent from
    building the frames/bodies to having both matrices.  ``plain()`` gives
    them in plain symbols (conversion not timed).
    """

    coordinates: tuple[str, ...]
    method: str
    mass_matrix: Matrix
    forcing: Matrix
    seconds: float
    _q: tuple = field(repr=False, default=())
    _u: tuple = field(repr=False, default=())

    def plain(self) -> tuple[Matrix, Matrix]:
        return (
            to_plain(self.mass_matrix, self._q, self._u),
            to_plain(self.forcing, self._q, self._u),
        )


# --------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------


def to_plain(expr, q: Sequence, u: Sequence = ()):
    """Replace dynamicsymbols by plain Symbols: derivatives first, then functions.

    ``q`` are coordinate dynamicsymbols (``theta(t)`` -> ``theta``,
    ``theta(t)'`` -> ``theta_dot``); ``u`` are generalized-speed dynamicsymbols
    named ``<coordinate>_dot`` (``theta_dot(t)`` -> ``theta_dot``).
    """
    t = T_SYMBOL
    derivs = {}
    funcs = {}
    for qi in q:
        name = qi.func.__name__
        derivs[qi.diff(t)] = Symbol(f"{name}_dot")
    for ui in u:
        name = ui.func.__name__
        funcs[ui] = Symbol(name)
    for qi in q:
        funcs[qi] = Symbol(qi.func.__name__)

    def conv(e):
        e = sympy.sympify(e).xreplace(derivs).xreplace(funcs)
        leftover = [f for f in e.atoms(sympy.Function) if isinstance(f, sympy.core.function.AppliedUndef)]
        leftover += list(e.atoms(sympy.Derivative))
        if leftover:
            raise ValueError(f"unconverted dynamicsymbols remain: {leftover}")
        return e

    if isinstance(expr, sympy.MatrixBase):
        return Matrix(expr.shape[0], expr.shape[1], [conv(e) for e in expr])
    return conv(expr)


def _simp(expr, simplify: bool):
    if not simplify:
        return expr
    if isinstance(expr, sympy.MatrixBase):
        return expr.applyfunc(sympy.simplify)
    return sympy.simplify(expr)


def _names(names: str | Iterable[str]) -> list[str]:
    return names.split() if isinstance(names, str) else list(names)


@dataclass
class _Model:
    """What a ``build`` callback returns to :func:`_kane_reference`."""

    bodies: list
    gravity: list  # [(mass, point)] acted on by gravity
    up: object  # unit Vector pointing "up" (gravity is -g*up)
    g: sympy.Expr
    loads: list = field(default_factory=list)  # non-gravity applied loads
    extra_potential: sympy.Expr = sympy.S.Zero  # potential of other conservative loads


def _kane_reference(
    coordinates: str | Iterable[str],
    build: Callable[[list, list, ReferenceFrame, Point], _Model],
    simplify: bool = True,
) -> Reference:
    """Derive with KanesMethod (u_i = q_i'), split forcing into f and h."""
    names = _names(coordinates)
    q = [dynamicsymbols(nm) for nm in names]
    u = [dynamicsymbols(f"{nm}_dot") for nm in names]
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    model = build(q, u, N, O)
    gravity_loads = [(P, -m * model.g * model.up) for m, P in model.gravity]
    V = sum(
        (m * model.g * P.pos_from(O).dot(model.up) for m, P in model.gravity),
        sympy.S.Zero,
    ) + model.extra_potential
    all_loads = gravity_loads + list(model.loads)

    kd = [qi.diff(T_SYMBOL) - ui for qi, ui in zip(q, u)]

    kane_all = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    kane_all.kanes_equations(model.bodies, all_loads or None)
    kane_free = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    kane_free.kanes_equations(model.bodies, None)

    M = to_plain(kane_all.mass_matrix, q, u)
    forcing_all = to_plain(kane_all.forcing, q, u)
    forcing_free = to_plain(kane_free.forcing, q, u)
    M_free = to_plain(kane_free.mass_matrix, q, u)
    assert sympy.simplify(M - M_free) == sympy.zeros(*M.shape)
    h = -forcing_free
    f = forcing_all - forcing_free
    T = to_plain(kinetic_energy(N, *model.bodies), q, u)
    return Reference(
        coordinates=tuple(names),
        mass_matrix=_simp(M, simplify),
        velocity_terms=_simp(h, simplify),
        forces=_simp(f, simplify),
        kinetic_energy=_simp(T, simplify),
        potential_energy=_simp(to_plain(V, q, u), simplify),
    )


def numeric(ref: Reference, values: dict[str, float]):
    """Evaluate ``(M, h, f)`` of ``ref`` as numpy arrays.

    ``values`` maps symbol NAMES (parameters, coordinates, ``<q>_dot``, ``t``)
    to floats; extra names are ignored, missing ones raise ``KeyError``.
    Returns ``M`` with shape (n, n) and ``h``, ``f`` with shape (n,).
    """
    fn = ref._cache.get("numeric")
    if fn is None:
        exprs = [ref.mass_matrix, ref.velocity_terms, ref.forces]
        syms = set()
        for e in exprs:
            syms |= e.free_symbols
        syms = sorted(syms, key=lambda s: s.name)
        lam = sympy.lambdify(syms, exprs, modules="numpy")
        fn = ([s.name for s in syms], lam)
        ref._cache["numeric"] = fn
    names, lam = fn
    missing = [n for n in names if n not in values]
    if missing:
        raise KeyError(f"numeric(): no value given for {missing}")
    n = len(ref.coordinates)
    M, h, f = lam(*[float(values[k]) for k in names])
    M = np.array(M, dtype=float).reshape(n, n)
    h = np.array(h, dtype=float).reshape(n)
    f = np.array(f, dtype=float).reshape(n)
    return M, h, f


def _rod(name: str, frame: ReferenceFrame, centre: Point, mass, izz) -> RigidBody:
    return RigidBody(name, centre, frame, mass, (inertia(frame, 0, 0, izz), centre))


# --------------------------------------------------------------------------
# 1. Hoffmann's System I
# --------------------------------------------------------------------------


def _system1_build(params, phi_of_q=None):
    m1, m2, a1, a2, I1, I2, g, F = params

    def build(q, u, N, O):
        theta = q[0]
        phi = q[1] if phi_of_q is None else phi_of_q(theta)
        A = N.orientnew("A", "Axis", (theta, N.z))
        B = N.orientnew("B", "Axis", (phi, N.z))
        # -A.y = (sin theta, -cos theta): "from the downward vertical, ccw positive"
        G1 = O.locatenew("G1", -a1 * A.y)
        P = O.locatenew("P", -2 * a1 * A.y)  # hinge
        G2 = P.locatenew("G2", -a2 * B.y)
        for pt in (G1, P, G2):
            pt.set_vel(N, pt.pos_from(O).dt(N))
        rod1 = _rod("rod1", A, G1, m1, I1)
        rod2 = _rod("rod2", B, G2, m2, I2)
        return _Model(
            bodies=[rod1, rod2],
            gravity=[(m1, G1), (m2, G2)],
            up=N.y,
            g=g,
            loads=[(G2, F * N.x)],
        )

    return build


def system1() -> Reference:
    """Hoffmann (1944) illustrative example I: two hinged rods, force F on rod 2."""
    params = sympy.symbols("m1 m2 a1 a2 I1 I2 g F")
    return _kane_reference("theta phi", _system1_build(params))


# --------------------------------------------------------------------------
# 2. Hoffmann's System II
# --------------------------------------------------------------------------


def system2() -> Reference:
    """System I with the lower rod's lower end on the vertical line x = 2c.

    One coordinate ``theta``; phi = asin((c - a1 sin theta)/a2) (eq. 26) is
    built into the orientation of the lower rod, so Kane's method sees a
    one-degree-of-freedom system directly.
    """
    params = sympy.symbols("m1 m2 a1 a2 I1 I2 g F")
    m1, m2, a1, a2, I1, I2, g, F = params
    c = Symbol("c")
    build = _system1_build(params, phi_of_q=lambda th: asin((c - a1 * sin(th)) / a2))
    # sympy.simplify is slow here (~15 s) and cannot remove the
    # a2*sqrt((a2**2 - (c - a1*sin(theta))**2)/a2**2) factors anyway (no
    # positivity assumptions), so the expressions are left as derived.
    return _kane_reference("theta", build, simplify=False)


# --------------------------------------------------------------------------
# 3. Double pendulum (point masses)
# --------------------------------------------------------------------------


def _double_pendulum_build(params):
    m1, m2, l1, l2, g = params

    def build(q, u, N, O):
        A = N.orientnew("A", "Axis", (q[0], N.z))
        B = N.orientnew("B", "Axis", (q[1], N.z))
        P1 = O.locatenew("P1", -l1 * A.y)
        P2 = P1.locatenew("P2", -l2 * B.y)
        for pt in (P1, P2):
            pt.set_vel(N, pt.pos_from(O).dt(N))
        return _Model(
            bodies=[Particle("p1", P1, m1), Particle("p2", P2, m2)],
            gravity=[(m1, P1), (m2, P2)],
            up=N.y,
            g=g,
        )

    return build


def double_pendulum() -> Reference:
    return _kane_reference("q1 q2", _double_pendulum_build(sympy.symbols("m1 m2 l1 l2 g")))


# --------------------------------------------------------------------------
# 4. Cart-pole with damper and push force
# --------------------------------------------------------------------------


def _cart_pole_build(params):
    mc, mp, l, g, b, u_force = params

    def build(q, u, N, O):
        x, theta = q
        x_dot = u[0]
        C = O.locatenew("C", x * N.x)
        B = N.orientnew("B", "Axis", (theta, N.z))
        G = C.locatenew("G", -(l / 2) * B.y)
        for pt in (C, G):
            pt.set_vel(N, pt.pos_from(O).dt(N))
        cart = Particle("cart", C, mc)
        pole = _rod("pole", B, G, mp, mp * l**2 / 12)
        return _Model(
            bodies=[cart, pole],
            gravity=[(mc, C), (mp, G)],
            up=N.y,
            g=g,
            loads=[(C, (u_force - b * x_dot) * N.x)],
        )

    return build


def cart_pole() -> Reference:
    return _kane_reference("x theta", _cart_pole_build(sympy.symbols("mc mp l g b u")))


# --------------------------------------------------------------------------
# 5. Particle on a sphere
# --------------------------------------------------------------------------


def particle_on_sphere() -> Reference:
    m, R, g = sympy.symbols("m R g")

    def build(q, u, N, O):
        theta, phi = q
        P = O.locatenew(
            "P",
            R * sin(theta) * cos(phi) * N.x
            + R * sin(theta) * sin(phi) * N.y
            + R * cos(theta) * N.z,
        )
        P.set_vel(N, P.pos_from(O).dt(N))
        return _Model(bodies=[Particle("p", P, m)], gravity=[(m, P)], up=N.z, g=g)

    return _kane_reference("theta phi", build)


# --------------------------------------------------------------------------
# 6. Watt governor
# --------------------------------------------------------------------------


def watt_governor() -> Reference:
    J, m, l, Ms, g, tau = sympy.symbols("J m l M g tau")

    def build(q, u, N, O):
        psi, alpha = q
        S = N.orientnew("S", "Axis", (psi, N.z))  # spindle frame
        ball1 = O.locatenew("B1", l * sin(alpha) * S.x - l * cos(alpha) * S.z)
        ball2 = O.locatenew("B2", -l * sin(alpha) * S.x - l * cos(alpha) * S.z)
        sleeve = O.locatenew("Sl", -2 * l * cos(alpha) * N.z)
        for pt in (ball1, ball2, sleeve):
            pt.set_vel(N, pt.pos_from(O).dt(N))
        spindle = RigidBody("spindle", O, S, 0, (inertia(S, 0, 0, J), O))
        return _Model(
            bodies=[
                spindle,
                Particle("ball1", ball1, m),
                Particle("ball2", ball2, m),
                Particle("sleeve", sleeve, Ms),
            ],
            gravity=[(m, ball1), (m, ball2), (Ms, sleeve)],
            up=N.z,
            g=g,
            loads=[(S, tau * N.z)],
        )

    return _kane_reference("psi alpha", build)


# --------------------------------------------------------------------------
# 7. Chain of n uniform rods
# --------------------------------------------------------------------------


def _chain_derive(n: int, method: str, gravity: bool = True):
    """Build and derive the rod chain; returns (M, forcing, seconds, q, u, T, V)."""
    if n < 1:
        raise ValueError("n must be >= 1")
    if method not in ("kane", "lagrange"):
        raise ValueError(f"method must be 'kane' or 'lagrange', not {method!r}")
    start = time.perf_counter()
    names = [f"q{i}" for i in range(1, n + 1)]
    q = [dynamicsymbols(nm) for nm in names]
    u = [dynamicsymbols(f"{nm}_dot") for nm in names] if method == "kane" else []
    ms = [Symbol(f"m{i}") for i in range(1, n + 1)]
    ls = [Symbol(f"l{i}") for i in range(1, n + 1)]
    g = Symbol("g")
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    bodies, loads = [], []
    V = sympy.S.Zero
    prev = O
    for i in range(n):
        A = N.orientnew(f"A{i + 1}", "Axis", (q[i], N.z))
        if method == "kane":
            A.set_ang_vel(N, u[i] * N.z)
        G = prev.locatenew(f"G{i + 1}", -(ls[i] / 2) * A.y)
        P = prev.locatenew(f"P{i + 1}", -ls[i] * A.y)
        G.v2pt_theory(prev, N, A)
        P.v2pt_theory(prev, N, A)
        bodies.append(_rod(f"rod{i + 1}", A, G, ms[i], ms[i] * ls[i] ** 2 / 12))
        if gravity:
            loads.append((G, -ms[i] * g * N.y))
            V += ms[i] * g * G.pos_from(O).dot(N.y)
        prev = P
    if method == "kane":
        kd = [qi.diff(T_SYMBOL) - ui for qi, ui in zip(q, u)]
        kane = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
        kane.kanes_equations(bodies, loads or None)
        M, forcing = kane.mass_matrix, kane.forcing
    else:
        L = Lagrangian(N, *bodies) - V
        lm = LagrangesMethod(L, q, frame=N)
        lm.form_lagranges_equations()
        M, forcing = lm.mass_matrix, lm.forcing
    seconds = time.perf_counter() - start
    T = kinetic_energy(N, *bodies)
    return M, forcing, seconds, q, u, T, V


def rod_chain_raw(n: int, method: str = "kane") -> RawDerivation:
    """Raw (unsimplified) mechanics output for the n-rod chain, with timing."""
    M, forcing, seconds, q, u, _, _ = _chain_derive(n, method)
    return RawDerivation(
        coordinates=tuple(f"q{i}" for i in range(1, n + 1)),
        method=method,
        mass_matrix=M,
        forcing=forcing,
        seconds=seconds,
        _q=tuple(q),
        _u=tuple(u),
    )


def rod_chain(n: int, method: str = "kane", *, raw: bool = False, simplify: bool | None = None):
    """n uniform rods hanging in a chain from the origin (absolute angles q1..qn).

    With ``raw=True`` returns a :class:`RawDerivation` (mechanics' own
    ``mass_matrix``/``forcing`` and the seconds spent); otherwise a
    :class:`Reference`, split into h and f by deriving a second time without
    gravity.  ``simplify`` defaults to ``n <= 2`` (sympy.simplify takes ~8 s at n = 3).
    """
    if raw:
        return rod_chain_raw(n, method)
    if simplify is None:
        simplify = n <= 2
    M, forcing_all, _, q, u, T, V = _chain_derive(n, method, gravity=True)
    _, forcing_free, _, _, _, _, _ = _chain_derive(n, method, gravity=False)
    M = to_plain(M, q, u)
    forcing_all = to_plain(forcing_all, q, u)
    forcing_free = to_plain(forcing_free, q, u)
    h = -forcing_free
    f = forcing_all - forcing_free
    if not simplify:
        f = f.applyfunc(sympy.expand)  # cancels the velocity terms exactly
    return Reference(
        coordinates=tuple(f"q{i}" for i in range(1, n + 1)),
        mass_matrix=_simp(M, simplify),
        velocity_terms=_simp(h, simplify),
        forces=_simp(f, simplify),
        kinetic_energy=_simp(to_plain(T, q, u), simplify),
        potential_energy=_simp(to_plain(V, q, u), simplify),
    )


# --------------------------------------------------------------------------
# 8. Three particles, two of them coalesced
# --------------------------------------------------------------------------


def three_particles() -> Reference:
    m1, m2, m3, f1, f2, f3 = sympy.symbols("m1 m2 m3 f1 f2 f3")

    def build(q, u, N, O):
        x1, x2 = q
        P1 = O.locatenew("P1", x1 * N.x)
        P2 = O.locatenew("P2", x2 * N.x)
        P3 = O.locatenew("P3", x2 * N.x)  # coalesced with P2
        for pt in (P1, P2, P3):
            pt.set_vel(N, pt.pos_from(O).dt(N))
        return _Model(
            bodies=[Particle("p1", P1, m1), Particle("p2", P2, m2), Particle("p3", P3, m3)],
            gravity=[],
            up=N.y,
            g=sympy.S.Zero,
            loads=[(P1, f1 * N.x), (P2, f2 * N.x), (P3, f3 * N.x)],
        )

    return _kane_reference("x1 x2", build)


# --------------------------------------------------------------------------
# 9. Linearisations by sympy.physics.mechanics (KanesMethod.linearize)
# --------------------------------------------------------------------------

_LINEARIZABLE = {
    # name: (coordinates, parameter names, build factory); inputs are parameters made dynamicsymbols
    "double_pendulum": ("q1 q2", "m1 m2 l1 l2 g", _double_pendulum_build),
    "cart_pole": ("x theta", "mc mp l g b u", _cart_pole_build),
}


def linearized(name: str, op_point: dict, inputs: Sequence[str] = ()) -> tuple[Matrix, Matrix]:
    """``A``, ``B`` of ``d/dt [q; u] = A [q; u] + B r`` from :meth:`KanesMethod.linearize`
    (u_i = q_i'), independent of kronsub.

    ``op_point`` maps coordinate names and ``<coordinate>_dot`` names to values (the
    speeds), and input names to their operating values; missing ones are 0. ``inputs``
    are parameters (such as ``u`` of the cart-pole) made functions of time, the columns
    of ``B`` in the order given. Everything else stays a plain symbol.
    """
    coordinates, parameter_names, factory = _LINEARIZABLE[name]
    names = _names(coordinates)
    params = [dynamicsymbols(p) if p in inputs else Symbol(p) for p in parameter_names.split()]
    q = [dynamicsymbols(nm) for nm in names]
    u = [dynamicsymbols(f"{nm}_dot") for nm in names]
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    model = factory(params)(q, u, N, O)
    loads = [(P, -m * model.g * model.up) for m, P in model.gravity] + list(model.loads)
    kd = [qi.diff(T_SYMBOL) - ui for qi, ui in zip(q, u)]
    kane = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    kane.kanes_equations(model.bodies, loads)
    point = {}
    for qi, ui, nm in zip(q, u, names):
        point[qi] = op_point.get(nm, 0)
        point[ui] = op_point.get(f"{nm}_dot", 0)
        point[qi.diff(T_SYMBOL)] = op_point.get(f"{nm}_dot", 0)
    r = [params[parameter_names.split().index(nm)] for nm in inputs]
    for ri, nm in zip(r, inputs):
        point[ri] = op_point.get(nm, 0)
    # away from an equilibrium A holds the accelerations u' too: Kane's own, at the point
    accelerations = kane.mass_matrix.LUsolve(kane.forcing).subs(point)
    point.update({ui.diff(T_SYMBOL): a for ui, a in zip(u, accelerations)})
    A, B, found_r = kane.linearize(A_and_B=True, op_point=point, new_method=True)
    if r:
        B = Matrix.hstack(*[B[:, list(found_r).index(ri)] for ri in r])
    else:
        B = sympy.zeros(2 * len(q), 0)
    return to_plain(A, q, u), to_plain(B, q, u)
