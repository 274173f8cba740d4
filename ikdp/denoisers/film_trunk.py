"""The FiLM residual trunk the MLP denoisers share: the condition network, normed blocks, the residual pass.

Functions, not a module of their own: each denoiser keeps the pieces under its own attribute
names (`condition_net`, `norms`, `blocks`), so the checkpoints' weight names and the order of
parameters (and so of optimizer state and of the seeded initialisation) stay what they were.
"""

from __future__ import annotations

import torch
from torch import nn


def condition_network(time_dim: int, condition_dim: int, hidden: int, blocks: int) -> nn.Sequential:
    """(time embedding, target features) -> a FiLM scale and shift per block, flattened: (M, blocks * 2 * hidden)."""
    return nn.Sequential(nn.Linear(time_dim + condition_dim, hidden), nn.SiLU(), nn.Linear(hidden, blocks * 2 * hidden))


def normed_blocks(hidden: int, blocks: int) -> tuple[nn.ModuleList, nn.ModuleList]:
    """`blocks` residual layers, each with a parameter-free LayerNorm before its FiLM."""
    norms = nn.ModuleList(nn.LayerNorm(hidden, elementwise_affine=False) for _ in range(blocks))
    return norms, nn.ModuleList(nn.Linear(hidden, hidden) for _ in range(blocks))


def film_residual_pass(h: torch.Tensor, film: torch.Tensor, norms: nn.ModuleList, blocks: nn.ModuleList):
    """h: (M, hidden), film: (M, >= blocks, 2, hidden) scale then shift -> h after every residual block."""
    for index, (norm, block) in enumerate(zip(norms, blocks, strict=True)):
        h = h + block(nn.functional.silu(torch.addcmul(film[:, index, 1], norm(h), film[:, index, 0])))
    return h
