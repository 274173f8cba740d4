"""The joint space of a planar arm: the exact 2-link solution set, angles on the torus, the denoiser's field.

A pose is the model's own coordinates, the absolute link headings (ikdp.arm.PlanarArm),
so two of them span a torus: every angle here is wrapped into [-pi, pi), and the
shortest way from one angle to another is taken across the seam when that is shorter.

The field is what the denoiser does to a grid of poses at one timestep t: each grid
pose enters as x_t (its own encoding, `representation.encode`), the denoiser and the
schedule give x̂0 exactly as in the sampling loop (ikdp.sampling), and the arrow is
the wrapped difference x̂0 - x_t in headings. A solve's fields, one per state
(`SolveFields`), are computed on the solve worker's thread with the solve, or later
for the solve on screen (`solve_fields`); the drawing loop only draws them.
No viser here but the panel's controls.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
import torch

import ikdp
from ikdp.arm import PlanarArm
from ikdp_viz.readouts import JOINT_SPACE_HINT
from ikdp_viz.solve_worker import Cancelled

if TYPE_CHECKING:  # the controls' types only: the solve worker imports this file, and it needs no viser
    import viser

BOUNDARY_TOLERANCE = 1e-9  # |cos q2| within this of 1: the target is on the reach boundary, one solution
CURVE_POINTS = 256  # samples of a solution curve


def wrap_to_square(angles) -> np.ndarray:
    """Angles (any shape) wrapped into [-pi, pi): the joint-space square's range, pi and -pi one point."""
    wrapped = np.remainder(np.asarray(angles, dtype=np.float64) + math.pi, 2 * math.pi) - math.pi
    return np.where(wrapped >= math.pi, -math.pi, wrapped)  # remainder can round up to exactly 2 pi


def shortest_difference(start, end) -> np.ndarray:
    """end - start on the circle, wrapped into [-pi, pi): the arrow that does not go round the long way."""
    return wrap_to_square(np.asarray(end, dtype=np.float64) - np.asarray(start, dtype=np.float64))


@dataclass(frozen=True)
class SolutionSet:
    """Every pose of a 2-link arm whose tip is on the target, as absolute headings (theta1, theta2)."""

    points: np.ndarray  # (P, 2) isolated solutions: 2 (elbow up and down), 1 (on the reach boundary) or 0
    curve: np.ndarray | None  # (C, 2) a closed curve of solutions, when the target sits on a circle of them


def two_link_solutions(lengths, target) -> SolutionSet:
    """The exact inverse kinematics of a 2-link planar arm for the target (2,), in headings wrapped to [-pi, pi).

    A target out of reach is replaced by the nearest reachable point, as the solver conditions on it.
    With l1 = l2 and the target on the base the solution set is the curve theta2 = theta1 + pi
    (the elbow folded back, any heading of the first link).
    """
    lengths = tuple(float(length) for length in lengths)
    if len(lengths) != 2:
        raise ValueError(f"lengths: expected the two bone lengths of a 2-link arm, got {lengths}")
    l1, l2 = lengths
    point = torch.as_tensor(np.asarray(target, dtype=np.float64).reshape(1, 2))
    x, y = PlanarArm(lengths).clamp_to_workspace(point)[0].tolist()
    radius = math.hypot(x, y)
    if radius <= BOUNDARY_TOLERANCE * (l1 + l2) and math.isclose(l1, l2):
        first = np.linspace(-math.pi, math.pi, CURVE_POINTS, endpoint=False)
        return SolutionSet(np.zeros((0, 2)), wrap_to_square(np.stack((first, first + math.pi), axis=-1)))
    # law of cosines for the relative elbow angle q2 = theta2 - theta1
    cos_elbow = (radius**2 - l1**2 - l2**2) / (2 * l1 * l2)
    if abs(cos_elbow) >= 1 - BOUNDARY_TOLERANCE:
        elbows = [0.0 if cos_elbow > 0 else math.pi]  # stretched (outer boundary) or folded (inner)
    else:
        elbow = math.acos(cos_elbow)
        elbows = [elbow, -elbow]
    rows = []
    for elbow in elbows:
        first = math.atan2(y, x) - math.atan2(l2 * math.sin(elbow), l1 + l2 * math.cos(elbow))
        rows.append((first, first + elbow))
    return SolutionSet(wrap_to_square(np.array(rows)), None)


