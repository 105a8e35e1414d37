"""From a model file to the first trajectory: ``kronsub simulate MODEL --t 10``, cold and warm,
beside PyDy (its cython and lambdify backends) and MuJoCo, each run in a fresh process.

    python benchmarks/first_trajectory.py [--sizes 2,5,10,20,50,100] [--spatial 3,5,10] [--pins 3]
                                          [--repeats 3] [--timeout 600]
                                          [--tools kronsub,pydy-cython,pydy-lambdify,mujoco]

Models: the n-link chain of uniform rods (``models/chain/generate.py``: mass 1, length 1, the
angles 0.1 at rest) and the spatial chain of n rods on ball joints
(``models/chain/generate_spatial.py``: mass 1, length 1, radius 0.05), its joints as the
connection (``spatial``) or as ``pin`` constraints (``spatial-pins``, ``--pins``).

* ``kronsub cold``: ``kronsub simulate MODEL --t 10`` with an empty cache folder. The run is the
  command's own (``kronsub.cli.main``), in a child process that times its phases by wrapping the
  functions that do them: ``import`` (the modules a derived run needs, imported inside the
  command's preparation, ``kronsub.collector.preparation``, as the command imports them), ``load``
  (``load_model``), ``derive`` (``derive_scene``), ``emit`` (``emit_c``), ``compile``
  (``native.compile_library``), ``integrate`` (the rest: the run and the CSV written to
  /dev/null). ``wall`` is measured by the parent, interpreter start included. ``warm``: the
  same command again on that folder, run as it is (a prepared run: no phases to time).
* ``pydy-cython``, ``pydy-lambdify`` (planar chain): ``sympy.physics.mechanics.KanesMethod``
  derives the same chain (``derive``), PyDy's ``generate_ode_function`` builds its right-hand
  side (``compile``), SciPy's ``solve_ivp`` (DOP853, rtol = atol = 1e-10, kronsub's defaults,
  output every 0.01) integrates to t = 10.
* ``mujoco``: the same rods as MJCF (hinges, or ball joints for the spatial chain; exact
  inertias, no contacts), loaded (``compile``) and stepped with RK4 at h = 1e-3 to t = 10.
* ``start-up``: ``python -c pass`` (the interpreter alone, the floor of every row),
  ``python -c "import kronsub"``, ``python -m kronsub --help`` and ``kronsub simulate
  models/hoffmann/system1.yaml --t 10`` warm, interleaved with the same command derived from
  the cached known system and library (its prepared run removed first: the warm run before
  prepared runs), and their ratio.

kronsub's modules are compiled to bytecode first (``compileall``, as ``pip install`` does), so no
child compiles them from source, whatever ``PYTHONDONTWRITEBYTECODE`` says.

Peak memory: the child's largest resident set (``wait4``). Each cell: min/median of
``--repeats`` fresh processes; ``goal``: issue 34's target, ``x goal`` the ratio min/median to it
(below 1: met). A run that passes ``--timeout`` seconds is killed and shown as ``>T``.
"""
from __future__ import annotations

import argparse
import compileall
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PHASES = ("import", "load", "derive", "emit", "compile", "integrate")
CHAIN_GOALS = {10: 1.0, 20: 1.5, 50: 5.0, 100: 20.0}  # kronsub cold, seconds
SPATIAL_GOALS = {3: 5.0, 10: 30.0}
MEMORY_GOAL = (50, 250.0)  # the 50-link chain, cold, MB
STARTUP_GOALS = {"import kronsub": 0.15, "kronsub --help": 0.15, "system1 warm": 0.3}
TOOLS = ("kronsub", "pydy-cython", "pydy-lambdify", "mujoco")


# ---------------------------------------------------------------------------------------------
# children: each runs one case in a fresh process and writes its phases as JSON
# ---------------------------------------------------------------------------------------------

def child_kronsub(model: str, out: str) -> None:
    phases = dict.fromkeys(PHASES, 0.0)
    start = time.perf_counter()
    from kronsub.collector import preparation

    with preparation():  # the command imports these in its preparation too (kronsub.collector)
        import kronsub.emitters.code as code
        import kronsub.model.loader as loader
        import kronsub.model.scenes as scenes
        import kronsub.simulation.native as native
        from kronsub.cli import main
        import kronsub.commands.simulate  # noqa: F401
        import kronsub.simulation.run  # noqa: F401

    phases["import"] = time.perf_counter() - start

    def timed(module, name: str, phase: str) -> None:
        real = getattr(module, name)

        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return real(*args, **kwargs)
            finally:
                phases[phase] += time.perf_counter() - t0

        setattr(module, name, wrapper)

    timed(loader, "load_model", "load")
    timed(scenes, "derive_scene", "derive")
    timed(code, "emit_c", "emit")
    timed(native, "compile_library", "compile")
    try:
        main(["simulate", model, "--t", "10"], standalone_mode=False)
    finally:
        total = time.perf_counter() - start
        phases["integrate"] = total - sum(phases[p] for p in PHASES[:-1])
        Path(out).write_text(json.dumps(phases))


