"""Linearisations of textbook models (``kronsub linearize``) against the Jacobians of hand
derivations in plain sympy, at equilibria found by kronsub (also where Levenberg-Marquardt
stalls), with inputs in time, through closed loops (against the multipliers) and with names
other tools reserve.
"""
from __future__ import annotations

import json

import numpy as np
import sympy as sp
from click.testing import CliRunner

from helpers.compare import worst
from kronsub.cli import main
from reference import sweep3, sweep5, sweep6
from reference.lagrange import dots, S, t


def test_linearize_through_springs_of_rest_length_on_a_line():
    """`linearize` of a model whose springs on a line have a rest length (|x + w| - l0: the
    derivative of sign) stopped with an internal error (DiracDelta). A against finite
    differences of the hand equations at the equilibrium it finds."""
    q, M, h, f, _ = sweep3.cart_pendulum_reference()
    system = sweep3.derived("cart_pendulum.yaml")
    lin = system.linearize()
    assert lin.equilibrium
    point = {s.name: float(v) for s, v in lin.point}
    values = {p.name: float(p.value) for p in system.parameters}
    args = [t, *q, *dots(q)]
    sub = {sp.Symbol(k): v for k, v in values.items()}
    fM, fr = (sp.lambdify(args, e.subs(sub), "numpy") for e in (M, f - h))
    n, tt = len(q), float(lin.time)

    def rhs(y):
        return np.concatenate([y[n:], np.linalg.solve(np.array(fM(tt, *y), dtype=float),
                                                      np.array(fr(tt, *y), dtype=float).ravel())])

    y0 = np.array([point[s.name] for s in q] + [point[f"{s.name}_dot"] for s in q])
    assert np.max(np.abs(rhs(y0))) < 1e-9
    eps, cols = 1e-6, []
    for i in range(2 * n):
        e = np.zeros(2 * n)
        e[i] = eps
        cols.append((rhs(y0 + e) - rhs(y0 - e)) / (2 * eps))
    assert np.allclose(np.asarray(lin.A, dtype=float), np.column_stack(cols), rtol=1e-6, atol=1e-6)


def test_planar_body_linearized_by_hand(tmp_path):
    """`linearize --scene still`: the equilibrium kronsub finds is one of the hand equations
    (``f(q*) = 0``) and ``A`` is the hand Jacobian ``[[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]``."""
    q, M, h, f, _ = sweep5.plate_reference(still=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep5.HERE / "planar_body_tethered.yaml"), "--scene", "still",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    point = data["operating_point"]
    values = {p.name: float(p.value) for p in sweep5.derived("planar_body_tethered.yaml").parameters}
    qd = dots(q)
    sub = {s: values[s.name] for s in (f.free_symbols | M.free_symbols) if s.name in values}
    qstar = {s: float(point[s.name]) for s in q}
    zero = {v: 0.0 for v in qd}
    residual = np.array((f - h).xreplace(sub).xreplace(qstar).xreplace(zero).evalf(), dtype=float)
    assert np.max(np.abs(residual)) < 1e-9, residual
    rhs = M.inv() * (f - h)
    y = q + qd
    J = rhs.jacobian(y).xreplace(sub).xreplace(qstar).xreplace(zero)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [np.array(J.evalf(), dtype=float)]])
    ours = np.array(data["A"], dtype=float)
    assert np.allclose(ours, A, rtol=1e-8, atol=1e-8), (ours, A)


def test_linearize_a_closed_loop_in_space_against_the_multipliers(tmp_path):
    """`linearize --scene free` of the turntable bead: the hand accelerations (the multiplier
    solve on x, y, z, a) vanish at kronsub's operating point, and kronsub's A is their
    Jacobian in [a, z, a_dot, z_dot] by central differences.

    The turntable's angle is not fixed by the equilibrium (its column of dr/dq is round-off,
    ~1e-16, not an exact zero): Levenberg-Marquardt scaled by those column norms (scipy's
    default for 'lm') sent it to a = -9.7e13 (and from the model's initial values to
    -1.4e15, "no equilibrium found"). With unit scaling it stays where it started."""
    ref = sweep5.turntable_reference(free=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep5.HERE / "turntable_bead.yaml"), "--scene", "free",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["state"] == ["a", "z", "a_dot", "z_dot"] and data["equilibrium"]
    assert abs(data["operating_point"]["a"] - 0.2) < 1e-9, data["operating_point"]  # the model's initial a
    values = {p.name: float(p.value) for p in sweep5.derived("turntable_bead.yaml").parameters}
    pv = [values[n] for n in ref.params]
    point = np.array([data["operating_point"][n] for n in data["state"]], dtype=float)
    guess = [point[0], 0.4, 0.1, point[1]]

    def acc(state):
        yv, ydv = ref.consistent(state[:2], state[2:], guess, pv)
        return ref.evaluate(0.0, yv, ydv, pv)[3]

    assert np.max(np.abs(acc(point))) < 1e-9
    eps, cols = 1e-6, []
    for j in range(4):
        e = np.zeros(4)
        e[j] = eps
        cols.append((acc(point + e) - acc(point - e)) / (2 * eps))
    A = np.vstack([np.hstack([np.zeros((2, 2)), np.eye(2)]), np.column_stack(cols)])
    assert np.allclose(np.array(data["A"], dtype=float), A, rtol=1e-6, atol=1e-6)


