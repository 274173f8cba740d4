"""How a solve's constraints act: on the reverse loop (inpainting, guidance) and on the refinement.

`ConstraintSet` binds a solve's constraints to the arm and the batch. Its `guidance(...)` is
the hook ikdp/sampling.py calls at each step:
1. x̂0 is decoded to joints, moved by each constraint's guidance in turn (a pose to stay near,
   obstacles, a partial target's residual), put back in range, its locked joints set to their
   values, and encoded again: the sampler then steps with the constrained estimate;
2. the state the sampler lands on gets its locked coordinates replaced by the locked values
   noised to that step's level, alpha x0 + sigma z (RePaint, Lugmayr et al. 2022): the free
   coordinates are denoised beside a state that is consistent with the locks.
Its `refine_task()` is what damped least squares minimises instead of the end-effector error:
the (partial) target's rows first, then each obstacle constraint's penetration depth, cleared in
the null space of the target's rows (ikdp.refine.null_space_step); the locked joints' columns
are removed from both, so a step never moves them.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import torch

from ikdp.arm_inputs import drawing_device
from ikdp.constraint_base import Constraint
from ikdp.joint_constraints import BoundLockedJoints
from ikdp.partial_targets import BoundPartialTarget
from ikdp.refine import clamp_task_error
from ikdp.tree_partial_targets import BoundEffectorParts

PARTIAL_TARGETS = (BoundPartialTarget, BoundEffectorParts)  # a chain's, a tree's (per end effector)


class ConstraintSet:
    """A solve's constraints bound to the arm and its M = B x K sampled rows."""

    def __init__(self, arm, constraints: Sequence[Constraint], batch: int, num_samples: int):
        self.arm = arm
        self.batch, self.num_samples = batch, num_samples
        bound = [constraint.bind(arm, batch, num_samples) for constraint in checked(constraints)]
        locked = [item for item in bound if isinstance(item, BoundLockedJoints)]
        partial = [item for item in bound if isinstance(item, PARTIAL_TARGETS)]
        self.locked: BoundLockedJoints | None = merge_locks(locked) if locked else None
        self.partial: BoundPartialTarget | BoundEffectorParts | None = partial[0] if partial else None
        self.others = [item for item in bound if not isinstance(item, (BoundLockedJoints, *PARTIAL_TARGETS))]

    @staticmethod
    def validate_targets(arm, targets, constraints: Sequence[Constraint]) -> torch.Tensor:
        """A partial target reads its own target shapes (position only: (B, 3) too); else the arm's check."""
        partial = [item for item in checked(constraints) if hasattr(item, "validate_targets")]
        if len(partial) > 1:
            raise ValueError(f"constraints: at most one partial target, got {[item.name for item in partial]}")
        return partial[0].validate_targets(arm, targets) if partial else arm.validate_targets(targets)

    def hold(self, joints: torch.Tensor) -> torch.Tensor:
        return joints if self.locked is None else self.locked.hold(joints)

    def restart_from(self, starts: torch.Tensor) -> torch.Tensor:
        """starts (R, K, J) uniform draws of a restart -> what it refines: each constraint's own starts (a pose to
        stay near starts there), the locked joints at their values."""
        for item in self.others:
            starts = item.restart_from(starts)
        return self.hold(starts)

    def of_targets(self, chosen: torch.Tensor) -> ConstraintSet:
        """The same constraints over the rows of the targets `chosen` (B,) bool only: what restarts refine."""
        rows = chosen.cpu().repeat_interleave(self.num_samples).nonzero()[:, 0]
        subset = copy.copy(self)
        subset.batch = int(chosen.sum())
        subset.locked = None if self.locked is None else self.locked.of_rows(rows)
        subset.partial = None if self.partial is None else self.partial.of_rows(rows)
        subset.others = [item.of_rows(rows) for item in self.others]
        return subset

    def violation(self, joints: torch.Tensor) -> torch.Tensor:
        """(B, K, J) -> (B, K) the summed violation of every checkable constraint; 0 where all hold."""
        rows = joints.reshape(-1, joints.shape[-1])
        total = torch.zeros(rows.shape[0], dtype=torch.float64, device=rows.device)
        for item in ([self.locked] if self.locked is not None else []) + self.others:
            total = total + item.violation(rows.double() if item is not self.locked else rows).double()
        return total.reshape(joints.shape[:-1])

    def guidance(self, representation, sampler, row_targets: torch.Tensor) -> SamplingGuidance:
        return SamplingGuidance(self, representation, sampler, row_targets)

    def refine_task(self) -> ConstrainedTask:
        return ConstrainedTask(self)


def checked(constraints) -> list[Constraint]:
    if isinstance(constraints, Constraint) or not isinstance(constraints, (list, tuple)):
        raise ValueError(f"constraints: expected a list of constraints (ikdp.constraint_names()), got {constraints!r}")
    for item in constraints:
        if not isinstance(item, Constraint):
            raise ValueError(f"constraints: expected constraint objects (e.g. ikdp.LockedJoints), got {item!r}")
    return list(constraints)