def torus_grid(count: int) -> np.ndarray:
    """(count * count, 2) cell centres of a count x count grid over [-pi, pi)^2, first angle varying fastest."""
    if not isinstance(count, int) or count < 1:
        raise ValueError(f"count: expected a positive integer, got {count!r}")
    centres = -math.pi + (np.arange(count) + 0.5) * (2 * math.pi / count)
    second, first = np.meshgrid(centres, centres, indexing="ij")
    return np.stack((first.reshape(-1), second.reshape(-1)), axis=-1)


def grid_poses(grid: np.ndarray, joints: tuple[int, int], held) -> np.ndarray:
    """Full poses (M, N) for grid points (M, 2) over `joints`: every other joint held at `held` (N,)."""
    held = np.asarray(held, dtype=np.float64)
    first, second = joints
    if first == second or not (0 <= first < len(held) and 0 <= second < len(held)):
        raise ValueError(f"joints: expected two different joints of 0..{len(held) - 1}, got {joints}")
    poses = np.repeat(held[None], len(grid), axis=0)
    poses[:, first], poses[:, second] = grid[:, 0], grid[:, 1]
    return poses


@torch.inference_mode()
def clean_estimates_of_vectors(solver: ikdp.Solver, x: torch.Tensor, timestep: int, target) -> torch.Tensor:
    """The denoiser's x̂0 (M, N) in headings for diffused vectors x_t (M, D) at the 0-based `timestep`, target (2,).

    One batched call, the same composition as a step of the sampling loop (ikdp.sampling): the
    target the solver conditions on (clamped into the workspace), the denoiser's output, and the
    schedule's `predict_clean` for what the model predicts; decoded to headings (decoding wraps and
    normalises, so the loop's projection onto the manifold changes nothing here).
    """
    model = solver.model
    if not 0 <= timestep < solver.timesteps:
        raise ValueError(f"timestep: expected 0 <= t < {solver.timesteps}, got {timestep}")
    rows = x.shape[0]
    targets = solver.arm.validate_targets(np.asarray(target, dtype=np.float64).reshape(1, -1)).to(solver.device)
    targets = solver.arm.clamp_to_workspace(targets).expand(rows, -1)
    t = torch.full((rows,), timestep, dtype=torch.long, device=solver.device)
    output = model.denoiser(x, t, targets)
    clean = model.schedule.predict_clean(output, timestep, x, model.config.prediction)
    return model.representation.decode(clean)


def clean_estimates(solver: ikdp.Solver, poses, timestep: int, target) -> np.ndarray:
    """x̂0 (M, N) for every pose (M, N) of headings taken as x_t, in its own encoding, at `timestep`."""
    headings = torch.as_tensor(np.asarray(poses), dtype=torch.float32, device=solver.device)
    x = solver.model.representation.encode(headings)  # (M, D)
    return clean_estimates_of_vectors(solver, x, timestep, target).double().cpu().numpy()


