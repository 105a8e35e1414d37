"""``kronsub animate``: the mechanism drawn over time (matplotlib and Pillow; an optional extra).

The shapes and their places come from :mod:`kronsub.simulation.mechanism`. The fixed ones
(pivots on hatched ground, walls, rails) are drawn once into a background; each frame
restores that background and draws the moving artists over it, updated in place
(blitting), and the pictures go to Pillow's GIF writer with one palette, or to ffmpeg
as raw frames for mp4. The plane is drawn as it is, space seen along +y (x to the right,
z up), axes equal and in metres.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..emitters.escape import plot_text
from ..errors import KronsubError, Location, ModelError, Problem
from ..model.file_reading import read_user_text
from .plot import plane

FORMATS = (".gif", ".mp4")

MAX_FRAMES = 20_000
"""More frames is a mistake (11 minutes at 30 per second): a GIF's frames are held in memory
until written, 230 kB each at 480 px."""


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



def at_frames(t: np.ndarray, times: np.ndarray, places: np.ndarray) -> np.ndarray:
    """``places`` (rows x ...) at the frames' ``times``, linear between the rows."""
    if len(t) < 2:
        return places[:1].repeat(len(times), axis=0)
    upper = np.clip(np.searchsorted(t, times, side="right"), 1, len(t) - 1)
    lower = upper - 1
    w = ((times - t[lower]) / (t[upper] - t[lower])).reshape((-1,) + (1,) * (places.ndim - 1))
    return places[lower] * (1 - w) + places[upper] * w


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.hypot(v[..., 0], v[..., 1])[..., None]
    return np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)


def _normal(e: np.ndarray) -> np.ndarray:
    return np.stack([-e[..., 1], e[..., 0]], axis=-1)


def zigzag(a: np.ndarray, b: np.ndarray, width: float, coils: int | None = None) -> np.ndarray:
    """A spring from ``a`` to ``b`` (points of the plane): straight leads, then ``2 coils``
    strokes of half-width ``width`` across the line (by default one coil per two widths of
    length, 4 to 16)."""
    d = b - a
    length = float(np.hypot(*d))
    if coils is None:
        coils = int(np.clip(length / (2 * width), 4, 16)) if width > 0 else 4
    e = _unit(d)
    n = _normal(e)
    lead = min(0.15 * length, width)
    s = lead + (length - 2 * lead) * (np.arange(2 * coils) + 0.5) / (2 * coils)
    side = width * np.where(np.arange(2 * coils) % 2 == 0, 1.0, -1.0)
    middle = a + s[:, None] * e + side[:, None] * n
    return np.vstack([a, a + lead * e, middle, b - lead * e, b])


def dashpot(a: np.ndarray, b: np.ndarray, width: float) -> np.ndarray:
    """A damper from ``a`` to ``b``: a cylinder open towards ``b`` on a rod from ``a``, and a
    piston plate inside it on a rod from ``b`` (NaN rows break the line)."""
    d = b - a
    length = float(np.hypot(*d))
    e, n = _unit(d), _normal(_unit(d))
    gap = np.full(2, np.nan)

    def at(s, w=0.0):
        return a + s * length * e + w * n

    return np.vstack([a, at(0.3), gap, at(0.3, width), at(0.3, -width), gap,
                      at(0.3, width), at(0.7, width), gap, at(0.3, -width), at(0.7, -width), gap,
                      at(0.55, 0.75 * width), at(0.55, -0.75 * width), gap, at(0.55), b])


def hatch(start: np.ndarray, end: np.ndarray, side: np.ndarray, step: float) -> np.ndarray:
    """Ground from ``start`` to ``end``: the line and short slanted strokes towards ``side``."""
    d = end - start
    length = float(np.hypot(*d))
    e = _unit(d)
    count = max(2, int(length / step) + 1)
    rows = [start, end]
    for s in np.linspace(0, length, count):
        p = start + s * e
        rows += [np.full(2, np.nan), p, p + 0.6 * step * (side - e)]
    return np.vstack(rows)


class _Clock:
    """The time over the axes' top right corner, written into each picture with Pillow in
    matplotlib's font (a text artist is most of the cost of a blitted frame)."""

    def __init__(self, fig, ax):
        from matplotlib import font_manager
        from PIL import ImageFont

        size = fig.dpi * 10 / 72  # matplotlib's 10 points
        self.font = ImageFont.truetype(font_manager.findfont(font_manager.FontProperties()), round(size))
        box = ax.get_window_extent()
        self.corner = (box.x1, fig.bbox.height - box.y1 - 0.45 * size)

    def stamp(self, rgb: np.ndarray, t: float) -> np.ndarray:
        from PIL import Image, ImageDraw

        image = Image.fromarray(rgb)
        ImageDraw.Draw(image).text(self.corner, f"t = {t:.2f} s", font=self.font, fill=(0, 0, 0), anchor="rs")
        return np.asarray(image)


