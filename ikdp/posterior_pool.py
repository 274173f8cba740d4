"""The distribution term's other reference: samples of the true posterior p(theta | target), not of the teacher.

`ikdp.distill --reference posterior` compares the student's poses with poses drawn from the model's own prior by
rejection (those whose tip lands within POSTERIOR_RADIUS of the target, then polished onto it: the reference that
benchmarks/fidelity.py measures every sampler against), in place of the teacher's DDPM samples. A student matched
to its teacher's DDPM can come no closer to the posterior than that DDPM (the relaxed planar model's, ten seeds:
excess MMD² 0.00074, the best 4-evaluation student 1.22 × it); matched to the posterior itself it is not capped
there (the student shipped in ikdp_n4_relaxed, trained so: 0.59 × it).

Rejection needs the target's region to hold a fair share of the prior's mass: a planar tip (2 numbers) does, a 3-D
position far less (one more factor of the small radius), a pose target none: the option is for planar arms.
"""

from __future__ import annotations

import sys

import torch
from tqdm import tqdm

from ikdp.evaluation.reference import rejection_reference
from ikdp.priors import PosePrior

POSTERIOR_RADIUS = 0.02  # the rejection radius over the arm's span: benchmarks/fidelity.py's default
TARGET_CHUNK = 128  # targets of one rejection call: its distance table is TARGET_CHUNK x 2^19 prior draws
MAX_DRAWS = 2**22  # prior draws per chunk before its targets still short of samples are replaced by others


def check_posterior_target(arm, teacher_name: str) -> None:
    """ValueError unless rejection from the prior can reach `arm`'s targets (a planar tip, 2 numbers)."""
    if arm.target_dim != 2:
        raise ValueError(
            f"reference: posterior samples are drawn by rejection around a planar tip (2 numbers); "
            f"{teacher_name}'s targets have {arm.target_dim}: use --reference teacher"
        )


def posterior_pool(
    prior: PosePrior, arm, representation, size: int, per_target: int, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """(size, J) poses from the prior and (size, per_target, D) poses of p(theta | their tip) in the representation's
    coordinates. Where the prior's mass near a tip is too thin for `per_target` draws in MAX_DRAWS, that pose is left
    out and another drawn in its place (rare: the tips come from the same prior)."""
    joints, samples = [], []
    have = 0
    progress = tqdm(total=size, desc="reference pool (posterior by rejection)", file=sys.stderr)
    while have < size:
        count = min(TARGET_CHUNK, size - have)
        chunk = prior.sample(count, arm, generator=generator)
        found, complete, _ = rejection_reference(
            prior,
            arm.end_effector(chunk),
            arm,
            count=per_target,
            radius=POSTERIOR_RADIUS * arm.span,
            generator=generator,
            max_draws=MAX_DRAWS,
        )
        if not complete.any():  # a prior that never comes back near its own tips would loop here for ever
            raise ValueError(
                f"reference: none of {count} targets from the prior got {per_target} poses in {MAX_DRAWS} draws"
            )
        joints.append(chunk[complete])
        samples.append(representation.encode(found.flatten(0, 1)).unflatten(0, (len(found), per_target)))
        have += len(found)
        progress.update(len(found))
    progress.close()
    return torch.cat(joints), torch.cat(samples)
