"""FABRIK (Aristidou & Lasenby 2011), batched over targets and restarts.

Works on joint positions, not angles: a backward pass pins the tip on the target and
walks to the base keeping every bone's length, a forward pass pins the base back at
the origin and walks out again. The headings are read off the final positions.
A target beyond reach ends with the arm stretched toward it, as in the paper's
algorithm.
"""

from __future__ import annotations

import torch

from ikdp.arm import PlanarArm


def _place(anchor: torch.Tensor, toward: torch.Tensor, length: torch.Tensor) -> torch.Tensor:
    """The point at `length` from `anchor` on the ray to `toward`; (..., 2)."""
    direction = toward - anchor
    norm = direction.norm(dim=-1, keepdim=True)
    # coincident points give no direction: keep the bone along +x rather than divide by zero
    unit = torch.where(norm > 1e-12, direction / norm.clamp_min(1e-12), torch.tensor([1.0, 0.0]).to(direction))
    return anchor + length * unit


def fabrik(link_headings: torch.Tensor, targets: torch.Tensor, arm: PlanarArm, *, iterations: int = 20) -> torch.Tensor:
    """link_headings: (..., N) starting poses, targets: (..., 2) -> solved headings (..., N)."""
    if iterations < 0:
        raise ValueError(f"iterations: expected a non-negative integer, got {iterations}")
    lengths = torch.tensor(arm.lengths, dtype=torch.float64)
    targets = targets.double()
    positions = list(arm.forward_kinematics(link_headings.double()).unbind(-2))  # N+1 tensors (..., 2)
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
