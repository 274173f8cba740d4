"""The reverse diffusion loop, one for every sampler: from pure noise to a pose.

The loop is short and visible: denoise, estimate x̂0, let the sampler step,
record, call back. What makes it fast is what it does not do per step:
- the denoiser's condition (timestep and target) does not depend on the noisy
  sample, so every step's condition is computed in one batched call per solve;
- the states live in one preallocated buffer (the trajectory itself when it is
  asked for, else two slots used in turn), and samplers write into it in place;
- a denoiser that offers a `workspace(rows, like)` (the FiLM one does) computes
  into buffers allocated once per solve, with the same ops as its plain path.

A `callback(step_index, timestep, state, estimate)` sees every step as joint
values (B, K, J) and stops the run by returning True. A `guidance` (ikdp/guidance.py:
constraints at sampling time) may rewrite x̂0 before the sampler uses it and the next
state after it (inpainting); without one the loop is unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Protocol

import torch

from ikdp.representation import AngleRepresentation
from ikdp.samplers import Sampler
from ikdp.schedule import DiffusionSchedule

PRECOMPUTE_CONDITION_LIMIT = 16 * 2**20  # floats; above this the condition is computed per step
FEW_CONDITIONS = 64  # steps x targets up to which the conditions are computed before their size is checked

StepCallback = Callable[[int, int, torch.Tensor, torch.Tensor], "bool | None"]


class Guidance(Protocol):
    """What the loop asks of sampling-time constraints; both methods edit their tensor in place."""

    def adjust_estimate(self, index: int, clean: torch.Tensor) -> None:
        """x̂0 (M, D) at step `index`, before the sampler steps with it."""

    def adjust_state(self, index: int, state: torch.Tensor, generator: torch.Generator | None) -> None:
        """The state (M, D) step `index` landed on."""


@dataclass
class Trajectory:
    headings: torch.Tensor  # (B, K, J) the final poses (the last state reached when stopped)
    states: torch.Tensor | None  # (S'+1, B, K, J) every state from pure noise on, as joint values
    estimates: torch.Tensor | None  # (S', B, K, J) the denoiser's x̂0 at each step
    timesteps: list[int]  # the S timesteps of the sampler, noisiest first
    stopped: bool = False  # True when the callback stopped the run; S' < S steps were run then
    network_evaluations: int = 0  # S', the denoiser calls each sample went through, one after another


def step_conditions(denoiser, timesteps, targets: torch.Tensor, num_samples: int):
    """Every step's condition, (S, M, ...), in one call when it fits in memory, else None.

    `timesteps`: a list, or a tensor on the targets' device (`Sampler.timestep_tensor`: no host copy).
    One target's condition broadcasts over its K rows as it is; several are spread over them.
    """
    batch = targets.shape[0]
    t_all = torch.as_tensor(timesteps, device=targets.device)
    per_target = None
    if len(timesteps) * batch <= FEW_CONDITIONS:  # computed at once, then sized: no call to size them first
        # one target or one step needs no copy (each a few microseconds of a one-target solve)
        times = t_all.repeat_interleave(batch) if batch > 1 else t_all
        per_target = denoiser.condition(times, targets.repeat(len(timesteps), 1) if len(timesteps) > 1 else targets)
        per_row = per_target[0].numel()
    else:
        per_row = denoiser.condition(t_all[:1], targets[:1]).numel()
    if len(timesteps) * batch * num_samples * per_row > PRECOMPUTE_CONDITION_LIMIT:
        return None
    if per_target is None:
        per_target = denoiser.condition(t_all.repeat_interleave(batch), targets.repeat(len(timesteps), 1))
    conditions = per_target.unflatten(0, (len(timesteps), batch))
    if batch > 1 and num_samples > 1:
        conditions = conditions.repeat_interleave(num_samples, dim=1)
    return conditions


def run_reverse_diffusion(
    denoiser,
    schedule: DiffusionSchedule,
    representation: AngleRepresentation,
    sampler: Sampler,
    targets: torch.Tensor,
    *,
    num_samples: int = 1,
    prediction: str,
    generator: torch.Generator | None = None,
    return_trajectory: bool = False,
    return_estimates: bool = False,
    callback: StepCallback | None = None,
    conditions: torch.Tensor | None = None,
    initial_noise: torch.Tensor | None = None,
    guidance: Guidance | None = None,
) -> Trajectory:
    """targets: (B, C) conditions -> K = num_samples poses per target, (B, K, J).

    `conditions`: step_conditions() for these targets, when the caller computed them already
    (ikdp.cuda_graph does, outside the captured graph: they need a host-to-device copy).
    `initial_noise`: x_T, (B, K, D) in the representation's coordinates (D = representation.dim),
    so that two samplers can start from the same noise; None draws it from `generator`.
    """
    batch = targets.shape[0]
    rows = batch * num_samples  # M: the K samples of a target are consecutive rows
    steps = sampler.num_steps
    dim = representation.dim
    project = not (prediction == "sample" and getattr(denoiser, "output_on_manifold", False))

    # states: the whole trajectory when asked for, else two slots used in turn
    like = {"device": targets.device, "dtype": targets.dtype}
    states = torch.empty((steps + 1 if return_trajectory else 2, rows, dim), **like)
    estimates = torch.empty((steps, rows, dim), **like) if return_estimates else None
    if initial_noise is None:
        torch.randn((rows, dim), generator=generator, out=states[0])  # x_T ~ N(0, I)
    else:
        if tuple(initial_noise.shape) != (batch, num_samples, dim):
            expected = (batch, num_samples, dim)
            raise ValueError(f"initial_noise: expected x_T of shape {expected}, got {tuple(initial_noise.shape)}")
        states[0].copy_(initial_noise.reshape(rows, dim))
    x = states[0]
    make_workspace = getattr(denoiser, "workspace", None)
    workspace = make_workspace(rows, x) if make_workspace is not None else None
    denoise = denoiser.denoise if workspace is None else partial(denoiser.denoise, workspace=workspace)

    # a target's K rows share its target and condition; a denoiser (or its workspace) that reads them per
    # target is spared the K copies (for 500 targets x 16 samples, 100 MB of conditions per 3-step solve)
    reader = workspace if workspace is not None else denoiser
    per_target = getattr(reader, "accepts_per_target_conditions", False) and conditions is None
    row_targets = targets if per_target else targets.repeat_interleave(num_samples, dim=0)  # (M or B, C)
    if conditions is None:
        t_all = sampler.timestep_tensor(targets.device)
        conditions = step_conditions(denoiser, t_all, targets, 1 if per_target else num_samples)
    sampler.reset()
    unflatten = (batch, num_samples)
    steps_run, stopped = 0, False
    for index, t in enumerate(sampler.timesteps):
        if conditions is not None:
            condition = conditions[index]
        else:
            condition = denoiser.condition(t_all[index].expand(batch), targets)
            if batch > 1 and not per_target:
                condition = condition.repeat_interleave(num_samples, dim=0)
        output = denoise(x, row_targets, condition)
        clean = schedule.predict_clean(output, t, x, prediction)
        if project:
            clean = representation.project(clean)
        if guidance is not None:
            guidance.adjust_estimate(index, clean)
        if estimates is not None:
            estimates[index].copy_(clean)
        next_x = states[index + 1] if return_trajectory else states[(index + 1) % 2]
        x = sampler.step(index, x, clean, out=next_x, generator=generator)
        if guidance is not None:
            guidance.adjust_state(index, x, generator)
        steps_run = index + 1
        if callback is not None:
            state_joints = representation.decode(x).unflatten(0, unflatten)
            estimate_joints = representation.decode(clean).unflatten(0, unflatten)
            if callback(index, t, state_joints, estimate_joints):
                stopped = True
                break

    return Trajectory(
        headings=representation.decode(x).unflatten(0, unflatten),
        states=representation.decode(states[: steps_run + 1]).unflatten(1, unflatten) if return_trajectory else None,
        estimates=representation.decode(estimates[:steps_run]).unflatten(1, unflatten) if return_estimates else None,
        timesteps=list(sampler.timesteps),
        stopped=stopped,
        network_evaluations=steps_run,
    )
