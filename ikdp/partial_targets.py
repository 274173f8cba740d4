"""Partial targets for a pose model: the position only, or a rotation free about one axis.

A tree (several end effectors) says per end effector which parts count, `PositionOnly(effectors=...)`:
ikdp/tree_partial_targets.py.

The model was trained on full poses, so it is conditioned on one: each of a target's K samples
gets its own full pose that satisfies the partial target (position only: the rotation of a
random reachable pose whose hand lies nearest the target; free axis: the target's rotation
turned about the axis by K angles spread round the circle). Guidance and refinement then work
on the residual that matters: the position alone, or the position and the cross product of
the free axis as reached and as asked (zero exactly when the rotations differ only by a turn
about that axis).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar

import torch

from ikdp.arm_inputs import drawing_device, validate_target_rows
from ikdp.constraint_base import BoundConstraint, Constraint, finite_tensor
from ikdp.refine import clamp_task_error, dls_step
from ikdp.rotations import quaternion_multiply, quaternion_to_matrix

ROTATION_POOL = 4096  # random reachable poses the position-only conditions draw their rotations from
GUIDE_DAMPING = 1e-2  # damping of guidance's least-squares step: x̂0 early on is far from any solution


def require_pose_model(arm, name: str) -> None:
    if arm.kind == "tree":
        raise ValueError(f"{name}: a tree's partial targets are PositionOnly(effectors=...), got {arm!r}")
    if getattr(arm, "target_dim", 0) != 7:
        raise ValueError(f"{name}: partial targets need a pose model (targets of 7 numbers), got {arm!r}")


@dataclass(frozen=True)
class PositionOnly(Constraint):
    """Reach the target's position with any rotation; targets may be (B, 3) or (B, 7) (rotation ignored).

    A tree: `effectors` maps an end effector to the part of its target that counts, "position" or "free"
    (none: its row is ignored); the others keep their pose. None: every end effector's position only.
    """

    weight: float = 0.5  # per step, the share of a least-squares step on the position miss applied to x̂0
    effectors: Mapping[str, str] | None = None  # a tree's end effectors whose target is partial, by link name
    name: ClassVar[str] = "position_only"

    def validate_targets(self, arm, targets) -> torch.Tensor:
        return arm.position_only_targets(self, targets)

    def bind(self, arm, batch: int, num_samples: int) -> BoundPartialTarget:
        return arm.bind_position_only(self)


def check_one_effector(arm, constraint: PositionOnly) -> None:
    """ValueError unless `constraint` fits an arm of one end effector: a pose model, no `effectors`."""
    require_pose_model(arm, constraint.name)
    if constraint.effectors is not None:
        raise ValueError(
            f"{constraint.name}: effectors names the end effectors of a tree; this arm has one, "
            f"got {constraint.effectors!r}"
        )


def chain_position_only_targets(arm, constraint: PositionOnly, targets) -> torch.Tensor:
    """`ChainArm.position_only_targets`: (B, 3) positions or (B, 7) poses -> (B, 7), the rotation a placeholder."""
    check_one_effector(arm, constraint)
    rows = validate_target_rows(targets, 3) if _width(targets) == 3 else arm.validate_targets(targets)[:, :3]
    identity = torch.tensor([[1.0, 0.0, 0.0, 0.0]]).expand(len(rows), 4)
    return torch.cat([rows, identity], dim=-1)


def bind_chain_position_only(arm, constraint: PositionOnly) -> BoundPartialTarget:
    """`ChainArm.bind_position_only`."""
    check_one_effector(arm, constraint)
    return BoundPartialTarget(arm, None, checked_weight(constraint.weight, constraint.name))


@dataclass(frozen=True)
class FreeAxis(Constraint):
    """Reach the target's pose up to a turn about `axis` (in the end-effector's frame): a symmetric tool."""

    axis: Sequence | torch.Tensor = (0.0, 0.0, 1.0)  # (3,) in the end-effector link's frame (Panda hand: z)
    weight: float = 0.5  # per step, the share of a least-squares step on the residual applied to x̂0
    name: ClassVar[str] = "free_axis"

    def validate_targets(self, arm, targets) -> torch.Tensor:
        require_pose_model(arm, self.name)
        return arm.validate_targets(targets)

    def bind(self, arm, batch: int, num_samples: int) -> BoundPartialTarget:
        require_pose_model(arm, self.name)
        axis = finite_tensor(self.axis, "free_axis: axis")
        if axis.shape != (3,) or float(axis.norm()) < 1e-9:
            raise ValueError(f"free_axis: axis expected a non-zero vector of 3 numbers, got {axis.tolist()}")
        return BoundPartialTarget(arm, (axis / axis.norm()).float(), checked_weight(self.weight, self.name))


def _width(targets) -> int | None:
    shape = getattr(targets, "shape", None)
    if shape is None:
        try:
            return len(targets[0])
        except (TypeError, IndexError, KeyError):
            return None
    return shape[-1] if len(shape) == 2 else None


def checked_weight(weight: float, name: str) -> float:
    if not 0 <= weight <= 1:
        raise ValueError(f"{name}: weight expected in [0, 1], got {weight}")
    return float(weight)


def axis_turn(axis: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """axis (3,), angles (...) -> the quaternions (..., 4) of turns by `angles` about `axis`."""
    half = angles / 2
    return torch.cat([half.cos()[..., None], half.sin()[..., None] * axis], dim=-1)


@dataclass
class BoundPartialTarget(BoundConstraint):
    arm: object
    axis: torch.Tensor | None  # (3,) the free axis in the end-effector frame; None: position only
    weight: float
    position_dim: int = 3  # the leading rows of `task_error` that are positions (refinement's clamp)

    def conditions(self, targets: torch.Tensor, num_samples: int, generator: torch.Generator | None) -> torch.Tensor:
        """targets (B, 7) -> a full pose per sample, (B * K, 7), each meeting the partial target."""
        batch = len(targets)
        positions = targets[:, None, :3].expand(batch, num_samples, 3)
        if self.axis is None:
            pool = self.arm.end_effector(self.arm.random_poses(max(ROTATION_POOL, num_samples), generator=generator))
            nearest = torch.cdist(targets[:, :3], pool[:, :3].to(targets)).topk(num_samples, largest=False).indices
            rotations = pool[:, 3:].to(targets)[nearest]  # (B, K, 4)
        else:
            offset = torch.rand((batch, 1), generator=generator, device=drawing_device(generator)).cpu()
            angles = 2 * math.pi * (torch.arange(num_samples) + offset) / num_samples  # (B, K)
            turns = axis_turn(self.axis, angles).to(targets)
            rotations = quaternion_multiply(targets[:, None, 3:].expand(batch, num_samples, 4), turns)
        return torch.cat([positions, rotations], dim=-1).reshape(batch * num_samples, 7)

    def task_error(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(..., J), (..., 7) -> the residual that matters, (..., 3) or (..., 6).

        For a free axis, the rotation rows are a_reached x a_asked (the axis in the world, as
        reached and as asked): zero exactly when the two agree, whatever the turn about them.
        """
        rotation, position = self.arm.end_effector_frame(joints)
        position_error = targets[..., :3] - position
        if self.axis is None:
            return position_error
        reached = rotation @ self.axis.to(rotation)
        return torch.cat([position_error, torch.linalg.cross(reached, self._world_axis(targets))], dim=-1)

    def jacobian(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(..., J) -> the Jacobian of `task_error`'s rows, (..., 3 or 6, J): a step dq changes them by -J dq.

        d(a_r x a_t) = (w x a_r) x a_t = -[(a_t . a_r) I - a_r a_t^T] w for an angular velocity w.
        """
        jacobian = self.arm.jacobian(joints)
        if self.axis is None:
            return jacobian[..., :3, :]
        rotation, _ = self.arm.end_effector_frame(joints)
        reached, asked = rotation @ self.axis.to(rotation), self._world_axis(targets)
        eye = torch.eye(3, dtype=joints.dtype, device=joints.device)
        mixing = (reached * asked).sum(-1)[..., None, None] * eye - reached[..., :, None] * asked[..., None, :]
        return torch.cat([jacobian[..., :3, :], mixing @ jacobian[..., 3:, :]], dim=-2)

    def of_rows(self, rows: torch.Tensor) -> BoundPartialTarget:
        return self  # nothing per row: each row's full pose is in the solve's goals

    def _world_axis(self, targets: torch.Tensor) -> torch.Tensor:
        rotation = quaternion_to_matrix(targets[..., 3:7])
        return rotation @ self.axis.to(device=targets.device, dtype=targets.dtype)

    def rotation_error(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor | None:
        """(..., J) -> the angle (radians) between the free axis as reached and as asked; None for position only."""
        if self.axis is None:
            return None
        rotation, _ = self.arm.end_effector_frame(joints.double())
        axis = self.axis.to(rotation)
        reached, asked = rotation @ axis, self._world_axis(targets.double())
        return torch.atan2(torch.linalg.cross(reached, asked).norm(dim=-1), (reached * asked).sum(-1)).float()

    def tip_and_rotation_errors(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The position error (...) and `rotation_error` (...): what reaching this partial target means."""
        return self.arm.tip_error(joints, targets), self.rotation_error(joints, targets)

    def errors_by_effector(self, joints, targets: torch.Tensor) -> None:
        return None  # one end effector: its errors are `tip_and_rotation_errors`

    def guide_toward(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """joints (M, J), targets (M, 7) -> `weight` times a damped least-squares step on the residual."""
        error = clamp_task_error(self.task_error(joints, targets), self.position_dim, 0.2 * self.arm.span, math.pi / 4)
        return self.weight * dls_step(self.jacobian(joints, targets), error, GUIDE_DAMPING**2)
