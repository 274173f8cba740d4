"""The forward process q(x_t | x_0) of a pose, at every t of the schedule: a clean pose taken toward pure noise.

Training noises a pose in one jump, x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps (Ho et al. 2020, eq. 4),
so no step-by-step forward chain is needed: with one eps held for the whole run, the poses at t = 0 .. T
are the path a viewer shows when it "noises" a final pose along the same time axis as the reverse run.
The mixing happens in the model's representation (e.g. cossin), as in training; the result is decoded to
joint values, so it is drawn like any reverse state.
"""

from __future__ import annotations

import torch

from ikdp.representation import AngleRepresentation
from ikdp.schedule import DiffusionSchedule


def forward_trajectory(
    schedule: DiffusionSchedule,
    representation: AngleRepresentation,
    clean: torch.Tensor,
    noise: torch.Tensor,
) -> torch.Tensor:
    """Joint values (K, J) of clean poses and noise eps (K, D) -> x_t decoded to joints, (T+1, K, J).

    Row 0 is x_0 itself; row t (1 .. T) is q(x_t | x_0) at the schedule's index t - 1 (its 0-based
    timesteps: index T-1 is the noisiest), the same t a reverse run's states are drawn at.
    """
    joints = representation.num_links
    if clean.dim() != 2 or clean.shape[1] != joints:
        raise ValueError(f"clean: expected joint values of shape (K, {joints}), got {tuple(clean.shape)}")
    expected = (clean.shape[0], representation.dim)
    if tuple(noise.shape) != expected:
        raise ValueError(f"noise: expected eps of shape {expected}, got {tuple(noise.shape)}")
    encoded = representation.encode(clean.float())  # (K, D)
    signal = torch.cat((torch.ones(1), schedule.sqrt_alphas_cumprod))[:, None, None]  # (T+1, 1, 1)
    spread = torch.cat((torch.zeros(1), schedule.sqrt_one_minus_alphas_cumprod))[:, None, None]
    mixed = signal * encoded[None] + spread * noise.float()[None]  # (T+1, K, D)
    return representation.decode(mixed)
