"""The reverse diffusion loop: from pure noise to a pose, DDPM or DDIM.

One short loop, visible top to bottom. The denoiser's condition (time embedding
and target) does not depend on the noisy sample, so when it is small enough it
is computed for every step at once: one batched call instead of S small ones,
which is most of the speed of a single-target solve.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ikdp.representation import AngleRepresentation
from ikdp.schedule import DiffusionSchedule

SAMPLERS = ("ddpm", "ddim")
PRECOMPUTE_CONDITION_LIMIT = 16 * 2**20  # floats; above this the condition is computed per step


@dataclass
class Trajectory:
    headings: torch.Tensor  # (B, K, N) the final poses, radians in (-pi, pi]
    states: torch.Tensor | None  # (S+1, B, K, N) every state from pure noise to final, as headings
    timesteps: list[int]  # the S timesteps visited, noisiest first


def run_reverse_diffusion(
    denoiser,
    schedule: DiffusionSchedule,
    representation: AngleRepresentation,
    targets: torch.Tensor,
    *,
    num_samples: int = 1,
    prediction: str,
    sampler: str = "ddpm",
    steps: int | None = None,
    generator: torch.Generator | None = None,
    return_trajectory: bool = False,
) -> Trajectory:
    """targets: (B, 2) -> K = num_samples poses per target, (B, K, N)."""
    if sampler not in SAMPLERS:
        raise ValueError(f"sampler: expected one of {SAMPLERS}, got {sampler!r}")
    if sampler == "ddpm" and steps not in (None, schedule.num_timesteps):
        raise ValueError(f"steps: DDPM runs all {schedule.num_timesteps} steps; use sampler='ddim' for {steps}")
    timesteps = list(range(schedule.num_timesteps - 1, -1, -1)) if sampler == "ddpm" else schedule.ddim_timesteps(steps)
    batch = targets.shape[0]
    rows = batch * num_samples  # M: the K samples of a target are consecutive rows
    device = targets.device
    t_all = torch.tensor(timesteps, device=device)
    row_targets = targets.repeat_interleave(num_samples, dim=0)  # (M, 2)

    precomputed = None
    condition_size = len(timesteps) * rows * denoiser.condition(t_all[:1], targets[:1]).numel()
    if condition_size <= PRECOMPUTE_CONDITION_LIMIT:
        # every step's condition for every distinct target in one call (S*B rows), then spread over the K samples
        per_target = denoiser.condition(t_all.repeat_interleave(batch), targets.repeat(len(timesteps), 1))
        precomputed = per_target.unflatten(0, (len(timesteps), batch))
        if batch > 1:  # one target's condition broadcasts over its K rows as it is; several need spreading
            precomputed = precomputed.repeat_interleave(num_samples, dim=1)

    # theta_T ~ N(0, I)
    x = torch.randn((rows, representation.dim), generator=generator, device=device, dtype=targets.dtype)
    states = [x] if return_trajectory else None
    for index, t in enumerate(timesteps):
        if precomputed is not None:
            condition = precomputed[index]
        else:
            condition = denoiser.condition(t_all[index].expand(batch), targets)  # once per distinct target
            if batch > 1:
                condition = condition.repeat_interleave(num_samples, dim=0)
        output = denoiser.denoise(x, row_targets, condition)
        clean = schedule.predict_clean(output, t, x, prediction)
        if not (prediction == "sample" and getattr(denoiser, "output_on_manifold", False)):
            clean = representation.project(clean)
        if sampler == "ddpm":
            x = schedule.ddpm_step(clean, t, x, generator=generator)
        else:
            t_prev = timesteps[index + 1] if index + 1 < len(timesteps) else -1
            x = schedule.ddim_step(clean, t, t_prev, x)
        if return_trajectory:
            states.append(x)

    unflatten = (batch, num_samples)
    return Trajectory(
        headings=representation.decode(x).unflatten(0, unflatten),
        states=representation.decode(torch.stack(states)).unflatten(1, unflatten) if return_trajectory else None,
        timesteps=timesteps,
    )
