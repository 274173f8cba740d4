"""The DDPM noise schedule (Ho et al. 2020): betas, alphas and the forward process.

The schedule is not a network: it owns T, the betas and every constant derived
from them, computed in float64 and kept as float32. The reverse updates are the
samplers' (ikdp/samplers.py); they read their coefficients from here. Timesteps are 0-based
indices: index t here is the paper's step t+1, so t = T-1 is pure noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

SCHEDULE_KINDS = ("linear", "cosine", "karras")
PREDICTION_KINDS = ("epsilon", "sample")
# how a few-step sampler spreads its timesteps over [0, T-1]: evenly, or packed near t = 0 (quadratic)
TIMESTEP_SPACINGS = ("uniform", "quadratic")


@dataclass(frozen=True)
class ScheduleConfig:
    timesteps: int = 80  # T, the number of diffusion steps (the paper tries 40, 80, 100)
    kind: str = "linear"  # beta schedule: linear (DDPM) or cosine (Nichol & Dhariwal)
    beta_start: float = 1e-4  # linear betas at T=1000; scaled by 1000/T for other T
    beta_end: float = 0.02
    sigma_min: float = 0.002  # karras: the noise levels sigma = sqrt((1 - abar) / abar) at t = 0 and t = T-1,
    sigma_max: float = 80.0  # spaced as in EDM (Karras et al. 2022), so many steps sit at low noise
    rho: float = 7.0


def make_betas(config: ScheduleConfig) -> torch.Tensor:
    """Betas in float64, shape (T,)."""
    steps = config.timesteps
    if config.kind == "linear":
        scale = 1000 / steps  # keeps the total noise of DDPM's T=1000 schedule at any T
        return torch.linspace(scale * config.beta_start, scale * config.beta_end, steps, dtype=torch.float64).clamp(
            max=0.999
        )
    if config.kind == "karras":
        return karras_betas(steps, config.sigma_min, config.sigma_max, config.rho)
    s = 0.008
    x = torch.linspace(0, steps, steps + 1, dtype=torch.float64)
    alphas_cumprod = torch.cos(((x / steps) + s) / (1 + s) * math.pi / 2) ** 2
    alphas_cumprod = alphas_cumprod / alphas_cumprod[0]
    return (1 - alphas_cumprod[1:] / alphas_cumprod[:-1]).clamp(max=0.999)


def karras_betas(steps: int, sigma_min: float, sigma_max: float, rho: float) -> torch.Tensor:
    """A variance-preserving schedule with EDM's noise levels, (T,) float64.

    Why: a linear schedule at T = 100 leaves sigma = 0.03 at its last step (0.08 rad of noise on a
    Panda joint, ~0.1 m at the hand), which the last denoiser call must remove in one go; with
    rho = 7 a fifth of the steps lie below sigma = 0.1 and the last ones polish millimetres.
    """
    if not 0 < sigma_min < sigma_max:
        raise ValueError(f"karras schedule: expected 0 < sigma_min < sigma_max, got {sigma_min} and {sigma_max}")
    ramp = torch.linspace(0, 1, steps, dtype=torch.float64)
    low, high = sigma_min ** (1 / rho), sigma_max ** (1 / rho)
    sigmas = (low + ramp * (high - low)) ** rho  # rising with t
    alphas_cumprod = 1 / (1 + sigmas**2)
    previous = torch.cat((torch.ones(1, dtype=torch.float64), alphas_cumprod[:-1]))
    return (1 - alphas_cumprod / previous).clamp(max=0.999)


class DiffusionSchedule:
    def __init__(self, config: ScheduleConfig = ScheduleConfig()):
        if config.kind not in SCHEDULE_KINDS:
            raise ValueError(f"schedule kind: expected one of {SCHEDULE_KINDS}, got {config.kind!r}")
        if config.timesteps < 1:
            raise ValueError(f"timesteps: expected a positive integer, got {config.timesteps}")
        self.config = config
        self.num_timesteps = config.timesteps
        betas = make_betas(config)
        alphas = 1 - betas
        alphas_cumprod = torch.cumprod(alphas, dim=0)
        alphas_cumprod_prev = torch.nn.functional.pad(alphas_cumprod[:-1], (1, 0), value=1.0)
        # q(x_{t-1} | x_t, x_0) = N(coef_clean * x_0 + coef_noisy * x_t, posterior_variance)  (Ho eq. 6-7)
        posterior_variance = betas * (1 - alphas_cumprod_prev) / (1 - alphas_cumprod)
        as32 = lambda value: value.to(torch.float32)  # noqa: E731
        self.betas = as32(betas)
        self.alphas_cumprod = as32(alphas_cumprod)
        self.alphas_cumprod_prev = as32(alphas_cumprod_prev)
        self.sqrt_alphas_cumprod = as32(alphas_cumprod.sqrt())
        self.sqrt_one_minus_alphas_cumprod = as32((1 - alphas_cumprod).sqrt())
        self.posterior_variance = as32(posterior_variance)
        self.posterior_mean_coef_clean = as32(betas * alphas_cumprod_prev.sqrt() / (1 - alphas_cumprod))
        self.posterior_mean_coef_noisy = as32((1 - alphas_cumprod_prev) * alphas.sqrt() / (1 - alphas_cumprod))
        self._levels: dict[torch.device, tuple[torch.Tensor, torch.Tensor]] = {}  # levels_on's copies
        # Python floats for the sampling loop: indexing a tensor per step costs more than the step's arithmetic.
        self.floats = {
            name: getattr(self, name).tolist()
            for name in (
                "alphas_cumprod",
                "sqrt_alphas_cumprod",
                "sqrt_one_minus_alphas_cumprod",
                "posterior_variance",
                "posterior_mean_coef_clean",
                "posterior_mean_coef_noisy",
            )
        }

    def add_noise(self, clean: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Forward process q(x_t | x_0) = sqrt(abar_t) x_0 + sqrt(1 - abar_t) eps.  clean, noise: (B, D); t: (B,)."""
        if t.min() < 0 or t.max() >= self.num_timesteps:
            raise ValueError(f"timestep: expected values in [0, {self.num_timesteps}), got [{t.min()}, {t.max()}]")
        return self.mix(clean, noise, t.to(clean.device))

    def mix(self, clean: torch.Tensor, noise: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """`add_noise` for timesteps already on `clean`'s device and in range: it asks the device nothing (the range
        check reads t back), so a training step on a GPU captures it (ikdp/train_steps.py)."""
        signal, spread = self.levels_on(clean.device)
        return signal[t, None].to(clean) * clean + spread[t, None].to(clean) * noise

    def levels_on(self, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
        """(sqrt(abar_t), sqrt(1 - abar_t)) of every step, (T,) each, on `device`: copied there once, not per step."""
        device = torch.device(device)
        if device not in self._levels:
            self._levels[device] = (self.sqrt_alphas_cumprod.to(device), self.sqrt_one_minus_alphas_cumprod.to(device))
        return self._levels[device]

    def noise_levels(self) -> torch.Tensor:
        """sigma_t = sqrt((1 - abar_t) / abar_t) of every step, (T,): the noise of x_t / sqrt(abar_t)."""
        return self.sqrt_one_minus_alphas_cumprod / self.sqrt_alphas_cumprod

    def predict_clean(self, model_output: torch.Tensor, t: int, sample: torch.Tensor, prediction: str) -> torch.Tensor:
        """The denoiser's estimate of x_0, whatever it was trained to predict."""
        if prediction == "sample":
            return model_output
        if prediction != "epsilon":
            raise ValueError(f"prediction: expected one of {PREDICTION_KINDS}, got {prediction!r}")
        f = self.floats
        return (sample - f["sqrt_one_minus_alphas_cumprod"][t] * model_output) / f["sqrt_alphas_cumprod"][t]

    def timestep_grid(self, steps: int | None, spacing: str = "uniform") -> list[int]:
        """Timesteps from T-1 down to 0 for a run of `steps` steps (None = all T), noisiest first.

        `uniform`: evenly strided (DDIM's). `quadratic`: t_i = (T-1)(1 - i/(n-1))^2, rounded, packed
        near t = 0 where a few-step sampler's last steps decide the pose's millimetres (T = 100, n = 4:
        99, 44, 11, 0); where rounding would repeat a timestep it is raised to one above the next.
        """
        steps = self.num_timesteps if steps is None else steps
        if not 1 <= steps <= self.num_timesteps:
            raise ValueError(f"steps: expected 1 <= steps <= {self.num_timesteps}, got {steps}")
        if spacing not in TIMESTEP_SPACINGS:
            raise ValueError(f"spacing: expected one of {TIMESTEP_SPACINGS}, got {spacing!r}")
        if steps == 1:
            return [self.num_timesteps - 1]
        # both ends included: the last step denoises from t=0, where the model is most precise
        last = self.num_timesteps - 1
        if spacing == "uniform":
            return torch.linspace(last, 0, steps, dtype=torch.float64).round().long().tolist()
        fraction = torch.linspace(1, 0, steps, dtype=torch.float64)  # (steps,) from the noisy end to the clean one
        grid = (last * fraction**2).round().long().tolist()
        for index in range(steps - 2, -1, -1):  # strictly decreasing; never above T-1 when steps <= T
            grid[index] = max(grid[index], grid[index + 1] + 1)
        return grid
