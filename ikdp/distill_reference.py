"""The distillation's poses, and the distribution term's reference: the teacher's DDPM samples for the same targets.

`ikdp.distill --distribution-weight w` adds each target's energy distance between the student's poses and as many
samples of the teacher's full DDPM (other noises, the same target). The teacher's deterministic sampler the student
is matched to is itself further from the true posterior than its DDPM (relaxed planar model, five seeds: excess
MMD² 0.00226 for DPM-Solver++ 16 against 0.00091), so matching it alone caps the student there.

The DDPM costs most of a step (80-100 evaluations of the teacher against the student's 4): `--reference-pool P`
draws P targets and their samples once, before training (the same seed, the same pool on a resume), and each
step then picks its targets from the pool with fresh noises for the student.
"""

from __future__ import annotations

import sys

import torch
from tqdm import tqdm

from ikdp.model import IKDiffusion
from ikdp.priors import PosePrior

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


@torch.no_grad()
def teacher_samples(teacher: IKDiffusion, targets: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """One sample of the teacher's full DDPM per row of `targets` (B, target_dim), in the representation's
    coordinates (B, D): the reference distribution of the distribution term."""
    noise = torch.randn((len(targets), 1, teacher.representation.dim), generator=generator).to(targets.device)
    on_cpu = targets.device.type == "cpu"  # the data stream's generator is a CPU one; elsewhere the device's own
    trajectory = teacher.sample(targets, sampler="ddpm", initial_noise=noise, generator=generator if on_cpu else None)
    return teacher.representation.encode(trajectory.headings[:, 0]).clone()


class PoseStream:
    """Each step's poses (B, J), each target's `noises_per_target` rows consecutive, and the DDPM's samples (B, D)
    for them when the distribution term is on (else None): afresh from the prior, or picked from a pool."""

    def __init__(self, teacher: IKDiffusion, prior: PosePrior, config, device: torch.device):
        self.teacher, self.prior, self.device = teacher, prior, device
        self.batch, self.per_target = config.batch, config.noises_per_target
        self.with_reference = config.distribution_weight > 0
        self.pool = None
        if self.with_reference and config.reference_pool:
            self.pool = self.draw_pool(config.reference_pool, torch.Generator().manual_seed(config.seed + 1))

    def draw(self, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor | None]:
        count = self.batch // self.per_target
        if self.pool is not None:
            joints, samples = self.pool
            picked = torch.randint(len(joints), (count,), generator=generator)
            rows = joints[picked].repeat_interleave(self.per_target, dim=0).to(self.device)
            return rows, samples[picked].flatten(0, 1).to(self.device)
        arm = self.teacher.arm
        rows = self.prior.sample(count, arm, generator=generator).repeat_interleave(self.per_target, dim=0)
        rows = rows.to(self.device)
        reference = teacher_samples(self.teacher, arm.end_effector(rows), generator) if self.with_reference else None
        return rows, reference

    def draw_pool(self, size: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """(size, J) poses and (size, noises_per_target, D) DDPM samples for their targets, on the CPU."""
        arm = self.teacher.arm
        joints = self.prior.sample(size, arm, generator=generator)
        rows = joints.repeat_interleave(self.per_target, dim=0)
        samples = []
        for start in tqdm(range(0, len(rows), POOL_CHUNK), desc="reference pool (teacher's DDPM)", file=sys.stderr):
            chunk = rows[start : start + POOL_CHUNK].to(self.device)
            samples.append(teacher_samples(self.teacher, arm.end_effector(chunk), generator).cpu())
        return joints, torch.cat(samples).unflatten(0, (size, self.per_target))
