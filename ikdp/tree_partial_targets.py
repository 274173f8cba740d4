"""Partial targets for a tree: per end effector, which parts of its target count.

    solver.solve(targets, constraints=[ikdp.PositionOnly(effectors={"right_hand": "position"})])  # left: its pose
    solver.solve(targets, constraints=[ikdp.PositionOnly(effectors={"left_hand": "free"})])  # right: its pose

Each end effector's part is "pose" (position and rotation), "position" (any rotation) or "free" (no target:
its row is ignored); those `effectors` does not name keep the tree's own target kind. It is the chain's
position-only target (ikdp/partial_targets.py) said per end effector, and works the same way: the model
was trained on every hand's full pose, so each of a target's K samples is conditioned on a full pose that
meets the partial target (a random pose of the tree whose asked positions lie nearest the target's gives
the parts left open), and guidance and refinement work on the asked rows of the stacked task alone.

Errors: `tip_and_rotation_errors` are the worst over the asked parts (a free hand's position and a
position-only hand's rotation do not count toward reaching), `errors_by_effector` each hand's, NaN where
that part was not asked.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from ikdp.constraint_base import BoundConstraint
from ikdp.refine import clamp_task_error, dls_step

PARTS = ("pose", "position", "free")
ROTATION_POOL = 4096  # random poses of the tree the conditions draw their open parts from
GUIDE_DAMPING = 1e-2  # as a chain's partial target: x̂0 early on is far from any solution


def effector_parts(arm, effectors: Mapping[str, str] | None, name: str) -> tuple[str, ...]:
    """Each end effector's part in `arm.ee_links`' order; None: every one's position only."""
    if effectors is None:
        return ("position",) * arm.num_effectors
    if not isinstance(effectors, Mapping):
        raise ValueError(f"{name}: effectors expected a mapping of end effector to part {PARTS}, got {effectors!r}")
    unknown = [link for link in effectors if link not in arm.ee_links]
    if unknown:
        raise ValueError(f"{name}: effectors: unknown end effector {unknown[0]!r}, expected one of {arm.ee_links}")
    bad = {link: part for link, part in effectors.items() if part not in PARTS}
    if bad:
        raise ValueError(f"{name}: effectors: expected parts in {PARTS}, got {bad}")
    own = "pose" if arm.target == "pose" else "position"
    parts = tuple(
        effectors.get(link, own) if arm.target == "pose" else ("free" if effectors.get(link) == "free" else own)
        for link in arm.ee_links
    )
    if all(part == "free" for part in parts):
        raise ValueError(f"{name}: effectors: every end effector is free; keep at least one target")
    return parts


def validate_tree_targets(arm, parts: tuple[str, ...], targets) -> torch.Tensor:
    """(B, E, 7) or (B, E, 3) (no end effector's pose counting), or the flat rows -> the flat rows (B, target_dim)
    with an identity rotation where the rotation is not asked and the zero pose's position where the position
    is not (so any numbers may stand there)."""
    count, width = arm.num_effectors, arm.per_effector_dim
    try:
        tensor = torch.as_tensor(
            targets if isinstance(targets, torch.Tensor) else np.asarray(targets, np.float32), dtype=torch.float32
        )
    except (TypeError, ValueError, RuntimeError) as error:
        expected = f"(B, {count}, {width})"
        raise ValueError(f"targets: expected numbers of shape {expected}, could not read them ({error})") from None
    if tensor.ndim == 2 and tensor.shape[1] == arm.target_dim:
        tensor = arm.stacked_targets(tensor)
    widths = (3,) if width == 3 else (7, 3)
    if tensor.ndim != 3 or tensor.shape[1] != count or tensor.shape[2] not in widths or tensor.shape[0] == 0:
        raise ValueError(
            f"targets: expected shape (B, {count}, {' or '.join(map(str, widths))}), one row per end effector "
            f"{arm.ee_links}, with B >= 1, got {tuple(tensor.shape)}"
        )
    if width == 7:
        if tensor.shape[2] == 3:
            posed = [link for link, part in zip(arm.ee_links, parts, strict=True) if part == "pose"]
            if posed:
                raise ValueError(f"targets: {posed[0]!r}'s pose counts, expected (B, {count}, 7), got (B, {count}, 3)")
            tensor = torch.cat([tensor, tensor.new_zeros(tensor.shape[:2] + (4,))], dim=-1)
        identity = tensor.new_tensor([1.0, 0.0, 0.0, 0.0])
        open_rotation = torch.tensor([part != "pose" for part in parts])[None, :, None]
        tensor = torch.cat([tensor[..., :3], torch.where(open_rotation, identity, tensor[..., 3:])], dim=-1)
    # a free hand's position: where it is at the zero pose, a point within its reach, so that `reachable` and
    # the workspace clamp judge the asked parts alone
    free = torch.tensor([part == "free" for part in parts])[None, :, None]
    rest = arm.end_effector_frame(torch.zeros(arm.num_joints))[1]  # (E, 3)
    tensor = torch.cat([torch.where(free, rest, tensor[..., :3]), tensor[..., 3:]], dim=-1)
    return arm.validate_targets(tensor)


