"""``kronsub animate``: the mechanism drawn over time (matplotlib's animation; an optional extra).

The drawing needs only the named points' world positions per row (the ``--points``
columns ``label.x``, ``label.y``...). Points are grouped by their component (the label
up to its last dot); a component with one point is a dot, with several a set of
segments from its first point (a rod from its centre or pivot to its ends; a lone
point, such as a particle, is a larger square), and a
component with a ``rim`` is a disc about its ``centre``. Positions in space are seen
along y (x horizontal, z up). GIF is written with pillow, mp4 with ffmpeg where present.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..emitters.escape import plot_text
from ..errors import KronsubError, Location, ModelError, Problem
from ..model.file_reading import read_user_text
from .plot import point_paths

FORMATS = (".gif", ".mp4")


class AnimationError(KronsubError):
    """The animation cannot be written (format, writer or input)."""


WRITE_POINTS = "kronsub simulate MODEL --points --output FILE.csv"
TRAJECTORY = f"trajectory CSV ({WRITE_POINTS})"


def read_points_csv(path: Path) -> tuple[np.ndarray, list[str], np.ndarray]:
    """``t``, the point column names and their values from a trajectory CSV (lines
    starting with ``#`` are skipped, so files with and without comment lines are read).

    Every row has the header's number of values, each a finite number, and ``t``
    increases from row to row; else a `ModelError` at the line and column."""
    def bad(line: int, column: int, message: str, hint: str = f"write it again with {WRITE_POINTS}"):
        return ModelError([Problem(Location(str(path), line, column), message, hint)])

    records = [(n, line) for n, line in enumerate(read_user_text(path, TRAJECTORY).splitlines(), 1)
               if line.strip() and not line.startswith("#")]
    header = next(csv.reader([records[0][1]])) if records else []
    if "t" not in header:
        raise AnimationError(f"{path}: not a kronsub trajectory (no header row with a column 't')\n"
                             f"  hint: give a {TRAJECTORY}")
    if len(records) < 2:
        raise AnimationError(f"{path}: the trajectory has no rows to animate\n"
                             f"  hint: write it again with {WRITE_POINTS}")
    data = np.empty((len(records) - 1, len(header)))
    it = header.index("t")
    for i, (n, line) in enumerate(records[1:]):
        row = next(csv.reader([line]))
        if len(row) != len(header):
            raise bad(n, 1, f"the row has {len(row)} values, the header {len(header)} columns "
                            "(a damaged or truncated file)")
        column = 1
        for j, text in enumerate(row):
            try:
                value = float(text)
            except ValueError:
                value = None
            if value is None or not np.isfinite(value):
                raise bad(n, column, f"column '{header[j]}': expected a finite number, got '{text[:40]}'")
            data[i, j] = value
            column += len(text) + 1
        if i and not data[i, it] > data[i - 1, it]:
            raise bad(n, 1, f"t = {float(data[i, it])!r} does not increase (the row before has "
                            f"t = {float(data[i - 1, it])!r})")
    columns = [j for j, name in enumerate(header) if name.rpartition(".")[2] in ("x", "y", "z")
               and "." in name]
    if not columns:
        raise AnimationError(f"{path} has no columns of named points\n  hint: write it with "
                             "`kronsub simulate MODEL --points --output FILE.csv`, or animate the model itself")
    return data[:, it], [header[j] for j in columns], data[:, columns]


def _groups(labels) -> dict[str, list[str]]:
    groups: dict[str, list[str]] = {}
    for label in labels:
        groups.setdefault(label.rpartition(".")[0] or label, []).append(label)
    return groups


def frame_times(t: np.ndarray, fps: int, gif: bool = False) -> tuple[np.ndarray, float]:
    """The times of the frames, one every ``1/fps`` s of motion from the first row, and that
    interval: the animation then plays in real time. A GIF stores its delays in hundredths of a
    second, so there the interval is the nearest whole number of them (at least 2: viewers slow
    shorter ones down)."""
    interval = 1.0 / fps
    if gif:
        interval = max(2, round(100.0 / fps)) / 100.0
    if len(t) < 2:
        return np.asarray(t[:1], dtype=float), interval
    count = int(np.floor((t[-1] - t[0]) / interval + 1e-9)) + 1
    return t[0] + interval * np.arange(count), interval


def animate(t: np.ndarray, names: list[str], values: np.ndarray, path: Path, *, fps: int = 30,
            size: int = 480, title: str = "") -> int:
    """Write the animation to ``path`` (.gif or .mp4); returns the number of frames."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import animation
    from matplotlib.patches import Circle

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise AnimationError(f"{path}: cannot write '{path.suffix}' animations\n  hint: use a .gif or .mp4 name")
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise AnimationError("writing .mp4 needs ffmpeg, which is not on the PATH\n"
                             "  hint: install ffmpeg, or write a .gif (pillow)")
    if len(t) == 0:
        raise AnimationError("the trajectory has no rows to animate\n  hint: give a trajectory with at least one row")
    paths = point_paths(names, values)
    if not paths:
        raise AnimationError("nothing to draw: the model has no named points (flywheels have none)"
                             "\n  hint: `kronsub simulate` writes its coordinates over time")
    groups = _groups(paths)
    times, interval = frame_times(t, fps, suffix == ".gif")
    if len(t) > 1:  # the points at the frames' times, between the rows
        paths = {label: np.column_stack([np.interp(times, t, xy[:, i]) for i in range(xy.shape[1])])
                 for label, xy in paths.items()}
    rows = range(len(times))

    dpi = 80
    fig = plt.figure(figsize=(size / dpi, size / dpi), dpi=dpi)
    ax = fig.add_axes((0.1, 0.08, 0.85, 0.84))
    everything = np.vstack(list(paths.values()))
    low, high = everything.min(axis=0), everything.max(axis=0)
    centre, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 1e-9) * 1.15
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("height")
    artists = []
    for k, (group, labels) in enumerate(sorted(groups.items())):
        colour = f"C{k % 10}"
        base = labels[0]
        rim = next((lab for lab in labels if lab.endswith(".rim")), None)
        hub = next((lab for lab in labels if lab.endswith(".centre")), base)
        disc = Circle((0, 0), 0, fill=False, color=colour, lw=2) if rim else None
        if disc is not None:
            ax.add_patch(disc)
        spokes = [ax.plot([], [], "-", color=colour, lw=3, solid_capstyle="round")[0] for _ in labels[1:]]
        alone = len(labels) == 1  # a particle (or a body with one point): a larger square
        dots = ax.plot([], [], "s" if alone else "o", color=colour, ms=11 if alone else 5,
                       zorder=1 if alone else 2)[0]
        artists.append((labels, hub, rim, disc, spokes, dots))
    clock = ax.set_title("")
    shown = plot_text(title)

    def draw(frame: int):
        row = rows[frame]
        changed = []
        for labels, hub, rim, disc, spokes, dots in artists:
            first = paths[labels[0]][row]
            for line, other in zip(spokes, labels[1:]):
                end = paths[other][row]
                line.set_data([first[0], end[0]], [first[1], end[1]])
                changed.append(line)
            xy = np.array([paths[lab][row] for lab in labels])
            dots.set_data(xy[:, 0], xy[:, 1])
            changed.append(dots)
            if disc is not None:
                c, r = paths[hub][row], paths[rim][row]
                disc.center = (c[0], c[1])
                disc.set_radius(float(np.hypot(*(r - c))))
                changed.append(disc)
        clock.set_text(f"{shown}  t = {times[row]:.2f}".strip())
        return changed + [clock]

    movie = animation.FuncAnimation(fig, draw, frames=len(rows), blit=False)
    # Pillow's writer takes int(1000 / fps) ms a frame and GIF keeps hundredths: a rate a hair
    # below 1/interval keeps 30 ms from becoming 29, and so 20
    rate = 1000.0 / (1000.0 * interval + 1e-6)
    writer = animation.PillowWriter(fps=rate) if suffix == ".gif" else animation.FFMpegWriter(fps=1.0 / interval)
    try:
        with atomic_path(path) as tmp:  # the writers want a file name with the format's suffix
            movie.save(str(tmp), writer=writer, dpi=dpi)
    finally:
        plt.close(fig)
    return len(rows)


__all__ = ["AnimationError", "FORMATS", "TRAJECTORY", "WRITE_POINTS", "animate", "frame_times", "read_points_csv"]
