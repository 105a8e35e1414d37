"""The C integrators and their ctypes driver, on hand-written C models (no code generator).

Each model implements the ABI of the generated C (``ks_rhs``, ``ks_rhs_canonical``, energies,
``ks_momentum``, ``ks_velocity``) and is paired with an independent answer: the oscillator's exact
solution, the conserved energy, scipy's own DOP853, or the order of the method.
"""
from __future__ import annotations

import ctypes
import math
import os

import numpy as np
import pytest

from conftest import MODELS
from kronsub.errors import KronsubError
from kronsub.simulation import native
from kronsub.simulation.native import (
    CompileError,
    CompilerNotFound,
    NativeModel,
    SingularMassMatrix,
    compile_library,
)

pytestmark = pytest.mark.skipif(
    native.shutil.which((os.environ.get("CC") or "gcc").split()[0]) is None, reason="no C compiler"
)

# M = m, h = 0, f = -k q;  param = [m, k]
OSCILLATOR = r"""
#include <math.h>
#define KS_NQ 1
#define KS_NY 2
#define KS_NPARAM 2
int ks_rhs(double t, const double *y, const double *param, double *ydot)
{
    (void)t;
    if (!(param[0] > 0.0)) return 1;
    ydot[0] = y[1];
    ydot[1] = -param[1] * y[0] / param[0];
    return 0;
}
int ks_rhs_canonical(double t, const double *z, const double *param, double *zdot)
{
    (void)t;
    if (!(param[0] > 0.0)) return 1;
    zdot[0] = z[1] / param[0];
    zdot[1] = -param[1] * z[0];
    return 0;
}
double ks_kinetic_energy(const double *y, const double *param) { return 0.5 * param[0] * y[1] * y[1]; }
double ks_potential_energy(double t, const double *y, const double *param)
{
    (void)t;
    return 0.5 * param[1] * y[0] * y[0];
}
void ks_momentum(const double *y, const double *param, double *z) { z[0] = y[0]; z[1] = param[0] * y[1]; }
int ks_velocity(const double *z, const double *param, double *y)
{
    if (!(param[0] > 0.0)) return 1;
    y[0] = z[0];
    y[1] = z[1] / param[0];
    return 0;
}
"""

# M = m l^2, f = -m g l sin q, V = m g l (1 - cos q);  param = [m, l, g]
PENDULUM = r"""
#include <math.h>
#define KS_NQ 1
#define KS_NY 2
#define KS_NPARAM 3
int ks_rhs(double t, const double *y, const double *param, double *ydot)
{
    const double M = param[0] * param[1] * param[1];
    (void)t;
    if (!(M > 0.0)) return 1;
    ydot[0] = y[1];
    ydot[1] = -param[0] * param[2] * param[1] * sin(y[0]) / M;
    return 0;
}
int ks_rhs_canonical(double t, const double *z, const double *param, double *zdot)
{
    const double M = param[0] * param[1] * param[1];
    (void)t;
    if (!(M > 0.0)) return 1;
    zdot[0] = z[1] / M;
    zdot[1] = -param[0] * param[2] * param[1] * sin(z[0]);
    return 0;
}
double ks_kinetic_energy(const double *y, const double *param)
{
    return 0.5 * param[0] * param[1] * param[1] * y[1] * y[1];
}
double ks_potential_energy(double t, const double *y, const double *param)
{
    (void)t;
    return param[0] * param[2] * param[1] * (1.0 - cos(y[0]));
}
void ks_momentum(const double *y, const double *param, double *z)
{
    z[0] = y[0];
    z[1] = param[0] * param[1] * param[1] * y[1];
}
int ks_velocity(const double *z, const double *param, double *y)
{
    const double M = param[0] * param[1] * param[1];
    if (!(M > 0.0)) return 1;
    y[0] = z[0];
    y[1] = z[1] / M;
    return 0;
}
"""

