"""``simulate --plot``: units on every axis, joints and fixed points drawn once, the title, the formats."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import MODELS
from kronsub.cli import main

pytest.importorskip("matplotlib")

CART_POLE = MODELS / "examples" / "cart_pole.yaml"
FOUR_BAR = MODELS / "examples" / "four_bar.yaml"


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def figure_of(monkeypatch, tmp_path, *args):
    from kronsub.simulation import plot

    figures = []
    monkeypatch.setattr(plot, "save_figure", lambda fig, path, fmt: figures.append(fig))
    result = invoke("simulate", *args, "--plot", tmp_path / "run.png", "--output", tmp_path / "run.csv")
    assert result.exit_code == 0, result.output
    (fig,) = figures
    return fig


def test_every_axis_has_its_unit(tmp_path, monkeypatch):
    fig = figure_of(monkeypatch, tmp_path, FOUR_BAR, "--t", 0.2, "--points")
    for ax in fig.axes:
        assert ax.get_ylabel().endswith(("[rad]", "[m]", "[rad/s]", "[m/s]", "[J]")), ax.get_ylabel()
    assert fig.axes[-2].get_xlabel() == "t [s]" and fig.axes[-1].get_xlabel() == "x [m]"
    assert "[per s]" not in " ".join(ax.get_ylabel() for ax in fig.axes)


def test_fixed_points_are_one_marker_and_joints_one_path(tmp_path, monkeypatch):
    fig = figure_of(monkeypatch, tmp_path, FOUR_BAR, "--t", 0.2, "--points")
    lines = {line.get_label(): line for line in fig.axes[-1].get_lines()}
    # the crank and rocker turn about fixed pivots; the coupler hangs from the crank's tip
    assert lines["crank.pivot (fixed)"].get_xydata().tolist() == [[0.0, 0.0]]
    assert lines["rocker.pivot (fixed)"].get_xydata().tolist() == [[0.9, 0.0]]
    assert lines["crank.pivot (fixed)"].get_marker() == "s" and lines["crank.pivot (fixed)"].get_linestyle() == "None"
    joined = {frozenset(label.split(" = ")): line for label, line in lines.items()}
    assert frozenset({"crank.tip", "coupler.pivot"}) in joined
    everywhere = [label.split(" = ") for label in lines]
    names = [name.removesuffix(" (fixed)") for group in everywhere for name in group]
    assert len(names) == len(set(names))  # every point once
    # the pin B holds coupler.tip on rocker.tip only to the constraints' tolerance: within it, one path
    assert frozenset({"coupler.tip", "rocker.tip"}) in joined
    crank = joined[frozenset({"crank.tip", "coupler.pivot"})].get_xydata()
    assert np.allclose(np.hypot(crank[:, 0], crank[:, 1]), 0.4)  # on the crank's circle about its pivot


def test_the_title_names_the_scene_and_method_once(tmp_path, monkeypatch):
    fig = figure_of(monkeypatch, tmp_path, CART_POLE, "--t", 0.1, "--scene", "damped")
    title = fig._suptitle.get_text()
    assert title == "Cart-pole with a damper (scene damped), method dop853"
    assert title.count("(") == 1


@pytest.mark.parametrize("suffix, head", [(".png", b"\x89PNG"), (".svg", b"<?xml"), (".pdf", b"%PDF")])
def test_plot_formats_by_name(tmp_path, suffix, head):
    out = tmp_path / f"run{suffix}"
    result = invoke("simulate", CART_POLE, "--t", 0.05, "--plot", out, "--output", tmp_path / "run.csv")
    assert result.exit_code == 0, result.output
    assert out.read_bytes()[:len(head)] == head


@pytest.mark.parametrize("name", ["run.jpg", "run"])
def test_plot_refuses_a_format_it_does_not_write(tmp_path, name):
    out = tmp_path / name
    result = invoke("simulate", CART_POLE, "--t", 0.05, "--plot", out, "--output", tmp_path / "run.csv")
    suffix = "'.jpg'" if name.endswith(".jpg") else "suffix-less"
    assert result.exit_code == 2, result.output
    assert result.output == (f"Error: --plot {out}: cannot write {suffix} plots\n"
                             "  hint: end the name in one of .png, .pdf, .svg\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # refused before the run


def test_animate_refuses_a_format_before_the_run(tmp_path):
    out = tmp_path / "motion.avi"
    result = invoke("animate", CART_POLE, "--output", out, "--t", 0.1)
    assert result.exit_code == 2
    assert result.output == f"Error: --output {out}: cannot write '.avi' animations\n  hint: end the name in .gif or .mp4\n"
    assert list(tmp_path.iterdir()) == []


def test_paths_in_space_are_seen_along_y(tmp_path, monkeypatch):
    fig = figure_of(monkeypatch, tmp_path, MODELS / "examples" / "particle_on_sphere.yaml", "--t", 0.1, "--points")
    ax = fig.axes[-1]
    assert ax.get_ylabel() == "z [m]" and "seen along +y" in ax.get_title()
