"""Drawable arrays from one solve: polylines, colours from faint to dark, link and joint placements.

No viser here. The viewer (app.py) only copies these arrays into scene handles,
so everything it draws is built, and tested, as plain numpy. All geometry lies
in the arm's plane, z = 0, with the base at the origin.

A solve's trajectory has S+1 *states*: state 0 is pure noise (t = T), state S
the sampler's final pose (t = 0). Poses are drawn as the paper's Fig. "vis" draws
them: state 0 faintest, state S darkest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ikdp import SolveResult, forward_kinematics
from ikdp_viz.style import ACCENT_DARK, ACCENT_FAINT, DARK, FAINT, OTHERS_FINAL, TRAIL_FAINT, TRAIL_GAMMA

FADE_GAMMA = 2.0  # how late the lines darken: weight of DARK at state s is (s / S) ** FADE_GAMMA
ERROR_FLOOR = 1e-6  # tip errors below this are charted at it (log10 of 0 is -inf)
# Heights above the plane, in joint radii, that set what a top-down view draws on top of what: the
# K arms over the trail, the refined poses over the arms, the highlighted arm over them, the target's
# cross over everything.
ARM_LIFT = 0.25
REFINED_LIFT = 1.0
HIGHLIGHT_LIFT = 2.0
TARGET_LIFT = 4.0
LAYER_HEIGHT = 1e-4  # z step between consecutive states, so later (darker) lines draw over earlier ones


def line_colors(colors: np.ndarray) -> np.ndarray:
    """sRGB colours (..., 3) uint8 -> what viser's line segments must be sent to show them.

    The page takes a line's vertex colours as linear and encodes its output as sRGB, so a
    colour sent as is shows lighter (DARK, 28, drew as 92), while meshes and dots show theirs
    as sent: the arms' links would not match their joints.
    """
    unit = np.asarray(colors, dtype=np.float64) / 255.0
    linear = np.where(unit <= 0.04045, unit / 12.92, ((unit + 0.055) / 1.055) ** 2.4)
    return np.rint(255.0 * linear).astype(np.uint8)


def fade_colors(count: int, faint=FAINT, dark=DARK, *, gamma: float = FADE_GAMMA) -> np.ndarray:
    """(count, 3) uint8 colours from `faint` (index 0) to `dark` (last index).

    The weight of `dark` is (i / (count-1)) ** gamma: with gamma > 1 the many noisy
    states stay faint and the last steps darken fast, as in the paper's figure. Every
    channel moves monotonically, so each colour is at least as dark as the one before.
    One colour alone is `dark`: a single state is a final pose.
    """
    if count < 1:
        raise ValueError(f"count: expected a positive number of colours, got {count}")
    weights = np.linspace(0.0, 1.0, count) ** gamma if count > 1 else np.ones(1)
    faint, dark = np.asarray(faint, dtype=np.float64), np.asarray(dark, dtype=np.float64)
    return np.rint(faint + weights[:, None] * (dark - faint)).astype(np.uint8)


def clamp_to_workspace(point, inner: float, outer: float) -> tuple[np.ndarray, bool]:
    """The nearest point of the annulus inner <= |p| <= outer to `point` (2,), and whether it moved."""
    point = np.asarray(point, dtype=np.float64).reshape(-1)[:2]
    if point.shape != (2,) or not np.isfinite(point).all():
        raise ValueError(f"point: expected two finite numbers, got {point.tolist()}")
    radius = float(np.hypot(*point))
    if inner <= radius <= outer:
        return point, False
    direction = point / radius if radius > 0 else np.array([1.0, 0.0])
    return direction * (outer if radius > outer else inner), True


def state_labels(timesteps: list[int]) -> np.ndarray:
    """Diffusion time of each of the S+1 states, (S+1,) int: T for pure noise down to 0 for the final pose.

    `timesteps` are the sampler's 0-based steps, noisiest first (T-1, ..., 0 for DDPM). The step
    at t lands on noise level t-1 (DDPM) or on the next visited level (DDIM); in the paper's
    1-based time both read "the state after stepping at t_k is x at t_{k+1} + 1", and the last is x_0.
    """
    return np.array([t + 1 for t in timesteps] + [0], dtype=np.int64)


def nearest_state(labels: np.ndarray, t: float) -> int:
    """Index of the state whose diffusion time is closest to t (the noisier one on a tie)."""
    return int(np.argmin(np.abs(np.asarray(labels, dtype=np.float64) - t)))


@dataclass(frozen=True)
class SolveView:
    """Everything the viewer draws for one solve of one target."""

    target: np.ndarray  # (2,) the target the arm was asked to reach
    lengths: np.ndarray  # (N,) bone lengths
    labels: np.ndarray  # (S+1,) diffusion time of each state, T (pure noise) down to 0
    joints: np.ndarray  # (S+1, K, N+1, 2) every joint of every sample at every state, base first
    tip_error: np.ndarray  # (S+1, K) distance from each state's tip to the target
    final_joints: np.ndarray  # (K, N+1, 2) the pose the solver returned (refined when `refined`)
    final_tip_error: np.ndarray  # (K,) the solver's tip error of that pose
    refined: bool  # final_joints is the damped-least-squares polish of joints[-1]
    estimate_joints: np.ndarray | None = None  # (S, K, N+1, 2) the denoiser's x̂0 at the step into state s+1

    def estimate_at(self, state: int) -> np.ndarray | None:
        """(K, N+1, 2) what the denoiser believed the final pose to be when it made state `state`; None at t = T (no
        guess made yet) and at t = 0, where the guess is the final pose itself and would hide under it, unseen."""
        if self.estimate_joints is None or state < 1 or state >= self.num_states - 1:
            return None
        return self.estimate_joints[state - 1]

    @property
    def num_states(self) -> int:
        return self.joints.shape[0]

    @property
    def num_samples(self) -> int:
        return self.joints.shape[1]

    @property
    def num_links(self) -> int:
        return self.joints.shape[2] - 1

    @property
    def final_error(self) -> np.ndarray:
        """(K,) how far each returned pose lands: its tip error (the robot view adds the rotation)."""
        return self.final_tip_error

    def best_sample(self) -> int:
        """The sample whose returned pose lands closest to the target."""
        return int(np.argmin(self.final_error))


def build_view(result: SolveResult, lengths, target) -> SolveView:
    """The drawable arrays of the first target of a `solver.solve(..., return_trajectory=True)` result.

    With `return_estimates=True` too, the view holds the joints of each step's x̂0.
    """
    if result.trajectory is None:
        raise ValueError("result: solve with return_trajectory=True, the viewer draws every state")
    lengths = torch.as_tensor(lengths, dtype=torch.float64)
    target = np.asarray(target, dtype=np.float64).reshape(2)
    trajectory = result.trajectory[:, 0].detach().cpu().double()  # (S+1, K, N)
    joints = forward_kinematics(trajectory, lengths).numpy()  # (S+1, K, N+1, 2)
    estimates = None if result.estimates is None else result.estimates[:, 0].detach().cpu().double()  # (S, K, N)
    final_joints = forward_kinematics(result.angles[0].detach().cpu().double(), lengths).numpy()  # (K, N+1, 2)
    return SolveView(
        target=target,
        lengths=lengths.numpy(),
        labels=state_labels(result.timesteps),
        joints=joints,
        tip_error=np.linalg.norm(joints[:, :, -1] - target, axis=-1),
        final_joints=final_joints,
        final_tip_error=result.tip_error[0].detach().cpu().double().numpy(),
        refined=not torch.equal(result.angles, result.raw_angles),
        estimate_joints=None if estimates is None else forward_kinematics(estimates, lengths).numpy(),
    )


def sample_colors(num_states: int, num_samples: int, highlight: int | None) -> np.ndarray:
    """(S+1, K, 3) uint8: the faint-to-dark ramp per state, the accent ramp for the highlighted sample."""
    colors = np.repeat(fade_colors(num_states)[:, None], num_samples, axis=1)
    if highlight is not None:
        colors[:, highlight] = fade_colors(num_states, ACCENT_FAINT, ACCENT_DARK)
    return colors


def polyline_segments(joints: np.ndarray, z: float = 0.0) -> np.ndarray:
    """Polylines (..., P, 2) -> their segments (M, 2, 3) in order, M = prod(...) * (P-1), at height z."""
    joints = np.asarray(joints)
    ends = np.stack((joints[..., :-1, :], joints[..., 1:, :]), axis=-2)  # (..., P-1, 2, 2)
    heights = np.full(ends.shape[:-1] + (1,), z, dtype=ends.dtype)
    return np.concatenate((ends, heights), axis=-1).reshape(-1, 2, 3)


def trail_points(joints: np.ndarray) -> np.ndarray:
    """Every state's K polylines as segments, (S+1, K*N, 2, 3) float32; state s lies at z = s * LAYER_HEIGHT."""
    num_states = joints.shape[0]
    per_state = [polyline_segments(joints[state], z=state * LAYER_HEIGHT) for state in range(num_states)]
    return np.stack(per_state).astype(np.float32)