@dataclass
class BoundEffectorParts(BoundConstraint):
    """A tree's partial target: the rows of its stacked task (every position's, then every rotation's) asked."""

    arm: object
    parts: tuple[str, ...]  # (E,) "pose", "position" or "free"
    weight: float  # per step, the share of a least-squares step on the asked rows applied to x̂0

    def __post_init__(self):
        count = self.arm.num_effectors
        positions = [3 * e + axis for e, part in enumerate(self.parts) if part != "free" for axis in range(3)]
        rotations = [3 * (count + e) + axis for e, part in enumerate(self.parts) if part == "pose" for axis in range(3)]
        self.rows = torch.tensor(positions + rotations)  # the stacked task's rows that count
        self.position_dim = len(positions)  # the leading asked rows that are positions (refinement's clamp)
        self.asked_positions = torch.tensor([part != "free" for part in self.parts])  # (E,)
        self.asked_rotations = torch.tensor([part == "pose" for part in self.parts])  # (E,)

    def conditions(self, targets: torch.Tensor, num_samples: int, generator: torch.Generator | None) -> torch.Tensor:
        """targets (B, target_dim) -> a full target per sample (B * K, target_dim): the asked parts as given, the
        others from the K pool poses whose asked positions lie nearest."""
        arm, batch = self.arm, len(targets)
        pool = arm.end_effector(arm.random_poses(max(ROTATION_POOL, num_samples), generator=generator)).to(targets)
        asked = arm.stacked_targets(targets)  # (B, E, w)
        drawn = arm.stacked_targets(pool)  # (P, E, w)
        positions = self.asked_positions.to(targets.device)
        distance = torch.cdist(asked[:, positions, :3].flatten(1), drawn[:, positions, :3].flatten(1))
        nearest = drawn[distance.topk(num_samples, largest=False).indices]  # (B, K, E, w)
        given = asked[:, None].expand_as(nearest)
        keep = torch.cat(
            [
                positions[:, None].expand(-1, 3),
                self.asked_rotations.to(targets.device)[:, None].expand(-1, nearest.shape[-1] - 3),
            ],
            dim=-1,
        )  # (E, w): where the target's own numbers stand
        return arm.flat_targets(torch.where(keep, given, nearest)).reshape(batch * num_samples, -1)

    def task_error(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(..., J), (..., target_dim) -> the asked rows of the stacked task error."""
        return self.arm.task_error(joints, targets)[..., self.rows.to(joints.device)]

    def jacobian(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """(..., J) -> the asked rows' Jacobian (..., R, J): a step dq changes them by -J dq."""
        return self.arm.jacobian(joints)[..., self.rows.to(joints.device), :]

    def of_rows(self, rows: torch.Tensor) -> BoundEffectorParts:
        return self  # nothing per row: each row's full target is in the solve's goals

    def errors_by_effector(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Each end effector's position error (..., E) and (poses) rotation error (..., E); NaN where not asked."""
        position, rotation = self.arm.errors_by_effector(joints, targets)
        nan = torch.tensor(math.nan, device=position.device)
        position = torch.where(self.asked_positions.to(position.device), position, nan)
        if rotation is not None:
            rotation = torch.where(self.asked_rotations.to(rotation.device), rotation, nan)
        return position, rotation

    def tip_and_rotation_errors(self, joints, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The worst asked position error (...) and the worst asked rotation error (...), None where none is asked."""
        position, rotation = self.errors_by_effector(joints, targets)
        worst_position = position.nan_to_num(0.0).amax(dim=-1)
        if rotation is None or not bool(self.asked_rotations.any()):
            return worst_position, None
        return worst_position, rotation.nan_to_num(0.0).amax(dim=-1)

    def rotation_error(self, joints, targets: torch.Tensor) -> torch.Tensor | None:
        return self.tip_and_rotation_errors(joints, targets)[1]

    def guide_toward(self, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """joints (M, J), targets (M, target_dim) -> `weight` times a damped least-squares step on the asked rows."""
        error = clamp_task_error(self.task_error(joints, targets), self.position_dim, 0.2 * self.arm.span, math.pi / 4)
        return self.weight * dls_step(self.jacobian(joints, targets), error, GUIDE_DAMPING**2)
