"""Denoisers map (x_t, t, target) to a prediction (x_0 or the noise), nothing else."""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.chain_film import ChainFiLMDenoiser
from ikdp.denoisers.config import DENOISER_KINDS, DenoiserConfig
from ikdp.denoisers.film import FiLMDenoiser
from ikdp.denoisers.mlp import MLPDenoiser
from ikdp.denoisers.paper import PaperDenoiser
from ikdp.representation import AngleRepresentation

__all__ = [
    "DENOISER_KINDS",
    "ChainFiLMDenoiser",
    "DenoiserConfig",
    "FiLMDenoiser",
    "MLPDenoiser",
    "PaperDenoiser",
    "build_denoiser",
]

_CLASSES = {"film": FiLMDenoiser, "chain_film": ChainFiLMDenoiser, "mlp": MLPDenoiser, "paper": PaperDenoiser}


def build_denoiser(
    config: DenoiserConfig, representation: AngleRepresentation, arm, noise_levels: torch.Tensor | None = None
) -> nn.Module:
    """`noise_levels`: the schedule's sigma_t (T,), which the chain denoiser's DLS skip starts from."""
    if config.kind not in DENOISER_KINDS:
        raise ValueError(f"denoiser: expected one of {DENOISER_KINDS}, got {config.kind!r}")
    if config.kind == "chain_film":
        return ChainFiLMDenoiser(config, representation, arm, noise_levels)
    return _CLASSES[config.kind](config, representation, arm)
