"""Denoisers map (x_t, t, target) to a prediction (x_0 or the noise), nothing else."""

from __future__ import annotations

from torch import nn

from ikdp.denoisers.config import DENOISER_KINDS, DenoiserConfig
from ikdp.denoisers.film import FiLMDenoiser
from ikdp.denoisers.mlp import MLPDenoiser
from ikdp.denoisers.paper import PaperDenoiser
from ikdp.representation import AngleRepresentation

__all__ = ["DENOISER_KINDS", "DenoiserConfig", "FiLMDenoiser", "MLPDenoiser", "PaperDenoiser", "build_denoiser"]

_CLASSES = {"film": FiLMDenoiser, "mlp": MLPDenoiser, "paper": PaperDenoiser}


def build_denoiser(config: DenoiserConfig, representation: AngleRepresentation, arm) -> nn.Module:
    if config.kind not in DENOISER_KINDS:
        raise ValueError(f"denoiser: expected one of {DENOISER_KINDS}, got {config.kind!r}")
    return _CLASSES[config.kind](config, representation, arm)