def test_linearize_finds_the_equilibrium_where_levenberg_marquardt_stalls(tmp_path, monkeypatch):
    """`linearize --scene free` of the spinning frame from the model's initial values (psi = 0.1,
    zb = 0.3): Levenberg-Marquardt stalled at zb = 0.144, where the residual turns (the largest
    acceleration 1.01: "no equilibrium found"); the trust-region reflective method from the same
    start finds the equilibrium, where the hand accelerations (the multiplier solve) vanish."""
    import scipy.optimize

    methods, real = [], scipy.optimize.least_squares

    def spy(*args, **kwargs):
        methods.append(kwargs["method"])
        return real(*args, **kwargs)

    monkeypatch.setattr(scipy.optimize, "least_squares", spy)
    ref = sweep5.frame_reference(free=True)
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep5.HERE / "spinning_frame_slider.yaml"), "--scene", "free",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert methods == ["lm", "trf"], methods
    data = json.loads(out.read_text())
    assert data["state"] == ["psi", "zb", "psi_dot", "zb_dot"] and data["equilibrium"], data
    values = {p.name: float(p.value) for p in sweep5.derived("spinning_frame_slider.yaml").parameters}
    pv = [values[n] for n in ref.params]
    point = [data["operating_point"][n] for n in ("psi", "zb")]
    yv, ydv = ref.consistent(point, [0.0, 0.0], [point[0], 0.2, 0.1, point[1]], pv)
    assert np.max(np.abs(ref.evaluate(0.0, yv, ydv, pv)[3])) < 1e-9


def test_names_other_tools_reserve_linearized_symbolically(tmp_path):
    """`linearize --symbolic` of the odd names (the push off: `--at oo=0`): every entry of A read
    back with those names (`Abs`, `I`, `E`... as the model's symbols) equals the hand Jacobian at
    the operating point and the parameters' values."""
    q, M, h, f, _ = sweep5.odd_reference()
    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep5.HERE / "odd_names.yaml"), "--symbolic", "--at", "oo=0",
                                       "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["state"] == ["nan", "E", "nan_dot", "E_dot"] and data["equilibrium"]
    values = {p.name: float(p.value) for p in sweep5.derived("odd_names.yaml").parameters}
    values["oo"] = 0.0
    names = {n: sp.Symbol(n) for n in values}
    point = {n: float(sp.Float(v)) for n, v in data["operating_point"].items()}
    ours = np.array([[float(sp.sympify(e, locals=names).xreplace({names[k]: v for k, v in values.items()}))
                      for e in row] for row in data["A"]])  # test code reading the output, not kronsub
    qd = dots(q)
    rhs = M.inv() * (f - h)
    sub = {s: values[s.name] for s in rhs.free_symbols if s.name in values}
    sub.update({s: point[s.name] for s in [*q, *qd]})
    sub[t] = 0.0
    J = np.array(rhs.jacobian([*q, *qd]).xreplace(sub).evalf(), dtype=float)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [J]])
    assert np.allclose(ours, A, rtol=1e-9, atol=1e-9), (ours, A)