# A cart x on a spring k carrying a pendulum theta: q = [x, theta], param = [mc, m, l, k, g];
# T = 1/2 (mc + m) xd^2 + m l xd thd cos th + 1/2 m l^2 thd^2, V = 1/2 k x^2 - m g l cos th.
CART_PENDULUM = r"""
#include <math.h>
#define KS_NQ 2
#define KS_NY 4
#define KS_NPARAM 5
static void mass(const double *q, const double *p, double M[3])
{
    M[0] = p[0] + p[1];
    M[1] = p[1] * p[2] * cos(q[1]);
    M[2] = p[1] * p[2] * p[2];
}
/* x = M^-1 b for the symmetric 2 x 2 M = [M0 M1; M1 M2]; 1 when not positive definite */
static int solve(const double M[3], const double *b, double *x)
{
    const double det = M[0] * M[2] - M[1] * M[1];
    if (!(M[0] > 0.0) || !(det > 0.0)) return 1;
    x[0] = (M[2] * b[0] - M[1] * b[1]) / det;
    x[1] = (M[0] * b[1] - M[1] * b[0]) / det;
    return 0;
}
int ks_rhs(double t, const double *y, const double *p, double *ydot)
{
    double M[3], r[2];
    const double s = sin(y[1]);
    (void)t;
    mass(y, p, M);
    r[0] = -p[3] * y[0] + p[1] * p[2] * y[3] * y[3] * s;
    r[1] = -p[1] * p[4] * p[2] * s;
    ydot[0] = y[2];
    ydot[1] = y[3];
    return solve(M, r, ydot + 2);
}
int ks_rhs_canonical(double t, const double *z, const double *p, double *zdot)
{
    double M[3], v[2];
    const double s = sin(z[1]);
    (void)t;
    mass(z, p, M);
    if (solve(M, z + 2, v)) return 1;
    zdot[0] = v[0];
    zdot[1] = v[1];
    zdot[2] = -p[3] * z[0];
    zdot[3] = -p[1] * p[2] * v[0] * v[1] * s - p[1] * p[4] * p[2] * s;
    return 0;
}
double ks_kinetic_energy(const double *y, const double *p)
{
    double M[3];
    mass(y, p, M);
    return 0.5 * (M[0] * y[2] * y[2] + 2.0 * M[1] * y[2] * y[3] + M[2] * y[3] * y[3]);
}
double ks_potential_energy(double t, const double *y, const double *p)
{
    (void)t;
    return 0.5 * p[3] * y[0] * y[0] - p[1] * p[4] * p[2] * cos(y[1]);
}
void ks_momentum(const double *y, const double *p, double *z)
{
    double M[3];
    mass(y, p, M);
    z[0] = y[0];
    z[1] = y[1];
    z[2] = M[0] * y[2] + M[1] * y[3];
    z[3] = M[1] * y[2] + M[2] * y[3];
}
int ks_velocity(const double *z, const double *p, double *y)
{
    double M[3];
    mass(z, p, M);
    y[0] = z[0];
    y[1] = z[1];
    return solve(M, z + 2, y + 2);
}
"""

# The oscillator that fails on purpose: ks_rhs returns 1 from t_bad on, NaN from t_nan on;
# param = [m, k, t_bad, t_nan].
FAULTY = OSCILLATOR.replace("#define KS_NPARAM 2", "#define KS_NPARAM 4").replace(
    "    (void)t;\n    if (!(param[0] > 0.0)) return 1;\n    ydot[0] = y[1];\n"
    "    ydot[1] = -param[1] * y[0] / param[0];",
    "    if (!(param[0] > 0.0) || t >= param[2]) return 1;\n    ydot[0] = y[1];\n"
    "    ydot[1] = t >= param[3] ? NAN : -param[1] * y[0] / param[0];",
).replace(
    "    (void)t;\n    if (!(param[0] > 0.0)) return 1;\n    zdot[0] = z[1] / param[0];\n"
    "    zdot[1] = -param[1] * z[0];",
    "    if (!(param[0] > 0.0) || t >= param[2]) return 1;\n    zdot[0] = z[1] / param[0];\n"
    "    zdot[1] = t >= param[3] ? NAN : -param[1] * z[0];",
)


