"""A compiled model is found by its equations' fingerprint without emitting C again
(:mod:`kronsub.simulation.compiled`), and the index never makes an unverified library load."""
from __future__ import annotations

import dataclasses
import json
import os
import shutil

import numpy as np
import pytest

from conftest import MODELS
from kronsub import cache as kcache
from kronsub.emitters import code
from kronsub.model.loader import load_model
from kronsub.simulation import compiled, native
from kronsub.api import simulate
from kronsub.simulation.start import starting_values

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


@pytest.fixture
def emissions(monkeypatch):
    """Counts the C emissions (the costly step the index skips)."""
    calls = []
    real = code.emit_c

    def counted(*args, **kwargs):
        calls.append(args[0].name)
        return real(*args, **kwargs)

    monkeypatch.setattr(code, "emit_c", counted)
    return calls


def _run(system):
    return simulate(system, t=0.5, dt=0.25, dataframe=False)


def test_a_second_run_loads_the_library_without_emitting_c(cache, emissions):
    system = load_model(SYSTEM1).derive()
    first = _run(system)
    assert emissions == [system.name]
    again = _run(load_model(SYSTEM1).derive())
    assert emissions == [system.name]  # no second emission
    np.testing.assert_array_equal(first.y, again.y)


def test_other_parameter_values_share_the_library_other_equations_do_not(cache, emissions):
    system = load_model(SYSTEM1).derive()
    key = compiled.fingerprint(system)
    other_values = dataclasses.replace(system, name="renamed", parameters=tuple(
        dataclasses.replace(p, value=None) for p in system.parameters))
    assert compiled.fingerprint(other_values) == key
    fewer_effects = dataclasses.replace(system, effect_forces={k: v for k, v in list(system.effect_forces.items())[:1]})
    assert compiled.fingerprint(fewer_effects) != key
    free = load_model(MODELS / "hoffmann" / "system2.yaml").derive()
    assert compiled.fingerprint(free) != key
    from kronsub.model.scenes import Outputs
    assert compiled.fingerprint(system, Outputs(energies=False)) != key


@pytest.mark.parametrize("tamper", ["digest", "folder", "traversal", "garbage", "library"])
def test_a_tampered_index_never_loads_an_unverified_library(cache, emissions, tamper):
    system = load_model(SYSTEM1).derive()
    _run(system)
    key = compiled.fingerprint(system, canonical=False)  # dop853's library: no canonical form
    index = compiled._index_file(key)
    entry = json.loads(kcache.load_entry(index))  # sealed with its digest (kronsub.cache.store_entry)
    library = native.build_root() / entry["folder"] / entry["library"]
    if tamper == "digest":
        entry["sha256"] = "0" * 64
    elif tamper == "folder":
        entry["folder"] = "model-" + "0" * 24
    elif tamper == "traversal":
        entry["folder"] = "../../elsewhere"
    elif tamper == "library":
        changed = library.with_name("changed.tmp")  # a new file: this process has the old one mapped
        changed.write_bytes(library.read_bytes()[:100])
        os.replace(changed, library)  # the sidecar no longer matches
    # written as kronsub writes entries (private, sealed): refused for what it says, not its form
    kcache.store_entry(index, b"{not json" if tamper == "garbage" else json.dumps(entry).encode())
    assert compiled.lookup(key) is None
    _run(system)  # emitted and built again, then indexed afresh
    assert len(emissions) == 2
    assert compiled.lookup(key) is not None and native.verified(compiled.lookup(key))


def test_cache_clear_removes_the_index(cache):
    from kronsub import cache as kcache

    _run(load_model(SYSTEM1).derive())
    assert list((cache / "native" / "index").iterdir())
    kcache.clear()
    assert not (cache / "native").exists()


def test_a_run_compiles_only_the_functions_its_method_calls(cache, emissions):
    """dop853 on ``[q; qdot]`` calls neither the canonical right-hand side nor ``hbar`` and
    ``fbar`` apart: its library leaves them out; gauss4 integrates ``[q; p]`` and gets a
    library with the canonical form, whose trajectory is that of the complete library."""
    import ctypes

    system = load_model(SYSTEM1).derive()
    _run(system)
    lean = compiled.lookup(compiled.fingerprint(system, canonical=False))
    functions = ctypes.CDLL(str(lean))
    assert hasattr(functions, "ks_rhs") and hasattr(functions, "ks_kinetic_energy")
    for absent in ("ks_rhs_canonical", "ks_velocity_terms", "ks_forces"):
        assert not hasattr(functions, absent)
    assert compiled.lookup(compiled.fingerprint(system)) is None
    run = simulate(system, t=0.5, dt=0.05, method="gauss4", dataframe=False)
    assert len(emissions) == 2  # another library: with the canonical form
    assert hasattr(ctypes.CDLL(str(compiled.lookup(compiled.fingerprint(system)))), "ks_rhs_canonical")
    complete = native.NativeModel(compiled.compiled_library(system), len(system.coordinates), len(system.parameters))
    values = starting_values(system, {}).values
    _, rows, result = complete.integrate("gauss4", 0.0, np.array(values.y0), 0.5, 0.05, np.array(values.parameters))
    assert result.ok
    np.testing.assert_array_equal(rows, run.y)


