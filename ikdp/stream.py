"""Following targets one at a time, as a control loop asks for them: `stream = solver.stream(start_pose)`, then
`pose = stream(target)` at every tick.

Each call starts from the last answer and refines it toward the new target by damped least squares, one step
at a time until it is within the arm's tolerances (1 mm and 1 degree on a robot), at most `max_steps` steps:
on a path that moves a little between calls (a 1 kHz loop), one or two steps, with the arm's kinematics as a
few fused operations (ikdp/fused_chain.py), and no network at all. A warm-started numerical step moves the
joints along the minimum-norm change, so the arm stays on its branch: the continuity `solver.track` gets from
its pull toward the previous pose.

Where the warm start does not reach the target in `max_steps` steps (the path jumped, or ran into a joint
limit), or reaching it took a joint jump larger than `max_jump`, that call is answered by `solver.track` for
the one target from the last pose (the diffusion's samples pulled toward the last pose, the nearest reaching
one kept; tracking.py): slower, and counted in `fallbacks`.
"""

from __future__ import annotations

import math

import torch

from ikdp.constraint_base import joint_difference
from ikdp.fused_chain import small_batch
from ikdp.tracking import BRANCH_SWITCH_FLOOR, track

STREAM_MAX_STEPS = 4  # DLS steps a call may take before it falls back to a tracking solve


class PoseStream:
    """One target at a time, warm-started from the last answer (module docstring). Build it with
    `solver.stream(start_pose, ...)`."""

    def __init__(
        self,
        solver,
        start_pose,
        *,
        max_steps: int = STREAM_MAX_STEPS,
        max_jump: float = BRANCH_SWITCH_FLOOR,
        **track_options,
    ):
        """`start_pose` (J,): the arm's joints now (clamped into the limits, continuous joints wrapped).
        `max_steps`: DLS steps a call may take; `max_jump`: the largest joint change (radians) a warm-started
        answer may make; past either the call falls back to `solver.track` with `track_options` (its `weight`,
        `num_samples`, `sampler`, `steps`, `refine_steps`, ...)."""
        arm = solver.arm
        pose = torch.as_tensor(start_pose, dtype=torch.float32)
        if pose.shape != (arm.num_joints,):
            raise ValueError(f"start_pose: expected shape ({arm.num_joints},), got {tuple(pose.shape)}")
        if not bool(torch.isfinite(pose).all()):
            raise ValueError(f"start_pose: expected finite joint values, got {pose.tolist()}")
        if not isinstance(max_steps, int) or isinstance(max_steps, bool) or max_steps < 1:
            raise ValueError(f"max_steps: expected a positive integer, got {max_steps!r}")
        if not (isinstance(max_jump, (int, float)) and math.isfinite(max_jump) and max_jump > 0):
            raise ValueError(f"max_jump: expected a positive number of radians, got {max_jump!r}")
        self.solver, self.arm = solver, arm
        self.kinematics = arm.small_batch_kinematics() if small_batch(1, solver.device) else arm
        self.max_steps, self.max_jump, self.track_options = max_steps, float(max_jump), track_options
        self.pose = arm.normalize_joints(pose).to(solver.device)  # (J,) the last answer
        self.reached = True  # whether the last answer is within the arm's tolerances
        self.position_error: float = 0.0  # of the last answer
        self.rotation_error: float | None = None  # radians, pose targets
        self.steps = 0  # DLS steps the last warm-started answer took
        self.calls = 0
        self.fallbacks = 0  # calls answered by a tracking solve

    def __call__(self, target) -> torch.Tensor:
        """target (target_dim,) or (1, target_dim) -> the arm's joints for it, (J,), near the last answer."""
        arm = self.arm
        rows = torch.as_tensor(target, dtype=torch.float32)
        if rows.ndim == 1:
            rows = rows[None]
        if rows.shape != (1, arm.target_dim):
            raise ValueError(
                f"target: expected one target of shape ({arm.target_dim},) or (1, {arm.target_dim}), "
                f"got {tuple(rows.shape)}"
            )
        rows = arm.validate_targets(rows).to(self.pose.device)  # finite, a unit quaternion
        goal = arm.clamp_to_workspace(rows)  # (1, target_dim): the nearest reachable point, as solve aims
        self.calls += 1
        pose, steps, within = self.pose[None], 0, False
        while not within and steps < self.max_steps:  # at least one step: the target moved since the last call
            pose = self.kinematics.refine(pose, goal, steps=1)
            steps += 1
            within, position, rotation = self._check(pose, rows)
        jump = float(joint_difference(arm, pose[0], self.pose).abs().max())
        if within and jump <= self.max_jump:
            self.steps = steps
            return self._keep(pose[0], True, position, rotation)
        self.fallbacks += 1
        tracked = track(self.solver, rows, self.pose.cpu(), **self.track_options)
        rotation = None if tracked.rotation_error is None else float(tracked.rotation_error[0])
        return self._keep(
            tracked.angles[0].to(self.pose.device), bool(tracked.reached[0]), float(tracked.position_error[0]), rotation
        )

    def _check(self, pose: torch.Tensor, target: torch.Tensor) -> tuple[bool, float, float | None]:
        position, rotation = self.kinematics.tip_and_rotation_errors(pose, target)
        within = bool(position[0] < self.arm.position_tolerance)
        if rotation is not None:
            within &= bool(rotation[0] < self.arm.rotation_tolerance)
        return within, float(position[0]), None if rotation is None else float(rotation[0])

    def _keep(self, pose: torch.Tensor, reached: bool, position: float, rotation: float | None) -> torch.Tensor:
        self.pose, self.reached, self.position_error, self.rotation_error = pose, reached, position, rotation
        return pose
