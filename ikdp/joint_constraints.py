"""Constraints on the joints themselves: some held at given values, all pulled toward a pose.

Locked joints are sampled by inpainting: their coordinates are replaced at every reverse step
(ikdp/guidance.py), so the free joints are drawn from p(θ | target, locked). A pose to stay
near is guidance: each step's x̂0 is moved part of the way toward it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import ClassVar

import torch

from ikdp.constraint_base import BoundConstraint, Constraint, finite_tensor, joint_difference, joint_index, per_row
from ikdp.kinematics import wrap_angle


# --- locked joints ------------------------------------------------------------------------------
@dataclass(frozen=True)
class LockedJoints(Constraint):
    """Joints held at given values: `{name or index: value}`, a value for all targets or one per target (B,).

    Sampled by inpainting (the locked coordinates replaced at every step) from p(θ | target,
    locked); the refinement never moves them, and the returned poses hold them exactly.
    """

    values: Mapping  # joint name or 0-based index -> a value (radians, metres), or a sequence of B values
    repaint: bool = True  # also replace the locked coordinates of each state by their noised values (RePaint)
    name: ClassVar[str] = "locked_joints"

    def bind(self, arm, batch: int, num_samples: int) -> BoundLockedJoints:
        if not isinstance(self.values, Mapping) or not self.values:
            raise ValueError(f"locked_joints: expected a non-empty {{joint: value}} mapping, got {self.values!r}")
        mask = torch.zeros(arm.num_joints, dtype=torch.bool)
        values = torch.zeros(batch * num_samples, arm.num_joints, dtype=torch.float64)
        limits = arm.joint_limits
        named_as = {}  # joint index -> the key that locked it: a name and an index may name the same joint
        for key, value in self.values.items():
            index = joint_index(arm, key)
            if index in named_as:
                raise ValueError(
                    f"locked_joints: joint {index} is locked twice, as {named_as[index]!r} and as {key!r}; lock it once"
                )
            named_as[index] = key
            label = f"locked_joints: joint {key!r}"
            value = finite_tensor(value, label)
            if bool(arm.continuous_joints[index]):  # a heading or a continuous joint: any angle, wrapped
                value = wrap_angle(value)
            elif limits is not None:
                lower, upper = float(limits[index, 0]), float(limits[index, 1])
                outside = (value < lower) | (value > upper)
                if outside.any():
                    bad = float(value[outside].flatten()[0])
                    raise ValueError(f"{label}: value {bad:.6g} outside its limits [{lower:.6g}, {upper:.6g}]")
            mask[index] = True
            values[:, index] = per_row(value, batch, num_samples, 0, label)
        # the float32 value a float32 pose holds: "exactly" is then exact in the dtype returned
        return BoundLockedJoints(mask=mask, values=values.float(), repaint=self.repaint)


@dataclass
class BoundLockedJoints(BoundConstraint):
    mask: torch.Tensor  # (J,) True where locked
    values: torch.Tensor  # (M, J) the locked values (others zero)
    repaint: bool

    def hold(self, joints: torch.Tensor) -> torch.Tensor:
        """(M, J) or (B, K, J) -> the same with the locked joints set to their values exactly."""
        values = self.values.to(device=joints.device, dtype=joints.dtype).reshape(*joints.shape[:-1], -1)
        return torch.where(self.mask.to(joints.device), values, joints)

    def violation(self, joints: torch.Tensor) -> torch.Tensor:
        values = self.values.to(device=joints.device, dtype=joints.dtype).reshape(*joints.shape[:-1], -1)
        return ((joints - values).abs() * self.mask.to(joints.device)).sum(dim=-1)

    def of_rows(self, rows: torch.Tensor) -> BoundLockedJoints:
        return replace(self, values=self.values[rows])


# --- near a pose ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class NearPose(Constraint):
    """Pull samples toward a configuration (the robot's current one): small joint motions along a path.

    `weight` is the share of the way to `pose` that each step's x̂0 is moved: 0 ignores the pose,
    1 would replace the estimate by it. A soft constraint: it never fails a check.
    """

    pose: Sequence | torch.Tensor  # (J,) joint values, or (B, J) one per target
    weight: float = 0.3  # per step, the share of the distance to `pose` removed from x̂0
    name: ClassVar[str] = "near_pose"

    def bind(self, arm, batch: int, num_samples: int) -> BoundNearPose:
        pose = finite_tensor(self.pose, "near_pose: pose")
        if pose.ndim not in (1, 2) or pose.shape[-1] != arm.num_joints:
            raise ValueError(
                f"near_pose: pose expected shape ({arm.num_joints},) or (B, {arm.num_joints}), got {tuple(pose.shape)}"
            )
        if not 0 <= self.weight <= 1:
            raise ValueError(f"near_pose: weight expected in [0, 1], got {self.weight}")
        if int(arm.limit_violations(pose, tolerance=1e-6).sum()):
            raise ValueError(f"near_pose: pose {pose.tolist()} is outside the joint limits")
        return BoundNearPose(arm, per_row(pose, batch, num_samples, 1, "near_pose: pose").float(), self.weight)


@dataclass
class BoundNearPose(BoundConstraint):
    arm: object
    pose: torch.Tensor  # (M, J)
    weight: float

    def guide(self, joints):
        reference = self.pose.to(device=joints.device, dtype=joints.dtype)
        return -self.weight * joint_difference(self.arm, joints, reference)

    def restart_from(self, starts: torch.Tensor) -> torch.Tensor:
        """A restart stays near the pose too: its first start is the pose itself (the seed a numerical IK takes
        from the robot's current joints), the next ones a growing share of the way to the uniform draws, the
        last one the draw (K starts: shares 0, 1/(K-1), ..., 1), so the fallback still explores."""
        reference = self.pose.to(device=starts.device, dtype=starts.dtype).reshape(starts.shape)
        share = torch.linspace(0, 1, starts.shape[1], device=starts.device, dtype=starts.dtype)[:, None]
        return reference + share * joint_difference(self.arm, starts, reference)

    def of_rows(self, rows: torch.Tensor) -> BoundNearPose:
        return replace(self, pose=self.pose[rows])