def _kane_chain(n: int):
    """The planar chain by ``KanesMethod``: (mass matrix, forcing, q, u, constants, values)."""
    import sympy
    from sympy.physics.mechanics import KanesMethod, Point, ReferenceFrame, RigidBody, dynamicsymbols, inertia

    q, u = dynamicsymbols(f"q1:{n + 1}"), dynamicsymbols(f"u1:{n + 1}")
    m, l, g = sympy.symbols(f"m1:{n + 1}"), sympy.symbols(f"l1:{n + 1}"), sympy.Symbol("g")
    N, O = ReferenceFrame("N"), Point("O")
    O.set_vel(N, 0)
    bodies, loads, joint = [], [], O
    for i in range(n):
        A = N.orientnew(f"A{i + 1}", "Axis", (q[i], N.z))
        A.set_ang_vel(N, u[i] * N.z)
        G, P = joint.locatenew(f"G{i + 1}", -l[i] / 2 * A.y), joint.locatenew(f"P{i + 1}", -l[i] * A.y)
        G.v2pt_theory(joint, N, A)
        P.v2pt_theory(joint, N, A)
        bodies.append(RigidBody(f"rod{i + 1}", G, A, m[i], (inertia(A, 0, 0, m[i] * l[i] ** 2 / 12), G)))
        loads.append((G, -m[i] * g * N.y))
        joint = P
    t = dynamicsymbols._t
    kane = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u)])
    kane.kanes_equations(bodies, loads)
    return kane.mass_matrix, kane.forcing, q, u, [*m, *l, g], [1.0] * (2 * n) + [9.81]


