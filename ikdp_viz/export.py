"""A solve on screen, written to files for a slide: the denoising as a GIF and the paper-style trail figure as a PNG.

Drawn with matplotlib (Agg) from the same arrays the viewer draws (`scene.SolveView`),
so no browser is needed. No viser here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ikdp_viz.scene import ACCENT_DARK, SolveView, sample_colors

TARGET_RED = "#dc1919"


def _figure(view: SolveView, size_pixels: int):
    from matplotlib.figure import Figure

    dpi = 100
    figure = Figure(figsize=(size_pixels / dpi, size_pixels / dpi), dpi=dpi)
    axes = figure.add_axes((0, 0, 1, 1))
    reach = float(np.sum(view.lengths))
    axes.set_xlim(-1.05 * reach, 1.05 * reach)
    axes.set_ylim(-1.05 * reach, 1.05 * reach)
    axes.set_aspect("equal")
    axes.axis("off")
    axes.add_patch(_circle(reach))
    return figure, axes


def _circle(radius: float):
    from matplotlib.patches import Circle

    return Circle((0, 0), radius, fill=False, color="#969696", linewidth=0.8)


def _draw_state(axes, view: SolveView, state: int, highlight: int, *, trail: bool) -> None:
    """The trail up to `state` (faint to dark, per the viewer's ramp) and the arms at `state`."""
    colors = sample_colors(view.num_states, view.num_samples, highlight) / 255.0  # (S+1, K, 3)
    first = 0 if trail else state
    for shown in range(first, state + 1):
        width = 2.0 if shown == state else 0.5
        for sample in range(view.num_samples):
            joints = view.joints[shown, sample]  # (N+1, 2)
            axes.plot(joints[:, 0], joints[:, 1], color=colors[shown, sample], linewidth=width, zorder=shown)
    chosen = view.joints[state, highlight]
    axes.plot(chosen[:, 0], chosen[:, 1], color=np.array(ACCENT_DARK) / 255, linewidth=2.5, zorder=view.num_states + 1)
    axes.plot(*view.target, marker="x", color=TARGET_RED, markersize=12, mew=3, zorder=view.num_states + 2)


def write_trail_png(view: SolveView, path: Path, highlight: int, *, size_pixels: int = 800) -> Path:
    """The paper's Fig. "vis": every state of every sample, faint (t = T) to dark (t = 0), the final poses solid."""
    figure, axes = _figure(view, size_pixels)
    _draw_state(axes, view, view.num_states - 1, highlight, trail=True)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    return path


def write_gif(
    view: SolveView,
    path: Path,
    highlight: int,
    *,
    seconds: float = 4.0,
    size_pixels: int = 480,
    max_frames: int = 41,
    progress=None,
) -> Path:
    """The denoising from t = T to 0 as a looping GIF of at most `max_frames` frames over `seconds`.

    Each frame says its diffusion time `t` (top left). `progress(done, total)`, if given, is called
    after each frame is drawn: the panel shows it while a long GIF renders.
    """
    import imageio.v2 as imageio
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if seconds <= 0 or max_frames < 2:
        raise ValueError(f"seconds, max_frames: expected > 0 and >= 2, got {seconds}, {max_frames}")
    states = np.unique(np.linspace(0, view.num_states - 1, min(max_frames, view.num_states)).round().astype(int))
    frames = []
    for state in states:
        figure, axes = _figure(view, size_pixels)
        _draw_state(axes, view, int(state), highlight, trail=False)
        axes.text(0.03, 0.97, time_label(view, int(state)), transform=axes.transAxes, ha="left", va="top", fontsize=16)
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        frames.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())
        if progress is not None:
            progress(len(frames), len(states))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(path, frames, duration=1000 * seconds / len(frames), loop=0)
    return path


def time_label(view: SolveView, state: int) -> str:
    """What a GIF frame says: its diffusion time, t = T for pure noise down to t = 0."""
    return f"t = {view.labels[state]:g}"
