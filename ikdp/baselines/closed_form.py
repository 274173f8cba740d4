"""The exact two-link solution (law of cosines): the reference for N = 2.

Every reachable target has two solutions, elbow one way and the other (one when
the arm is fully stretched or folded). Targets beyond reach get the nearest pose.
"""

from __future__ import annotations

import torch

from ikdp.arm import PlanarArm
from ikdp.kinematics import wrap_angle


def two_link_solutions(targets: torch.Tensor, arm: PlanarArm) -> torch.Tensor:
    """targets: (B, 2) -> headings (B, 2, 2): [:, 0] bends the elbow counter-clockwise, [:, 1] clockwise."""
    if arm.num_joints != 2:
        raise ValueError(f"arm: the closed form is for two links, got {arm.num_joints}")
    targets = targets.double()
    first, second = torch.tensor(arm.lengths, dtype=torch.float64).unbind()
    squared_radius = (targets**2).sum(-1)
    cos_elbow = ((squared_radius - first**2 - second**2) / (2 * first * second)).clamp(-1.0, 1.0)
    elbow = torch.stack((torch.acos(cos_elbow), -torch.acos(cos_elbow)), dim=-1)  # (B, 2) relative joint angle
    direction = torch.atan2(targets[:, 1], targets[:, 0])[:, None]
    shoulder = direction - torch.atan2(second * torch.sin(elbow), first + second * torch.cos(elbow))
    return wrap_angle(torch.stack((shoulder, shoulder + elbow), dim=-1)).float()


def solve_two_link(
    targets: torch.Tensor, arm: PlanarArm, *, num_samples: int = 2, generator: torch.Generator | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """targets: (B, 2) -> (headings (B, K, 2), tip_error (B, K)); the K samples alternate the two elbows."""
    headings = two_link_solutions(targets, arm)[:, torch.arange(num_samples) % 2]
    return headings, arm.tip_error(headings, targets[:, None])