class _Canvas:
    """The figure: the fixed shapes drawn once (the background), the moving ones as artists
    updated in place and drawn over a copy of it for each frame (blitting)."""

    def __init__(self, shapes, size: int, title: str):
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib.figure import Figure
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        self.dpi = 80
        self.fig = Figure(figsize=(size / self.dpi, size / self.dpi), dpi=self.dpi)
        FigureCanvasAgg(self.fig)
        self.ax = ax = self.fig.add_axes((0.13, 0.1, 0.82, 0.8))
        self.space = any(s.places.shape[-1] == 3 for s in shapes if s.kind != "dial")
        drawn = [plane(s.places) if s.kind != "dial" else s.places for s in shapes]
        low, high = self._extent(shapes, drawn)
        centre = (low + high) / 2
        half = 1.15 * max(float(np.max(high - low)) / 2, 1e-3 * float(np.max(np.abs([low, high]))))
        if not half > 1e-6:  # nothing apart, nothing far: a metre around it
            half = 1.0
        self.half, self.centre, self.dials = half, centre, 0
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("z [m]" if self.space else "y [m]")
        if self.space:
            ax.text(0.99, 0.01, "seen along +y", transform=ax.transAxes, ha="right", va="bottom", fontsize="small")
        self.unit = 0.05 * half  # the size of pivots, walls, springs' coils
        colours: dict[str, str] = {}

        def colour(label):
            part = label.split(".")[0]
            return colours.setdefault(part, f"C{len(colours) % 10}")

        self.updates = []  # per moving shape: (its artists, update(frame))
        for shape, xy in zip(shapes, drawn):
            self._add(shape, xy, colour(shape.label))
        ax.text(0.0, 1.02, plot_text(title), transform=ax.transAxes, ha="left", va="bottom")
        self.fig.canvas.draw()
        self.background = self.fig.canvas.copy_from_bbox(self.fig.bbox)
        self.clock = _Clock(self.fig, ax)

    @staticmethod
    def _extent(shapes, drawn):
        seen = []
        for shape, xy in zip(shapes, drawn):
            if shape.kind in ("dial", "rail"):  # a dial is apart from the world, a rail a whole line
                continue
            if shape.kind in ("axes", "wall"):
                seen.append(xy[:, :1].reshape(-1, 2))
            elif shape.kind == "disc":
                radius = np.hypot(*(xy[:, 1] - xy[:, 0]).T)[:, None]
                seen += [xy[:, 0] - radius, xy[:, 0] + radius]
            else:
                seen.append(xy.reshape(-1, 2))
        if not seen:
            return np.zeros(2), np.zeros(2)
        everything = np.vstack(seen)
        return everything.min(axis=0), everything.max(axis=0)

    def _line(self, *args, **kw):
        return self.ax.plot(*args, animated=True, **kw)[0]

    def _add(self, shape, xy, colour: str) -> None:
        """Draw a fixed shape into the background, or add a moving one's artists and update."""
        drawn = getattr(self, f"_{shape.kind}")(shape, xy, colour)
        if drawn is not None:
            self.updates.append(drawn)

    def _pivot(self, shape, xy, colour):
        u, p = self.unit, xy[0, 0]
        tri = np.array([p, p + [-0.8 * u, -1.4 * u], p + [0.8 * u, -1.4 * u], p])
        self.ax.plot(tri[:, 0], tri[:, 1], "-", color="0.2", lw=1.2, zorder=3)
        ground = hatch(p + [-1.4 * u, -1.4 * u], p + [1.4 * u, -1.4 * u], np.array([0, -1.0]), 0.5 * u)
        self.ax.plot(ground[:, 0], ground[:, 1], "-", color="0.2", lw=1, zorder=3)
        self.ax.plot([p[0]], [p[1]], "o", color="0.2", mfc="white", ms=5, zorder=4)

    def _wall(self, shape, xy, colour):
        u, (p, towards) = self.unit, xy[0]
        e = _unit(towards - p)
        if not e.any():
            e = np.array([1.0, 0.0])
        n = _normal(e)
        ground = hatch(p - 2 * u * n, p + 2 * u * n, -e, 0.6 * u)
        self.ax.plot(ground[:, 0], ground[:, 1], "-", color="0.2", lw=1.2, zorder=3)

    def _rail(self, shape, xy, colour):
        u, reach = self.unit, 3 * self.half + float(np.hypot(*(xy[0, 0] - self.centre)))
        if shape.fixed:  # hatched on its lower side
            p, e = xy[0, 0], _unit(xy[0, 1] - xy[0, 0])
            n = _normal(e)
            below = -n if n[1] > 0 or (n[1] == 0 and n[0] > 0) else n
            ground = hatch(p - reach * e + 0.6 * u * below, p + reach * e + 0.6 * u * below, below, 0.8 * u)
            self.ax.plot(ground[:, 0], ground[:, 1], "-", color="0.45", lw=1, zorder=1)
            return None
        line = self._line([], [], "--", color=colour, lw=1, zorder=1)

        def update(k):
            p, e = xy[k, 0], _unit(xy[k, 1] - xy[k, 0])
            line.set_data([p[0] - reach * e[0], p[0] + reach * e[0]], [p[1] - reach * e[1], p[1] + reach * e[1]])
        return [line], update

    def _link(self, shape, xy, colour):
        line = self._line([], [], "-", color=colour, lw=3, solid_capstyle="round", zorder=2)
        dots = self._line([], [], "o", color=colour, ms=4, zorder=2)
        star = np.full((xy.shape[0], 3 * (xy.shape[1] - 1), 2), np.nan)  # first-other pairs, NaN between
        star[:, 0::3], star[:, 1::3] = xy[:, :1], xy[:, 1:]

        def update(k):
            line.set_data(star[k, :, 0], star[k, :, 1])
            dots.set_data(xy[k, :, 0], xy[k, :, 1])
        return [line, dots], update

    def _disc(self, shape, xy, colour):
        from matplotlib.patches import Circle

        disc = Circle((0, 0), 0, fill=True, fc=colour, alpha=0.25, ec=colour, lw=2, animated=True, zorder=1)
        self.ax.add_patch(disc)
        mark = self._line([], [], "-", color=colour, lw=2, zorder=2)
        radius = np.hypot(*(xy[:, 1] - xy[:, 0]).T)

        def update(k):
            disc.center = tuple(xy[k, 0])
            disc.set_radius(float(radius[k]))
            mark.set_data(xy[k, :, 0], xy[k, :, 1])
        return [disc, mark], update

    def _dial(self, shape, xy, colour):
        from matplotlib.patches import Circle

        ax = self.ax
        where = np.array([0.09 + 0.14 * self.dials, 0.89])  # in the top left corner, one beside the other
        self.dials += 1
        ax.add_patch(Circle(where, 0.05, transform=ax.transAxes, fill=False, ec=colour, lw=2))
        ax.text(where[0], where[1] - 0.065, plot_text(shape.label), transform=ax.transAxes, ha="center",
                va="top", fontsize="x-small", color=colour)
        mark = self._line([], [], "-", color=colour, lw=2, transform=ax.transAxes)
        ends = where + 0.05 * _unit(xy[:, 0, :2])

        def update(k):
            mark.set_data([where[0], ends[k, 0]], [where[1], ends[k, 1]])
        return [mark], update

    def _axes(self, shape, xy, colour):
        length = 2.5 * self.unit
        lines = [self._line([], [], "-", color=c, lw=2, zorder=3)
                 for c in ("tab:red", "tab:green", "tab:blue")[:xy.shape[1] - 1]]

        def update(k):
            c = xy[k, 0]
            for line, end in zip(lines, xy[k, 1:]):
                tip = c + length * (end - c)
                line.set_data([c[0], tip[0]], [c[1], tip[1]])
        return lines, update

    def _element(self, xy, make):
        line = self._line([], [], "-", color="0.25", lw=1.3, zorder=2)
        width = 0.7 * self.unit

        def update(k):
            path = make(xy[k, 0], xy[k, 1], width)
            line.set_data(path[:, 0], path[:, 1])
        return [line], update

    def _spring(self, shape, xy, colour):
        return self._element(xy, zigzag)

    def _damper(self, shape, xy, colour):
        return self._element(xy, dashpot)

    def _marker(self, xy, **style):
        dot = self._line([], [], linestyle="none", **style)

        def update(k):
            dot.set_data(xy[k, :1, 0], xy[k, :1, 1])
        return [dot], update

    def _mass(self, shape, xy, colour):
        return self._marker(xy, marker="o", ms=10, color=colour, zorder=3)

    def _block(self, shape, xy, colour):
        return self._marker(xy, marker="s", ms=13, mfc="white", mec=colour, mew=2, color=colour, zorder=3)

    def _joint(self, shape, xy, colour):
        return self._marker(xy, marker="o", ms=6, mfc="white", mec="0.1", mew=1.3, color="0.1", zorder=5)

    def frame(self, k: int, t: float) -> np.ndarray:
        """The picture at frame ``k`` (time ``t``), as rows x columns x RGB."""
        canvas = self.fig.canvas
        canvas.restore_region(self.background)
        for artists, update in self.updates:
            update(k)
            for artist in artists:
                self.ax.draw_artist(artist)
        return self.clock.stamp(np.asarray(canvas.buffer_rgba())[..., :3].copy(), t)


