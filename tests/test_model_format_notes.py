"""What docs/model-format.md promises in passing: massless links, commas in flow mappings."""
from __future__ import annotations

import numpy as np
import sympy
from click.testing import CliRunner

import kronsub
from kronsub.cli import main

MASSLESS = """\
name: bob on a massless rod
parameters: {m: 2, L: 1.5, g: 9.81}
components:
  rod: {type: pinned_rod, parameters: {mass: 0, length: L}, coordinates: {angle: theta}}
  bob: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}
coordinates: [theta]
connection: {x: L*sin(theta), y: -L*cos(theta)}
effects:
  gravity: {type: gravity, g: g}
initial: {theta: 0.1}
"""


def test_a_massless_rod_carrying_a_bob_is_the_simple_pendulum(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(MASSLESS)
    system = kronsub.load(path).derive(cache=False)
    th, m, L, g = (system.symbol(n) for n in ("theta", "m", "L", "g"))
    # hand Lagrangian: T = m (L thd)^2 / 2, V = -m g L cos(theta)
    assert sympy.simplify(system.mass_matrix[0, 0] - m * L**2) == 0
    assert sympy.simplify(system.forces[0] - system.velocity_terms[0] + m * g * L * sympy.sin(th)) == 0
    lin = system.linearize()
    assert np.allclose(sorted(np.imag(lin.eigenvalues)), [-np.sqrt(9.81 / 1.5), np.sqrt(9.81 / 1.5)], rtol=1e-12)


def test_a_comma_in_a_flow_mapping_says_to_quote(tmp_path):
    text = ("name: well\nparameters: {m: 1, k: 2}\ncomponents:\n"
            "  p: {type: particle2d, parameters: {mass: m}, coordinates: [x, y]}\ncoordinates: [x, y]\n"
            "effects:\n  well: {type: potential, value: k*atan2(y, x)**2}\n")
    path = tmp_path / "m.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1
    assert "unknown key 'x)**2' in effect 'well'" in result.output and "quote an expression" in result.output
    path.write_text(text.replace("value: k*atan2(y, x)**2", 'value: "k*atan2(y, x)**2"'))
    assert CliRunner().invoke(main, ["check", str(path)]).exit_code == 0
