"""The conditional diffusion model of IK: an arm, a representation, a schedule and a denoiser.

Two verbs, as in diffusion_policy: `compute_loss(headings)` for training
(paper Algorithm 1) and `sample(targets)` for solving (Algorithm 2, or DDIM).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import torch
from torch import nn

from ikdp.denoisers import DenoiserConfig, build_denoiser
from ikdp.kinematics import tip_position
from ikdp.representation import AngleRepresentation
from ikdp.sampling import Trajectory, run_reverse_diffusion
from ikdp.schedule import PREDICTION_KINDS, DiffusionSchedule, ScheduleConfig


@dataclass(frozen=True)
class ModelConfig:
    lengths: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)  # bone lengths; their count is the number of links N
    representation: str = "cossin"  # what is diffused: angle (the paper's theta/pi) or cossin (wrap-free)
    prediction: str = "sample"  # what the denoiser predicts: sample (x_0, paper Alg. 1) or epsilon
    schedule: ScheduleConfig = field(default_factory=ScheduleConfig)
    denoiser: DenoiserConfig = field(default_factory=DenoiserConfig)

    def __post_init__(self):
        if len(self.lengths) < 1 or any(not length > 0 for length in self.lengths):
            raise ValueError(f"lengths: expected one or more positive bone lengths, got {self.lengths}")
        if self.prediction not in PREDICTION_KINDS:
            raise ValueError(f"prediction: expected one of {PREDICTION_KINDS}, got {self.prediction!r}")

    @property
    def num_links(self) -> int:
        return len(self.lengths)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> ModelConfig:
        return cls(
            lengths=tuple(float(length) for length in values["lengths"]),
            representation=values["representation"],
            prediction=values["prediction"],
            schedule=ScheduleConfig(**values["schedule"]),
            denoiser=DenoiserConfig(**values["denoiser"]),
        )


class IKDiffusion(nn.Module):
    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        self.register_buffer("lengths", torch.tensor(config.lengths, dtype=torch.float32), persistent=False)
        self.representation = AngleRepresentation(config.representation, config.num_links)
        self.schedule = DiffusionSchedule(config.schedule)
        self.denoiser = build_denoiser(config.denoiser, self.representation, self.lengths)

    def compute_loss(
        self,
        headings: torch.Tensor,
        *,
        tip_loss_weight: float = 0.0,
        snr_gamma: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> dict[str, torch.Tensor]:
        """Paper Algorithm 1 on a batch of ground-truth poses, headings: (B, N).

        Returns `loss` (what is minimised), `theta_loss` (MSE on the diffused vector, the
        paper's loss) and `tip_distance` (mean ||t - t_hat|| of the predicted clean pose,
        the paper's second curve). A positive `tip_loss_weight` adds the squared tip miss
        of the prediction to the loss: an FK-consistency term. A positive `snr_gamma`
        weights each sample by min(SNR_t, gamma) / gamma (Min-SNR, Hang et al. 2023): the
        noisiest steps, whose best answer is a blur, stop drowning out the last steps,
        where the pose's precision is decided.
        """
        batch = headings.shape[0]
        device = headings.device
        targets = tip_position(headings, self.lengths)  # (B, 2)
        clean = self.representation.encode(headings)  # (B, D)
        t = torch.randint(self.schedule.num_timesteps, (batch,), generator=generator).to(device)
        noise = torch.randn(clean.shape, generator=generator).to(device)
        noisy = self.schedule.add_noise(clean, noise, t)
        output = self.denoiser(noisy, t, targets)
        alpha = self.schedule.sqrt_alphas_cumprod.to(device)[t, None]
        sigma = self.schedule.sqrt_one_minus_alphas_cumprod.to(device)[t, None]
        if self.config.prediction == "sample":
            squared_error = (output - clean) ** 2
            predicted_clean = output
        else:
            squared_error = (output - noise) ** 2
            predicted_clean = (noisy - sigma * output) / alpha
        weight = torch.ones(batch, device=device)
        if snr_gamma > 0:
            snr = (alpha / sigma).squeeze(-1) ** 2
            weight = snr.clamp(max=snr_gamma) / snr_gamma
        predicted_tip = tip_position(self.representation.decode(predicted_clean), self.lengths)
        tip_miss = ((predicted_tip - targets) ** 2).sum(-1)  # (B,)
        per_sample = squared_error.mean(-1) + tip_loss_weight * tip_miss / self.lengths.sum() ** 2
        loss = (weight * per_sample).mean()
        return {
            "loss": loss,
            "theta_loss": squared_error.mean().detach(),
            "tip_distance": tip_miss.detach().sqrt().mean(),
        }

    @torch.inference_mode()
    def sample(
        self,
        targets: torch.Tensor,
        *,
        num_samples: int = 1,
        sampler: str = "ddpm",
        steps: int | None = None,
        generator: torch.Generator | None = None,
        return_trajectory: bool = False,
    ) -> Trajectory:
        """Reverse diffusion, targets: (B, 2) -> K = num_samples poses per target, (B, K, N), and the trajectory."""
        return run_reverse_diffusion(
            self.denoiser,
            self.schedule,
            self.representation,
            targets,
            num_samples=num_samples,
            prediction=self.config.prediction,
            sampler=sampler,
            steps=steps,
            generator=generator,
            return_trajectory=return_trajectory,
        )
