"""A solve on screen, written to files for a slide: the denoising as a GIF and the trail figure as a PNG.

Drawn with matplotlib (Agg), no browser, from the same colours the viewer uses (the arm kind's
palette: the followed sample's trail faint to dark, the others light) and on the viewer's clock
(clock.py: each GIF frame shows the state the animation has reached at its time, so the noisy
steps pass as fast as in the viewer). A robot is drawn as its skeletons seen from the
viewer's camera (an orthographic projection). The PNG has a title and the legend. No viser here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ikdp_viz.emphasis import emphasis_colors, follows_one

TARGET_RED = "#dc1919"
TITLE_BAND = 40  # pixels above the trail PNG's picture, for its title


@dataclass(frozen=True)
class Drawing:
    """What the files draw, in the picture's plane: every state's polylines and how to colour them."""

    polylines: np.ndarray  # (S+1, K, P, 2) each sample's joints at each state, projected
    target: np.ndarray  # (2,) the target, projected
    half_width: float  # the picture shows [-w, w] around `center`
    center: np.ndarray  # (2,)
    circle: float | None  # the workspace boundary's radius (planar), or None
    arms: np.ndarray  # (S+1, K, 3) uint8 each sample's colour at each state (the viewer's)
    trail: np.ndarray  # (S+1, K, 3) uint8 each sample's trail colour at each state
    highlight: int  # the sample followed
    follows_one: bool  # only the followed sample's trail is drawn (the default picture)
    labels: np.ndarray  # (S+1,) diffusion time of each state
    offsets: np.ndarray  # (S+1,) seconds from state 0 at which each state shows (clock.py)
    title: str  # what was solved
    legend: tuple  # legend.Entry of what each colour means

    @property
    def num_states(self) -> int:
        return self.polylines.shape[0]


def drawing(solved, polylines, target, *, circle, highlight: int, trail_of: str, arms, offsets, title, legend):
    """A Drawing of `solved` with the viewer's colours: `arms` (S+1, K, 3), the trail ramp from `trail_of`."""
    view = solved.view
    _, trail = emphasis_colors(view.num_states, view.num_samples, highlight, trail_of)
    points = np.concatenate([np.asarray(polylines).reshape(-1, 2), np.asarray(target)[None, :2]])
    low, high = points.min(axis=0), points.max(axis=0)
    if circle is not None:
        low, high = np.minimum(low, -circle), np.maximum(high, circle)
    center = (low + high) / 2
    return Drawing(
        polylines=np.asarray(polylines), target=np.asarray(target)[:2], half_width=1.05 * float(np.max(high - low)) / 2,
        center=center, circle=circle, arms=arms, trail=trail, highlight=highlight, follows_one=follows_one(trail_of),
        labels=view.labels, offsets=np.asarray(offsets), title=title, legend=tuple(legend),
    )  # fmt: skip


