"""Drawable arrays of the joint-space view: a flat square beside the workspace that shows two joints' torus.

No viser here (joint_space_nodes.py copies these into handles). Angles in [-pi, pi)
map linearly onto the square, first joint along +x and second along +y, so the
square's opposite edges are the same points: a segment that would cross the seam
is cut there instead of being drawn across the whole square.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ikdp_viz.joint_space import wrap_to_square

GAP = 0.2  # between the workspace's outer circle and the square, in units of the reach
SIDE = 1.8  # the square's side, in units of the reach
ARROW_CELL_FILL = 0.9  # an arrow of length pi (the farthest x̂0 can be on one joint) spans this much of a cell
ARROW_HEAD = 0.3  # head length as a share of the drawn arrow
ARROW_HEAD_ANGLE = math.radians(25.0)
ARROW_MIN_HEAD = 0.08  # head length floor, in cells, so that short arrows still show their direction
CROSS_CELLS = 0.035  # half the arms of a solution's cross, as a share of the side


@dataclass(frozen=True)
class Square:
    """Where the joint-space square lies in the scene: centre (x, y), side, and the height it is drawn at."""

    centre: tuple[float, float]
    side: float
    z: float

    def place(self, angles, lift: float = 0.0) -> np.ndarray:
        """Angles (..., 2) in radians -> scene points (..., 3); wrapped first, so any angle lands in the square."""
        unit = (wrap_to_square(angles) + math.pi) / (2 * math.pi) - 0.5  # (..., 2) in [-0.5, 0.5)
        xy = np.asarray(self.centre) + unit * self.side
        return np.concatenate((xy, np.full(xy.shape[:-1] + (1,), self.z + lift)), axis=-1)

    def scale(self) -> float:
        """Scene length of one radian."""
        return self.side / (2 * math.pi)


def square_beside(reach: float, clear_of: float | None = None) -> Square:
    """The square to the right of a workspace of radius `reach` (the base at the origin), level with it; with
    `clear_of`, its left edge past x = clear_of too (the ground grid's edge: a square over the grid is hard to read)."""
    left = (1 + GAP) * reach if clear_of is None else max((1 + GAP) * reach, clear_of + 0.5 * GAP * reach)
    return Square(centre=(left + SIDE / 2 * reach, 0.0), side=SIDE * reach, z=0.0)


def camera_over_both(reach: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera above the workspace and the square together, as camera_fit frames one."""
    left, right = -reach, (1 + GAP + SIDE) * reach
    half, middle = (right - left) / 2, (right + left) / 2
    distance = 1.55 * half  # camera.camera_fit's framing of a radius-`half` disc
    return (middle, -1e-3 * distance, distance), (middle, 0.0, 0.0)


def frame_segments(square: Square) -> tuple[np.ndarray, np.ndarray]:
    """The square's border and its lines at multiples of pi/2, (M, 2, 3); and which are the border or zero (M,)."""
    ticks = np.array([-math.pi, -math.pi / 2, 0.0, math.pi / 2, math.pi])
    ends = np.array([-math.pi, math.pi])
    segments, strong = [], []
    for tick in ticks:
        for line in ((np.full(2, tick), ends), (ends, np.full(2, tick))):
            angles = np.stack(line, axis=-1)  # (2, 2): the line's two ends
            unit = (angles + math.pi) / (2 * math.pi) - 0.5  # no wrap: pi is the far edge here
            xy = np.asarray(square.centre) + unit * square.side
            segments.append(np.concatenate((xy, np.full((2, 1), square.z)), axis=-1))
            strong.append(tick in (-math.pi, 0.0, math.pi))
    return np.stack(segments), np.array(strong)


def arrow_segments(square: Square, starts: np.ndarray, arrows: np.ndarray, count: int, lift: float) -> np.ndarray:
    """Short arrows from `starts` (M, 2) along `arrows` (M, 2), radians, as shaft and two head strokes (3M, 2, 3).

    Lengths are to scale with one another: an arrow of length pi fills ARROW_CELL_FILL of a grid cell
    of a count x count grid, and none is drawn longer than a cell, so arrows never cross.
    """
    cell = 2 * math.pi / count
    drawn = np.asarray(arrows, dtype=np.float64) * (ARROW_CELL_FILL * cell / math.pi)  # (M, 2) radians
    length = np.linalg.norm(drawn, axis=-1, keepdims=True)
    drawn = np.where(length > cell, drawn * cell / np.maximum(length, 1e-12), drawn)
    length = np.minimum(length, cell)
    base = square.place(starts)[:, :2]
    tip = base + drawn * square.scale()  # not wrapped: the arrow's tip may reach a little past the edge
    direction = drawn / np.maximum(length, 1e-12)  # (M, 2)
    head = np.maximum(ARROW_HEAD * length, ARROW_MIN_HEAD * cell) * square.scale()  # (M, 1)
    strokes = []
    for side in (1.0, -1.0):
        cos, sin = math.cos(ARROW_HEAD_ANGLE), side * math.sin(ARROW_HEAD_ANGLE)
        turned = (cos * direction[:, 0] - sin * direction[:, 1], sin * direction[:, 0] + cos * direction[:, 1])
        back = -np.stack(turned, axis=-1)  # the arrow's direction turned by +-ARROW_HEAD_ANGLE, reversed
        strokes.append(np.stack((tip, tip + head * back), axis=1))
    shafts = np.stack((base, tip), axis=1)  # (M, 2, 2)
    segments = np.stack((shafts, *strokes), axis=1).reshape(-1, 2, 2)  # per arrow: shaft, head, head
    return np.concatenate((segments, np.full(segments.shape[:-1] + (1,), square.z + lift)), axis=-1)


def cross_segments(square: Square, points: np.ndarray, lift: float) -> np.ndarray:
    """A diagonal cross on each point (P, 2) radians, (2P, 2, 3): the target's mark, in joint space."""
    centres = square.place(np.asarray(points, dtype=np.float64).reshape(-1, 2), lift)  # (P, 3)
    arm = CROSS_CELLS * square.side
    strokes = [np.stack((centres - offset, centres + offset), axis=1) for offset in ((arm, arm, 0), (arm, -arm, 0))]
    segments = np.stack(strokes, axis=1).reshape(-1, 2, 3)
    (cx, cy), half = square.centre, square.side / 2  # a cross on an edge is cut there, not spilled outside
    segments[..., 0] = np.clip(segments[..., 0], cx - half, cx + half)
    segments[..., 1] = np.clip(segments[..., 1], cy - half, cy + half)
    return segments


def curve_segments(square: Square, curve: np.ndarray, lift: float) -> np.ndarray:
    """A closed curve of angles (C, 2) as segments (M, 2, 3), cut where it crosses the square's seam."""
    curve = wrap_to_square(curve)
    following = np.roll(curve, -1, axis=0)
    jumps = np.abs(following - curve).max(axis=-1) > math.pi  # the next point is across an edge
    ends = np.stack((curve, following), axis=1)[~jumps]  # (M, 2, 2)
    return square.place(ends, lift)


def link_headings(joints: np.ndarray) -> np.ndarray:
    """Joint positions (..., N+1, 2), base first -> the absolute heading of each link, (..., N)."""
    bones = np.diff(np.asarray(joints, dtype=np.float64), axis=-2)
    return np.arctan2(bones[..., 1], bones[..., 0])


def model_timestep(labels: np.ndarray, state: int) -> int:
    """The 0-based timestep the denoiser is called at on state `state`: the call that makes the next state.

    labels (S+1,) are scene.state_labels: state s < S was reached at diffusion time labels[s], and the
    sampler's step from it runs the denoiser at labels[s] - 1. The final state shows the last call's field.
    """
    last_call = len(labels) - 2
    return int(labels[min(state, last_call)]) - 1