def merge_locks(locks: list[BoundLockedJoints]) -> BoundLockedJoints:
    """Several LockedJoints act as one; a joint locked twice is refused."""
    mask, values = locks[0].mask.clone(), locks[0].values.clone()
    for lock in locks[1:]:
        if (mask & lock.mask).any():
            raise ValueError("locked_joints: a joint is locked by two constraints")
        mask |= lock.mask
        values = torch.where(lock.mask, lock.values, values)
    return BoundLockedJoints(mask=mask, values=values, repaint=all(lock.repaint for lock in locks))


class SamplingGuidance:
    """The reverse loop's hook (ikdp.sampling.Guidance) for a ConstraintSet."""

    def __init__(self, constraints: ConstraintSet, representation, sampler, row_targets: torch.Tensor):
        self.constraints = constraints
        self.arm = constraints.arm
        self.representation = representation
        self.sampler = sampler
        self.row_targets = row_targets  # (M, target_dim) each row's full condition
        locked = constraints.locked
        if locked is not None:
            device = row_targets.device
            self.locked_coordinates = representation.coordinate_mask(locked.mask).to(device)  # (D,)
            self.locked_clean = representation.encode(locked.values.to(device))  # (M, D)
        self.active = locked is not None or constraints.partial is not None or bool(constraints.others)

    def adjust_estimate(self, index: int, clean: torch.Tensor) -> None:
        if not self.active:
            return
        joints = self.representation.decode(clean)  # (M, J)
        fraction = self.sampler.timesteps[index] / self.sampler.schedule.num_timesteps
        for item in self.constraints.others:
            if not item.guides_at(fraction):
                continue
            step = item.guide(joints)
            if step is not None:
                joints = joints + step.to(joints)
        if self.constraints.partial is not None:
            joints = joints + self.constraints.partial.guide_toward(joints, self.row_targets)
        joints = self.constraints.hold(self.arm.normalize_joints(joints))
        clean.copy_(self.representation.encode(joints))

    def adjust_state(self, index: int, state: torch.Tensor, generator: torch.Generator | None) -> None:
        locked = self.constraints.locked
        if locked is None or not locked.repaint:
            return
        t_next = self.sampler.previous_timestep(index)
        floats = self.sampler.schedule.floats
        alpha = 1.0 if t_next < 0 else floats["sqrt_alphas_cumprod"][t_next]
        sigma = 0.0 if t_next < 0 else floats["sqrt_one_minus_alphas_cumprod"][t_next]
        noised = self.locked_clean * alpha
        if sigma > 0:
            # drawn where the generator lives (a CUDA generator cannot draw on the CPU), then moved to the state
            noise = torch.randn(state.shape, generator=generator, device=drawing_device(generator))
            noised = noised + sigma * noise.to(state)
        state.copy_(torch.where(self.locked_coordinates, noised, state))


class ConstrainedTask:
    """What damped least squares minimises under constraints (ikdp.refine.RefineTask)."""

    def __init__(self, constraints: ConstraintSet, max_miss_fraction: float = 0.2):
        self.constraints = constraints
        self.arm = constraints.arm
        self.max_position = max_miss_fraction * self.arm.span

    def _target_rows(self, joints, targets):
        partial = self.constraints.partial
        if partial is None:
            return self.arm.task_error(joints, targets), None
        return partial.task_error(joints, targets), partial

    def error(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        error, _ = self._target_rows(joints, targets)
        penetrations = self.penetrations(joints)
        return error if penetrations is None else torch.cat([error, -penetrations[0]], dim=-1)

    def linearize(self, joints: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        error, partial = self._target_rows(joints, targets)
        position_dim = self.arm.position_dim if partial is None else partial.position_dim
        error = clamp_task_error(error, position_dim, self.max_position, math.pi / 4)
        jacobian = self.arm.jacobian(joints) if partial is None else partial.jacobian(joints, targets)
        return error, self._free_columns(jacobian)

    def penetrations(self, joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | None:
        rows = joints.reshape(-1, joints.shape[-1])
        found = [item.penetration_rows(rows) for item in self.constraints.others]
        found = [item for item in found if item is not None]
        if not found:
            return None
        depths = torch.cat([depth for depth, _ in found], dim=-1).reshape(*joints.shape[:-1], -1)
        gradients = torch.cat([gradient for _, gradient in found], dim=-2)
        return depths, self._free_columns(gradients.reshape(*joints.shape[:-1], -1, joints.shape[-1]))

    def _free_columns(self, jacobian: torch.Tensor) -> torch.Tensor:
        """The locked joints' columns zeroed, so no step moves them."""
        if self.constraints.locked is None:
            return jacobian
        return jacobian * ~self.constraints.locked.mask.to(jacobian.device)

    def hold(self, joints: torch.Tensor) -> torch.Tensor:
        return self.constraints.hold(joints)
