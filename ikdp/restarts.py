"""Random restarts for the targets a solve left unreached: a numerical fallback after the diffusion's poses.

A few-step sampler's K poses for a target can all land where a short damped-least-squares refinement does not
finish (one Panda target in a hundred for a one-evaluation student + 8 DLS steps: `python -m
benchmarks.few_step_pipeline`); fresh uniform starts within the limits reach most of those. Only the unreached
targets pay for them, so the cost is a share of a random-start solve as small as the share of targets missed.
"""

from __future__ import annotations

import torch

from ikdp.refine import better_of, damped_least_squares


def within_tolerances(arm, joints: torch.Tensor, goals: torch.Tensor, constraints=None, errors=None) -> torch.Tensor:
    """joints (..., J), goals (..., target_dim) -> (...) True where the tip is within `arm.position_tolerance`
    of the goal (and, for pose targets, its orientation within `arm.rotation_tolerance`).

    `constraints` (a ConstraintSet over the same B x K rows): a partial target's errors replace the full
    ones (only the parts asked count), and every constraint must hold (violation 0, as tracking checks).
    `errors`: `arm.tip_and_rotation_errors` compiled (ikdp/cuda_graph.py's fused capture); None: the method.
    """
    partial = None if constraints is None else constraints.partial
    if partial is not None:  # only the parts asked count (a free hand's position does not)
        position, rotation = partial.tip_and_rotation_errors(joints, goals)
    else:
        position, rotation = (arm.tip_and_rotation_errors if errors is None else errors)(joints, goals)
    within = position < arm.position_tolerance
    if rotation is not None:
        within &= rotation.to(within.device) < arm.rotation_tolerance
    if constraints is not None:
        within &= constraints.violation(joints).to(within.device) == 0
    return within


def restart_unreached(
    arm,
    angles: torch.Tensor,
    goals: torch.Tensor,
    steps: int,
    generator: torch.Generator | None = None,
    constraints=None,
    within: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """angles (B, K, J), goals (B, K, target_dim) -> (angles, restarted (B,)).

    `within` (B, K): `within_tolerances` of the angles when the caller measured it already (a one-target solve's
    refinement does on its way); None: measured here.

    Each target none of whose K poses is `within_tolerances` gets K fresh uniform poses within the limits
    (`arm.random_poses`), refined by `steps` damped-least-squares steps toward its goals. Each of its poses
    becomes the fresh one where that is within the tolerances, else the one of the two nearer the goal (the
    task error's norm, what the refinement minimises): a near miss is never traded for a worse start.

    `constraints` (a ConstraintSet over the B x K rows): reaching also means meeting them; the fresh poses
    start with the locked joints at their values and are refined by the constrained task (obstacles cleared,
    a partial target's free rows left free), cut to the restarted targets' rows (`ConstraintSet.of_targets`); with a
    pose to stay near (NearPose) they start from it and a growing share of the way to the uniform draws.
    """
    if within is None:
        within = within_tolerances(arm, angles, goals, constraints)
    restarted = ~within.any(dim=-1)
    if steps == 0 or not bool(restarted.any()):
        return angles, torch.zeros_like(restarted)
    rows, samples = int(restarted.sum()), angles.shape[1]
    starts = arm.random_poses(rows * samples, generator=generator).to(angles).unflatten(0, (rows, samples))
    subset = None if constraints is None else constraints.of_targets(restarted)
    task = None if subset is None else subset.refine_task()
    if subset is not None:
        starts = subset.restart_from(starts)
    row_goals = goals[restarted]
    fresh = arm.refine(starts, row_goals, steps=steps, task=task)
    angles = angles.clone()
    angles[restarted] = fresh_or_nearer(arm, angles[restarted], fresh, row_goals, constraints=subset, task=task)
    return angles, restarted


def restart_every_target(
    arm,
    angles: torch.Tensor,
    goals: torch.Tensor,
    restarted: torch.Tensor,
    steps: int,
    generator: torch.Generator | None,
    iteration=None,
    errors=None,
) -> torch.Tensor:
    """`restart_unreached`'s choice without a host sync or a shape that depends on the data (a CUDA graph's
    needs): every target gets K fresh starts on the poses' device (`arm.random_poses_like`, `generator` on that
    device) and the refinement, and only the `restarted` (B,) ones keep them. It pays for all B targets where
    the default pays for the unreached few: on a GPU the graph's single launch is the cheaper of the two.
    `iteration`, `errors`: damped_least_squares' step and the arm's error check, compiled, if any.
    """
    starts = arm.random_poses_like(angles, generator=generator)
    fresh = damped_least_squares(arm, starts, goals, steps=steps, sync_free=True, iteration=iteration)
    return torch.where(restarted[:, None, None], fresh_or_nearer(arm, angles, fresh, goals, errors=errors), angles)


def fresh_or_nearer(arm, old, fresh, goals, *, constraints=None, task=None, errors=None) -> torch.Tensor:
    """Per pose (..., J): the fresh one where it is `within_tolerances` (and meets the constraints), else the one
    of the two nearer the goal (`better_of`, by the refinement's own task error): the restarts' choice."""
    kept = better_of(arm, goals, old, fresh, task=task)
    return torch.where(within_tolerances(arm, fresh, goals, constraints, errors)[..., None], fresh, kept)
