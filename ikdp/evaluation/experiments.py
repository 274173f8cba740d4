"""The four measurements of a method: accuracy, diversity, fidelity and runtime.

Each takes a Method and fixed inputs and returns plain numbers (JSON-ready), plus
the arrays a figure needs.
"""

from __future__ import annotations

import torch

from ikdp.evaluation.methods import Method
from ikdp.evaluation.metrics import (
    angle_distance,
    both_elbows_share,
    mean_pairwise_distance,
    median_seconds,
    tip_error_summary,
    valid_mask,
)
from ikdp.evaluation.mmd import mmd2

CDF_POINTS = 101  # quantiles kept of each tip-error distribution, for the CDF figure


def accuracy(method: Method, targets: torch.Tensor, truth: torch.Tensor | None, reach: float, seed: int) -> dict:
    """One solution per target (K = 1, the paper's protocol). truth: the poses that generated the targets, if known."""
    headings, tip_error = method.solve(targets, 1, torch.Generator().manual_seed(seed))
    result = {"target_distance": tip_error_summary(tip_error, reach)}
    result["target_distance"]["mean_fraction_of_reach"] = result["target_distance"]["mean"] / reach
    if truth is not None:
        distance = angle_distance(headings[:, 0].double(), truth.double())
        result["angle_distance"] = {"mean": float(distance.mean()), "median": float(distance.median())}
    quantiles = torch.linspace(0, 1, CDF_POINTS, dtype=torch.float64)
    result["tip_error_quantiles"] = torch.quantile(tip_error.flatten().double(), quantiles).tolist()
    return result


def diversity(
    method: Method, targets: torch.Tensor, num_samples: int, reach: float, seed: int
) -> tuple[dict, torch.Tensor]:
    """K solutions per target: how many are valid and how different the valid ones are. Also returns the headings."""
    headings, tip_error = method.solve(targets, num_samples, torch.Generator().manual_seed(seed))
    valid = valid_mask(tip_error, reach)
    result = {"samples_per_target": num_samples, "valid_share": float(valid.double().mean())}
    if headings.shape[-1] == 2:
        result["both_elbows_share"] = both_elbows_share(headings, valid)
    else:
        spread, counted = mean_pairwise_distance(headings, valid)
        result["mean_pairwise_distance"] = spread
        result["targets_with_two_valid"] = counted
    return result, headings


def fidelity(method: Method, targets: torch.Tensor, reference: torch.Tensor, reach: float, seed: int) -> dict:
    """MMD^2 between the method's K solutions and the reference samples of each target, K = reference size."""
    num_samples = reference.shape[1]
    headings, tip_error = method.solve(targets, num_samples, torch.Generator().manual_seed(seed))
    per_target = mmd2(headings, reference)
    return {
        "mmd2": float(per_target.mean()),
        "mmd2_sem": float(per_target.std() / len(per_target) ** 0.5),
        "valid_share": float(valid_mask(tip_error, reach).double().mean()),
    }


def runtime(
    method: Method,
    one_target: torch.Tensor,
    batch_targets: torch.Tensor,
    *,
    repeats_single: int,
    repeats_batch: int,
    seed: int,
) -> dict:
    """Median wall time: one target (batch 1, K = 1), and per target in one batch of len(batch_targets), K = 1."""
    generator = torch.Generator().manual_seed(seed)
    single = median_seconds(lambda: method.solve(one_target, 1, generator), repeats=repeats_single, warmup=2)
    batch = median_seconds(lambda: method.solve(batch_targets, 1, generator), repeats=repeats_batch, warmup=1)
    return {
        "single_target_ms": 1e3 * single,
        "batch_size": len(batch_targets),
        "per_target_in_batch_ms": 1e3 * batch / len(batch_targets),
        "repeats": [repeats_single, repeats_batch],
    }
