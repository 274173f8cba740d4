"""Arms: what the solver, the denoisers, training and the viewer know of a robot.

An arm owns its kinematics (forward kinematics, the end-effector Jacobian), its
targets (their dimension, validation, the workspace and clamping onto it) and the
draw of random poses. Everything above it takes an arm, never `lengths` plus a
hard-wired `(B, 2)`. `PlanarArm` is the paper's N-link arm; a spatial chain read
from a URDF is a second class with the same methods (ikdp/chain_arm.py).

The pose of a planar arm is its vector of absolute link headings, radians.
"""

from __future__ import annotations

import math

import torch

from ikdp.arm_inputs import drawing_device, validate_target_rows
from ikdp.kinematics import (
    forward_kinematics,
    project_to_workspace,
    reach,
    tip_jacobian,
    tip_position,
    wrap_angle,
)
from ikdp.refine import RefinedByDampedLeastSquares


def uniform_angles(
    shape: tuple[int, ...],
    *,
    generator: torch.Generator | None = None,
    like: torch.Tensor | None = None,
    device: torch.device | None = None,
) -> torch.Tensor:
    """Angles uniform on [-pi, pi), any shape: the draw of random headings and random restarts.

    `like`: drawn on its device and in its dtype; else on `device` (default: the CPU). `generator` lives there.
    """
    where = {"device": device} if like is None else {"device": like.device, "dtype": like.dtype}
    return (torch.rand(shape, generator=generator, **where) * 2 - 1) * math.pi


