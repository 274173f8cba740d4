"""FABRIK (Aristidou & Lasenby 2011), batched over targets and restarts.

Works on joint positions, not angles: a backward pass pins the tip on the target and
walks to the base keeping every bone's length, a forward pass pins the base back at
the origin and walks out again. The headings are read off the final positions.
A target beyond reach ends with the arm stretched toward it, as in the paper's
algorithm.
"""

from __future__ import annotations

import math

import torch

from ikdp.kinematics import forward_kinematics, tip_position


def _place(anchor: torch.Tensor, toward: torch.Tensor, length: torch.Tensor) -> torch.Tensor:
    """The point at `length` from `anchor` on the ray to `toward`; (..., 2)."""
    direction = toward - anchor
    norm = direction.norm(dim=-1, keepdim=True)
    # coincident points give no direction: keep the bone along +x rather than divide by zero
    unit = torch.where(norm > 1e-12, direction / norm.clamp_min(1e-12), torch.tensor([1.0, 0.0]).to(direction))
    return anchor + length * unit


def fabrik(
    link_headings: torch.Tensor, targets: torch.Tensor, lengths: torch.Tensor, *, iterations: int = 20
) -> torch.Tensor:
    """link_headings: (..., N) starting poses, targets: (..., 2) -> solved headings (..., N)."""
    if iterations < 0:
        raise ValueError(f"iterations: expected a non-negative integer, got {iterations}")
    lengths = lengths.double()
    targets = targets.double()
    positions = list(forward_kinematics(link_headings.double(), lengths).unbind(-2))  # N+1 tensors (..., 2)
    base = positions[0].clone()
    num_links = len(positions) - 1
    for _ in range(iterations):
        positions[num_links] = targets  # backward: tip on the target, walk to the base
        for joint in reversed(range(num_links)):
            positions[joint] = _place(positions[joint + 1], positions[joint], lengths[joint])
        positions[0] = base  # forward: base back at the origin, walk to the tip
        for joint in range(num_links):
            positions[joint + 1] = _place(positions[joint], positions[joint + 1], lengths[joint])
    bones = torch.stack(positions[1:], dim=-2) - torch.stack(positions[:-1], dim=-2)  # (..., N, 2)
    return torch.atan2(bones[..., 1], bones[..., 0]).to(link_headings.dtype)


def solve_fabrik(
    targets: torch.Tensor,
    lengths: torch.Tensor,
    *,
    restarts: int = 1,
    iterations: int = 20,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """targets: (B, 2) -> (headings (B, K, N), tip_error (B, K)), K = restarts from uniformly random poses."""
    batch, num_links = targets.shape[0], lengths.shape[0]
    starts = (torch.rand(batch, restarts, num_links, generator=generator) * 2 - 1) * math.pi
    goals = targets[:, None].expand(-1, restarts, -1)
    headings = fabrik(starts, goals, lengths, iterations=iterations)
    error = (tip_position(headings.double(), lengths.double()) - goals.double()).norm(dim=-1).float()
    return headings, error
