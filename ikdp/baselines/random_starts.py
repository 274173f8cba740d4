"""Numerical IK from uniformly random starts: the one wrapper CCD, FABRIK and DLS share.

K random poses per target, each polished by a local solver, all in one batch. A polish
maps (starting poses (B, K, N), goals (B, K, 2), arm) to solved poses (B, K, N); the
solvers differ only there.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from ikdp.arm import PlanarArm, uniform_angles
from ikdp.refine import damped_least_squares

Polish = Callable[[torch.Tensor, torch.Tensor, PlanarArm], torch.Tensor]


def solve_from_random_starts(
    polish: Polish,
    targets: torch.Tensor,
    arm: PlanarArm,
    *,
    restarts: int = 1,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """targets: (B, 2) -> (headings (B, K, N), tip_error (B, K)) with K = restarts, each from a uniform pose."""
    if restarts < 1:
        raise ValueError(f"restarts: expected a positive integer, got {restarts}")
    starts = uniform_angles((targets.shape[0], restarts, arm.num_joints), generator=generator)  # (B, K, N)
    goals = targets[:, None].expand(-1, restarts, -1)  # (B, K, 2)
    headings = polish(starts, goals, arm)
    return headings, arm.tip_error(headings, goals)


def dls_polish(*, iterations: int = 10, damping: float = 1e-3) -> Polish:
    """Damped least squares (ikdp.refine) as a polish: `iterations` steps with the given damping."""

    def polish(starts: torch.Tensor, goals: torch.Tensor, arm: PlanarArm) -> torch.Tensor:
        return damped_least_squares(arm, starts, goals, steps=iterations, damping=damping)

    return polish
