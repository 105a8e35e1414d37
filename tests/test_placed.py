"""A known system placed with ``origin:`` moves with everything of it: its points and bodies,
and the potential of its own gravity, which is ``-m g (d . centre)`` in the world it now sits
in. Independent route: the world potential of every body written by hand, three levels deep,
in a plane and in space."""
from __future__ import annotations

import math

import pytest

import kronsub

PENDULUM = """name: pendulum
parameters:
  m: {value: 1.3, unit: kg}
  L: {value: 0.9, unit: m}
  g: {value: 9.81, unit: m/s^2}
components:
  arm: {type: pinned_rod, parameters: {mass: m, length: L}, coordinates: {angle: theta}}
coordinates: [theta]
effects:
  gravity: {type: gravity, g: g, direction: [DX, DY]}
"""

def _wrapper(name, inner, origin, extra=""):
    return (f"name: {name}\nparameters:\n  e: {{value: 0.7, unit: m}}\n  w: {{value: -0.4, unit: m}}\n"
            f"components:\n  inner: {{model: {inner}, origin: [{origin}]}}\n"
            f"coordinates: [theta]\n{extra}")


@pytest.mark.parametrize("direction", [(0, -1), (1, -2)])
def test_potential_of_a_known_system_placed_twice(tmp_path, monkeypatch, direction):
    monkeypatch.setenv("KRONSUB_CACHE_DIR", str(tmp_path / "cache"))
    dx, dy = direction
    (tmp_path / "pendulum.yaml").write_text(PENDULUM.replace("DX", str(dx)).replace("DY", str(dy)))
    (tmp_path / "middle.yaml").write_text(_wrapper("middle", "pendulum.yaml", "w, e"))
    (tmp_path / "outer.yaml").write_text(_wrapper("outer", "middle.yaml", "e, 2*w")
                                         .replace("  e:", "  f:").replace("origin: [e, 2*w]", "origin: [f, 2*w]"))
    for cached in (False, True):  # derived, then read back from the cache
        system = kronsub.load(tmp_path / "outer.yaml").derive()
        values = {s.name: s for s in system.potential_energy.free_symbols}
        theta = values["theta"]
        state = {"theta": 0.4, "m": 1.3, "L": 0.9, "g": 9.81, "e": 0.7, "w": -0.4, "f": 0.7}
        # the rod's centre in the world: the pendulum's origin moved by (w, e), then by (f, 2 w)
        x = 0.45 * math.sin(0.4) + (-0.4) + 0.7
        y = -0.45 * math.cos(0.4) + 0.7 + 2 * (-0.4)
        norm = math.hypot(dx, dy)
        expected = -1.3 * 9.81 * (dx * x + dy * y) / norm
        got = float(system.potential_energy.subs({values[k]: v for k, v in state.items() if k in values}))
        assert got == pytest.approx(expected, rel=1e-12), (cached, system.potential_energy)
        assert theta in system.potential_energy.free_symbols