def animate(t: np.ndarray, shapes, path: Path, *, fps: int = 30, size: int = 480, title: str = "",
            progress: bool | None = None) -> int:
    """Write the animation of ``shapes`` (:mod:`kronsub.simulation.mechanism`, their places one
    row per time of ``t``) to ``path`` (.gif or .mp4); returns the number of frames. A bar on
    stderr counts the frames (``progress``: None shows it on a terminal only)."""
    from .accuracy import Progress

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise AnimationError(f"{path}: cannot write '{path.suffix}' animations\n  hint: use a .gif or .mp4 name")
    ffmpeg = _ffmpeg() if suffix == ".mp4" else None
    if len(t) == 0:
        raise AnimationError("the trajectory has no rows to animate\n  hint: give a trajectory with at least one row")
    if not shapes:
        raise AnimationError("nothing to draw: the model has no named points and no flywheel"
                             "\n  hint: `kronsub simulate` writes its coordinates over time")
    times, interval = frame_times(t, fps, suffix == ".gif")
    if len(times) > MAX_FRAMES:
        raise AnimationError(f"{len(times)} frames ({float(t[-1] - t[0]):.6g} s at {fps} per second) are more than "
                             f"{MAX_FRAMES}\n  hint: lower --fps, or animate a shorter run")
    from .mechanism import Shape

    shapes = [s if s.fixed else Shape(s.kind, s.label, at_frames(t, times, s.places), s.fixed) for s in shapes]
    canvas = _Canvas(shapes, size, title)
    bar = Progress(len(times), progress)
    try:
        with atomic_path(path) as tmp:  # the writers want a file name with the format's suffix
            if suffix == ".gif":
                _write_gif(canvas, times, interval, tmp, bar)
            else:
                _write_mp4(canvas, times, interval, tmp, bar, ffmpeg)
    finally:
        bar.close()
    return len(times)


