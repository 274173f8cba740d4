"""Accuracy and diversity of IK solutions, as plain functions of tensors.

Every distance is in bone-length units; success thresholds are fractions of the
reach (the sum of bone lengths). Angle differences are wrapped into (-pi, pi]
before any norm: theta = pi and theta = -pi are one heading.
"""

from __future__ import annotations

import time

import torch

from ikdp.kinematics import absolute_to_relative, wrap_angle

SUCCESS_FRACTIONS = (1e-2, 1e-3)  # success when the tip lands within this fraction of the reach


def angle_distance(predicted: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """||wrap(theta_hat - theta)||_2 over the last axis: (..., N), (..., N) -> (...)."""
    return wrap_angle(predicted - truth).norm(dim=-1)


def tip_error_summary(tip_error: torch.Tensor, reach: float) -> dict[str, float]:
    """Mean, median, p95 of the tip errors (any shape) and the success rates at each fraction of reach."""
    error = tip_error.flatten().double()
    summary = {
        "mean": float(error.mean()),
        "sem": float(error.std() / len(error) ** 0.5) if len(error) > 1 else float("nan"),
        "median": float(error.median()),
        "p95": float(torch.quantile(error, 0.95)),
    }
    for fraction in SUCCESS_FRACTIONS:
        summary[f"success@{fraction:g}"] = float((error < fraction * reach).double().mean())
    return summary


def valid_mask(tip_error: torch.Tensor, reach: float, fraction: float = SUCCESS_FRACTIONS[0]) -> torch.Tensor:
    """(B, K) -> (B, K) bool: which solutions reach their target within `fraction` of the reach."""
    return tip_error < fraction * reach


def both_elbows_share(headings: torch.Tensor, valid: torch.Tensor, *, margin: float = 1e-3) -> float:
    """N = 2: the share of targets whose valid solutions include both elbows. headings (B, K, 2), valid (B, K).

    The elbow is the sign of the relative joint angle; a nearly straight elbow
    (|q| < margin) counts as neither, as the two solutions coincide there.
    """
    if headings.shape[-1] != 2:
        raise ValueError(f"headings: both-elbows diversity is for two links, got {headings.shape[-1]}")
    elbow = absolute_to_relative(headings)[..., 1]  # (B, K)
    up = ((elbow > margin) & valid).any(dim=1)
    down = ((elbow < -margin) & valid).any(dim=1)
    return float((up & down).double().mean())


def mean_pairwise_distance(headings: torch.Tensor, valid: torch.Tensor) -> tuple[float, int]:
    """N >= 3: mean wrapped joint-space distance between distinct valid solutions of a target.

    headings (B, K, N), valid (B, K). Averaged over the pairs of each target, then over the
    targets with at least two valid solutions; returns (mean, number of such targets).
    """
    difference = wrap_angle(headings[:, :, None] - headings[:, None, :]).norm(dim=-1)  # (B, K, K)
    pair = valid[:, :, None] & valid[:, None, :]
    pair = pair & ~torch.eye(headings.shape[1], dtype=torch.bool, device=headings.device)
    pairs = pair.sum(dim=(1, 2))
    counted = pairs > 0
    if not counted.any():
        return float("nan"), 0
    per_target = (difference * pair).sum(dim=(1, 2))[counted] / pairs[counted]
    return float(per_target.mean()), int(counted.sum())


def median_seconds(function, *, repeats: int, warmup: int = 1) -> float:
    """Median wall time of `function()` over `repeats` calls, after `warmup` untimed calls."""
    for _ in range(warmup):
        function()
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return float(torch.tensor(times).median())