@torch.inference_mode()
def clean_estimates_of_states(
    solver: ikdp.Solver, poses, timesteps, target, cancel: threading.Event | None = None
) -> np.ndarray:
    """x̂0 (S, M, N) for S sets of M poses of headings (S, M, N), set s taken as x_t at the 0-based timesteps[s].

    The sampling loop's own composition (ikdp.sampling), one denoiser call a set as it makes one a step:
    every set's condition computed in one call and shared by the set's rows, one workspace reused. Per
    row this is what `clean_estimates` computes (to float32 rounding: the workspace is the torch one,
    not the compiled kernel), at a third of its cost: the condition network is most of the denoiser.
    One call of all S * M rows was slower still on one CPU thread (its activations leave the cache).
    Raises Cancelled between sets once `cancel` is set.
    """
    model, denoiser = solver.model, solver.model.denoiser
    poses = np.asarray(poses, dtype=np.float64)
    timesteps = [int(timestep) for timestep in timesteps]
    if poses.ndim != 3 or len(poses) != len(timesteps):
        raise ValueError(f"poses: expected (S, M, N) for {len(timesteps)} timesteps, got shape {poses.shape}")
    for timestep in timesteps:
        if not 0 <= timestep < solver.timesteps:
            raise ValueError(f"timesteps: expected 0 <= t < {solver.timesteps}, got {timestep}")
    rows = poses.shape[1]
    targets = solver.arm.validate_targets(np.asarray(target, dtype=np.float64).reshape(1, -1)).to(solver.device)
    targets = solver.arm.clamp_to_workspace(targets)
    times = torch.as_tensor(timesteps, dtype=torch.long, device=solver.device)
    conditions = denoiser.condition(times, targets.expand(len(timesteps), -1))  # (S, ...)
    row_targets = targets.expand(rows, -1)
    headings = torch.as_tensor(poses, dtype=torch.float32, device=solver.device)
    make_workspace = getattr(denoiser, "workspace", None)  # as the sampling loop asks it: a denoiser's own option
    workspace = None if make_workspace is None else make_workspace(rows, headings, compiled=False)
    denoise = denoiser.denoise if workspace is None else partial(denoiser.denoise, workspace=workspace)
    estimates = np.empty(poses.shape)
    for index, timestep in enumerate(timesteps):
        if cancel is not None and cancel.is_set():
            raise Cancelled
        x = model.representation.encode(headings[index])  # (M, D)
        output = denoise(x, row_targets, conditions[index : index + 1])  # the workspace's buffer: used at once
        clean = model.schedule.predict_clean(output, timestep, x, model.config.prediction)
        estimates[index] = model.representation.decode(clean).double().cpu().numpy()
    return estimates


@dataclass(frozen=True)
class Field:
    """The denoiser's arrows on a grid over two joints at one timestep."""

    starts: np.ndarray  # (M, 2) grid poses x_t on the two joints, in [-pi, pi)
    arrows: np.ndarray  # (M, 2) the shortest x̂0 - x_t on the two joints, each in [-pi, pi)
    timestep: int  # the 0-based timestep the denoiser was called at


def field_at(solver: ikdp.Solver, target, timestep: int, joints: tuple[int, int], held, count: int) -> Field:
    """The field at `timestep` on a count x count grid over `joints`, the other joints at `held` (N,): one state's
    arrows computed alone (the viewer computes a solve's with `clean_estimates_of_states`, states together)."""
    grid = torus_grid(count)
    estimates = clean_estimates(solver, grid_poses(grid, joints, held), int(timestep), target)[:, list(joints)]
    return Field(grid, shortest_difference(grid, estimates), int(timestep))


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


@dataclass(frozen=True)
class FieldAsk:
    """The fields a solve asked with the joint-space view shown should bring: two joints, the grid, and the
    highlight dropdown's choice, whose sample holds the other joints (resolved once the solve is known)."""

    joints: tuple[int, int]
    count: int  # arrows per side of the square
    highlight: str  # "best" or a sample's number from 1 (frame.highlighted_sample)


@dataclass(frozen=True)
class SolveFields:
    """The denoiser's field at the states of one solve, on one grid over two joints."""

    joints: tuple[int, int]
    count: int
    held_by: int | None  # the sample whose headings at each state hold the other joints; None: none is held (N = 2)
    starts: np.ndarray  # (M, 2) the grid poses on the two joints, in [-pi, pi)
    arrows: np.ndarray  # (S+1, M, 2) state s's shortest x̂0 - x_t on the two joints (NaN where not computed)
    timesteps: np.ndarray  # (S+1,) the 0-based timestep of each state's denoiser call (model_timestep)
    computed: np.ndarray  # (S+1,) bool: the states whose arrows were computed

    def fits(self, joints: tuple[int, int], highlight: int, count: int) -> bool:
        """These are the arrows of the pair, held pose and grid asked for (else they would be stale)."""
        held = self.held_by is None or self.held_by == highlight
        return tuple(joints) == self.joints and count == self.count and held

    def at(self, state: int) -> Field | None:
        """The field at `state`; None where it was not computed."""
        if not self.computed[state]:
            return None
        return Field(self.starts, self.arrows[state], int(self.timesteps[state]))


