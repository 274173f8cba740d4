"""Denoisers map (x_t, t, target) to an estimate of the clean sample x_0, nothing else."""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.config import DENOISER_KINDS, DenoiserConfig
from ikdp.denoisers.film import FiLMDenoiser
from ikdp.denoisers.paper import PaperDenoiser
from ikdp.representation import AngleRepresentation

__all__ = ["DENOISER_KINDS", "DenoiserConfig", "FiLMDenoiser", "PaperDenoiser", "build_denoiser"]


def build_denoiser(config: DenoiserConfig, representation: AngleRepresentation, lengths: torch.Tensor) -> nn.Module:
    if config.kind not in DENOISER_KINDS:
        raise ValueError(f"denoiser: expected one of {DENOISER_KINDS}, got {config.kind!r}")
    cls = FiLMDenoiser if config.kind == "film" else PaperDenoiser
    return cls(config, representation, lengths)
