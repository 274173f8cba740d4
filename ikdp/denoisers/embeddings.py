"""Sinusoidal timestep embedding (Vaswani et al. 2017, as in DDPM)."""

from __future__ import annotations

import math

import torch


def sinusoidal_embedding(t: torch.Tensor, dim: int, *, max_period: float = 10_000.0) -> torch.Tensor:
    """t: (M,) integer or float timesteps -> (M, dim)."""
    half = dim // 2
    frequencies = torch.exp(-math.log(max_period) * torch.arange(half, dtype=torch.float32, device=t.device) / half)
    angles = t.float()[:, None] * frequencies[None]
    return torch.cat((torch.cos(angles), torch.sin(angles)), dim=-1)