# q'' = 2 q^3 from q = q' = 1: q = 1 / (1 - t), which blows up at t = 1 (ks_rhs only).
BLOWUP = r"""
int ks_rhs(double t, const double *y, const double *param, double *ydot)
{
    (void)t;
    (void)param;
    ydot[0] = y[1];
    ydot[1] = 2.0 * y[0] * y[0] * y[0];
    return 0;
}
"""


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A private kronsub cache for the module's libraries."""
    folder = tmp_path_factory.mktemp("kronsub-cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("KRONSUB_CACHE_DIR", str(folder))
        mp.delenv("CC", raising=False)
        yield folder


@pytest.fixture(scope="module")
def oscillator(cache):
    return NativeModel.build([OSCILLATOR], "oscillator", nq=1, nparam=2)


@pytest.fixture(scope="module")
def pendulum(cache):
    return NativeModel.build([PENDULUM], "pendulum", nq=1, nparam=3)


@pytest.fixture(scope="module")
def cart(cache):
    return NativeModel.build([CART_PENDULUM], "cart_pendulum", nq=2, nparam=5)


@pytest.fixture(scope="module")
def faulty(cache):
    return NativeModel.build([FAULTY], "faulty", nq=1, nparam=4)


def oscillator_exact(t, m, k, q0, v0):
    w = math.sqrt(k / m)
    q = q0 * np.cos(w * t) + v0 / w * np.sin(w * t)
    v = -q0 * w * np.sin(w * t) + v0 * np.cos(w * t)
    return np.column_stack([q, v])


def energy(model, t, Y, param):
    T, V = model.energies(t, Y, param)
    return T + V


PEND = [1.3, 0.8, 9.81]
PEND_Y0 = [2.0, 0.5]   # a large swing


# ---------------------------------------------------------------------------------------------
# dop853
# ---------------------------------------------------------------------------------------------

def test_dop853_matches_the_exact_oscillator_at_exactly_the_requested_times(oscillator):
    m, k, y0 = 2.0, 3.0, [1.0, 0.5]
    t, Y, res = oscillator.integrate("dop853", 0.0, y0, 10.05, 0.1, [m, k], rtol=1e-12, atol=1e-12)
    assert res.ok and res.status == 0 and res.message
    assert len(t) == 102 and res.n_rows == 102
    np.testing.assert_array_equal(t[:-1], 0.0 + np.arange(101) * 0.1)
    assert t[-1] == 10.05
    assert np.max(np.abs(Y - oscillator_exact(t, m, k, *y0))) < 1e-10
    # dense output: most rows fall inside steps, so the rows are many more than the steps
    assert res.n_steps < 101


def test_dop853_t_end_a_multiple_of_dt_out_gives_no_duplicate_row(oscillator):
    t, Y, res = oscillator.integrate("dop853", 0.0, [1.0, 0.0], 10.0, 0.01, [1.0, 1.0])
    assert res.ok and len(t) == 1001 and t[-1] == 10.0
    assert np.all(np.diff(t) > 0.009)


def test_dop853_without_dt_out_writes_every_accepted_step(oscillator):
    t, Y, res = oscillator.integrate("dop853", 1.0, [1.0, 0.0], 4.0, 0.0, [1.0, 1.0], rtol=1e-9,
                                     atol=1e-9)
    assert res.ok and len(t) == res.n_steps + 1
    assert t[0] == 1.0 and t[-1] == 4.0 and np.all(np.diff(t) > 0)
    assert np.max(np.abs(Y - oscillator_exact(t - 1.0, 1.0, 1.0, 1.0, 0.0))) < 1e-8


def test_dop853_pendulum_energy_drift_below_1e_10_over_10_s(pendulum):
    t, Y, res = pendulum.integrate("dop853", 0.0, PEND_Y0, 10.0, 0.01, PEND, rtol=1e-12,
                                   atol=1e-12)
    assert res.ok
    E = energy(pendulum, t, Y, PEND)
    assert np.max(np.abs(E - E[0])) / abs(E[0]) < 1e-10


def test_dop853_agrees_with_scipy_on_the_cart_pendulum(cart):
    from scipy.integrate import solve_ivp

    param, y0 = [2.0, 0.7, 1.1, 5.0, 9.81], [0.3, 2.5, -0.4, 0.2]
    t, Y, res = cart.integrate("dop853", 0.0, y0, 5.0, 0.05, param, rtol=1e-11, atol=1e-11)
    assert res.ok
    ref = solve_ivp(cart.scipy_rhs(param), (0.0, 5.0), y0, method="DOP853", t_eval=t,
                    rtol=1e-11, atol=1e-11)
    assert np.max(np.abs(Y - ref.y.T)) < 1e-8
    E = energy(cart, t, Y, param)
    assert np.max(np.abs(E - E[0])) / abs(E[0]) < 1e-9


def test_the_coupled_model_functions_are_consistent(cart):
    param, y = [2.0, 0.7, 1.1, 5.0, 9.81], np.array([0.3, 2.5, -0.4, 0.2])
    z = cart.momentum(y, param)
    np.testing.assert_allclose(cart.velocity(z, param), y, rtol=1e-14, atol=1e-15)
    # qdot of the canonical form is the velocity; 2 T = qdot . p
    np.testing.assert_allclose(cart.rhs_canonical(0.0, z, param)[:2], y[2:], rtol=1e-14)
    assert math.isclose(2 * cart.kinetic_energy(y, param), y[2:] @ z[2:], rel_tol=1e-14)
    # the canonical and velocity forms give the same motion
    t1, Y1, _ = cart.integrate("dop853", 0.0, y, 1.0, 0.5, param, rtol=1e-12, atol=1e-12)
    t2, Y2, _ = cart.integrate("gauss4", 0.0, y, 1.0, 0.5, param, h=0.005)
    np.testing.assert_allclose(Y2, Y1, atol=1e-7)


# ---------------------------------------------------------------------------------------------
# gauss4 and rk4
# ---------------------------------------------------------------------------------------------

def test_gauss4_energy_error_stays_bounded_over_10000_steps(pendulum):
    t, Y, res = pendulum.integrate("gauss4", 0.0, PEND_Y0, 100.0, 0.01, PEND, h=0.01)
    assert res.ok and res.n_steps == 10_000 and len(t) == 10_001 and t[-1] == 100.0
    err = np.abs(energy(pendulum, t, Y, PEND) - energy(pendulum, t[:1], Y[:1], PEND)[0])
    first, last = err[:2000].max(), err[-2000:].max()
    assert last < 1.5 * first + 1e-13        # no drift: the last fifth no worse than the first
    assert err.max() / abs(energy(pendulum, t[:1], Y[:1], PEND)[0]) < 1e-6
    # rk4 at the same step loses energy steadily: the test can see a drift
    t, Y, _ = pendulum.integrate("rk4", 0.0, PEND_Y0, 100.0, 0.01, PEND, h=0.01)
    err_rk4 = np.abs(energy(pendulum, t, Y, PEND) - energy(pendulum, t[:1], Y[:1], PEND)[0])
    assert err_rk4[-2000:].max() > 3 * err_rk4[:2000].max()


@pytest.mark.parametrize("method", ["gauss4", "rk4"])
def test_fixed_step_methods_have_order_4(pendulum, method):
    y0 = [1.0, 0.0]   # a moderate swing: rk4 is in its asymptotic regime at these steps
    _, Y_ref, _ = pendulum.integrate("dop853", 0.0, y0, 4.0, 0.2, PEND, rtol=1e-14, atol=1e-14)
    errors = []
    for h in (0.02, 0.01, 0.005):
        t, Y, res = pendulum.integrate(method, 0.0, y0, 4.0, 0.2, PEND, h=h)
        assert res.ok and t[-1] == 4.0 and len(t) == 21
        errors.append(np.max(np.abs(Y - Y_ref)))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(14 < r < 18 for r in ratios), (errors, ratios)


def test_fixed_step_rows_every_dt_out_and_at_t_end(oscillator):
    t, Y, res = oscillator.integrate("gauss4", 0.0, [1.0, 0.0], 1.0, 0.1, [1.0, 4.0], h=0.03)
    assert res.ok and res.n_steps == 40 and len(t) == 11        # h shortened to 0.025
    np.testing.assert_allclose(t, np.linspace(0.0, 1.0, 11), rtol=0, atol=1e-15)
    assert t[-1] == 1.0
    np.testing.assert_allclose(Y, oscillator_exact(t, 1.0, 4.0, 1.0, 0.0), atol=1e-6)


def test_integrators_are_reentrant_across_threads(pendulum):
    from concurrent.futures import ThreadPoolExecutor

    def run(i):
        method = ("dop853", "gauss4", "rk4")[i % 3]
        y0 = [0.5 + 0.25 * i, 0.0]
        return pendulum.integrate(method, 0.0, y0, 5.0, 0.1, PEND, h=0.01)[1]

    serial = [run(i) for i in range(6)]
    with ThreadPoolExecutor(max_workers=3) as pool:
        parallel = list(pool.map(run, range(6)))
    for a, b in zip(serial, parallel):
        np.testing.assert_array_equal(a, b)


# ---------------------------------------------------------------------------------------------
# failures
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["dop853", "gauss4", "rk4"])
def test_rhs_failure_stops_with_status_1_keeping_the_rows(faulty, method):
    param = [1.0, 1.0, 2.5, math.inf]
    t, Y, res = faulty.integrate(method, 0.0, [1.0, 0.0], 10.0, 0.1, param, h=0.01)
    assert res.status == 1 and not res.ok and "mass matrix" in res.message
    assert 2.5 <= res.t_fail < 2.7
    assert len(t) == res.n_rows and len(t) >= 20 and t[-1] <= 2.5 and t[-1] < res.t_fail
    np.testing.assert_allclose(Y, oscillator_exact(t, 1.0, 1.0, 1.0, 0.0), atol=1e-6)
    assert res.y_fail is not None and np.all(np.isfinite(res.y_fail))


