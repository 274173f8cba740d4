"""Damped least squares (Levenberg-Marquardt), written once for every arm.

One step: delta = J^T (J J^T + lambda^2 I)^-1 e, with J the arm's end-effector
Jacobian (E, J) and e its task error (E,): the tip's miss for a planar arm, the
position miss and the rotation error for a pose target. For E = 2 the inverse is
written out in closed form (Cayley-Hamilton), so a batch moves in a few tensor
ops. A planar arm's step is also written from its bone vectors (`planar_dls_step`),
with sums over links instead of batched 2x2 matrix products: the planar denoiser
computes it as a feature at every diffusion step, where each tensor op counts.
"""

from __future__ import annotations

import math
from typing import Protocol

import torch


def dls_step(jacobian: torch.Tensor, error: torch.Tensor, damping_squared: float) -> torch.Tensor:
    """jacobian (..., E, J), error (..., E) -> the damped least-squares step (..., J)."""
    gram = jacobian @ jacobian.transpose(-1, -2)  # (..., E, E)
    if error.shape[-1] == 2:
        # A^-1 e = (tr(A) e - A e) / det(A) for A = J J^T + lambda^2 I; det and trace by hand:
        # torch.linalg costs more than the rest of the step's algebra at this size
        a = gram[..., 0, 0] + damping_squared
        b = gram[..., 0, 1]
        d = gram[..., 1, 1] + damping_squared
        trace_times_error = (a + d)[..., None] * error
        gram_times_error = (gram @ error[..., None])[..., 0] + damping_squared * error
        solved = (trace_times_error - gram_times_error) / (a * d - b * b)[..., None]
    else:
        eye = torch.eye(gram.shape[-1], dtype=gram.dtype, device=gram.device)
        # solve_ex: linalg.solve's LU without its error check, whose device-to-host sync breaks CUDA-graph
        # capture; the damped Gram matrix is positive definite, so there is no singular case to report
        solved = torch.linalg.solve_ex(gram + damping_squared * eye, error[..., None], check_errors=False)[0][..., 0]
    return (jacobian.transpose(-1, -2) @ solved[..., None])[..., 0]


def planar_dls_step(bones: torch.Tensor, error: torch.Tensor, damping_squared: float) -> torch.Tensor:
    """bones (..., N, 2) bone vectors of a planar arm, error (..., 2) tip miss -> `dls_step`'s step (..., N).

    Bone n's Jacobian column is the bone turned by 90 degrees, j_n = (-b_y, b_x), so
    adj(J J^T + lambda^2 I) = sum_n b_n b_n^T + lambda^2 I: the inverse is that adjugate over
    its determinant, with no matrix product. FiLMWorkspace repeats these ops, call for call,
    into preallocated buffers (the two must stay bit-identical: a test checks it).
    """
    adjugate = (bones[..., :, None] * bones[..., None, :]).sum(dim=-3)  # (..., 2, 2)
    adjugate.diagonal(dim1=-2, dim2=-1).add_(damping_squared)
    determinant = torch.addcmul(
        adjugate[..., 0, 0] * adjugate[..., 1, 1], adjugate[..., 0, 1], adjugate[..., 0, 1], value=-1
    )
    solved = (adjugate * error[..., None, :]).sum(dim=-1) / determinant[..., None]  # (J J^T + lambda^2 I)^-1 e
    columns = torch.stack((-bones[..., 1], bones[..., 0]), dim=-1)  # (..., N, 2) the Jacobian's columns
    return (columns * solved[..., None, :]).sum(dim=-1)


def clamp_task_error(error: torch.Tensor, position_dim: int, max_position: float, max_rotation: float) -> torch.Tensor:
    """Shorten each miss to at most `max_position` (and a rotation error to `max_rotation` radians).

    Buss's clamping: a far miss linearised in one jump overshoots and oscillates.
    """
    position = error[..., :position_dim]
    position = position * (max_position / position.norm(dim=-1, keepdim=True).clamp(min=max_position))
    if error.shape[-1] == position_dim:
        return position
    rotation = error[..., position_dim:]
    rotation = rotation * (max_rotation / rotation.norm(dim=-1, keepdim=True).clamp(min=max_rotation))
    return torch.cat((position, rotation), dim=-1)


