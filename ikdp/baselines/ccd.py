"""Cyclic coordinate descent (CCD, Wang & Chen 1991), batched over targets and restarts.

One sweep visits the joints from the tip back to the base; each visit turns joint j
(and every link after it) by the angle that points the tip ray from joint j at the
target. Planar CCD needs no Jacobian: the best turn of one joint is an atan2.
"""

from __future__ import annotations

import math

import torch

from ikdp.kinematics import forward_kinematics, tip_position, wrap_angle


def ccd(link_headings: torch.Tensor, targets: torch.Tensor, lengths: torch.Tensor, *, sweeps: int = 20) -> torch.Tensor:
    """link_headings: (..., N) starting poses, targets: (..., 2) -> polished headings (..., N)."""
    if sweeps < 0:
        raise ValueError(f"sweeps: expected a non-negative integer, got {sweeps}")
    headings = link_headings.double().clone()
    targets = targets.double()
    lengths = lengths.double()
    num_links = headings.shape[-1]
    for _ in range(sweeps):
        for joint in reversed(range(num_links)):
            positions = forward_kinematics(headings, lengths)  # (..., N+1, 2)
            pivot = positions[..., joint, :]
            to_tip = positions[..., -1, :] - pivot
            to_target = targets - pivot
            cross = to_tip[..., 0] * to_target[..., 1] - to_tip[..., 1] * to_target[..., 0]
            dot = (to_tip * to_target).sum(-1)
            headings[..., joint:] += torch.atan2(cross, dot)[..., None]
    return wrap_angle(headings).to(link_headings.dtype)


def solve_ccd(
    targets: torch.Tensor,
    lengths: torch.Tensor,
    *,
    restarts: int = 1,
    sweeps: int = 20,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """targets: (B, 2) -> (headings (B, K, N), tip_error (B, K)), K = restarts from uniformly random poses."""
    batch, num_links = targets.shape[0], lengths.shape[0]
    starts = (torch.rand(batch, restarts, num_links, generator=generator) * 2 - 1) * math.pi
    goals = targets[:, None].expand(-1, restarts, -1)
    headings = ccd(starts, goals, lengths, sweeps=sweeps)
    error = (tip_position(headings.double(), lengths.double()) - goals.double()).norm(dim=-1).float()
    return headings, error