@pytest.mark.parametrize("method", ["dop853", "gauss4"])
def test_nan_from_the_model_stops_with_status_2(faulty, method):
    param = [1.0, 1.0, math.inf, 3.0]
    t, Y, res = faulty.integrate(method, 0.0, [1.0, 0.0], 10.0, 0.1, param, h=0.01)
    assert res.status == 2 and 3.0 <= res.t_fail < 3.2
    assert len(t) >= 29 and t[-1] <= 3.0 and t[-1] < res.t_fail and np.all(np.isfinite(Y))


def test_nonfinite_initial_state_and_bad_arguments(oscillator):
    t, Y, res = oscillator.integrate("dop853", 0.0, [math.nan, 0.0], 1.0, 0.1, [1.0, 1.0])
    assert res.status == 2 and len(t) == 0 and res.t_fail == 0.0
    with pytest.raises(ValueError, match="valid methods: dop853, gauss4, rk4"):
        oscillator.integrate("euler", 0.0, [1.0, 0.0], 1.0, 0.1, [1.0, 1.0])
    with pytest.raises(ValueError, match="y0 must be 1-dimensional with 2 entries"):
        oscillator.integrate("dop853", 0.0, [1.0], 1.0, 0.1, [1.0, 1.0])
    with pytest.raises(ValueError, match="param must have 2 entries"):
        oscillator.rhs(0.0, [1.0, 0.0], [1.0])


