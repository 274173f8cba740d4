"""The viewer's shared colours and line widths (RGB 0..255, screen pixels): one place for what both arms draw."""

from __future__ import annotations

from dataclasses import dataclass
from html import escape

import numpy as np

TARGET_RED = (220, 25, 25)
GRID_CELL = (236, 236, 236)  # grid lines every half bone length (a robot: every cell)
GRID_SECTION = (212, 212, 212)  # grid lines every mean bone length (a robot: every fifth cell)
ESTIMATE = (150, 80, 200)  # the denoiser's x̂0, ghosted
PRIOR = (150, 100, 50)  # poses drawn from the training prior
LINE_PIXELS = 1.5  # trail line thickness, screen pixels
ARM_PIXELS = 5.0  # the K arms' links, screen pixels (the joints' spheres are about twice as wide at the default zoom)
OBSTACLE = (190, 30, 150)  # magenta: an obstacle dropped on the arm stays apart from the red of a failing pose
COMPARE_STROKE = "#2a9d5c"  # the chart's line of the compared sampler


# What the two arm views (planar_view.py, robot_view.py) do alike, as functions of their nodes: no base class.
def start_rebuild(view, solver, target) -> None:
    """Before an arm view builds its nodes for `solver`: the old samples, prior draw and static nodes go."""
    view.remove_samples()
    view.clear_prior()
    for handle in view._static_nodes:
        handle.remove()
    view._static_nodes = []
    view.solver, view.target = solver, np.asarray(target, dtype=np.float64)


def prior_lines(server, segments: np.ndarray, old=None):
    """The prior's draw, (M, 2, 3) segments in brown until the next solve, replacing `old`'s node."""
    if old is not None:
        old.remove()
    return server.scene.add_line_segments(
        "/prior", segments, colors=PRIOR, thickness=2 * LINE_PIXELS, thickness_units="screen"
    )


def removed(handle) -> None:
    """Remove `handle` if there is one; None, for the attribute that held it."""
    if handle is not None:
        handle.remove()


# The panel's legend: one line per colour in the scene, its swatch drawn in that colour (HTML, no viser here).
@dataclass(frozen=True)
class Swatch:
    """How an entry looks: a line, a dot or a cross of one colour, or a line from `faint` to `color` (a ramp)."""

    color: tuple[int, int, int]
    shape: str = "line"  # line, dot or cross
    faint: tuple[int, int, int] | None = None  # a ramp from this colour (t = T) to `color` (t = 0)


@dataclass(frozen=True)
class Entry:
    swatch: Swatch
    text: str  # what the colour means, plain text
    flat: bool = False  # the flat picture of a solve (downloads.py's PNG) draws it too, so its legend lists it


def css(color: tuple[int, int, int]) -> str:
    if len(color) != 3 or not all(0 <= int(channel) <= 255 for channel in color):
        raise ValueError(f"color: expected three channels 0..255, got {color!r}")
    return "rgb({}, {}, {})".format(*(int(channel) for channel in color))


def swatch_html(swatch: Swatch) -> str:
    if swatch.shape not in {"line", "dot", "cross"}:
        raise ValueError(f"swatch.shape: expected line, dot or cross, got {swatch.shape!r}")
    box = "display:inline-block;vertical-align:middle;margin-right:6px;"
    if swatch.shape == "dot":  # one marker; with `faint`, its two halves the colours it takes at t = T and t = 0
        fill = css(swatch.color)
        if swatch.faint is not None:
            fill = f"linear-gradient(to right, {css(swatch.faint)} 50%, {css(swatch.color)} 50%)"
        return f'<span style="{box}width:10px;height:10px;border-radius:50%;background:{fill}"></span>'
    if swatch.shape == "cross":
        return f'<span style="{box}width:10px;text-align:center;font-weight:700;color:{css(swatch.color)}">✕</span>'
    fill = css(swatch.color)
    if swatch.faint is not None:
        fill = f"linear-gradient(to right, {css(swatch.faint)}, {css(swatch.color)})"
    return f'<span style="{box}width:22px;height:4px;border-radius:2px;background:{fill}"></span>'


def legend_html(entries: list[Entry]) -> str:
    """One line per entry, swatch then text, in the panel's small font."""
    lines = [f'<div style="margin:1px 0">{swatch_html(entry.swatch)}{escape(entry.text)}</div>' for entry in entries]
    return '<div style="font-size:0.8em;line-height:1.45">' + "".join(lines) + "</div>"