def test_planar_body_linearized_with_inputs_in_time(tmp_path):
    """`linearize --scene pushed --inputs F,tau --at t=0.5` at a given point that is no
    equilibrium: A and B (the columns of the force's size F sin(3t) and the torque's tau cos t)
    against the hand Jacobians there."""
    q, M, h, f, _ = sweep5.plate_reference(damper=False)
    at = {"x": 0.1, "y": 0.2, "th": 0.3, "x_dot": 0.5, "y_dot": -0.2, "th_dot": 1.0}
    args = ["linearize", str(sweep5.HERE / "planar_body_tethered.yaml"), "--scene", "pushed", "--inputs", "F,tau",
            "--at", "t=0.5", "--format", "json", "-o", str(tmp_path / "lin.json")]
    for name, value in at.items():
        args += ["--at", f"{name}={value}"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "lin.json").read_text())
    assert not data["equilibrium"] and data["inputs"] == ["F", "tau"]
    values = {p.name: float(p.value) for p in sweep5.derived("planar_body_tethered.yaml").parameters}
    rhs = M.inv() * (f - h)
    F, tau = S("F tau")
    sub = {s: values[s.name] for s in rhs.free_symbols if s.name in values}
    sub.update({s: at[s.name] for s in [*q, *dots(q)]})
    sub[t] = 0.5
    J = np.array(rhs.jacobian([*q, *dots(q)]).xreplace(sub).evalf(), dtype=float)
    Bl = np.array(rhs.jacobian([F, tau]).xreplace(sub).evalf(), dtype=float)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [J]])
    B = np.vstack([np.zeros((3, 2)), Bl])
    assert np.allclose(np.array(data["A"], dtype=float), A, rtol=1e-9, atol=1e-9)
    assert np.allclose(np.array(data["B"], dtype=float), B, rtol=1e-9, atol=1e-9)


def test_cart_with_two_pendulums_linearized_at_its_equilibrium(tmp_path):
    """`linearize` finds the equilibrium from the initial values (the tie between tips of unequal
    rods tilts both pendulums: p1, p2 != 0); there the hand accelerations vanish, and ``A`` is
    their Jacobian ``[[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]`` (at t = 0, the drive off)."""
    import json

    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep6.HERE / "cart_twin_pendulums.yaml"), "--format", "json",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["equilibrium"] and data["found"] == ["s", "p1", "p2"] and data["time"] == 0
    q, M, h, f, _ = sweep6.cart_twin_reference()
    y = [*q, *dots(q)]
    acc = M.LUsolve(f - h)
    given = data["parameters"]
    point = {**{v: data["operating_point"][v.name] for v in y}, t: 0}
    values = {s: float(given[s.name]) for s in (M.free_symbols | f.free_symbols) if s.name in given}
    at = lambda e: np.array(e.xreplace(values).xreplace(point).evalf(), dtype=float)  # noqa: E731
    assert abs(data["operating_point"]["p1"]) > 0.01 and np.max(np.abs(at(acc))) < 1e-9
    A = np.vstack([np.hstack([np.zeros((3, 3)), np.eye(3)]), at(acc.jacobian(y))])
    assert worst([(np.array(data["A"]), A)]) < 1e-8


def test_furuta_pendulum_linearized_upright(tmp_path):
    """`linearize --scene balance` at the upright (th = pi, u = 0, t = 0) with the motor's ``u``
    as input: ``A = [[0, I], [M^-1 d(f - h)/dq, M^-1 d(f - h)/dqdot]]`` and ``B = M^-1 df/du`` of
    the hand equations (without the tether), their accelerations zero there."""
    import json

    out = tmp_path / "lin.json"
    result = CliRunner().invoke(main, ["linearize", str(sweep6.HERE / "furuta.yaml"), "--scene", "balance", "--at",
                                       f"th={np.pi!r}", "--at", "al=0", "--at", "t=0", "--at", "u=0",
                                       "--inputs", "u", "--format", "json", "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["equilibrium"] and data["state"] == ["al", "th", "al_dot", "th_dot"]
    q, M, h, f, _ = sweep6.furuta_reference(tether=False)
    u = S("u")
    y = [*q, *dots(q)]
    acc = M.LUsolve(f - h)
    given = data["parameters"]
    values = {s: float(given[s.name]) for s in (M.free_symbols | f.free_symbols) if s.name in given}
    point = {**dict(zip(y, [0.0, sp.pi, 0, 0])), t: 0}
    jac = acc.jacobian(y).xreplace({**values, **point})
    A = np.vstack([np.hstack([np.zeros((2, 2)), np.eye(2)]), np.array(jac.evalf(), dtype=float)])
    B = np.vstack([np.zeros((2, 1)), np.array(acc.diff(u).xreplace({**values, **point}).evalf(), dtype=float)])
    assert np.max(np.abs(np.array(acc.xreplace({**values, **point}).evalf(), dtype=float))) < 1e-12
    assert worst([(np.array(data["A"]), A), (np.array(data["B"]), B)]) < 1e-9
