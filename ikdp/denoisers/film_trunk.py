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
    """`blocks` residual layers, each with a parameter-free LayerNorm before its FiLM (`film_residual_pass` runs
    its op without weights)."""
    norms = nn.ModuleList(nn.LayerNorm(hidden, elementwise_affine=False) for _ in range(blocks))
    return norms, nn.ModuleList(nn.Linear(hidden, hidden) for _ in range(blocks))


def scale_and_shift(film: torch.Tensor) -> torch.Tensor:
    """The condition network's output (M, blocks, 2, hidden) -> FiLM scales (1 + output) and shifts.

    An added constant, not a stack of two slices: in training each slice's backward filled a zero tensor
    of the condition's full size (a quarter of a CPU training step on the xArm7). The constant is filled on
    the condition's device, not copied from the host: a CUDA graph may capture this.
    """
    one_then_zero = torch.zeros((2, 1), dtype=film.dtype, device=film.device)
    one_then_zero[0].fill_(1.0)  # fill_, not `= 1.0`: that assignment copies a host scalar
    return film + one_then_zero


def film_residual_pass(h: torch.Tensor, rows, norms: nn.ModuleList, blocks: nn.ModuleList):
    """h: (M, hidden), rows: film.unbind(1) of a condition (M, >= blocks, 2, hidden), each block's scale then
    shift -> h after every residual block.

    The caller unbinds the condition once: the backward of one unbind stacks the rows' gradients, where an
    index per block filled a zero tensor of the whole condition for each.
    """
    for row, norm, block in zip(rows, norms, blocks, strict=False):  # a chain denoiser's last row is not a block's
        scale, shift = row.unbind(1)
        # the norm's own op, not the module's call: its checks cost more than the op at one target's 16 rows
        normed = torch.layer_norm(h, norm.normalized_shape, None, None, norm.eps)
        h = h + block(nn.functional.silu(torch.addcmul(shift, normed, scale)))
    return h