class PlanarArm(RefinedByDampedLeastSquares):
    """The paper's planar arm: N links of given lengths, pose = absolute link headings (N,)."""

    kind = "planar"
    target_dim = 2  # a target is a point (x, y) for the tip
    position_dim = 2  # the leading target entries that are a position
    space_dim = 2  # a point in the arm's space: the plane
    condition_dim = 2  # the size of target_features: what a denoiser is conditioned on
    joint_limits = None  # headings live on the circle: no limits, poses wrap

    def __init__(self, lengths):
        lengths = tuple(float(length) for length in lengths)
        if len(lengths) < 1 or any(not length > 0 for length in lengths):
            raise ValueError(f"lengths: expected one or more positive bone lengths, got {lengths}")
        self.lengths = lengths
        self._lengths64 = torch.tensor(lengths, dtype=torch.float64)
        self._lengths_by_device: dict = {}

    def __repr__(self) -> str:
        return f"PlanarArm(lengths={self.lengths})"

    def __eq__(self, other) -> bool:
        return isinstance(other, PlanarArm) and other.lengths == self.lengths

    def __hash__(self) -> int:
        return hash(("planar", self.lengths))

    # --- description -------------------------------------------------------------------------
    @property
    def num_joints(self) -> int:
        return len(self.lengths)

    num_links = num_joints

    @property
    def continuous_joints(self) -> torch.Tensor:
        """(N,) bool: every heading wraps at +-pi, as a robot's continuous joints do."""
        return torch.ones(self.num_joints, dtype=torch.bool)

    def limit_violations(self, headings: torch.Tensor, *, tolerance: float = 1e-6) -> torch.Tensor:
        """(..., N) -> (...,) 0: a heading has no limits to leave."""
        return torch.zeros(headings.shape[:-1], dtype=torch.long, device=headings.device)

    @property
    def reach(self) -> tuple[float, float]:
        """(inner, outer) radius of the annulus the tip can reach."""
        return reach(self.lengths)

    @property
    def span(self) -> float:
        """A length scale of the workspace: the outer reach."""
        return self.reach[1]

    @property
    def position_tolerance(self) -> float:
        """How near the tip must come for a target to count as reached: 1e-3 of the reach, in bone lengths."""
        return 1e-3 * self.span

    rotation_tolerance = math.radians(1.0)  # radians; a planar target has no rotation, so it never applies

    def to_config(self) -> dict:
        return {"kind": self.kind, "lengths": list(self.lengths)}

    def lengths_like(self, tensor: torch.Tensor) -> torch.Tensor:
        """The bone lengths in `tensor`'s dtype and on its device, copied there once (a CUDA graph's capture
        may not copy from the host)."""
        key = (tensor.dtype, tensor.device)
        if key not in self._lengths_by_device:
            self._lengths_by_device[key] = self._lengths64.to(device=tensor.device, dtype=tensor.dtype)
        return self._lengths_by_device[key]

    # --- kinematics --------------------------------------------------------------------------
    def forward_kinematics(self, headings: torch.Tensor) -> torch.Tensor:
        """(..., N) -> every joint, base first and tip last, (..., N+1, 2)."""
        headings = torch.as_tensor(headings)
        if not headings.is_floating_point():
            headings = headings.float()
        return forward_kinematics(headings, self.lengths_like(headings))

    def end_effector(self, headings: torch.Tensor) -> torch.Tensor:
        """(..., N) -> the tip, (..., 2)."""
        return tip_position(headings, self.lengths_like(headings))

    def jacobian(self, headings: torch.Tensor) -> torch.Tensor:
        """(..., N) -> d tip / d headings, (..., 2, N)."""
        return tip_jacobian(headings, self.lengths_like(headings))

    def task_error(self, headings: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """The vector from the tip to the target, (..., 2): what damped least squares drives to zero."""
        return targets - self.end_effector(headings)

    def task_error_and_jacobian(
        self, headings: torch.Tensor, targets: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """`task_error` and `jacobian` together (a robot computes both from one pass of its kinematics)."""
        return self.task_error(headings, targets), self.jacobian(headings)

    def tip_error(self, headings: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """Distance from the tip to the target, (...), computed in float64 and returned as float32.

        headings (..., N) and targets broadcastable to (..., 2). Float64 because refined poses
        land within 1e-6, where float32's FK would report its own rounding.
        """
        headings = headings.double()
        tip = tip_position(headings, self.lengths_like(headings))
        return (tip - targets.double()).norm(dim=-1).float()

    def tip_and_rotation_errors(self, headings: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, None]:
        """`tip_error`, and no rotation error: a planar target is a point."""
        return self.tip_error(headings, targets), None

    def small_batch_kinematics(self) -> PlanarArm:
        """The arm itself: its kinematics are closed-form sums over the links already, a few operations for any
        batch (ChainArm's counterpart fuses a chain's)."""
        return self

    def with_default_constraints(self, constraints) -> list:
        """The constraints a solve runs: those given (a tree adds its self-collision check)."""
        return list(constraints)

    def collision_spheres(self, held_joints=None) -> None:
        """None: obstacles meet the bones themselves, segments in the plane (a robot's links are sphere covers)."""
        if held_joints:
            raise ValueError(f"obstacles: held_joints: a planar arm has no joints off its chain, got {held_joints!r}")
        return None

    def position_only_targets(self, constraint, targets) -> torch.Tensor:
        """`PositionOnly`'s targets: a planar arm's targets are positions already, so it has none."""
        from ikdp.partial_targets import require_pose_model

        require_pose_model(self, constraint.name)

    def bind_position_only(self, constraint):
        """`PositionOnly.bind` (see `position_only_targets`)."""
        self.position_only_targets(constraint, None)

    def errors_by_effector(self, headings: torch.Tensor, targets: torch.Tensor) -> None:
        """None: one end effector, whose errors are `tip_and_rotation_errors` (a tree gives one per end effector)."""
        return None

    def target_features(self, targets: torch.Tensor) -> torch.Tensor:
        """What a denoiser is conditioned on: the target in units of the reach, (..., 2)."""
        return targets / self.span

    def normalize_joints(self, headings: torch.Tensor) -> torch.Tensor:
        """Put poses back in their canonical range after a step: headings wrap into (-pi, pi]."""
        return wrap_angle(headings)

    def blocked_by_limits(self, headings: torch.Tensor, step: torch.Tensor) -> None:
        """No joint is ever held by a limit: headings wrap (ChainArm answers with a mask)."""
        return None

    # --- targets -----------------------------------------------------------------------------
    def validate_targets(self, targets) -> torch.Tensor:
        """Array-like (B, 2) -> float32 tensor (B, 2); ValueError naming the problem otherwise."""
        return validate_target_rows(targets, self.target_dim)

    def is_reachable(self, targets: torch.Tensor) -> torch.Tensor:
        """(B, 2) -> (B,) True where the tip can reach the target."""
        inner, outer = self.reach
        radius = targets.norm(dim=-1)
        return (radius <= outer + 1e-6) & (radius >= inner - 1e-6)

    def clamp_to_workspace(self, targets: torch.Tensor) -> torch.Tensor:
        """(..., 2) -> the nearest reachable point to each target."""
        return project_to_workspace(targets, self.lengths)

    # --- poses -------------------------------------------------------------------------------
    def random_poses(self, count: int, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """`count` poses with every heading uniform on the circle, (count, N), on the generator's device."""
        return uniform_angles((count, self.num_joints), generator=generator, device=drawing_device(generator))

    def random_poses_like(self, like: torch.Tensor, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """Poses shaped like `like` (..., N), on its device, from a generator there: no host copy (CUDA graphs)."""
        return uniform_angles(like.shape, generator=generator, like=like)


def arm_from_config(config: dict):
    """Rebuild an arm from `to_config()`; ValueError if the description is not one we know."""
    kind = config.get("kind")
    if kind == "planar":
        return PlanarArm(config["lengths"])
    if kind == "chain":
        from ikdp.chain_arm import ChainArm  # spatial chains pull in the URDF reader only when used

        return ChainArm.from_config(config)
    if kind == "tree":
        from ikdp.tree_arm import TreeArm

        return TreeArm.from_config(config)
    raise ValueError(f"arm: unknown kind {kind!r}, expected 'planar', 'chain' or 'tree'")
