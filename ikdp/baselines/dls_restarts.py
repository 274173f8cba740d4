"""Damped least squares from uniformly random starts: the numerical baseline.

K random poses per target, each polished by `iterations` DLS steps, all in one batch.
"""

from __future__ import annotations

import math

import torch

from ikdp.arm import PlanarArm
from ikdp.kinematics import tip_position
from ikdp.refine import damped_least_squares


def solve_dls_restarts(
    targets: torch.Tensor,
    lengths: torch.Tensor,
    *,
    restarts: int = 16,
    iterations: int = 10,
    damping: float = 1e-3,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """targets: (B, 2) -> (headings (B, K, N), tip_error (B, K)) with K = restarts."""
    batch, num_links = targets.shape[0], lengths.shape[0]
    starts = (torch.rand(batch, restarts, num_links, generator=generator) * 2 - 1) * math.pi
    goals = targets[:, None].expand(-1, restarts, -1)
    headings = damped_least_squares(PlanarArm(lengths.tolist()), starts, goals, steps=iterations, damping=damping)
    error = (tip_position(headings.double(), lengths.double()) - goals.double()).norm(dim=-1).float()
    return headings, error