def trail_colors(colors: np.ndarray, num_links: int) -> np.ndarray:
    """Per-sample colours (S+1, K, 3) -> one per segment end, (S+1, K*N, 2, 3) matching `trail_points`."""
    num_states, num_samples, _ = colors.shape
    per_segment = np.broadcast_to(colors[:, :, None, None, :], (num_states, num_samples, num_links, 2, 3))
    return per_segment.reshape(num_states, num_samples * num_links, 2, 3)


def trail_until(
    points: np.ndarray, colors: np.ndarray, state: int, *, most_states: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The polylines of states 0..state, the current pose's included, as (M, 2, 3) segments and colours.

    With `most_states`, the light trail drawn while an animation plays: of all S + 1 states only
    every s-th (a fixed grid, so drawn lines stay put from frame to frame) and the current one,
    at most `most_states` in all. Software WebGL pays for every segment in every frame.
    """
    if most_states is None:
        return points[: state + 1].reshape(-1, 2, 3), colors[: state + 1].reshape(-1, 2, 3)
    stride = -(-len(points) // (most_states - 1))  # ceil: the whole trail's grid fits most_states - 1
    chosen = np.append(np.arange(0, state, stride), state)
    return points[chosen].reshape(-1, 2, 3), colors[chosen].reshape(-1, 2, 3)


@dataclass(frozen=True)
class ArmPlacement:
    """K arms drawn as the paper's figure draws them: each link a line segment, a small sphere on each joint and tip.

    Lines, not lit cylinders: software WebGL spends on each triangle, and K = 16 capsule arms
    (11,800 triangles) cost the page more than everything else in the scene (docs/viewer.md).
    """

    link_segments: np.ndarray  # (K*N, 2, 3) each bone's start and end
    joint_positions: np.ndarray  # (K*(N+1), 3) base, joints and tip of each arm
    tip_positions: np.ndarray  # (K, 3)


def arm_placement(
    joints: np.ndarray, *, height: float = 0.0, raised: int | None = None, lift: float = 0.0
) -> ArmPlacement:
    """K arms of joints (K, N+1, 2) at `height` above the plane; the `raised` sample at `lift`, to draw on top."""
    joints = np.asarray(joints, dtype=np.float64)
    num_samples, num_points, _ = joints.shape
    heights = np.full((num_samples, 1, 1), height)
    if raised is not None:
        heights[raised] = lift
    points = np.concatenate((joints, np.broadcast_to(heights, (num_samples, num_points, 1))), -1)
    segments = np.stack((points[:, :-1], points[:, 1:]), axis=2)  # (K, N, 2, 3)
    return ArmPlacement(
        link_segments=segments.reshape(-1, 2, 3),
        joint_positions=points.reshape(-1, 3),
        tip_positions=points[:, -1],
    )


def grid_segments(half_width: float, cell: float, section: float, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A square grid of lines |x|, |y| <= half_width as segments (M, 2, 3), and whether each is a section line (M,).

    Lines every `cell`; those on a multiple of `section` are section lines. Drawn as line segments:
    viser's own grid is a full-screen shader that software WebGL renders at a few frames a second.
    """
    count = int(round(half_width / cell))
    offsets = cell * np.arange(-count, count + 1)  # (2*count+1,)
    ends = np.full_like(offsets, half_width)
    vertical = np.stack((np.stack((offsets, -ends), -1), np.stack((offsets, ends), -1)), axis=1)  # (L, 2, 2)
    horizontal = vertical[..., ::-1]
    segments = np.concatenate((vertical, horizontal))
    points = np.concatenate((segments, np.full(segments.shape[:-1] + (1,), z)), axis=-1)
    ratio = np.concatenate((offsets, offsets)) / section
    return points, np.isclose(ratio, np.round(ratio))


def circle_segments(radius: float, count: int = 256, z: float = 0.0) -> np.ndarray:
    """A circle about the origin as `count` segments, (count, 2, 3)."""
    angles = np.linspace(0.0, 2 * np.pi, count + 1)
    ring = radius * np.stack((np.cos(angles), np.sin(angles)), axis=-1)  # (count+1, 2)
    return polyline_segments(ring, z=z)


def error_curves(view: SolveView, highlight: int, state: int | None, *, scale: float = 1.0) -> tuple[np.ndarray, ...]:
    """uPlot data for log10 of the tip error (times `scale`: a unit) against diffusion time, x ascending (t = 0 .. T).

    Series: the median over the K samples, the highlighted sample, and a marker
    that is the highlighted sample's value at the current state and NaN elsewhere.
    The chart's y axis is linear in log10(error): uPlot's own logarithmic axis threw
    `RangeError: Invalid array length` in the page for ranges that are not whole decades.
    """
    order = np.argsort(view.labels, kind="stable")  # labels run T..0; uPlot needs x ascending
    error = view.tip_error * scale  # (S+1, K)
    median = np.log10(np.maximum(np.median(error, axis=1), ERROR_FLOOR))
    chosen = np.log10(np.maximum(error[:, highlight], ERROR_FLOOR))
    marker = np.full(view.num_states, np.nan)  # None: no state marked
    if state is not None:
        marker[state] = chosen[state]
    return (view.labels[order].astype(np.float64), median[order], chosen[order], marker[order])


def compare_curve(view, compare, highlight: int, *, scale: float = 1.0) -> np.ndarray:
    """log10 of the followed sample's tip error under the second sampler, on the main chart's x (t = 0 .. T).

    Its states sit at fewer diffusion times than DDPM's: between two, the line joins them.
    """
    x = np.sort(view.labels).astype(np.float64)
    order = np.argsort(compare.labels, kind="stable")
    values = np.log10(np.maximum(scale * compare.tip_error[:, highlight], ERROR_FLOOR))[order]
    return np.interp(x, compare.labels[order].astype(np.float64), values)


# What the default picture stresses, as the paper's figure does: one sample's denoising, the others in the background.
TRAIL_CHOICES = ("highlighted", "all samples")  # the panel's "trail of" dropdown, the default first


def follows_one(trail_of: str) -> bool:
    """The trail and the dark colours belong to the highlighted sample alone (the default picture)."""
    if trail_of not in TRAIL_CHOICES:
        raise ValueError(f"trail_of: expected one of {TRAIL_CHOICES}, got {trail_of!r}")
    return trail_of == TRAIL_CHOICES[0]


def emphasis_colors(num_states: int, num_samples: int, highlight: int, trail_of: str) -> tuple[np.ndarray, np.ndarray]:
    """(arm colours, trail colours), each (S+1, K, 3) uint8: the colour of each sample at each state.

    Following one sample, its trail runs from faint to dark blue while its arm is dark blue at every
    state (so the pose being followed is never lost in the noise), and the other samples fade from
    faint to a light grey. With "all samples", arms and trails share the faint-to-dark ramp.
    """
    if not follows_one(trail_of):
        colors = sample_colors(num_states, num_samples, highlight)
        return colors, colors
    trail = np.repeat(fade_colors(num_states, FAINT, OTHERS_FINAL)[:, None], num_samples, axis=1)
    trail[:, highlight] = fade_colors(num_states, TRAIL_FAINT, ACCENT_DARK, gamma=TRAIL_GAMMA)
    arms = trail.copy()
    arms[:, highlight] = ACCENT_DARK
    return arms, trail


def estimate_rows(num_samples: int, highlight: int, trail_of: str) -> slice:
    """The samples whose x̂0 is ghosted: the highlighted one's alone when it is followed (16 are a tangle)."""
    return slice(highlight, highlight + 1) if follows_one(trail_of) else slice(0, num_samples)


def trail_rows(num_samples: int, num_segments: int, highlight: int, trail_of: str) -> slice:
    """The trail's rows (of K * num_segments, sample-major) to draw: the highlighted sample's, or all."""
    if not follows_one(trail_of):
        return slice(0, num_samples * num_segments)
    return slice(highlight * num_segments, (highlight + 1) * num_segments)
