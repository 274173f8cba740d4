"""The denoiser's hyperparameters, saved in every checkpoint to rebuild it."""

from __future__ import annotations

from dataclasses import dataclass

DENOISER_KINDS = ("film", "chain_film", "mlp", "paper")


@dataclass(frozen=True)
class DenoiserConfig:
    kind: str = "film"  # film / chain_film: kinematics-aware FiLM MLP, planar / spatial; mlp: plain; paper
    hidden: int = 128  # film, mlp: width of the residual MLP
    blocks: int = 3  # film, mlp: residual blocks
    kinematic_until: int = 0  # film, chain_film: give the tip miss and DLS step only at t < this (0: at every t)
    # chain_film: the kinematic features and the loss's FK term at joint values past a limit as they are (True),
    # or clamped into the limits (False, the first Panda model's): a clamped joint gets no FK gradient
    kinematics_past_limits: bool = False
    # chain_film: add the DLS step to the estimate through a gain per timestep and coordinate (starting at 1 at low
    # noise, 0 at high, plus a learned change), so the last steps take a solver's step instead of relearning it
    dls_skip: bool = False
    # the noise level (x units: 1 = half a joint's range) where that gain starts at 1/2; kept in the checkpoint, so
    # a model keeps the start it was trained with (xArm7 at step 1,000: 41 mm with 0.1, 57 mm with a gain of 1 at
    # every t, 126 mm from a gain of 0)
    dls_skip_noise: float = 0.1
    # chain_film: where a joint on its limit would be pushed further out, the DLS step is solved without it (as the
    # refinement does), instead of a step the clamp undoes; samples stuck at a limit were most of the raw tail
    limit_aware_step: bool = False
    time_dim: int = 64  # size of the sinusoidal timestep embedding
    model_dim: int = 64  # paper: transformer token width
    heads: int = 4  # paper: attention heads
    layers: int = 2  # paper: layers in the encoder and in the decoder
    mlp_hidden: int = 256  # paper: width of the MLP between encoder and decoder


def require_feature_width(kind: str, hidden: int, feature_dim: int) -> None:
    """The FiLM denoisers carry each input feature's scale in one hidden-wide row of the condition: refuse narrower."""
    if hidden < feature_dim:
        raise ValueError(f"denoiser {kind!r}: hidden ({hidden}) must be at least its {feature_dim} input features")
