"""Damped least squares (Levenberg-Marquardt) polish of poses toward their targets.

Each step: delta = J^T (J J^T + lambda^2 I)^-1 e, with J the 2xN tip Jacobian and
e the tip's miss vector. J J^T is 2x2, so its inverse is written out in closed
form: the whole batch moves in a few tensor ops.
"""

from __future__ import annotations

import torch

from ikdp.kinematics import tip_jacobian, tip_position, wrap_angle


def damped_least_squares(
    link_headings: torch.Tensor,
    targets: torch.Tensor,
    lengths: torch.Tensor,
    *,
    steps: int = 5,
    damping: float = 1e-3,
    max_miss_fraction: float = 0.2,
) -> torch.Tensor:
    """link_headings: (..., N), targets: (..., 2) -> refined headings (..., N), wrapped.

    Each step aims at most `max_miss_fraction` of the reach away (Buss's clamping):
    a far miss linearised in one jump overshoots and oscillates. Runs in float64:
    the last steps correct errors near float32's resolution.
    """
    if steps < 0:
        raise ValueError(f"refine steps: expected a non-negative integer, got {steps}")
    dtype = link_headings.dtype
    headings = link_headings.double()
    targets = targets.double()
    lengths = lengths.double()
    max_miss = max_miss_fraction * float(lengths.sum())
    for _ in range(steps):
        miss = targets - tip_position(headings, lengths)  # (..., 2)
        miss = miss * (max_miss / miss.norm(dim=-1, keepdim=True).clamp(min=max_miss))
        jacobian = tip_jacobian(headings, lengths)  # (..., 2, N)
        gram = jacobian @ jacobian.transpose(-1, -2)  # (..., 2, 2)
        a = gram[..., 0, 0] + damping**2
        b = gram[..., 0, 1]
        d = gram[..., 1, 1] + damping**2
        determinant = a * d - b * b
        # (J J^T + lambda^2 I)^-1 e by the 2x2 inverse formula
        solved = torch.stack((d * miss[..., 0] - b * miss[..., 1], a * miss[..., 1] - b * miss[..., 0]), dim=-1)
        solved = solved / determinant[..., None]
        headings = headings + (jacobian.transpose(-1, -2) @ solved[..., None])[..., 0]
    return wrap_angle(headings).to(dtype)
