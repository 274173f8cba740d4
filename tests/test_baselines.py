"""Classical and learned baselines: exact answers where there are any, convergence on easy targets."""

from __future__ import annotations

import math

import pytest
import torch

from ikdp.arm import PlanarArm
from ikdp.baselines.ccd import ccd
from ikdp.baselines.closed_form import solve_two_link, two_link_solutions
from ikdp.baselines.fabrik import fabrik
from ikdp.baselines.mlp import MLPConfig, mlp_from_state, mlp_state, train_mlp
from ikdp.baselines.neural_ik import (
    NeuralIKConfig,
    neural_ik_from_state,
    neural_ik_state,
    sample_von_mises,
    train_neural_ik,
)
from ikdp.baselines.random_starts import dls_polish, solve_from_random_starts
from ikdp.kinematics import absolute_to_relative, tip_position
from ikdp.priors import PosePrior


def easy_targets(num_links: int, count: int = 64) -> torch.Tensor:
    """Tips of random poses kept away from the rim and the base, where every solver should converge."""
    arm = PlanarArm((1.0,) * num_links)
    targets = arm.end_effector(arm.random_poses(count, generator=torch.Generator().manual_seed(num_links)))
    radius = targets.norm(dim=-1)
    return targets[(radius > 0.2 * num_links) & (radius < 0.8 * num_links)]


@pytest.mark.parametrize("lengths", [(1.0, 1.0), (1.5, 0.7)])
def test_two_link_closed_form_reaches_exactly_with_both_elbows(lengths):
    arm = PlanarArm(lengths)
    targets = torch.tensor([[1.2, 0.4], [-0.9, -0.3], [0.0, 1.0]])
    solutions = two_link_solutions(targets, arm)  # (B, 2, 2)
    miss = (tip_position(solutions.double(), torch.tensor(lengths).double()) - targets[:, None].double()).norm(dim=-1)
    assert miss.max() < 1e-6
    elbows = absolute_to_relative(solutions)[..., 1]
    assert (elbows[:, 0] > 0).all() and (elbows[:, 1] < 0).all()
    headings, error = solve_two_link(targets, arm, num_samples=3)
    assert headings.shape == (3, 3, 2) and error.max() < 1e-6
    with pytest.raises(ValueError, match="two links"):
        two_link_solutions(targets, PlanarArm((1.0, 1.0, 1.0)))


def test_two_link_closed_form_stretches_toward_a_far_target():
    headings = two_link_solutions(torch.tensor([[0.0, 5.0]]), PlanarArm((1.0, 1.0)))
    torch.testing.assert_close(headings[0, 0], torch.tensor([math.pi / 2, math.pi / 2]))


POLISHES = {
    "ccd": lambda starts, goals, arm: ccd(starts, goals, arm, sweeps=200),
    "fabrik": lambda starts, goals, arm: fabrik(starts, goals, arm, iterations=50),
    "dls": dls_polish(iterations=30),
}


@pytest.mark.parametrize("num_links", [3, 5])
@pytest.mark.parametrize("polish", list(POLISHES))
def test_random_start_solvers_converge_on_easy_targets(polish, num_links):
    targets = easy_targets(num_links)
    arm = PlanarArm((1.0,) * num_links)
    generator = torch.Generator().manual_seed(0)
    headings, error = solve_from_random_starts(POLISHES[polish], targets, arm, restarts=2, generator=generator)
    assert headings.shape == (len(targets), 2, num_links)
    assert (error < 1e-4).double().mean() > 0.95
    recomputed = (tip_position(headings.double(), torch.ones(num_links).double()) - targets[:, None].double()).norm(
        dim=-1
    )
    torch.testing.assert_close(error, recomputed.float())


def test_random_starts_are_seeded_and_refuse_no_restarts():
    arm, targets = PlanarArm((1.0, 1.0, 1.0)), easy_targets(3, count=8)
    identity = lambda starts, goals, arm: starts  # noqa: E731 (no polish: returns the random starts themselves)
    first, _ = solve_from_random_starts(identity, targets, arm, restarts=3, generator=torch.Generator().manual_seed(1))
    again, _ = solve_from_random_starts(identity, targets, arm, restarts=3, generator=torch.Generator().manual_seed(1))
    torch.testing.assert_close(first, again)
    assert first.abs().max() <= math.pi and first.std() > 1.0  # uniform on the circle, not a constant
    with pytest.raises(ValueError, match="restarts"):
        solve_from_random_starts(identity, targets, arm, restarts=0)


def test_zero_iterations_leave_the_pose_alone():
    start = torch.tensor([[0.3, -1.0, 2.0]])
    target = torch.tensor([[1.0, 1.0]])
    arm = PlanarArm((1.0, 1.0, 1.0))
    torch.testing.assert_close(ccd(start, target, arm, sweeps=0), start)
    torch.testing.assert_close(fabrik(start, target, arm, iterations=0), start, atol=1e-6, rtol=0)
    with pytest.raises(ValueError, match="sweeps"):
        ccd(start, target, arm, sweeps=-1)


def test_one_ccd_joint_step_points_the_tip_at_the_target():
    # a single link: one visit of joint 0 aims the whole arm at the target
    headings = ccd(torch.tensor([[0.0]]), torch.tensor([[0.0, 1.0]]), PlanarArm((1.0,)), sweeps=1)
    assert headings.item() == pytest.approx(math.pi / 2)


def test_von_mises_sampler_matches_its_moments():
    generator = torch.Generator().manual_seed(0)
    for kappa in (0.5, 4.0, 1000.0):
        draws = sample_von_mises(torch.full((20000,), 1.0), torch.full((20000,), kappa), generator).double()
        mean_resultant = torch.stack((torch.cos(draws - 1.0).mean(), torch.sin(draws - 1.0).mean()))
        concentration = torch.tensor(kappa, dtype=torch.float64)
        expected = torch.special.i1e(concentration) / torch.special.i0e(concentration)  # E cos(x - mu) = I1/I0
        assert mean_resultant[0].item() == pytest.approx(expected.item(), abs=0.02)
        assert abs(mean_resultant[1].item()) < 0.02


@pytest.mark.slow
def test_learned_baselines_learn_and_round_trip():
    prior, arm = PosePrior("uniform"), PlanarArm((1.0, 1.0))
    targets = easy_targets(2)
    mlp = train_mlp(MLPConfig(num_links=2, steps=150, batch=256, hidden=64, layers=2), prior, arm, progress=False)
    neural_ik = train_neural_ik(
        NeuralIKConfig(num_links=2, steps=150, batch=256, hidden=64, layers=2), prior, arm, progress=False
    )
    for model, rebuild in (
        (mlp, mlp_from_state(mlp_state(mlp))),
        (neural_ik, neural_ik_from_state(neural_ik_state(neural_ik))),
    ):
        for name, tensor in model.state_dict().items():
            torch.testing.assert_close(rebuild.state_dict()[name], tensor)
    untrained = torch.distributions.Uniform(-math.pi, math.pi)  # a random pose misses by ~1.4 on average
    _, mlp_error = mlp.solve(targets)
    _, neural_error = neural_ik.solve(targets, num_samples=4, generator=torch.Generator().manual_seed(0))
    assert neural_error.shape == (len(targets), 4)
    assert mlp_error.mean() < 1.2 and neural_error.mean() < 1.0, untrained
