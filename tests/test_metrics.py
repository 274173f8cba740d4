"""Metric functions on cases whose answers are known."""

from __future__ import annotations

import math

import pytest
import torch

from ikdp.arm import PlanarArm
from ikdp.evaluation.metrics import (
    angle_distance,
    both_elbows_share,
    mean_pairwise_distance,
    tip_error_summary,
    valid_mask,
)
from ikdp.evaluation.mmd import mmd2
from ikdp.evaluation.reference import rejection_reference, targets_in_disk
from ikdp.kinematics import tip_position
from ikdp.priors import PosePrior


def test_angle_distance_wraps_each_difference():
    # pi - 0.1 and -pi + 0.1 are 0.2 apart on the circle, not 2 pi - 0.2
    predicted = torch.tensor([[math.pi - 0.1, 0.0]], dtype=torch.float64)
    truth = torch.tensor([[-math.pi + 0.1, 0.3]], dtype=torch.float64)
    assert angle_distance(predicted, truth).item() == pytest.approx(math.hypot(0.2, 0.3), abs=1e-12)
    assert angle_distance(truth, truth).item() == 0.0


def test_tip_error_summary_known_values():
    errors = torch.tensor([0.0, 0.001, 0.01, 0.1, 1.0])
    summary = tip_error_summary(errors, reach=4.0)
    assert summary["mean"] == pytest.approx(0.2222, abs=1e-4)
    assert summary["median"] == pytest.approx(0.01)
    assert summary["success@0.01"] == pytest.approx(3 / 5)  # below 0.04
    assert summary["success@0.001"] == pytest.approx(2 / 5)  # below 0.004
    assert summary["p95"] == pytest.approx(0.82, abs=1e-6)  # linear interpolation between 0.1 and 1.0


def test_both_elbows_share():
    up, down = [0.0, 1.0], [1.0, 0.0]  # relative elbow +1 and -1
    headings = torch.tensor([[up, down], [up, up], [down, down]])
    valid = torch.ones(3, 2, dtype=torch.bool)
    assert both_elbows_share(headings, valid) == pytest.approx(1 / 3)
    valid[0, 1] = False  # the down solution of target 0 misses: only one elbow left
    assert both_elbows_share(headings, valid) == 0.0
    with pytest.raises(ValueError, match="two links"):
        both_elbows_share(torch.zeros(1, 2, 3), torch.ones(1, 2, dtype=torch.bool))


def test_mean_pairwise_distance_counts_valid_pairs_only():
    headings = torch.tensor([[[0.0, 0.0, 0.0], [0.3, 0.4, 0.0], [3.0, 3.0, 3.0]]], dtype=torch.float64)
    valid = torch.tensor([[True, True, False]])
    spread, counted = mean_pairwise_distance(headings, valid)
    assert spread == pytest.approx(0.5) and counted == 1
    spread, counted = mean_pairwise_distance(headings, torch.tensor([[True, False, False]]))
    assert math.isnan(spread) and counted == 0


def test_valid_mask_is_a_fraction_of_reach():
    assert valid_mask(torch.tensor([[0.039, 0.041]]), reach=4.0).tolist() == [[True, False]]


def test_mmd_of_a_set_with_itself_is_zero_and_grows_with_a_shift():
    generator = torch.Generator().manual_seed(0)
    samples = torch.randn(3, 64, 4, generator=generator, dtype=torch.float64)
    assert mmd2(samples, samples).abs().max().item() < 1e-12
    other = torch.randn(3, 64, 4, generator=generator, dtype=torch.float64)
    same_distribution = mmd2(samples, other).mean().item()
    shifted = mmd2(samples, other + 1.0).mean().item()
    assert 0 < same_distribution < shifted
    # the embedding is periodic: a turn by 2 pi changes nothing
    assert mmd2(samples, samples + 2 * math.pi).abs().max().item() < 1e-12


def test_rejection_reference_reaches_targets_and_follows_the_prior():
    generator = torch.Generator().manual_seed(0)
    lengths = torch.ones(2)
    targets = torch.tensor([[1.2, 0.5], [0.0, -1.5]])
    reference, complete, draws = rejection_reference(
        PosePrior("uniform"), targets, PlanarArm((1.0, 1.0)), count=40, radius=0.05, generator=generator, chunk=2**15
    )
    assert complete.all() and reference.shape == (2, 40, 2) and draws > 0
    miss = (tip_position(reference.double(), lengths.double()) - targets[:, None].double()).norm(dim=-1)
    assert miss.max() < 1e-5
    # two links, uniform prior: the two elbows are equally likely
    elbow = torch.remainder(reference[..., 1] - reference[..., 0], 2 * math.pi) < math.pi
    assert 0.2 < elbow.double().mean() < 0.8


def test_rejection_reference_leaves_out_unreachable_targets():
    reference, complete, _ = rejection_reference(
        PosePrior("uniform"),
        torch.tensor([[1.0, 0.0], [5.0, 0.0]]),
        PlanarArm((1.0, 1.0)),
        count=5,
        radius=0.05,
        generator=torch.Generator().manual_seed(0),
        chunk=2**12,
        max_draws=2**14,
    )
    assert complete.tolist() == [True, False] and reference.shape == (1, 5, 2)


def test_disk_targets_fill_the_annulus():
    targets = targets_in_disk(4000, PlanarArm((1.0, 1.0, 1.0)), generator=torch.Generator().manual_seed(0))
    radius = targets.norm(dim=-1)
    assert radius.max() <= 3.0 + 1e-6
    assert (radius < 1.5).double().mean().item() == pytest.approx(0.25, abs=0.03)  # area share of the inner disk