class RefineTask(Protocol):
    """What damped least squares drives to zero in place of the arm's end-effector error (ikdp/constraints.py)."""

    def error(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(..., J), (..., target_dim) -> the task error (..., E): what `better_of` compares."""

    def linearize(self, joints: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The clamped task error (..., E) and its Jacobian (..., E, J): a small step dq changes it by -J dq."""

    def penetrations(self, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | None:
        """(..., J) -> depths (..., P) to bring down to zero, second to the target, and their gradients (..., P, J).

        None: nothing to avoid. They are met in the null space of the target's rows (`null_space_step`).
        """

    def hold(self, joints: torch.Tensor) -> torch.Tensor:
        """(..., J) after a step -> the same with every held (locked) joint put back exactly."""


NULL_SPACE_MAX_STEP = 0.3  # the largest joint move (radians) one clearing step may add: the null space can be thin


def null_space_step(
    jacobian: torch.Tensor,
    step: torch.Tensor,
    depths: torch.Tensor,
    gradients: torch.Tensor,
    damping_squared: float,
    max_step: float = NULL_SPACE_MAX_STEP,
) -> torch.Tensor:
    """The move (..., J) that clears the penetration `step` leaves, without moving the target's rows to first order.

    Task priority (Siciliano and Slotine 1991): the target's rows (`jacobian` (..., E, J)) come
    first; the depths (..., P) still predicted after `step`, d + G step, are cleared by moving
    along the gradients' parts in the target's null space, G (I - J^T (J J^T + l^2 I)^-1 J). As
    one more row stacked under a 6-row pose target, a 7-joint arm's system was square: each step
    solved both exactly, with joint moves that threw samples off the pose (after 5 steps 52 % of
    the Panda's samples were within 1 mm and 1 degree, against 87 % without the row).
    """
    remaining = (depths + (gradients @ step[..., None])[..., 0]).clamp_min(0)  # (..., P) predicted depths
    pulled = (jacobian[..., None, :, :] @ gradients[..., None])[..., 0]  # (..., P, E): J g per depth
    along_target = dls_step(jacobian[..., None, :, :].expand(*pulled.shape[:-1], -1, -1), pulled, damping_squared)
    projected = gradients - along_target  # (..., P, J): the gradients' parts that leave the target still
    move = dls_step(projected, -remaining, damping_squared)
    largest = move.abs().amax(dim=-1, keepdim=True)
    return move * (max_step / largest.clamp_min(max_step))


def damped_least_squares(
    arm,
    joints: torch.Tensor,
    targets: torch.Tensor,
    *,
    steps: int = 5,
    damping: float = 1e-3,
    max_miss_fraction: float = 0.2,
    task: RefineTask | None = None,
    sync_free: bool = False,
    iteration=None,
    until_reached: bool = False,
) -> torch.Tensor:
    """joints (..., J), targets (..., target_dim) -> refined joints (..., J), within the arm's limits.

    Each step is followed by `arm.normalize_joints` (headings wrap, limited joints are
    clamped), so every refined pose respects the limits. Where a joint already on a limit is
    pushed further out (`arm.blocked_by_limits`), the step is also solved without it, and each
    pose keeps the better of the two (`better_of`). Runs in float64: the last steps
    correct errors near float32's resolution. A `task` replaces the end-effector error and its
    Jacobian (constraints: partial targets, obstacles, locked joints).

    `sync_free` (no task): never ask the device whether a joint is blocked (a host sync, which a CUDA graph
    cannot capture): each step is `sync_free_iteration`, or `iteration`, the same function compiled
    (torch.compile: ikdp/cuda_graph.py's fused capture). The same poses as the default, which solves the step
    without the blocked joints for the blocked poses alone (cheaper on a CPU).

    `until_reached` (no task; joints (B, K, J)): stop before a step once each of the B targets has one of its K
    poses within the arm's tolerances, as that step's error says: the answer in fewer steps, its other poses
    refined less.
    """
    if not isinstance(steps, int) or steps < 0:
        raise ValueError(f"refine steps: expected a non-negative integer, got {steps!r}")
    dtype = joints.dtype
    joints = joints.double()
    targets = targets.double()
    max_position = max_miss_fraction * arm.span
    if sync_free:
        if task is not None:
            raise ValueError("task: the sync-free refinement (a CUDA graph's) takes none")
        iteration = sync_free_iteration if iteration is None else iteration
        for _ in range(steps):
            joints = iteration(arm, joints, targets, max_position, damping**2)
        return joints.to(dtype)
    for _ in range(steps):
        penetrations = None
        if task is None:
            error, jacobian = arm.task_error_and_jacobian(joints, targets)
            if until_reached and every_target_reached(arm, error):
                break
            error = clamp_task_error(error, arm.position_dim, max_position, math.pi / 4)
        else:
            error, jacobian = task.linearize(joints, targets)
            penetrations = task.penetrations(joints)
        step = prioritized_step(jacobian, error, penetrations, damping**2)
        moved = arm.normalize_joints(joints + step)
        blocked = arm.blocked_by_limits(joints, step)
        if blocked is not None and bool(blocked.any()):
            if task is None:  # only the poses with a blocked joint try the step without it: a few in a thousand
                rows = blocked.any(dim=-1)
                held_step = dls_step(jacobian[rows] * ~blocked[rows][..., None, :], error[rows], damping**2)
                row_targets = targets.expand(*joints.shape[:-1], targets.shape[-1])[rows]
                moved[rows] = better_of(arm, row_targets, moved[rows], arm.normalize_joints(joints[rows] + held_step))
            else:  # a task's penetrations and holds span the whole batch
                held_step = prioritized_step(jacobian, error, penetrations, damping**2, ~blocked)  # blocked: zeroed
                moved = better_of(arm, targets, moved, arm.normalize_joints(joints + held_step), task)
        joints = moved if task is None else task.hold(moved)
    return joints.to(dtype)


def every_target_reached(arm, error: torch.Tensor) -> bool:
    """error (B, K, E) the task error of each target's K poses -> whether each target has one within the arm's
    tolerances: the position part's norm is the position error, the rotation part's the rotation angle (a tree's
    stacked effectors: their norms together, no smaller than the worst effector's, so it stops no earlier)."""
    within = error[..., : arm.position_dim].norm(dim=-1) < arm.position_tolerance
    if error.shape[-1] > arm.position_dim:
        within &= error[..., arm.position_dim :].norm(dim=-1) < arm.rotation_tolerance
    return bool(within.reshape(-1, within.shape[-1]).any(dim=-1).all())


def sync_free_iteration(
    arm, joints: torch.Tensor, targets: torch.Tensor, max_position: float, damping_squared: float
) -> torch.Tensor:
    """One step of `damped_least_squares` without a task, float64 joints (..., J) -> the next, with nothing that
    waits for the device or sizes a tensor by its data: every pose's step without its blocked joints is solved
    too and kept only where a joint was blocked, by the same rule (`better_of`). Fixed shapes and tensor code
    alone: what a CUDA graph captures and torch.compile fuses."""
    error, jacobian = arm.task_error_and_jacobian(joints, targets)
    error = clamp_task_error(error, arm.position_dim, max_position, math.pi / 4)
    step = dls_step(jacobian, error, damping_squared)
    moved = arm.normalize_joints(joints + step)
    blocked = arm.blocked_by_limits(joints, step)
    if blocked is None:  # a planar arm: no limits
        return moved
    held_step = dls_step(jacobian * ~blocked[..., None, :], error, damping_squared)
    every_target = targets.expand(*joints.shape[:-1], targets.shape[-1])
    better = better_of(arm, every_target, moved, arm.normalize_joints(joints + held_step))
    return torch.where(blocked.any(dim=-1, keepdim=True), better, moved)


def prioritized_step(
    jacobian: torch.Tensor,
    error: torch.Tensor,
    penetrations: tuple[torch.Tensor, torch.Tensor] | None,
    damping_squared: float,
    movable: torch.Tensor | None = None,
) -> torch.Tensor:
    """The target's damped least-squares step, then (where there are) the penetrations cleared in its null space.

    `movable` (..., J): False for joints the step must not move (their columns are zeroed).
    """
    if movable is not None:
        jacobian = jacobian * movable[..., None, :]
    step = dls_step(jacobian, error, damping_squared)
    if penetrations is None:
        return step
    depths, gradients = penetrations
    if movable is not None:
        gradients = gradients * movable[..., None, :]
    return step + null_space_step(jacobian, step, depths, gradients, damping_squared)


def better_of(
    arm, targets: torch.Tensor, clamped: torch.Tensor, without_blocked: torch.Tensor, task: RefineTask | None = None
) -> torch.Tensor:
    """Per pose, whichever candidate misses the target by less (the task error's norm, what DLS minimises).

    `clamped` took the full step, then the limits clipped it; `without_blocked` solved the step
    again with the joints that sat on a limit and were pushed further held still (an active
    set), so the others no longer count on a move the clamp undoes. Neither wins everywhere: on
    the Panda the active set alone took K=16 + 5 steps from 99.2 to 99.8 % of targets within
    1 mm and 1 degree, but left some poses stalled that the clamped step moved on; the better
    of the two kept 99.8 % with more valid poses per target (`python -m benchmarks.robot_benchmark`).
    """
    error = arm.task_error if task is None else task.error
    clamped_miss = error(clamped, targets).norm(dim=-1)
    without_miss = error(without_blocked, targets).norm(dim=-1)
    return torch.where((without_miss < clamped_miss)[..., None], without_blocked, clamped)


class RefinedByDampedLeastSquares:
    """An arm's refinement: `damped_least_squares` on its own task (a planar arm's tip, a chain's pose, a tree's
    stacked hands). A chain's few poses take FusedChain's fused loop instead (`small_batch_kinematics`)."""

    def refine(self, joints: torch.Tensor, targets: torch.Tensor, *, steps: int = 5, task=None) -> torch.Tensor:
        return damped_least_squares(self, joints, targets, steps=steps, task=task)

    def refine_scored(
        self, joints: torch.Tensor, targets: torch.Tensor, *, steps: int, until_reached: bool = False
    ) -> tuple[torch.Tensor, None]:
        """`refine` (no task), and no errors measured on the way (FusedChain's does): the caller measures them."""
        return damped_least_squares(self, joints, targets, steps=steps, until_reached=until_reached), None