def _figure(picture: Drawing, size_pixels: int, band: int = 0):
    """A figure `size_pixels` square for the picture and `band` pixels above it (free for a title)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    dpi = 100
    figure = Figure(figsize=(size_pixels / dpi, (size_pixels + band) / dpi), dpi=dpi)
    axes = figure.add_axes((0, 0, 1, size_pixels / (size_pixels + band)))
    (cx, cy), half = picture.center, picture.half_width
    axes.set_xlim(cx - half, cx + half)
    axes.set_ylim(cy - half, cy + half)
    axes.set_aspect("equal")
    axes.axis("off")
    if picture.circle is not None:
        axes.add_patch(Circle((0, 0), picture.circle, fill=False, color="#969696", linewidth=0.8))
    return figure, axes


def _draw_state(axes, picture: Drawing, state: int, *, trail: bool) -> None:
    """The trail up to `state` (the viewer's ramp; the followed sample's alone by default) and the arms at `state`."""
    num_samples = picture.polylines.shape[1]
    trail_samples = [picture.highlight] if picture.follows_one else range(num_samples)
    if trail:
        for shown in range(state):
            for sample in trail_samples:
                joints = picture.polylines[shown, sample]  # (P, 2)
                axes.plot(joints[:, 0], joints[:, 1], color=picture.trail[shown, sample] / 255, linewidth=0.5,
                          zorder=shown)  # fmt: skip
    top = picture.num_states
    for sample in range(num_samples):
        if sample != picture.highlight:
            joints = picture.polylines[state, sample]
            axes.plot(joints[:, 0], joints[:, 1], color=picture.arms[state, sample] / 255, linewidth=1.5, zorder=top)
    chosen = picture.polylines[state, picture.highlight]
    color = picture.arms[state, picture.highlight] / 255
    axes.plot(chosen[:, 0], chosen[:, 1], color=color, linewidth=2.5, marker="o", markersize=3, zorder=top + 1)
    axes.plot(*picture.target, marker="x", color=TARGET_RED, markersize=12, mew=3, zorder=top + 2)


def write_trail_png(picture: Drawing, path: Path, *, size_pixels: int = 800) -> Path:
    """The paper's Fig. "vis" as the viewer draws it at t = 0, with the legend, under a band with the title:
    `size_pixels` square for the picture, `TITLE_BAND` pixels more on top
    (a title inside it ran over the reach circle)."""
    figure, axes = _figure(picture, size_pixels, band=TITLE_BAND)
    _draw_state(axes, picture, picture.num_states - 1, trail=True)
    figure.text(0.02, 1 - 0.5 * TITLE_BAND / (size_pixels + TITLE_BAND), picture.title, ha="left", va="center",
                fontsize=11)  # fmt: skip
    handles = [_legend_handle(entry) for entry in picture.legend]
    axes.legend(handles=handles, loc="lower left", fontsize=7, frameon=True, framealpha=0.85)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    return path


def _legend_handle(entry):
    from matplotlib.lines import Line2D

    marker = {"dot": "o", "cross": "x"}.get(entry.swatch.shape)
    color = np.array(entry.swatch.color) / 255
    if marker is not None:
        return Line2D([], [], color=color, marker=marker, linestyle="none", label=entry.text)
    return Line2D([], [], color=color, linewidth=2.5, label=entry.text)


def gif_states(offsets: np.ndarray, seconds: float, max_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(states, durations in s) of a GIF on the viewer's clock: frames evenly spaced in time, each the state the
    clock has reached then; a state reached by several frames shows once, for their time together."""
    times = np.linspace(0.0, seconds, max_frames, endpoint=False)
    reached = np.clip(np.searchsorted(offsets, times, side="right") - 1, 0, len(offsets) - 1)
    states, first = np.unique(reached, return_index=True)
    ends = np.append(times[first[1:]], seconds)
    durations = ends - times[first]
    states = np.append(states, len(offsets) - 1) if states[-1] != len(offsets) - 1 else states
    durations = np.append(durations, 1.0) if len(durations) < len(states) else durations
    return states, durations


def write_gif(picture: Drawing, path: Path, *, seconds: float = 4.0, size_pixels: int = 480, max_frames: int = 41,
              progress=None) -> Path:  # fmt: skip
    """The denoising from t = T to 0 as a looping GIF of at most `max_frames` frames over `seconds`, on the viewer's
    clock. Each frame says its diffusion time `t` (top left). `progress(done, total)`, if given, is called after each
    frame is drawn: the panel shows it while a long GIF renders."""
    import imageio.v2 as imageio
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if seconds <= 0 or max_frames < 2:
        raise ValueError(f"seconds, max_frames: expected > 0 and >= 2, got {seconds}, {max_frames}")
    states, durations = gif_states(picture.offsets, seconds, max_frames)
    frames = []
    for state in states:
        figure, axes = _figure(picture, size_pixels)
        _draw_state(axes, picture, int(state), trail=False)
        axes.text(0.03, 0.97, time_label(picture, int(state)), transform=axes.transAxes, ha="left", va="top",
                  fontsize=16)  # fmt: skip
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        frames.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())
        if progress is not None:
            progress(len(frames), len(states))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(path, frames, duration=[1000 * float(value) for value in durations], loop=0)
    return path


def time_label(picture, state: int) -> str:
    """What a GIF frame says: its diffusion time, t = T for pure noise down to t = 0."""
    return f"t = {picture.labels[state]:g}"