def child_pydy(generator: str, n: int, out: str) -> None:
    phases = dict.fromkeys(PHASES, 0.0)
    start = time.perf_counter()
    import numpy as np
    import sympy
    from pydy.codegen.ode_function_generators import generate_ode_function
    from scipy.integrate import solve_ivp

    phases["import"] = time.perf_counter() - start
    t0 = time.perf_counter()
    M, forcing, q, u, constants, values = _kane_chain(n)
    phases["derive"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    folder = tempfile.mkdtemp(prefix="pydy-")
    here = os.getcwd()
    os.chdir(folder)  # cython writes its build files into the working folder
    try:
        rhs = generate_ode_function(forcing, q, u, constants, mass_matrix=M, coordinate_derivatives=sympy.Matrix(u),
                                    generator=generator, constants_arg_type="array")
    finally:
        os.chdir(here)
    phases["compile"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    param = np.array(values)
    solve_ivp(lambda t, y: rhs(y, t, param), (0.0, 10.0), np.r_[np.full(n, 0.1), np.zeros(n)], method="DOP853",
              rtol=1e-10, atol=1e-10, t_eval=np.linspace(0.0, 10.0, 1001))
    phases["integrate"] = time.perf_counter() - t0
    shutil.rmtree(folder, ignore_errors=True)
    Path(out).write_text(json.dumps(phases))


def mjcf(kind: str, n: int) -> str:
    """The rods of ``kind`` ("chain": hinges about -y, "spatial": ball joints) as MJCF: mass 1,
    length 1, inertia about the centre given exactly (a rod of radius 0.05 in space)."""
    r = 0.05
    across, along = (1 / 12, 1e-9) if kind == "chain" else ((3 * r * r + 1) / 12, r * r / 2)
    joint = '<joint type="hinge" axis="0 -1 0"/>' if kind == "chain" else '<joint type="ball"/>'
    body = ""
    for i in reversed(range(n)):
        body = (f'<body name="rod{i + 1}" pos="0 0 {0 if i == 0 else -1}">{joint}'
                f'<inertial pos="0 0 -0.5" mass="1" diaginertia="{across!r} {across!r} {along!r}"/>{body}</body>')
    return (f'<mujoco><compiler angle="radian" inertiafromgeom="false"/>'
            f'<option timestep="0.001" integrator="RK4" gravity="0 0 -9.81"><flag contact="disable"/></option>'
            f'<worldbody>{body}</worldbody></mujoco>')


def child_mujoco(kind: str, n: int, out: str) -> None:
    phases = dict.fromkeys(PHASES, 0.0)
    start = time.perf_counter()
    import mujoco

    phases["import"] = time.perf_counter() - start
    t0 = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(mjcf(kind, n))
    data = mujoco.MjData(model)
    phases["compile"] = time.perf_counter() - t0
    if kind == "chain":
        data.qpos[0] = 0.1  # the absolute angles 0.1 each: relative 0.1, 0, ...
    t0 = time.perf_counter()
    mujoco.mj_step(model, data, nstep=10_000)
    phases["integrate"] = time.perf_counter() - t0
    Path(out).write_text(json.dumps(phases))


# ---------------------------------------------------------------------------------------------
# the parent
# ---------------------------------------------------------------------------------------------

def run_child(args: list[str], timeout: float, env: dict | None = None) -> tuple[float, float, dict | None]:
    """(wall seconds, peak MB, phases) of ``python <args>`` (phases None: it failed or timed out;
    wall inf: timed out)."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "phases.json"
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, *args, str(out)] if args[0] == __file__ else [sys.executable, *args],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd=ROOT)
        deadline = t0 + timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                proc.kill()
                os.wait4(proc.pid, 0)
                return float("inf"), float("nan"), None
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
        if proc.returncode != 0:
            print(f"    (failed: {err.strip().splitlines()[-1] if err.strip() else proc.returncode})")
            return wall, usage.ru_maxrss / 1024, None
        phases = json.loads(out.read_text()) if out.exists() else None
        return wall, usage.ru_maxrss / 1024, phases


def _env(cache: str | None = None) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    if cache is not None:
        env["KRONSUB_CACHE_DIR"] = cache
    return env


def _seconds(value: float) -> str:
    return f"{value:.2f}" if value != float("inf") else f">{TIMEOUT:g}"


def _cell(values: list[float]) -> str:
    return f"{_seconds(min(values))}/{_seconds(statistics.median(values))}" if values else "-"


def _goal(values: list[float], goal: float | None) -> str:
    if goal is None or not values:
        return ""
    finite = sorted(values)
    best, median = finite[0], statistics.median(finite)
    verdict = "met" if median <= goal else ("min met" if best <= goal else "missed")
    return f"goal {goal:g} s: x{best / goal:.2f}/x{median / goal:.2f} {verdict}"


def case(label: str, runs: list[tuple[float, float, dict | None]], goal: float | None = None,
         memory_goal: float | None = None) -> list[float]:
    walls = [w for w, _, _ in runs]
    peaks = [p for _, p, _ in runs if p == p]
    done = [ph for _, _, ph in runs if ph]
    phases = " ".join(f"{p} {statistics.median(ph[p] for ph in done):.2f}" for p in PHASES
                      if done and any(ph[p] for ph in done))
    memory = f"{max(peaks):.0f} MB" if peaks else "-"
    note = _goal(walls, goal)
    if memory_goal is not None and peaks:
        note += f"; peak {max(peaks):.0f} <= {memory_goal:g} MB {'met' if max(peaks) <= memory_goal else 'missed'}"
    print(f"  {label:<24} {_cell(walls):>13}  {memory:>7}  {phases}  {note}")
    return walls


def ratios(ours: list[float], peers: dict[str, list[float]]) -> None:
    """kronsub cold over each peer measured in the same run (min/median)."""
    parts = [f"{name} x{min(ours) / min(walls):.2f}/x{statistics.median(ours) / statistics.median(walls):.2f}"
             for name, walls in peers.items() if walls and ours and float("inf") not in walls + ours]
    if parts:
        print(f"  {'kronsub cold / peer':<24} " + ", ".join(parts))


def _command(model: Path) -> list[str]:
    return ["-m", "kronsub", "simulate", str(model), "--t", "10"]


def kronsub_runs(model: Path, repeats: int, timeout: float) -> tuple[list, list]:
    """Cold runs (phases timed in a child) and warm ones (the command itself, a prepared run)."""
    cold, warm = [], []
    for _ in range(repeats):
        cache = tempfile.mkdtemp(prefix="ks-first-")
        try:
            cold.append(run_child([__file__, "--child", "kronsub", str(model)], timeout, _env(cache)))
            if cold[-1][2] is not None:
                warm.append(run_child(_command(model), timeout, _env(cache)))
        finally:
            shutil.rmtree(cache, ignore_errors=True)
    return cold, warm


def warm_runs(model: Path, repeats: int, timeout: float) -> tuple[list, list]:
    """The command again on a filled cache, interleaved: as a prepared run, and derived from the
    cached known system and compiled library (its prepared runs removed first)."""
    prepared, derived = [], []
    cache = tempfile.mkdtemp(prefix="ks-first-")
    try:
        run_child(_command(model), timeout, _env(cache))
        for _ in range(repeats):
            shutil.rmtree(Path(cache) / "kept", ignore_errors=True)
            derived.append(run_child(_command(model), timeout, _env(cache)))
            prepared.append(run_child(_command(model), timeout, _env(cache)))
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return prepared, derived


def available(tool: str) -> str | None:
    """None when ``tool``'s peer can run here, else why not."""
    modules = {"pydy-cython": ("pydy", "Cython"), "pydy-lambdify": ("pydy",), "mujoco": ("mujoco",)}
    for name in modules.get(tool, ()):  # in a child: the parent stays small (a child's peak counts the parent's at fork)
        done = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True, text=True)
        if done.returncode != 0:
            return f"not available ({done.stderr.strip().splitlines()[-1] if done.stderr.strip() else name})"
    return None


TIMEOUT = 600.0


def main() -> None:
    global TIMEOUT
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="2,5,10,20,50,100")
    parser.add_argument("--spatial", default="3,5,10")
    parser.add_argument("--pins", default="3", help="sizes of the spatial chain with its joints as pin constraints")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--tools", default=",".join(TOOLS))
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, *rest = args.child
        if kind == "kronsub":
            child_kronsub(*rest)
        elif kind.startswith("pydy-"):
            child_pydy(kind.removeprefix("pydy-"), int(rest[0]), rest[1])
        else:
            child_mujoco(rest[0], int(rest[1]), rest[2])
        return
    TIMEOUT = args.timeout
    tools = [t for t in args.tools.split(",") if t]
    sizes = [int(s) for s in args.sizes.split(",") if s]
    spatial = [int(s) for s in args.spatial.split(",") if s]
    pins = [int(s) for s in args.pins.split(",") if s]
    sys.path.insert(0, str(ROOT / "models" / "chain"))
    from generate import chain_yaml
    from generate_spatial import spatial_chain_yaml

    # as installed: pip compiles a package's bytecode, which every child then reads (an environment
    # with PYTHONDONTWRITEBYTECODE would otherwise compile kronsub's modules from source in each one)
    compileall.compile_dir(str(ROOT / "kronsub"), quiet=1)
    print(f"first trajectory, t = 10; wall min/median of {args.repeats} fresh processes [s], peak memory, "
          "phases (median) [s]; kronsub's bytecode compiled first, as an installation has it")
    missing = {t: available(t) for t in tools}
    with tempfile.TemporaryDirectory() as folder:
        print("\nstart-up")
        runs = [run_child(["-c", "pass"], args.timeout, _env()) for _ in range(args.repeats)]
        case("python -c pass", runs)  # the interpreter alone: the floor of every row
        runs = [run_child(["-c", "import kronsub"], args.timeout, _env()) for _ in range(args.repeats)]
        case("import kronsub", runs, STARTUP_GOALS["import kronsub"])
        runs = [run_child(["-m", "kronsub", "--help"], args.timeout, _env()) for _ in range(args.repeats)]
        case("kronsub --help", runs, STARTUP_GOALS["kronsub --help"])
        if "kronsub" in tools:
            warm, derived = warm_runs(ROOT / "models" / "hoffmann" / "system1.yaml", args.repeats, args.timeout)
            walls = case("system1 warm", warm, STARTUP_GOALS["system1 warm"])
            before = case("system1 warm, derived", derived)
            print(f"  {'warm / derived':<24} x{min(walls) / min(before):.2f}/"
                  f"x{statistics.median(walls) / statistics.median(before):.2f}")
        plan = [("chain", n, chain_yaml) for n in sizes] + [("spatial", n, spatial_chain_yaml) for n in spatial]
        plan += [("spatial-pins", n, lambda n: spatial_chain_yaml(n, pins=True)) for n in pins]
        for kind, n, writer in plan:
            print(f"\n{kind} n = {n}")
            model = Path(folder) / f"{kind}{n}.yaml"
            model.write_text(writer(n))
            goals = CHAIN_GOALS if kind == "chain" else SPATIAL_GOALS
            ours, peers = [], {}
            for tool in tools:
                if missing[tool]:
                    print(f"  {tool:<24} {missing[tool]}")
                    continue
                if tool == "kronsub":
                    cold, warm = kronsub_runs(model, args.repeats, args.timeout)
                    ours = case("kronsub cold", cold, goals.get(n),
                                MEMORY_GOAL[1] if kind == "chain" and n == MEMORY_GOAL[0] else None)
                    case("kronsub warm", warm)
                elif tool.startswith("pydy"):
                    if kind != "chain":
                        print(f"  {tool:<24} not run (the spatial chain is not written for KanesMethod here)")
                        continue
                    runs = [run_child([__file__, "--child", tool, str(n)], args.timeout, _env())
                            for _ in range(args.repeats)]
                    peers[tool] = case(tool, runs)
                    if runs and all(w == float("inf") for w, _, _ in runs):
                        tools = [t for t in tools if t != tool]  # larger n would time out too
                else:
                    runs = [run_child([__file__, "--child", "mujoco", kind.split("-")[0], str(n)], args.timeout,
                                      _env()) for _ in range(args.repeats)]
                    peers["mujoco"] = case("mujoco", runs)
            ratios(ours, peers)

if __name__ == "__main__":
    main()