def test_python_rhs_raises_on_a_singular_mass_matrix(faulty, oscillator):
    with pytest.raises(SingularMassMatrix, match=r"t = 3\b.*q = \[0\.5\]"):
        faulty.rhs(3.0, [0.5, 0.0], [1.0, 1.0, 2.0, math.inf])
    with pytest.raises(SingularMassMatrix):
        oscillator.scipy_rhs([0.0, 1.0])(0.0, np.array([1.0, 0.0]))
    np.testing.assert_array_equal(oscillator.rhs(0.0, [1.0, 2.0], [2.0, 4.0]), [2.0, -2.0])
    assert issubclass(SingularMassMatrix, KronsubError)


def test_dop853_step_size_underflow_at_a_blow_up(cache):
    model = NativeModel.build([BLOWUP], "blowup", nq=1, nparam=0)
    t, Y, res = model.integrate("dop853", 0.0, [1.0, 1.0], 2.0, 0.1, [])
    assert res.status == 3 and abs(res.t_fail - 1.0) < 1e-6
    assert len(t) == 11 and t[-1] <= 1.0
    np.testing.assert_allclose(Y[:-1, 0], 1.0 / (1.0 - t[:-1]), rtol=1e-8)


def test_too_many_steps_and_a_full_buffer(oscillator):
    _, _, res = oscillator.integrate("dop853", 0.0, [1.0, 0.0], 100.0, 0.1, [1.0, 1.0],
                                     max_steps=10)
    assert res.status == 4 and 0.0 < res.t_fail < 100.0
    # the C API directly: three rows of room
    lib = oscillator._lib
    out, work, cres = np.empty((3, 3)), np.empty(27 * 2), native._CResult()
    param, y0 = np.array([1.0, 1.0]), np.array([1.0, 0.0])
    status = lib.ks_dop853(ctypes.cast(lib.ks_rhs, ctypes.c_void_p), 2, param.ctypes.data, 0.0,
                           y0.ctypes.data, 1.0, 0.1, 1e-8, 1e-8, 0.0, 0, out.ctypes.data, 3,
                           work.ctypes.data, ctypes.byref(cres))
    assert status == 5 == cres.status and cres.n_rows == 3 and math.isclose(cres.t_fail, 0.3)
    np.testing.assert_allclose(out[:, 0], [0.0, 0.1, 0.2], atol=1e-15)


