"""Plots split by unit and ``kronsub animate`` (matplotlib, pillow)."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import kronsub
from conftest import MODELS
from kronsub.cli import main

pytest.importorskip("matplotlib")

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"
CART_POLE = MODELS / "examples" / "cart_pole.yaml"


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_system1_gif_has_the_frames_and_size_asked_for(tmp_path):
    Image = pytest.importorskip("PIL.Image")
    gif = tmp_path / "motion.gif"
    result = invoke("animate", SYSTEM1, "--output", gif, "--t", 1, "--dt", 0.05, "--fps", 20, "--size", 200)
    assert result.exit_code == 0, result.output
    assert "21 frames" in result.output
    with Image.open(gif) as image:
        assert image.size == (200, 200)
        assert image.n_frames == 21  # rows 0, 0.05, ..., 1: one frame each at 20 per second
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motion.gif"]  # no temporary file left


def test_animate_a_trajectory_csv_in_real_time(tmp_path):
    Image = pytest.importorskip("PIL.Image")
    csv = tmp_path / "run.csv"
    assert invoke("simulate", CART_POLE, "--t", 0.5, "--dt", 0.01, "--points", "--output", csv).exit_code == 0
    gif = tmp_path / "run.gif"
    result = invoke("animate", csv, "--output", gif, "--fps", 25, "--size", 160)
    assert result.exit_code == 0, result.output
    with Image.open(gif) as image:
        assert image.n_frames == 13  # 51 rows every 0.01 s, every 4th at 25 frames per second


def test_animate_needs_point_columns(tmp_path):
    csv = tmp_path / "run.csv"
    assert invoke("simulate", CART_POLE, "--t", 0.1, "--output", csv).exit_code == 0
    result = invoke("animate", csv, "--output", tmp_path / "run.gif")
    assert result.exit_code == 1 and "--points" in result.output and "Traceback" not in result.output


def test_animate_formats(tmp_path, monkeypatch):
    csv = tmp_path / "run.csv"
    assert invoke("simulate", CART_POLE, "--t", 0.1, "--points", "--output", csv).exit_code == 0
    other = invoke("animate", csv, "--output", tmp_path / "run.avi")
    assert other.exit_code == 2 and "--output" in other.output and ".gif or .mp4" in other.output
    from matplotlib import animation

    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    mp4 = invoke("animate", csv, "--output", tmp_path / "run.mp4")
    assert mp4.exit_code == 1 and "needs ffmpeg" in mp4.output and not (tmp_path / "run.mp4").exists()


def test_frames_keep_real_time():
    from kronsub.simulation.animate import frame_times

    t = np.linspace(0, 2, 201)
    times, interval = frame_times(t, 25)
    assert interval == 0.04 and len(times) == 51 and times[-1] == pytest.approx(2.0)
    times, interval = frame_times(t[::20], 25)  # sparser rows than frames: frames between them
    assert len(times) == 51
    times, interval = frame_times(t, 30, gif=True)  # GIF delays in hundredths of a second
    assert interval == 0.03 and len(times) == 67


def test_angles_are_told_from_lengths():
    from kronsub.simulation.plot import angle_coordinates

    cart_pole = kronsub.load(CART_POLE).derive()
    assert angle_coordinates(cart_pole) == {cart_pole.symbol("theta")}
    sphere = kronsub.load(MODELS / "examples" / "particle_on_sphere.yaml").derive()
    assert angle_coordinates(sphere) == set(sphere.coordinates)


def test_plot_has_one_panel_per_unit_and_legends_outside(tmp_path, monkeypatch):
    from kronsub.simulation import plot

    figures = []
    monkeypatch.setattr(plot, "save_figure", lambda fig, path, fmt: figures.append(fig))
    result = invoke("simulate", CART_POLE, "--t", 0.5, "--points", "--plot", tmp_path / "run.png",
                    "--output", tmp_path / "run.csv")
    assert result.exit_code == 0, result.output
    (fig,) = figures
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["angles [rad]", "lengths [m]", "angular velocities [rad/s]", "velocities [m/s]",
                      "energy change [J]", "y [m]"]
    for ax in fig.axes:
        legend = ax.get_legend()
        anchor = legend.get_bbox_to_anchor().transformed(ax.transAxes.inverted())
        assert anchor.x0 > 1.0  # to the right of the axes, over no curve
    angles, lengths = fig.axes[0], fig.axes[1]
    assert [line.get_label() for line in angles.get_lines()] == ["theta"]
    assert [line.get_label() for line in lengths.get_lines()] == ["x"]
    assert [line.get_label() for line in fig.axes[2].get_lines()] == ["theta_dot"]
    assert [line.get_label() for line in fig.axes[3].get_lines()] == ["x_dot"]
    # the pole hangs from the cart's centre: one path for both
    assert [line.get_label() for line in fig.axes[5].get_lines()] == ["cart.centre = pole.a", "pole.b", "pole.centre"]


@pytest.mark.parametrize("flag, shown", [("--progress", True), ("--no-progress", False), (None, False)])
def test_a_bar_counts_the_frames_on_request(tmp_path, flag, shown):
    pytest.importorskip("PIL")
    csv = tmp_path / "run.csv"
    assert invoke("simulate", CART_POLE, "--t", 0.2, "--dt", 0.05, "--points", "--output", csv).exit_code == 0
    args = ["animate", csv, "--output", tmp_path / "run.gif", "--fps", 10, "--size", 64] + ([flag] if flag else [])
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    assert ("] 3/3 frames" in result.stderr) is shown  # the runner is no terminal: no bar unless asked
    assert "wrote" in result.stderr and "3 frames" in result.stderr


def test_too_many_frames_are_refused_before_drawing(tmp_path):
    csv = tmp_path / "long.csv"
    csv.write_text("t,bob.centre.x,bob.centre.y\n0,0,0\n1000,1,0\n")
    result = invoke("animate", csv, "--output", tmp_path / "long.gif", "--fps", 30)
    assert result.exit_code == 1
    assert "are more than 20000" in result.output and "lower --fps" in result.output
    assert list(tmp_path.iterdir()) == [csv]


def test_mp4_frames_go_to_ffmpeg(tmp_path, monkeypatch):
    """The raw frames reach ffmpeg (here a stand-in that counts the bytes it is given)."""
    import matplotlib

    fake = tmp_path / "ffmpeg"
    fake.write_text("#!/usr/bin/env python3\nimport sys\n"
                    "data = sys.stdin.buffer.read()\nopen(sys.argv[-1], 'w').write(' '.join(sys.argv[1:]) + '\\n'"
                    " + str(len(data)))\n")
    fake.chmod(0o755)
    monkeypatch.setitem(matplotlib.rcParams, "animation.ffmpeg_path", str(fake))
    csv = tmp_path / "run.csv"
    assert invoke("simulate", CART_POLE, "--t", 0.2, "--dt", 0.05, "--points", "--output", csv).exit_code == 0
    out = tmp_path / "run.mp4"
    result = invoke("animate", csv, "--output", out, "--fps", 10, "--size", 64)
    assert result.exit_code == 0, result.output
    arguments, count = out.read_text().splitlines()
    assert "-s 64x64" in arguments and "-pix_fmt rgb24" in arguments and "-r 10.0" in arguments
    assert int(count) == 3 * 64 * 64 * 3  # frames at 0, 0.1, 0.2 s, 64 x 64 RGB each
