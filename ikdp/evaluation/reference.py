"""Target sets, and reference samples of theta given t drawn by rejection from a prior.

The reference for a target t: draw poses from the prior, keep those whose tip lands
within `radius` of t (rejection sampling of p(theta | tip near t)), then close the
last gap with a few damped-least-squares steps so every reference pose reaches t
exactly. The polish moves each pose by at most about `radius`, the minimum-norm way.
"""

from __future__ import annotations

import torch

from ikdp.arm import PlanarArm, uniform_angles
from ikdp.priors import PosePrior
from ikdp.refine import damped_least_squares


def targets_from_prior(prior: PosePrior, count: int, arm: PlanarArm, *, generator: torch.Generator):
    """FK of poses from the prior: (targets (B, 2), the poses that made them (B, N))."""
    headings = prior.sample(count, arm, generator=generator)
    return arm.end_effector(headings), headings


def targets_in_disk(count: int, arm: PlanarArm, *, generator: torch.Generator) -> torch.Tensor:
    """Targets uniform over the reachable annulus (a disk when the links are equal): (B, 2)."""
    inner, outer = arm.reach
    radius = torch.sqrt(inner**2 + torch.rand(count, generator=generator) * (outer**2 - inner**2))
    angle = uniform_angles((count,), generator=generator)
    return torch.stack((radius * torch.cos(angle), radius * torch.sin(angle)), dim=-1)


def rejection_reference(
    prior: PosePrior,
    targets: torch.Tensor,
    arm: PlanarArm,
    *,
    count: int,
    radius: float,
    generator: torch.Generator,
    chunk: int = 2**19,
    max_draws: int = 2**25,
    polish_steps: int = 8,
) -> tuple[torch.Tensor, torch.Tensor, int]:
    """`count` poses per target from p(theta | t).

    Returns (reference (B', count, N), complete (B,) bool, draws): the targets where the
    prior put so little mass that `max_draws` draws did not yield `count` poses are left
    out (complete is False there), and draws is the number of prior draws made.
    """
    batch, num_links = targets.shape[0], arm.num_joints
    kept = [[] for _ in range(batch)]
    have = torch.zeros(batch, dtype=torch.long)
    draws = 0
    while int(have.min()) < count:
        if draws >= max_draws:
            break
        headings = prior.sample(chunk, arm, generator=generator)  # (C, N)
        tips = arm.end_effector(headings)
        draws += chunk
        hits = torch.cdist(targets, tips) < radius  # (B, C)
        for row in torch.nonzero(have < count).flatten().tolist():
            found = headings[hits[row]][: count - int(have[row])]
            if len(found):
                kept[row].append(found)
                have[row] += len(found)
    complete = have >= count
    if not complete.any():
        return torch.empty(0, count, num_links), complete, draws
    reference = torch.stack([torch.cat(kept[row])[:count] for row in torch.nonzero(complete).flatten().tolist()])
    goals = targets[complete][:, None].expand(-1, count, -1)
    return damped_least_squares(arm, reference, goals, steps=polish_steps), complete, draws