def solve_fields(
    solver: ikdp.Solver, view, joints: tuple[int, int], highlight: int, count: int,
    cancel: threading.Event | None = None, states=None,
) -> SolveFields:  # fmt: skip
    """The field at the states of a planar solve's `view` (planar_scene.SolveView), all of them or the indices
    `states`: at state s the grid over `joints` with the other joints at sample `highlight`'s headings then, at
    that state's denoiser call. Run on the solve worker's thread, never the drawing loop's; raises Cancelled once
    `cancel` is set."""
    headings = link_headings(view.joints)  # (S+1, K, N)
    num_states, num_samples, num_joints = headings.shape
    if not 0 <= highlight < num_samples:
        raise ValueError(f"highlight: expected a sample of 0..{num_samples - 1}, got {highlight}")
    computed = np.zeros(num_states, dtype=bool)
    computed[slice(None) if states is None else np.asarray(states, dtype=np.int64)] = True
    grid = torus_grid(count)
    timesteps = np.array([model_timestep(view.labels, state) for state in range(num_states)])
    poses = np.stack([grid_poses(grid, joints, held) for held in headings[computed, highlight]])  # (S', M, N)
    estimates = clean_estimates_of_states(solver, poses, timesteps[computed], view.target, cancel)[..., list(joints)]
    arrows = np.full((num_states, len(grid), 2), np.nan)
    arrows[computed] = shortest_difference(grid, estimates)
    held_by = None if num_joints == 2 else int(highlight)
    return SolveFields(tuple(joints), count, held_by, grid, arrows, timesteps, computed)


# The panel's joint-space controls: the view's toggle and, for arms of more than two links, the two joints shown.
DEFAULT_GRID = 20  # field arrows per side of the square


def joint_labels(num_joints: int) -> tuple[str, ...]:
    """Dropdown options, one per link heading, counted from 1 as in the readouts: θ1 .. θN."""
    return tuple(f"θ{number}" for number in range(1, num_joints + 1))


@dataclass
class JointSpaceControls:
    folder: viser.GuiFolderHandle  # hidden for arms the view does not draw (robots)
    show: viser.GuiCheckboxHandle
    first: viser.GuiDropdownHandle  # the joint along the square's x axis
    second: viser.GuiDropdownHandle  # the joint along its y axis
    grid: viser.GuiSliderHandle  # arrows per side

    def joints(self) -> tuple[int, int]:
        """The 0-based pair shown; the second moves off the first when both name the same joint."""
        options = self.first.options
        first, second = options.index(self.first.value), options.index(self.second.value)
        if first == second:
            second = (first + 1) % len(options)
        return first, second

    def keep_apart(self, moved: viser.GuiDropdownHandle) -> None:
        """`moved` was set to the joint the other dropdown names: move the other to the next joint, on screen too.

        A square of one joint against itself is a line; the view used to draw the next joint silently while
        both dropdowns said the same one.
        """
        other = self.second if moved is self.first else self.first
        if moved.value != other.value:
            return
        options = tuple(moved.options)
        other.value = options[(options.index(moved.value) + 1) % len(options)]

    def fit(self, num_joints: int) -> None:
        """Offer the joints of an arm of `num_joints` links; with two there is nothing to choose."""
        options = joint_labels(max(num_joints, 2))
        if tuple(self.first.options) != options:
            self.first.options, self.second.options = options, options
            self.first.value, self.second.value = options[0], options[1]
        for dropdown in (self.first, self.second):
            if dropdown.disabled != (num_joints <= 2):  # called with every frame: write only a change
                dropdown.disabled = num_joints <= 2


def build_joint_space_controls(gui: viser.GuiApi) -> JointSpaceControls:
    with gui.add_folder("Joint space") as folder:
        show = gui.add_checkbox(
            "joint space view", False, hint=JOINT_SPACE_HINT,
        )  # fmt: skip
        options = joint_labels(2)
        first = gui.add_dropdown("x: joint", options, initial_value=options[0], disabled=True)
        second = gui.add_dropdown("y: joint", options, initial_value=options[1], disabled=True)
        grid = gui.add_slider("field grid", min=4, max=40, step=1, initial_value=DEFAULT_GRID)
    return JointSpaceControls(folder, show, first, second, grid)