def _frames(canvas, times, bar):
    for k, t in enumerate(times):
        yield canvas.frame(k, float(t))
        bar.step("frames")


def _write_gif(canvas, times, interval: float, path: Path, bar) -> None:
    """Pillow's GIF writer: one palette for the whole animation, made from the first frame
    (the background and every shape's colour are in it), no dithering; delays in hundredths."""
    from PIL import Image

    images, palette = [], None
    for rgb in _frames(canvas, times, bar):
        image = Image.fromarray(rgb)
        if palette is None:
            palette = image.quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
            images.append(palette)
        else:
            images.append(image.quantize(palette=palette, dither=Image.Dither.NONE))
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(round(1000 * interval)), loop=0, optimize=False)


def _ffmpeg() -> str:
    import matplotlib
    from matplotlib import animation

    if not animation.writers.is_available("ffmpeg"):
        raise AnimationError("writing .mp4 needs ffmpeg, which is not on the PATH\n"
                             "  hint: install ffmpeg, or write a .gif (pillow)")
    return matplotlib.rcParams["animation.ffmpeg_path"]


def _write_mp4(canvas, times, interval: float, path: Path, bar, ffmpeg: str) -> None:
    """ffmpeg reading raw RGB frames on its standard input (H.264, even sides)."""
    import subprocess

    height, width = canvas.frame(0, float(times[0])).shape[:2]
    command = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{width}x{height}", "-r", repr(1.0 / interval), "-i", "-",
               "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", "-vcodec", "libx264", str(path)]
    with subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
        try:
            for rgb in _frames(canvas, times, bar):
                proc.stdin.write(rgb.tobytes())
        except BrokenPipeError:
            pass
        _, err = proc.communicate()
    if proc.returncode != 0:
        raise AnimationError(f"ffmpeg could not write {path.name}: {err.decode(errors='replace').strip()[:300]}"
                             "\n  hint: write a .gif (pillow)")


__all__ = ["AnimationError", "FORMATS", "MAX_FRAMES", "TRAJECTORY", "WRITE_POINTS", "animate", "at_frames", "dashpot",
           "frame_times", "hatch", "read_points_csv", "zigzag"]
