"""Reverse-diffusion samplers: each owns its timesteps and its update; one registry.

A sampler is built for a schedule and a number of steps. It precomputes every
coefficient its update needs as Python floats (indexing a tensor per step costs
more than the step's arithmetic), and `step()` writes x_{next} from x_t and the
denoiser's clean estimate x̂0 into a buffer it is given, so the loop allocates
nothing per step. Timesteps are 0-based indices, noisiest first; after the last
listed timestep every sampler lands on the clean end (alpha_cumprod = 1).

    sampler = make_sampler("dpmpp2m", schedule, steps=10)               # evenly spaced timesteps
    sampler = make_sampler("dpmpp2m", schedule, 8, spacing="quadratic")  # packed near t = 0
    for index, t in enumerate(sampler.timesteps):
        clean = ...                                  # the denoiser's x̂0 at (x, t)
        sampler.step(index, x, clean, out=x_next, generator=generator)
"""

from __future__ import annotations

import math
from typing import ClassVar

import torch

from ikdp.schedule import TIMESTEP_SPACINGS, DiffusionSchedule


class Sampler:
    """One reverse-diffusion method. Subclasses set `name`, `supports_steps`, `precompute` and `step`."""

    name: ClassVar[str]
    supports_steps: ClassVar[bool]  # False: the method always runs all T steps
    deterministic: ClassVar[bool]  # True: no noise is drawn after the initial x_T
    _noise: torch.Tensor | None = None  # stochastic samplers: the buffer each step's noise is drawn into

    def __init__(
        self,
        schedule: DiffusionSchedule,
        steps: int | None = None,
        *,
        timesteps: list[int] | None = None,
        spacing: str = "uniform",
    ):
        if spacing not in TIMESTEP_SPACINGS:
            raise ValueError(f"spacing: expected one of {TIMESTEP_SPACINGS}, got {spacing!r}")
        self.schedule = schedule
        self.spacing = spacing
        self.timesteps = list(timesteps) if timesteps is not None else self.default_timesteps(schedule, steps)
        if not self.timesteps or any(not 0 <= t < schedule.num_timesteps for t in self.timesteps):
            raise ValueError(f"timesteps: expected values in [0, {schedule.num_timesteps}), got {self.timesteps}")
        if any(later >= earlier for earlier, later in zip(self.timesteps, self.timesteps[1:], strict=False)):
            raise ValueError(f"timesteps: expected strictly decreasing values, got {self.timesteps}")
        self.precompute(schedule)

    def precompute(self, schedule: DiffusionSchedule) -> None:
        """Every coefficient the update needs at self.timesteps, as Python floats (subclasses)."""

    @property
    def num_steps(self) -> int:
        return len(self.timesteps)

    def timestep_tensor(self, device: torch.device) -> torch.Tensor:
        """`timesteps` as a tensor on `device`, made once per device: a CUDA graph's capture may not copy from
        the host, and its warm-up run makes this first."""
        tensors = self.__dict__.setdefault("_timestep_tensors", {})
        if device not in tensors:
            tensors[device] = torch.tensor(self.timesteps, device=device)
        return tensors[device]

    def previous_timestep(self, index: int) -> int:
        """The timestep step `index` lands on; -1 is the clean end."""
        return self.timesteps[index + 1] if index + 1 < len(self.timesteps) else -1

    def default_timesteps(self, schedule: DiffusionSchedule, steps: int | None) -> list[int]:
        return schedule.timestep_grid(steps, self.spacing)

    def reset(self) -> None:
        """Forget the history of a previous run (multistep samplers keep one)."""

    def _add_noise(self, out: torch.Tensor, scale: float, generator: torch.Generator | None) -> torch.Tensor:
        """out += scale z, z ~ N(0, I) drawn into a buffer kept between steps; nothing drawn when scale is 0."""
        if scale > 0:
            noise = self._noise
            if noise is None or noise.shape != out.shape or noise.device != out.device:
                noise = self._noise = torch.empty_like(out)
            torch.randn(out.shape, generator=generator, out=noise)
            out.add_(noise, alpha=scale)
        return out

    def step(
        self,
        index: int,
        sample: torch.Tensor,
        clean: torch.Tensor,
        *,
        out: torch.Tensor,
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """x_t (M, D) and x̂0 (M, D) at timesteps[index] -> x at the next timestep, written into `out`."""
        raise NotImplementedError


def _alpha(schedule: DiffusionSchedule, t: int) -> float:
    """sqrt(alpha_cumprod) at t, 1 at the clean end (t = -1)."""
    return 1.0 if t < 0 else schedule.floats["sqrt_alphas_cumprod"][t]


def _sigma(schedule: DiffusionSchedule, t: int) -> float:
    """sqrt(1 - alpha_cumprod) at t, 0 at the clean end (t = -1)."""
    return 0.0 if t < 0 else schedule.floats["sqrt_one_minus_alphas_cumprod"][t]


class DDPMSampler(Sampler):
    """The paper's Algorithm 2 (Ho et al. 2020): ancestral sampling through all T steps."""

    name = "ddpm"
    supports_steps = False
    deterministic = False

    def precompute(self, schedule: DiffusionSchedule) -> None:
        floats = schedule.floats
        # q(x_{t-1} | x_t, x_0) = N(coef_clean x_0 + coef_noisy x_t, sigma_t^2)  (Ho eq. 6-7)
        self.coef_clean = [floats["posterior_mean_coef_clean"][t] for t in self.timesteps]
        self.coef_noisy = [floats["posterior_mean_coef_noisy"][t] for t in self.timesteps]
        self.noise_scale = [math.sqrt(floats["posterior_variance"][t]) if t > 0 else 0.0 for t in self.timesteps]

    def default_timesteps(self, schedule: DiffusionSchedule, steps: int | None) -> list[int]:
        if steps not in (None, schedule.num_timesteps):
            total = schedule.num_timesteps
            raise ValueError(f"steps: DDPM runs all {total} steps, got {steps}; use 'ddim' or 'dpmpp2m' for fewer")
        return list(range(schedule.num_timesteps - 1, -1, -1))  # all T steps: every spacing agrees

    def step(self, index, sample, clean, *, out, generator=None):
        # 1. the mean of the posterior q(x_{t-1} | x_t, x̂0): a blend of the clean estimate and x_t
        torch.mul(clean, self.coef_clean[index], out=out)
        out.add_(sample, alpha=self.coef_noisy[index])
        # 2. plus sigma_t z, z ~ N(0, I); none at the last step (t = 0)
        return self._add_noise(out, self.noise_scale[index], generator)


class DDIMSampler(Sampler):
    """Deterministic DDIM (Song et al. 2021, eq. 12 with eta = 0) on any number of strided steps."""

    name = "ddim"
    supports_steps = True
    deterministic = True

    def precompute(self, schedule: DiffusionSchedule) -> None:
        # x_prev = a_prev x̂0 + s_prev eps, eps = (x_t - a_t x̂0) / s_t
        #        = (s_prev / s_t) x_t + (a_prev - s_prev a_t / s_t) x̂0
        self.coef_noisy, self.coef_clean = [], []
        for index, t in enumerate(self.timesteps):
            t_prev = self.previous_timestep(index)
            ratio = _sigma(schedule, t_prev) / _sigma(schedule, t)
            self.coef_noisy.append(ratio)
            self.coef_clean.append(_alpha(schedule, t_prev) - ratio * _alpha(schedule, t))

    def step(self, index, sample, clean, *, out, generator=None):
        # 1. the noise x_t implies given x̂0; 2. x̂0 re-noised to the level of t_prev along that same noise
        torch.mul(clean, self.coef_clean[index], out=out)
        out.add_(sample, alpha=self.coef_noisy[index])
        return out

    def update(self, index: int, sample: torch.Tensor, clean: torch.Tensor) -> torch.Tensor:
        """step()'s x_next as a new tensor that keeps the graph: ikdp.distill trains a student through it."""
        return self.coef_clean[index] * clean + self.coef_noisy[index] * sample


class AncestralSampler(Sampler):
    """DDPM's ancestral update on any number of strided steps: x_prev ~ q(x_prev | x_t, x̂0).

    The posterior between two timesteps t > t' (Ho et al. 2020, eq. 6-7, with abar_t / abar_t' for
    alpha_t) is DDIM's update with eta = 1 (Song et al. 2021, eq. 12, 16):
        x_prev = a' x̂0 + sqrt(s'^2 - v) eps + sqrt(v) z,  eps = (x_t - a x̂0) / s,
        v = (s'^2 / s^2) (1 - a^2 / a'^2),   a = sqrt(abar), s = sqrt(1 - abar).
    On all T steps it is the DDPM's own update; on a few, packed near t = 0, it keeps the stochastic
    sampler's small tail where the deterministic ones lose it (benchmarks/few_step.py,
    benchmarks/results/few_step.json).
    """

    name = "ancestral"
    supports_steps = True
    deterministic = False

    def precompute(self, schedule: DiffusionSchedule) -> None:
        self.coef_noisy, self.coef_clean, self.noise_scale = [], [], []
        for index, t in enumerate(self.timesteps):
            t_prev = self.previous_timestep(index)
            alpha, sigma = _alpha(schedule, t), _sigma(schedule, t)
            alpha_prev, sigma_prev = _alpha(schedule, t_prev), _sigma(schedule, t_prev)
            variance = (sigma_prev / sigma) ** 2 * (1 - (alpha / alpha_prev) ** 2)
            direction = math.sqrt(max(sigma_prev**2 - variance, 0.0)) / sigma  # the share of eps kept
            self.coef_noisy.append(direction)
            self.coef_clean.append(alpha_prev - direction * alpha)
            self.noise_scale.append(math.sqrt(variance))

    def step(self, index, sample, clean, *, out, generator=None):
        # 1. the posterior's mean: x̂0 re-noised to t_prev along part of the implied noise
        torch.mul(clean, self.coef_clean[index], out=out)
        out.add_(sample, alpha=self.coef_noisy[index])
        # 2. plus its standard deviation times z ~ N(0, I); none on the last step (t_prev = -1)
        return self._add_noise(out, self.noise_scale[index], generator)


class DPMSolverPP2MSampler(Sampler):
    """DPM-Solver++(2M) (Lu et al. 2022, Alg. 2): second-order multistep in the data prediction.

    With lambda = log(alpha / sigma) and h = lambda_next - lambda_t:
        x_next = (sigma_next / sigma_t) x_t - alpha_next (e^-h - 1) D
    where D = x̂0 on the first step and the last (which lands on sigma = 0 and returns x̂0),
    and D = (1 + 1/(2r)) x̂0 - 1/(2r) x̂0_previous otherwise, r = h_previous / h.
    """

    name = "dpmpp2m"
    supports_steps = True
    deterministic = True

    def precompute(self, schedule: DiffusionSchedule) -> None:
        self.coef_noisy, self.coef_clean, self.coef_previous = [], [], []
        previous_h = None
        for index, t in enumerate(self.timesteps):
            t_next = self.previous_timestep(index)
            alpha_next, sigma_next = _alpha(schedule, t_next), _sigma(schedule, t_next)
            sigma_t = _sigma(schedule, t)
            if t_next < 0:  # the clean end: sigma = 0, x_next = x̂0
                self.coef_noisy.append(0.0)
                self.coef_clean.append(1.0)
                self.coef_previous.append(0.0)
                continue
            lambda_t = math.log(_alpha(schedule, t) / sigma_t)
            h = math.log(alpha_next / sigma_next) - lambda_t
            data_coef = -alpha_next * math.expm1(-h)  # alpha_next (1 - e^-h)
            self.coef_noisy.append(sigma_next / sigma_t)
            if previous_h is None:  # first step: first order
                self.coef_clean.append(data_coef)
                self.coef_previous.append(0.0)
            else:
                half_inverse_r = 0.5 * h / previous_h
                self.coef_clean.append(data_coef * (1 + half_inverse_r))
                self.coef_previous.append(-data_coef * half_inverse_r)
            previous_h = h
        self._previous_clean: torch.Tensor | None = None

    def reset(self) -> None:
        self._previous_clean = None

    def step(self, index, sample, clean, *, out, generator=None):
        if index == 0:
            self.reset()
        previous = self._previous_clean
        if self.coef_previous[index] != 0.0 and previous is None:
            raise ValueError("dpmpp2m: a second-order step needs the previous x̂0; run the steps in order from 0")
        torch.mul(clean, self.coef_clean[index], out=out)
        out.add_(sample, alpha=self.coef_noisy[index])
        if self.coef_previous[index] != 0.0:
            out.add_(previous, alpha=self.coef_previous[index])
        # keep x̂0 for the next step; the caller may reuse `clean`'s buffer, so copy into our own
        if previous is None or previous.shape != clean.shape or previous.device != clean.device:
            self._previous_clean = clean.clone()
        else:
            previous.copy_(clean)
        return out


SAMPLERS: dict[str, type[Sampler]] = {
    cls.name: cls for cls in (DDPMSampler, DDIMSampler, DPMSolverPP2MSampler, AncestralSampler)
}


def sampler_names() -> tuple[str, ...]:
    return tuple(SAMPLERS)


def make_sampler(name: str, schedule: DiffusionSchedule, steps: int | None = None, spacing: str = "uniform") -> Sampler:
    """The sampler called `name` for `schedule`, its `steps` timesteps spread by `spacing` (TIMESTEP_SPACINGS).

    ValueError naming the choices otherwise.
    """
    if name not in SAMPLERS:
        raise ValueError(f"sampler: expected one of {sampler_names()}, got {name!r}")
    return SAMPLERS[name](schedule, steps, spacing=spacing)
