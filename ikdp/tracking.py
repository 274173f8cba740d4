"""Following a path of targets with one continuous solution: `solver.track(path, start_pose)`.

Each target is solved with a pull toward the previous solution (`NearPose`: every step's x̂0
is moved part of the way to it), so the K samples gather on the branch the arm is already
on; of those that reach the target (and meet the other constraints), the one nearest the
previous pose is kept. Where none reaches it, the nearest of the K is kept anyway, so the
path never jumps to another branch to chase a target it cannot reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ikdp.constraint_base import joint_difference
from ikdp.joint_constraints import NearPose


@dataclass
class TrackResult:
    angles: torch.Tensor  # (P, J) one solution per target, in path order
    position_error: torch.Tensor  # (P,) distance to each target's position (arm's length unit)
    rotation_error: torch.Tensor | None  # (P,) radians, for pose targets
    reached: torch.Tensor  # (P,) True where the solution is within tolerance and meets every constraint
    joint_jumps: torch.Tensor  # (P,) largest joint change from the previous solution (the start pose first)

    @property
    def largest_jump(self) -> float:
        return float(self.joint_jumps.max())


def track(
    solver,
    path,
    start_pose,
    *,
    weight: float = 0.6,
    position_tolerance: float | None = None,
    rotation_tolerance: float = math.radians(1.0),
    constraints=(),
    **solve_options,
) -> TrackResult:
    """path (P, target_dim), start_pose (J,) -> one solution per target, each near the one before.

    `weight`: NearPose's pull (0.3 let a Panda circle jump branches once, 3.6 rad; 0.6 kept every
    jump under 0.02 rad: docs/CONSTRAINTS.md); tolerances decide which samples count as reaching a target
    (position: 1e-3 of the arm's span by default; 1 mm on a Panda); `solve_options` go to
    `solver.solve` (num_samples, sampler, steps, refine_steps, generator).
    """
    arm = solver.arm
    path = arm.validate_targets(path)
    previous = torch.as_tensor(start_pose, dtype=torch.float32)
    if previous.shape != (arm.num_joints,):
        raise ValueError(f"start_pose: expected shape ({arm.num_joints},), got {tuple(previous.shape)}")
    position_tolerance = 1e-3 * arm.span if position_tolerance is None else position_tolerance
    solutions, position_errors, rotation_errors, reached, jumps = [], [], [], [], []
    for target in path:
        near = NearPose(previous, weight=weight)
        out = solver.solve(target[None], constraints=[near, *constraints], **solve_options)
        ok = out.position_error[0] < position_tolerance
        if out.rotation_error is not None:
            ok &= out.rotation_error[0] < rotation_tolerance
        met = out.constraints_met[0] if out.constraints_met is not None else torch.ones_like(ok)
        ok &= met
        distance = joint_difference(arm, out.angles[0], previous).abs().amax(dim=-1)  # (K,)
        pick = int(torch.where(ok, distance, distance + math.inf if ok.any() else distance).argmin())
        if not ok.any():  # nothing reaches: keep the nearest sample that meets the constraints, if any does
            pick = int(torch.where(met, distance, distance + 1e6).argmin())
        chosen = out.angles[0, pick]
        solutions.append(chosen)
        position_errors.append(out.position_error[0, pick])
        if out.rotation_error is not None:
            rotation_errors.append(out.rotation_error[0, pick])
        reached.append(bool(ok[pick]))
        jumps.append(float(distance[pick]))
        previous = chosen
    return TrackResult(
        angles=torch.stack(solutions),
        position_error=torch.stack(position_errors),
        rotation_error=torch.stack(rotation_errors) if rotation_errors else None,
        reached=torch.tensor(reached),
        joint_jumps=torch.tensor(jumps),
    )
