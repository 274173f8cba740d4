"""What one step of `ikdp.distill` computes: the student's few-step DDIM unrolled from fresh noise, and its loss.

`DistillLoss` is that step's loss as a module, called as `ikdp.train`'s loss is (`loss(batch, generator)`, the
batch what the pose stream drew), so the same step runners take its steps (ikdp/train_steps.py): eagerly, or on
a GPU replayed from one CUDA graph. A step that runs the teacher (its ODE for the match or spread terms, or its
DDPM for a reference drawn afresh rather than from a pool) stays eager: the teacher's sampler is not recorded.
"""

from __future__ import annotations

import math

import torch

from ikdp.distill_reference import energy_distance, mean_distance, refined_in_place
from ikdp.model import IKDiffusion
from ikdp.samplers import DDIMSampler, make_sampler

DISTANCE_SMOOTHING = 1e-3  # metres: below this the distance form of the FK miss turns quadratic (no kink at zero)


def fk_distance(consistency: torch.Tensor, span: float) -> torch.Tensor:
    """(B,) each pose's FK miss as a distance over the arm's span, from `consistency` (B,), the squared miss over the
    span squared (rotation included): its square root, pseudo-Huber smoothed below DISTANCE_SMOOTHING."""
    smoothing = (DISTANCE_SMOOTHING / span) ** 2
    return (consistency + smoothing).sqrt() - math.sqrt(smoothing)


def student_sampler(model: IKDiffusion, config) -> DDIMSampler:
    sampler = make_sampler("ddim", model.schedule, config.student_steps, config.spacing)
    assert isinstance(sampler, DDIMSampler)
    return sampler


def unrolled_student(model: IKDiffusion, sampler: DDIMSampler, noise: torch.Tensor, targets: torch.Tensor):
    """The student's DDIM from x_T (B, D) to its clean pose (B, D), with the graph kept for the gradient.

    The loop of ikdp.sampling.run_reverse_diffusion, step for step (x̂0 from the denoiser, projected onto
    the representation's manifold, then DDIM's update), on the training forward of the denoiser.
    """
    project = not (model.config.prediction == "sample" and getattr(model.denoiser, "output_on_manifold", False))
    x = noise
    for index, t in enumerate(sampler.timesteps):
        output = model.denoiser(x, torch.full((len(x),), t, device=x.device), targets)
        clean = model.schedule.predict_clean(output, t, x, model.config.prediction)
        if project:
            clean = model.representation.project(clean)
        x = sampler.update(index, x, clean)
    return x


def spread_miss(student: torch.Tensor, teacher: torch.Tensor, per_target: int) -> torch.Tensor:
    """(B, D) student and teacher poses, `per_target` consecutive rows per target -> (B // per_target,) the squared
    difference between the mean distance of a target's student poses and that of its teacher poses from the same
    noises: zero when the student's samples are as spread as the teacher's, wherever each one lands. (Matching the
    distances pair by pair started 20 times larger than the other terms on the Panda: the teacher's 4- and 16-step
    runs already differ pair by pair.)"""
    return (mean_distance(student, student, per_target) - mean_distance(teacher, teacher, per_target)).square()


@torch.no_grad()
def teacher_poses(teacher: IKDiffusion, config, noise: torch.Tensor, targets: torch.Tensor):
    """The teacher's clean pose (B, D), in the representation's coordinates, from the noise x_T (B, D)."""
    trajectory = teacher.sample(
        targets,
        sampler=config.teacher_sampler,
        steps=config.teacher_steps,
        spacing=config.teacher_spacing,
        initial_noise=noise[:, None],
    )
    joints = trajectory.headings[:, 0]
    if config.refine_teacher_steps:
        joints = refined_in_place(teacher.arm, joints, targets, config.refine_teacher_steps)
    return teacher.representation.encode(joints).clone()  # a plain tensor, not an inference one


def runs_the_teacher(config) -> bool:
    """Whether each step runs the teacher's sampler: its ODE for the match or spread terms, or its DDPM for a
    distribution term without a pool."""
    afresh_reference = config.distribution_weight > 0 and config.reference_pool == 0
    return config.match_weight > 0 or config.spread_weight > 0 or afresh_reference


class DistillLoss(torch.nn.Module):
    """The student's loss on one batch: `loss(batch, generator)` -> the loss and its terms, each a tensor.

    `batch`: the pose stream's (poses (B, J), the reference's samples (B, D) or None); the noise x_T is drawn here,
    after the batch, from the same generator, on its device. The student is this module's one submodule (what the
    step's gradient clip and optimizer see); the teacher is kept beside it, frozen."""

    def __init__(self, student: IKDiffusion, teacher: IKDiffusion, sampler: DDIMSampler, config):
        super().__init__()
        self.student, self.sampler, self.config = student, sampler, config
        object.__setattr__(self, "teacher", teacher)  # not a submodule: its weights are not the student's

    def forward(self, batch, generator: torch.Generator) -> dict[str, torch.Tensor]:
        joints, reference = batch
        config, student, arm = self.config, self.student, self.student.arm
        shape = (len(joints), student.representation.dim)
        noise = torch.randn(shape, generator=generator, device=generator.device).to(joints.device)  # x_T (B, D)
        targets = arm.end_effector(joints)  # (B, target_dim)
        pose = unrolled_student(student, self.sampler, noise, targets)  # (B, D)
        consistency, tip_miss = student.consistency_miss(pose, joints, targets)
        loss = config.tip_loss_weight * consistency.mean()
        if config.tip_distance_weight > 0:
            loss = loss + config.tip_distance_weight * fk_distance(consistency, arm.span).mean()
        per_target = config.noises_per_target  # each target's poses on consecutive rows
        match, spread = pose.new_zeros(1), pose.new_zeros(1)
        if config.match_weight > 0 or config.spread_weight > 0:  # both need the teacher's ODE endpoint
            goal = teacher_poses(self.teacher, config, noise, targets)  # (B, D)
            match = ((pose - goal) ** 2).mean(-1)  # (B,)
            loss = loss + config.match_weight * match.mean()
            if per_target > 1:
                spread = spread_miss(pose, goal, per_target)
        loss = loss + config.spread_weight * spread.mean()
        distribution = match.new_zeros(1)
        if reference is not None:
            distribution = energy_distance(pose, reference, per_target)
            loss = loss + config.distribution_weight * distribution.mean()
        return {
            "loss": loss,
            "teacher_match": match.mean(),
            "spread_miss": spread.mean(),
            "energy_distance": distribution.mean(),
            "tip_distance": tip_miss.sqrt().mean(),
        }
