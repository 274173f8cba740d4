"""The distillation's poses, and the distribution term's reference: the teacher's DDPM samples for the same targets.

`ikdp.distill --distribution-weight w` adds each target's energy distance between the student's poses and as many
samples of the teacher's full DDPM (other noises, the same target). The teacher's deterministic sampler the student
is matched to is itself further from the true posterior than its DDPM (relaxed planar model, five seeds: excess
MMD² 0.00226 for DPM-Solver++ 16 against 0.00091), so matching it alone caps the student there.

The DDPM costs most of a step (80-100 evaluations of the teacher against the student's 4): `--reference-pool P`
draws P targets and their samples once, before training (the same seed, the same pool on a resume), and each
step then picks its targets from the pool with fresh noises for the student; the pool is kept on disk for the next
run (ikdp.reference_pool_cache).

`--refine-reference-steps n` takes n damped least-squares steps from each DDPM sample, in its own mode: the DDPM misses
the target by millimetres (the Panda's: 4.9 / 10.2 mm median / mean), and the energy distance's pull toward samples
off the target works against the FK term's pull onto it.
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch
from tqdm import tqdm

from ikdp.model import IKDiffusion
from ikdp.posterior_pool import posterior_pool
from ikdp.priors import PosePrior
from ikdp.reference_pool_cache import pool_key, pool_path, read_pool, write_pool
from ikdp.refine import better_of, damped_least_squares

POOL_CHUNK = 512  # rows of one DDPM call while the pool is drawn


def mean_distance(first: torch.Tensor, second: torch.Tensor, per_target: int) -> torch.Tensor:
    """(B, D) and (B, D) poses, `per_target` consecutive rows per target -> (B // per_target,) the mean distance
    between a target's rows of `first` and its rows of `second`; within one set (`second` is `first`) its own
    diagonal's zeros are left out."""
    a, b = first.unflatten(0, (-1, per_target)), second.unflatten(0, (-1, per_target))  # (G, K, D)
    distances = ((a[:, :, None] - b[:, None, :]).square().sum(-1) + 1e-12).sqrt()  # (G, K, K); the epsilon: no NaN
    pairs = per_target * (per_target - 1) if second is first else per_target**2
    return distances.sum(dim=(1, 2)) / pairs


def energy_distance(student: torch.Tensor, reference: torch.Tensor, per_target: int) -> torch.Tensor:
    """(B, D) student and reference poses, `per_target` consecutive rows per target -> (B // per_target,) each target's
    energy distance 2 E|x - y| - E|x - x'| - E|y - y'| (Szekely and Rizzo): zero when the two sets are drawn from one
    distribution, and its gradient moves the student's poses toward the reference's spread as well as its place."""
    cross = mean_distance(student, reference, per_target)
    return 2 * cross - mean_distance(student, student, per_target) - mean_distance(reference, reference, per_target)


# how far (joint-space norm, radians) the refinement may move a teacher's pose and keep it: past that the solver left
# the teacher's mode (from its far misses, 3 steps moved some Panda poses by 7 rad), and the student keeps the original
REFINE_MAX_MOVE = 0.5


def refined_in_place(arm, joints: torch.Tensor, targets: torch.Tensor, steps: int) -> torch.Tensor:
    """(B, J) poses -> each pose after `steps` damped least-squares steps where that misses the target by less and
    stays within REFINE_MAX_MOVE of it; the pose as it was elsewhere."""
    refined = damped_least_squares(arm, joints, targets, steps=steps)
    near = (refined - joints).norm(dim=-1) < REFINE_MAX_MOVE  # a planar heading wrapped past pi reads far: kept as was
    return torch.where(near[:, None], better_of(arm, targets, joints, refined), joints)


@torch.no_grad()
def teacher_samples(
    teacher: IKDiffusion, targets: torch.Tensor, generator: torch.Generator, refine_steps: int = 0
) -> torch.Tensor:
    """One sample of the teacher's full DDPM per row of `targets` (B, target_dim), in the representation's
    coordinates (B, D), after `refine_steps` damped least-squares steps in its own mode: the reference distribution
    of the distribution term."""
    shape = (len(targets), 1, teacher.representation.dim)
    noise = torch.randn(shape, generator=generator, device=generator.device).to(targets.device)
    # the DDPM's own noise from the same generator where it lives with the targets (the training's data stream);
    # a pool's CPU generator for a GPU's targets: the device's own
    same_device = torch.empty(0, device=generator.device).device == targets.device
    trajectory = teacher.sample(
        targets, sampler="ddpm", initial_noise=noise, generator=generator if same_device else None
    )
    joints = trajectory.headings[:, 0]
    if refine_steps:
        joints = refined_in_place(teacher.arm, joints, targets, refine_steps)
    return teacher.representation.encode(joints).clone()


class PoseStream:
    """Each step's poses (B, J), each target's `noises_per_target` rows consecutive, and the DDPM's samples (B, D)
    for them when the distribution term is on (else None): afresh from the prior, or picked from a pool, which is
    read from `pool_folder` when an earlier run of the same teacher file drew it there, and written there if not."""

    def __init__(
        self,
        teacher: IKDiffusion,
        prior: PosePrior,
        config,
        device: torch.device,
        teacher_path: str | Path | None = None,
        pool_folder: str | Path | None = None,
    ):
        self.teacher, self.prior, self.device = teacher, prior, device
        self.batch, self.per_target = config.batch, config.noises_per_target
        self.with_reference = config.distribution_weight > 0
        self.refine_steps = config.refine_reference_steps
        self.reference = config.reference  # "teacher": its DDPM's samples; "posterior": rejection from the prior
        self.pool = None
        if self.with_reference and config.reference_pool:
            pool = self.kept_pool(config.reference_pool, config.seed + 1, teacher_path, pool_folder)
            self.pool = tuple(part.to(device) for part in pool)  # on the training device once, not a copy per step

    def draw(self, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Each step's data, drawn from `generator` on its own device (the training device's: nothing is copied)."""
        count = self.batch // self.per_target
        if self.pool is not None:
            joints, samples = self.pool
            picked = torch.randint(len(joints), (count,), generator=generator, device=generator.device)
            rows = joints[picked].repeat_interleave(self.per_target, dim=0)
            return rows, samples[picked].flatten(0, 1)
        arm = self.teacher.arm
        rows = self.prior.sample(count, arm, generator=generator).repeat_interleave(self.per_target, dim=0)
        rows = rows.to(self.device)
        reference = None
        if self.with_reference:
            reference = teacher_samples(self.teacher, arm.end_effector(rows), generator, self.refine_steps)
        return rows, reference

    def kept_pool(self, size: int, seed: int, teacher_path, pool_folder) -> tuple[torch.Tensor, torch.Tensor]:
        """The pool read from `pool_folder` where an earlier run drew it; else drawn, and written there (with no
        folder or teacher file given: drawn only)."""
        if teacher_path is None or pool_folder is None:
            return self.draw_pool(size, torch.Generator().manual_seed(seed))
        key = pool_key(teacher_path, size, self.per_target, seed, self.refine_steps, self.reference)
        path = pool_path(pool_folder, key)
        pool = read_pool(path, key, self.teacher.arm.num_joints, self.teacher.representation.dim)
        if pool is None:
            pool = self.draw_pool(size, torch.Generator().manual_seed(seed))
            write_pool(path, key, *pool)
        return pool

    def draw_pool(self, size: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """(size, J) poses and (size, noises_per_target, D) reference samples for their targets, on the CPU: the
        teacher's DDPM's, or the posterior's by rejection from the prior."""
        arm = self.teacher.arm
        if self.reference == "posterior":
            return posterior_pool(self.prior, arm, self.teacher.representation, size, self.per_target, generator)
        joints = self.prior.sample(size, arm, generator=generator)
        rows = joints.repeat_interleave(self.per_target, dim=0)
        samples = []
        for start in tqdm(range(0, len(rows), POOL_CHUNK), desc="reference pool (teacher's DDPM)", file=sys.stderr):
            chunk = rows[start : start + POOL_CHUNK].to(self.device)
            targets = arm.end_effector(chunk)
            samples.append(teacher_samples(self.teacher, targets, generator, self.refine_steps).cpu())
        return joints, torch.cat(samples).unflatten(0, (size, self.per_target))
