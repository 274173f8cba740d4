"""Following a path of targets with one continuous solution: `solver.track(path, start_pose)`.

Each target is solved with a pull toward the previous solution (`NearPose`: every step's x̂0
is moved part of the way to it), so the K samples gather on the branch the arm is already
on; of those that reach the target (and meet the other constraints), the one nearest the
previous pose is kept. The previous solution refined toward the target is one more candidate
(`warm_start`): where no sample reaches a target, the nearest candidate is kept, so the path
jumps less often to another branch to chase a target it cannot reach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ikdp.constraint_base import joint_difference
from ikdp.guidance import ConstraintSet
from ikdp.joint_constraints import NearPose
from ikdp.refine import damped_least_squares

WARM_START_STEPS = 10  # DLS steps of the warm-started candidate (at least the solve's refine_steps)


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
    warm_start: bool = True,
    **solve_options,
) -> TrackResult:
    """path (P, target_dim), start_pose (J,) -> one solution per target, each near the one before.

    `weight`: NearPose's pull (0.3 let a Panda circle jump branches once, 3.6 rad; 0.6 kept every
    jump under 0.02 rad: docs/CONSTRAINTS.md); tolerances decide which samples count as reaching a target
    (position: 1e-3 of the arm's span by default; 1 mm on a Panda); `solve_options` go to
    `solver.solve` (num_samples, sampler, steps, refine_steps, generator). `warm_start`: the
    previous solution refined toward the target (damped least squares, as a warm-started numerical
    solver would) is one more candidate; where no sample reaches a target it is usually the
    nearest one, so the arm stays where it was, stretched toward it (on a Panda circle half out
    of reach it halved the jumps over 0.1 rad, 56 to 29, but not the share reached:
    docs/CONSTRAINTS.md).
    """
    arm = solver.arm
    path = arm.validate_targets(path)
    previous = torch.as_tensor(start_pose, dtype=torch.float32)
    if previous.shape != (arm.num_joints,):
        raise ValueError(f"start_pose: expected shape ({arm.num_joints},), got {tuple(previous.shape)}")
    position_tolerance = 1e-3 * arm.span if position_tolerance is None else position_tolerance
    solutions, position_errors, rotation_errors, reached, jumps = [], [], [], [], []
    partial = any(hasattr(item, "validate_targets") for item in constraints)
    warm_task = None
    if warm_start and constraints:
        warm_task = ConstraintSet(arm, list(constraints), 1, 1).refine_task()
    for target in path:
        near = NearPose(previous, weight=weight)
        out = solver.solve(target[None], constraints=[near, *constraints], **solve_options)
        angles, position_error = out.angles[0], out.position_error[0]
        rotation_error = None if out.rotation_error is None else out.rotation_error[0]
        met = out.constraints_met[0] if out.constraints_met is not None else torch.ones(len(angles), dtype=torch.bool)
        if warm_start and not partial:  # one more candidate: the previous solution refined toward the target
            goal = arm.clamp_to_workspace(target[None])[:, None]
            steps = max(int(solve_options.get("refine_steps", 0)), WARM_START_STEPS)
            warm = damped_least_squares(arm, previous[None, None], goal, steps=steps, task=warm_task)[0]
            angles = torch.cat([angles, warm])
            position_error = torch.cat([position_error, arm.tip_error(warm, target[None])])
            if rotation_error is not None:
                rotation_error = torch.cat([rotation_error, arm.rotation_error(warm, target[None])])
            warm_met = torch.ones(1, dtype=torch.bool)
            if warm_task is not None:
                warm_met = ConstraintSet(arm, list(constraints), 1, 1).violation(warm[None])[0] == 0
            met = torch.cat([met, warm_met])
        ok = position_error < position_tolerance
        if rotation_error is not None:
            ok &= rotation_error < rotation_tolerance
        ok &= met
        distance = joint_difference(arm, angles, previous).abs().amax(dim=-1)  # (candidates,)
        pick = int(torch.where(ok, distance, distance + math.inf if ok.any() else distance).argmin())
        if not ok.any():  # nothing reaches: keep the nearest candidate that meets the constraints, if any does
            pick = int(torch.where(met, distance, distance + 1e6).argmin())
        chosen = angles[pick]
        solutions.append(chosen)
        position_errors.append(position_error[pick])
        if rotation_error is not None:
            rotation_errors.append(rotation_error[pick])
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