# ---------------------------------------------------------------------------------------------
# building
# ---------------------------------------------------------------------------------------------

def test_the_library_is_reused_without_recompiling(cache, monkeypatch):
    first = compile_library([OSCILLATOR], "oscillator")
    mtime = first.stat().st_mtime_ns

    def no_compiler(*args, **kwargs):
        raise AssertionError("compiled again")

    monkeypatch.setattr(native, "_run_compiler", no_compiler)
    assert compile_library([OSCILLATOR], "oscillator") == first
    assert first.stat().st_mtime_ns == mtime
    assert first.parent.parent == cache / "native"
    # a changed source is a new library
    with pytest.raises(AssertionError, match="compiled again"):
        compile_library([OSCILLATOR + "\n/* changed */\n"], "oscillator")


def test_header_files_keep_their_names(cache):
    header = ("pendulum_model.h", "#define KS_NQ 1\n")
    source = ("pendulum_model.c",
              '#include "pendulum_model.h"\n' + PENDULUM.replace("#define KS_NQ 1\n", ""))
    model = NativeModel.build([header, source], "pendulum_model", nq=1, nparam=3)
    assert math.isclose(model.rhs(0.0, [math.pi / 2, 0.0], PEND)[1], -9.81 / 0.8)


def test_without_a_cache_the_library_goes_to_a_temporary_folder(cache, monkeypatch):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", "off")
    path = compile_library([OSCILLATOR], "oscillator")
    assert cache not in path.parents and path.is_file()
    assert NativeModel(path, 1, 2).kinetic_energy([0.0, 2.0], [3.0, 1.0]) == 6.0


def test_broken_source_raises_compile_error_with_the_compiler_message(cache):
    broken = OSCILLATOR.replace("ydot[0] = y[1];", "ydot[0] = y[1] + undeclared_thing;")
    with pytest.raises(CompileError) as info:
        compile_library([broken], "broken")
    assert "undeclared_thing" in str(info.value) and "undeclared_thing" in info.value.stderr
    assert isinstance(info.value, KronsubError)
    # warnings are errors
    with pytest.raises(CompileError, match="unused"):
        compile_library([OSCILLATOR + "static int unused_helper(void) { return 0; }\n"], "warned")


