"""Cyclic coordinate descent (CCD, Wang & Chen 1991), batched over targets and restarts.

One sweep visits the joints from the tip back to the base; each visit turns joint j
(and every link after it) by the angle that points the tip ray from joint j at the
target. Planar CCD needs no Jacobian: the best turn of one joint is an atan2.
"""

from __future__ import annotations

import torch

from ikdp.arm import PlanarArm
from ikdp.kinematics import wrap_angle


def ccd(link_headings: torch.Tensor, targets: torch.Tensor, arm: PlanarArm, *, sweeps: int = 20) -> torch.Tensor:
    """link_headings: (..., N) starting poses, targets: (..., 2) -> polished headings (..., N)."""
    if sweeps < 0:
        raise ValueError(f"sweeps: expected a non-negative integer, got {sweeps}")
    headings = link_headings.double().clone()
    targets = targets.double()
    num_links = headings.shape[-1]
    for _ in range(sweeps):
        for joint in reversed(range(num_links)):
            positions = arm.forward_kinematics(headings)  # (..., N+1, 2)
            pivot = positions[..., joint, :]
            to_tip = positions[..., -1, :] - pivot
            to_target = targets - pivot
            cross = to_tip[..., 0] * to_target[..., 1] - to_tip[..., 1] * to_target[..., 0]
            dot = (to_tip * to_target).sum(-1)
            headings[..., joint:] += torch.atan2(cross, dot)[..., None]
    return wrap_angle(headings).to(link_headings.dtype)
