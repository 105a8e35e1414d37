"""The projection onto the speeds kept at run time in the generated numpy module
(`codegen --lang python`, templates/model.py.j2 with emitters/projected_speeds.py): ``S = [G; A; Y]``,
``C``, ``Cdot u + ddot`` solved by numpy, ``Mbar = C^T M C`` and ``fbar - hbar`` from the
primitive's pieces, chosen by the criterion the C's route takes (core/projection_work.py).

Independent routes: on the small models in speeds forced onto it (a configuration constraint
beside the velocity constraints, a constraint in time, the rows of a rolling joint as made), every
function equals the expanded module's, from the symbolic projection, at random states to 1e-12;
the smaller models' modules stay the expanded ones by themselves; the Whipple bicycle, which takes
it by itself, writes its module within the default work budget (its symbolic projection is far
beyond it), and the module's right-hand side and energies equal its generated C's."""
from __future__ import annotations

import types

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.seeded import emitted_under_seed
import kronsub
from kronsub.cli import main
from kronsub.core.projection_work import projected_in_numbers
from kronsub.emitters.code import emit_python

from conftest import ROOT

SMALL = [ROOT / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc", "chaplygin_sleigh", "differential_drive")] + \
        [ROOT / "tests" / "models" / "nonholonomic" / f"{name}.yaml" for name in
         ("rolling_disc_joint", "rolling_disc_height", "sleigh_on_a_belt")]
BICYCLE = ROOT / "models" / "benchmarks" / "whipple_bicycle.yaml"


def module_of(text: str, name: str = "model") -> types.ModuleType:
    module = types.ModuleType(name)
    exec(compile(text, f"{name}.py", "exec"), module.__dict__)  # noqa: S102 - generated here, from the models above
    return module


def functions(mod, t, y, param) -> dict:
    """Every function of a module in the speeds at one state."""
    q, u = y[:mod.NQ], y[mod.NQ:]
    timed = getattr(mod, "TIMED", False)
    out = {"rhs": mod.rhs(t, y, param), "M": mod.mass_matrix(q, param), "f": mod.forces(t, q, u, param),
           "h": mod.velocity_terms(t, q, u, param) if timed else mod.velocity_terms(q, u, param),
           "T": mod.kinetic_energy(y, param), "V": mod.potential_energy(t, y, param),
           "momentum": mod.momentum(y, param), "kinematics": mod.kinematics(t, q, u, mod.prepare(param))}
    if hasattr(mod, "hold"):
        out["held"] = mod.hold(t, y, param)
    return out


@pytest.mark.parametrize("path", SMALL, ids=[p.stem for p in SMALL])
def test_the_run_time_projection_equals_the_symbolic_one(path):
    system = kronsub.load(path).derive()
    assert not projected_in_numbers(system)
    (expanded,) = emit_python(system, "model")
    assert "_in_speeds" not in expanded.text  # by itself, the small model's module stays expanded
    assert expanded.text == emit_python(system, "model", route="expanded")[0].text
    (kept,) = emit_python(system, "model", route="projected")
    assert "def _in_speeds" in kept.text and "import sympy" not in kept.text
    ours, theirs = module_of(kept.text), module_of(expanded.text)
    rng = np.random.default_rng(7)
    param = rng.uniform(0.5, 1.5, ours.NPARAM)
    for _ in range(4):
        t = float(rng.uniform(0, 2))
        y = rng.uniform(-1.2, 1.2, ours.NQ + ours.NU)
        if hasattr(theirs, "hold"):  # a state on the configuration constraints
            y[:ours.NQ] = theirs.hold(t, y, param)
        a, b = functions(ours, t, y, param), functions(theirs, t, y, param)
        assert a.keys() == b.keys()
        for name in a:
            scale = max(1.0, float(np.max(np.abs(b[name]))))
            np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-12 * scale, err_msg=name)


def test_the_route_is_refused_where_it_cannot_be_kept():
    system = kronsub.load(ROOT / "models" / "hoffmann" / "system1.yaml").derive(scene="free")
    (text,) = emit_python(system, "model", route="projected")  # no speeds: numpy keeps the derived expressions
    assert text.text == emit_python(system, "model")[0].text
    with pytest.raises(ValueError, match="route must be one of"):
        emit_python(system, "model", route="sideways")


def test_the_bicycle_module_is_written_and_equals_its_c(tmp_path):
    """The bicycle's projection work is beyond the symbolic route's: its module keeps the
    projection for run time, within the default budget, and agrees with its C."""
    from kronsub.simulation.compiled import native_model

    result = CliRunner().invoke(main, ["codegen", str(BICYCLE), "--lang", "python", "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    text = (tmp_path / "whipple_bicycle.py").read_text()
    assert "def _in_speeds" in text and "import sympy" not in text
    mod = module_of(text, "whipple_bicycle")
    system = kronsub.load(BICYCLE).derive()
    assert projected_in_numbers(system)
    native = native_model(system)
    param = np.array([mod.DEFAULTS[name] for name in mod.PARAMETERS], dtype=float)
    rng = np.random.default_rng(5)
    for _ in range(3):
        y = np.concatenate([rng.uniform(-0.3, 0.3, mod.NQ), rng.uniform(-3.0, 3.0, mod.NU)])
        y[:mod.NQ] = mod.hold(0.0, y, param)  # the pitch on the front contact
        np.testing.assert_allclose(mod.rhs(0.0, y, param), native.rhs(0.0, y, param), rtol=1e-11, atol=1e-11)
        assert mod.kinetic_energy(y, param) == pytest.approx(native.kinetic_energy(y, param), rel=1e-12)
        assert mod.potential_energy(0.0, y, param) == pytest.approx(native.potential_energy(0.0, y, param), rel=1e-12)


def test_a_state_without_accelerations_is_an_error_of_numpy():
    """The rolling disc flat on its plane (lean = pi/2): Mbar is singular there, and numpy says so,
    as the C's rhs returns 1 there (tests/test_projected_speeds.py); a frame S = [G; A; Y] that does
    not fix the velocities is refused before any solve."""
    system = kronsub.load(ROOT / "models" / "nonholonomic" / "rolling_disc.yaml").derive()
    mod = module_of(emit_python(system, "model", route="projected")[0].text)
    param = np.array([mod.DEFAULTS[name] for name in mod.PARAMETERS], dtype=float)
    y = np.full(mod.NQ + mod.NU, 0.3)
    assert np.all(np.isfinite(mod.rhs(0.0, y, param)))
    flat = y.copy()
    flat[mod.STATE.index("lean")] = np.pi / 2
    with pytest.raises(np.linalg.LinAlgError):
        mod.rhs(0.0, flat, param)
    S, r0 = mod._frame(0.0, y[:mod.NQ], mod.prepare(param))
    S[-1] = S[-2]  # two speeds alike: their rows of Y
    mod._frame = lambda t, q, pre: (S, r0)
    with pytest.raises(np.linalg.LinAlgError, match="do not fix the velocities"):
        mod.rhs(0.0, y, param)


def test_the_generated_module_is_deterministic():
    assert emitted_under_seed("emit_python", SMALL[4], "1") == emitted_under_seed("emit_python", SMALL[4], "2")