def test_missing_compiler_raises_compiler_not_found(cache, monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/kronsub-cc")
    with pytest.raises(CompilerNotFound, match="kronsub-cc"):
        compile_library([OSCILLATOR], "oscillator")


def test_a_build_for_the_host_gives_the_portable_build_s_numbers(cache, monkeypatch):
    """The host build (``-march=native``, no fused multiply-adds) only changes which
    instructions compute the same operations: a long dop853 run of the generated System I
    agrees bit for bit with the portable build, and the two are different libraries."""
    import kronsub
    from kronsub.simulation.compiled import compiled_library

    if native.build_flags() == native.FLAGS:
        pytest.skip("no processor to build for here (no /proc/cpuinfo)")
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    host = compiled_library(system)
    monkeypatch.setenv("KRONSUB_PORTABLE_C", "1")
    assert native.build_flags() == native.FLAGS
    portable = compiled_library(system)
    assert host != portable
    param = np.array([1.0, 1.0, 0.5, 0.5, 1 / 12, 1 / 12, 9.81, 0.3])
    runs = []
    for library in (host, portable):
        model = NativeModel(library, 2, len(param))
        _, Y, res = model.integrate("dop853", 0.0, np.array([2.0, -0.2, 0.0, 0.0]), 20.0, 0.5, param,
                                    rtol=1e-12, atol=1e-12)
        runs.append(Y)
    assert res.n_steps > 500 and np.array_equal(runs[0], runs[1])


def test_a_processor_that_vectorizes_128_bits_wide_gets_the_portable_build_s_numbers(cache, monkeypatch):
    """gcc 12 turns a pair of products ``a c + b d``, ``b c - a d`` (the Taylor integrator's
    angle addition) into one ``vfmaddsub`` where it vectorizes 128 bits wide (Zen 1's choice),
    although ``-ffp-contract=off`` forbids the contraction. The host flags forbid fused
    multiply-add instructions outright, so such a processor's Taylor run of the chaotic double
    pendulum agrees bit for bit with the portable build's (with the old flags it did not)."""
    import platform

    import kronsub
    from kronsub.simulation.taylor_c import TaylorC

    if native.build_flags() == native.FLAGS or platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("the 128-bit preference is an x86 option; no processor to build for here")
    system = kronsub.load(MODELS / "hoffmann" / "system1.yaml").derive()
    param = np.array([1.0, 1.0, 0.5, 0.5, 1 / 12, 1 / 12, 9.81, 0.0])
    y0 = np.array([2 * np.pi / 3, -np.pi / 18, 0.0, 0.0])
    monkeypatch.setattr(native, "HOST_FLAGS", (*native.HOST_FLAGS, "-mprefer-vector-width=128"))
    narrow, status, steps, _ = TaylorC(system).integrate(param, y0, 10.0, 1e-10, order=8)
    monkeypatch.setenv("KRONSUB_PORTABLE_C", "1")
    portable, *_ = TaylorC(system).integrate(param, y0, 10.0, 1e-10, order=8)
    assert status == 0 and steps > 500 and np.array_equal(narrow, portable), (narrow - portable)


def test_a_compiler_that_cannot_build_for_the_host_builds_portably(cache, monkeypatch):
    calls = []
    real = native._run_compiler

    def counted(command, cwd):
        calls.append(command)
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", counted)
    monkeypatch.setattr(native, "HOST_FLAGS", ("-march=no-such-processor",))
    monkeypatch.setattr(native, "_HOST_CPU", "a processor")
    model = NativeModel.build([OSCILLATOR], "oscillator", nq=1, nparam=2)
    hosted = [("-march=no-such-processor" in c) for c in calls]  # each file compiled, then linked
    assert hosted[0] and not hosted[-1] and hosted == sorted(hosted, reverse=True)
    assert math.isclose(model.rhs(0.0, [1.0, 0.0], [2.0, 8.0])[1], -4.0)


def test_the_integrators_compiled_ahead_go_into_the_next_library(cache, monkeypatch):
    """`compile_ahead` (called before a model's C is emitted) compiles the integrators once, in
    the background; the library built next links that object instead of compiling them again,
    and computes what a library built without it computes."""
    calls = []
    real = native._run_compiler

    def counted(command, cwd):
        calls.append((command[-1], cwd))
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", counted)
    monkeypatch.setattr(native, "_AHEAD", {})
    native.compile_ahead()
    native.compile_ahead()  # started already: not again
    model = NativeModel.build([OSCILLATOR + "/* integrators made ahead */\n"], "oscillator", nq=1, nparam=2)
    compiled = [(name, cwd) for name, cwd in calls if name.endswith(".c")]
    assert sorted(name for name, _ in compiled) == ["integrators.c", "oscillator_0.c"]
    (ahead,) = [cwd for name, cwd in compiled if name == "integrators.c"]
    assert cache not in ahead.parents  # the process's private temporary folder
    assert math.isclose(model.rhs(0.0, [1.0, 0.0], [2.0, 8.0])[1], -4.0)
    _, Y, res = model.integrate("dop853", 0.0, [1.0, 0.0], 1.0, 0.5, [2.0, 8.0])
    assert res.ok and math.isclose(Y[-1, 0], math.cos(2.0), rel_tol=1e-8)


def test_integrators_that_failed_ahead_are_compiled_with_the_model(cache, monkeypatch):
    real = native._run_compiler
    calls = []

    def failing_ahead(command, cwd):
        calls.append(command[-1])
        if command[-1] == "integrators.c" and cache not in cwd.parents:
            return real([*command[:-1], "no-such-file.c"], cwd)
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", failing_ahead)
    monkeypatch.setattr(native, "_AHEAD", {})
    native.compile_ahead()
    model = NativeModel.build([OSCILLATOR + "/* integrators failed ahead */\n"], "oscillator", nq=1, nparam=2)
    assert calls.count("integrators.c") == 2  # ahead (failed), then with the model
    assert math.isclose(model.rhs(0.0, [1.0, 0.0], [2.0, 8.0])[1], -4.0)


def test_a_forked_child_does_not_wait_on_its_parent_s_integrators(cache, monkeypatch):
    """A build started ahead by another process (a parent before it forked: its thread is not
    in the child) is neither waited on nor counted as started."""
    from concurrent.futures import Future

    monkeypatch.setattr(native, "_AHEAD", {})
    native.compile_ahead()
    (key, (pid, _, obj)), = native._AHEAD.items()
    assert pid == os.getpid()
    native._AHEAD[key] = (pid + 1, Future(), obj)  # never finished here
    files = [(name, (native.CSRC / name).read_text()) for name in native.INTEGRATOR_FILES]
    flags = [f for f in native.build_flags() if f != "-shared"]
    assert native._compiled_ahead(native.compiler_command(), flags, files) is None  # at once
    native.compile_ahead()
    assert native._AHEAD[key][0] == os.getpid()  # started again, here
    model = NativeModel.build([OSCILLATOR + "/* after a fork */\n"], "oscillator", nq=1, nparam=2)
    assert math.isclose(model.rhs(0.0, [1.0, 0.0], [2.0, 8.0])[1], -4.0)


def test_an_object_made_ahead_without_the_integrators_is_not_linked_into_a_library(cache, monkeypatch):
    """An object made ahead that lacks the integrators (written over by another build, the race
    once seen in CI) links without error into a library that cannot integrate: the build reads the
    library's dynamic symbols, finds them missing and compiles the integrators itself."""
    real = native._run_compiler
    calls = []

    def emptied(command, cwd):
        calls.append(command[-1])
        if command[-1] == "integrators.c" and cache not in cwd.parents:  # the start ahead: an empty object
            (cwd / "empty.c").write_text("typedef int ks_nothing;\n")
            return real([*command[:-1], "empty.c"], cwd)
        return real(command, cwd)

    monkeypatch.setattr(native, "_run_compiler", emptied)
    monkeypatch.setattr(native, "_AHEAD", {})
    native.compile_ahead()
    library = compile_library([OSCILLATOR + "/* integrators emptied ahead */\n"], "oscillator")
    assert calls.count("integrators.c") == 2  # ahead (empty), then again with the model
    assert native.lacking(library) == []
    model = NativeModel(library, nq=1, nparam=2)
    _, Y, res = model.integrate("dop853", 0.0, [1.0, 0.0], 1.0, 0.5, [2.0, 8.0])
    assert res.ok and math.isclose(Y[-1, 0], math.cos(2.0), rel_tol=1e-8)


def test_lacking_reads_the_dynamic_symbols(cache, tmp_path):
    """`native.lacking` against the library's own exports (loaded with ctypes): all present in a
    whole library; all missing in one built from the model alone (``-shared`` links it without
    them) and in a damaged one; none for another format (left to the loader)."""
    whole = compile_library([OSCILLATOR + "/* whole */\n"], "oscillator")
    assert native.lacking(whole) == [] and all(hasattr(ctypes.CDLL(str(whole)), n) for n in native.INTEGRATOR_SYMBOLS)
    (tmp_path / "alone.c").write_text(OSCILLATOR)
    alone = tmp_path / "libalone.so"
    native._run_compiler([*native.compiler_command(), *native.FLAGS, "-o", str(alone), "alone.c", *native.LIBS],
                         tmp_path).check_returncode()
    assert native.lacking(alone) == list(native.INTEGRATOR_SYMBOLS)
    assert hasattr(ctypes.CDLL(str(alone)), "ks_rhs") and not hasattr(ctypes.CDLL(str(alone)), "ks_dop853")
    (tmp_path / "cut.so").write_bytes(whole.read_bytes()[:len(whole.read_bytes()) // 3])
    assert native.lacking(tmp_path / "cut.so") == list(native.INTEGRATOR_SYMBOLS)
    (tmp_path / "text.so").write_text("no library")
    assert native.lacking(tmp_path / "text.so") == []


def test_data_address_is_numpys_for_every_kind_of_array():
    """`native.data_address` (what every call into a compiled model passes) is the address
    numpy gives, for writable, read-only, empty and non-contiguous arrays."""
    from kronsub.simulation.native import data_address

    writable = np.arange(6.0)
    read_only = np.arange(6.0)
    read_only.setflags(write=False)
    for array in (writable, read_only, np.zeros(0), writable[::2], np.zeros((3, 2)), np.zeros((3, 2)).T):
        assert data_address(array) == array.ctypes.data