RUN_SYSTEM1 = ("import sys; from kronsub.model.loader import load_model; from kronsub.api import simulate; "
               "run = simulate(load_model(sys.argv[1]).derive(), t=0.5, dt=0.25, dataframe=False); print(run.y[-1, 0])")


def test_a_cached_library_without_the_integrators_is_built_again(cache):
    """A library the cache holds, verified by its digest, but built without the integrators (an
    object made ahead that was written over, as an older build could leave it) is discarded and
    built again, not loaded and failed on by every run after it. Each run in a fresh process: a
    process keeps a library it loaded under its path."""
    import subprocess
    import sys

    def run():
        done = subprocess.run([sys.executable, "-c", RUN_SYSTEM1, str(SYSTEM1)], capture_output=True, text=True,
                              env={**os.environ, "KRONSUB_CACHE_DIR": str(cache)}, timeout=300)
        assert done.returncode == 0, done.stderr
        return float(done.stdout.split()[-1])

    first = run()
    (library,) = (cache / "native").glob("model-*/libmodel.so")
    folder = library.parent
    own = sorted(p.name for p in folder.glob("*.c") if p.name != "integrators.c")
    planted = folder / "planted.so"
    native._run_compiler([*native.compiler_command(), *native.FLAGS, "-I", str(folder), "-o", str(planted), *own,
                          *native.LIBS], folder).check_returncode()
    assert native.lacking(planted) == list(native.INTEGRATOR_SYMBOLS)
    os.chmod(planted, 0o600)
    os.replace(planted, library)
    digest, key = native.sidecar(library).read_text().split()
    native.sidecar(library).write_text(f"{native._digest_file(library)}\n{key}\n")  # as if built so
    assert native.verified(library, key) and native.lacking(library)
    assert run() == first
    assert native.lacking(library) == []


def test_a_runs_library_reads_mbar_from_its_equations(cache):
    """A run's library eliminates ``Mbar``'s common subexpressions once, in the equations' block,
    and its ``ks_mass_matrix`` (the energies', the momentum's) is that block's part for ``Mbar``:
    checked against the derived ``Mbar`` evaluated by sympy at random states, through
    ``T = 1/2 qdot^T Mbar qdot`` and ``p = Mbar qdot``. Where the equations' block does not hold
    ``Mbar`` as it is (a first-order coordinate's row is the identity there; a closed loop's needs
    its Newton solve) the block of its own stays; ``kronsub codegen`` keeps it always."""
    import sympy

    chain = load_model(MODELS / "chain" / "chain5.yaml").derive()
    run_c = dict(compiled.generated_sources(chain, canonical=False))["model.c"]
    part = "the equations' part for Mbar"
    assert part in run_c and part not in code.emit_c(chain, "model")[1].text
    for path in (MODELS / "electrical" / "parallel_rlc.yaml", MODELS / "hoffmann" / "system3.yaml"):
        assert part not in dict(compiled.generated_sources(load_model(path).derive(), canonical=False))["model.c"]

    lib = native.NativeModel(compiled.compiled_library(chain, canonical=False), len(chain.coordinates),
                             len(chain.parameters))
    values = starting_values(chain, {}).values
    param = np.array(values.parameters)
    numbers = {p.symbol: v for p, v in zip(chain.parameters, param)}
    mass = sympy.lambdify(list(chain.coordinates), chain.mass_matrix.xreplace(numbers), "numpy")
    rng = np.random.default_rng(7)
    n = len(chain.coordinates)
    for _ in range(5):
        y = rng.uniform(-3, 3, 2 * n)
        M = np.array(mass(*y[:n]), dtype=float)
        assert np.isclose(lib.kinetic_energy(y, param), 0.5 * y[n:] @ M @ y[n:], rtol=1e-13, atol=0)
        np.testing.assert_allclose(lib.momentum(y, param)[n:], M @ y[n:], rtol=1e-12, atol=1e-12)
