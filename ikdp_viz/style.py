"""The viewer's shared colours and line widths (RGB 0..255, screen pixels): one place for what both arms draw."""

from __future__ import annotations

from dataclasses import dataclass
from html import escape

import numpy as np

TARGET_RED = (220, 25, 25)
GRID_CELL = (236, 236, 236)  # a robot's grid lines every cell
GRID_SECTION = (212, 212, 212)  # a planar arm's grid lines every mean bone length; a robot's every fifth cell
ESTIMATE = (150, 80, 200)  # the denoiser's x̂0, ghosted
PRIOR = (150, 100, 50)  # poses drawn from the training prior
LINE_PIXELS = 1.5  # trail line thickness, screen pixels
ARM_PIXELS = 5.0  # the K arms' links, screen pixels (the joints' spheres are about twice as wide at the default zoom)
OBSTACLE = (190, 30, 150)  # magenta: an obstacle dropped on the arm stays apart from the red of a failing pose
COMPARE_STROKE = "#2a9d5c"  # the chart's line of the compared sampler
TARGET_RED_HEX = "#{:02x}{:02x}{:02x}".format(*TARGET_RED)  # the same red in the exported picture's matplotlib
HOLDS = (40, 170, 80)  # a state whose pose meets the constraints
VIOLATES = (215, 50, 40)  # one that does not
HOLDS_OTHERS = (110, 200, 130)  # the samples not highlighted: the same two hues, lighter, so the highlighted one
# still stands out among K = 16
VIOLATES_OTHERS = (235, 120, 105)
HOLDS_FAINT = (190, 230, 197)  # the kept sample's past states: fainter still, a history under the step shown
VIOLATES_FAINT = (247, 195, 187)
FREE_AXIS_COLOR = (235, 140, 0)  # the free axis through the target: amber, none of the gizmo's red, green, blue
FRAME_STRONG = (140, 140, 140)  # the border and the zero lines
FRAME_WEAK = (196, 196, 196)  # the lines at +-pi/2
ARROW = (185, 150, 215)  # the denoiser's arrows: a light shade of the x̂0 ghost's purple
SOLUTION = (220, 25, 25)  # the target's red: the exact solution set (N = 2)
BACKING = (255, 255, 255)
FAINT = (226, 226, 226)  # pure noise, t = T: the paper's lightest lines
DARK = (28, 28, 28)  # the final pose, t = 0
ACCENT_FAINT = (205, 222, 245)  # the highlighted sample at t = T
ACCENT_DARK = (20, 90, 210)  # the highlighted sample at t = 0
TIP_FAINT = (248, 222, 190)  # tip markers at t = T
TIP_DARK = (235, 120, 10)  # tip markers at t = 0
REFINED = (0, 150, 190)  # the damped-least-squares polish of the final pose: teal, not the green of "constraints hold"
OTHERS_FINAL = (185, 185, 185)  # the samples not highlighted at t = 0, with the trail of the highlighted one only
# The followed trail's noisy end: nearly the page's white. Its first states are random poses over half the
# workspace; at the accent's own faint blue they were a pale tangle that read as more samples, while this
# leaves the last states, where the pose forms, to stand out from the grey final samples.
TRAIL_FAINT = (236, 242, 251)
TRAIL_GAMMA = 3.0  # and it darkens later than the arms' ramp: the pale noisy half recedes behind the grey finals
GHOST_FAINT = (238, 238, 238)  # the robots' meshes at t = T
GHOST_DARK = (120, 120, 120)  # and at t = 0
JOINT_SPACE_DOT = (60, 60, 60)  # the joint-space view's dots of the other samples: dark at every step
REACH_RING = (150, 150, 150)  # the planar reach circle, here and beside
BASE = (90, 90, 90)  # the planar base
HAND_RED = (220, 40, 40)  # the x axis of the highlighted robot's hand frame
CHART_MEDIAN = "#999999"  # the chart's lines: the median sample, the highlighted one, the step shown
CHART_HIGHLIGHTED = "#1f5ad2"
CHART_NOW = "#eb780a"
REACH_RING_HEX = "#{:02x}{:02x}{:02x}".format(*REACH_RING)  # the exported picture's reach circle
FRAME_Y_GREEN = (0, 204, 0)  # viser's frame axes: x 0xcc0000, y 0x00cc00, z 0x0000cc (its client's own colours)
HIGHLIGHTED_ROBOT = (40, 110, 235)  # the followed sample's opaque robot: a lighter blue than the lines, as shading


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
