"""A refinement that stops once every target has a pose within the tolerances (`solve(stop_when_reached=True)`),
and the errors the fused refinement measures on its way, which a one-target solve reports as its own."""

import pytest
import torch

import ikdp
import ikdp.denoisers.chain_film
import ikdp.fused_chain
from ikdp.arm import PlanarArm
from ikdp.refine import damped_least_squares
from ikdp.robots import load_robot


def near_starts(arm, count: int, seed: int):
    """(1, count, J) starts a little off one pose, and that pose's end effector as every row's target."""
    generator = torch.Generator().manual_seed(seed)
    pose = arm.random_poses(1, generator=generator).double()
    starts = arm.normalize_joints(
        pose + 0.05 * torch.randn(count, arm.num_joints, generator=generator, dtype=pose.dtype)
    )
    target = arm.end_effector(pose)
    return starts[None], target[:, None].expand(1, count, -1)


def within(arm, joints, targets):
    position, rotation = arm.tip_and_rotation_errors(joints, targets)
    ok = position < arm.position_tolerance
    return ok if rotation is None else ok & (rotation < arm.rotation_tolerance)


@pytest.mark.parametrize("name", ["panda", "z1"])
def test_the_fused_and_general_loops_stop_at_the_same_step(name):
    arm = load_robot(name)
    starts, targets = near_starts(arm, 16, seed=3)
    full = damped_least_squares(arm, starts, targets, steps=20)
    for fused in (arm.small_batch_kinematics(), arm):
        stopped, _ = fused.refine_scored(starts, targets, steps=20, until_reached=True)
        assert within(arm, stopped, targets).any()
        assert not torch.allclose(stopped, full, atol=1e-9)  # it stopped before the twentieth step
        # the same steps as the whole loop's first few: some prefix of it
        matches = [
            torch.allclose(stopped, damped_least_squares(arm, starts, targets, steps=steps), atol=1e-6)
            for steps in range(20)
        ]
        assert any(matches)
    ours, _ = arm.small_batch_kinematics().refine_scored(starts, targets, steps=20, until_reached=True)
    theirs = damped_least_squares(arm, starts, targets, steps=20, until_reached=True)
    torch.testing.assert_close(ours, theirs, atol=1e-6, rtol=0)


def test_a_target_none_of_whose_poses_reaches_takes_every_step():
    arm = load_robot("panda")
    starts, targets = near_starts(arm, 8, seed=4)
    starts = arm.random_poses(8, generator=torch.Generator().manual_seed(5)).double()[None]  # far starts
    for steps in (1, 2):
        ours, _ = arm.small_batch_kinematics().refine_scored(starts, targets, steps=steps, until_reached=True)
        torch.testing.assert_close(ours, damped_least_squares(arm, starts, targets, steps=steps), atol=1e-9, rtol=0)


def test_a_planar_arm_stops_when_reached_too():
    arm = PlanarArm([1.0, 1.0, 1.0])
    headings = arm.random_poses(8, generator=torch.Generator().manual_seed(0))[None]
    target = arm.end_effector(arm.random_poses(1, generator=torch.Generator().manual_seed(1)))
    targets = target[:, None].expand(1, 8, -1)
    stopped, scores = arm.refine_scored(headings, targets, steps=30, until_reached=True)
    assert scores is None and within(arm, stopped, targets).any()
    assert not torch.equal(stopped, damped_least_squares(arm, headings, targets, steps=30))


@pytest.mark.parametrize("name", ["panda", "z1"])
def test_the_scores_are_the_arms_errors_of_the_poses_returned(name):
    arm = load_robot(name)
    starts, targets = near_starts(arm, 16, seed=6)
    starts, targets = starts.float(), targets.float()
    refined, scores = arm.small_batch_kinematics().refine_scored(starts, targets, steps=3)
    assert refined.dtype == torch.float32
    position, rotation = arm.tip_and_rotation_errors(refined, targets)
    torch.testing.assert_close(scores.position, position, atol=1e-7, rtol=1e-5)
    torch.testing.assert_close(scores.rotation, rotation, atol=1e-7, rtol=1e-5)
    torch.testing.assert_close(
        scores.first_position, arm.tip_and_rotation_errors(starts, targets)[0], atol=1e-7, rtol=1e-5
    )
    assert torch.equal(scores.within(arm), within(arm, refined, targets))


def test_a_one_target_solve_that_stops_when_reached_matches_the_general_path(tiny_chain_checkpoint, monkeypatch):
    solver = ikdp.load(tiny_chain_checkpoint)
    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(4, generator=torch.Generator().manual_seed(2)))
    options = {"num_samples": 8, "sampler": "ddim", "steps": 2, "refine_steps": 6, "restart_steps": 3}
    monkeypatch.setattr(ikdp.denoisers.chain_film, "small_batch", lambda rows, device: False)  # same raw poses
    answers = {}
    for rows in (ikdp.fused_chain.FUSED_ROWS, 0):
        monkeypatch.setattr(ikdp.fused_chain, "FUSED_ROWS", rows)
        answers[rows] = [
            solver.solve(target[None], generator=torch.Generator().manual_seed(i), stop_when_reached=True, **options)
            for i, target in enumerate(targets)
        ]
    for ours, theirs in zip(*answers.values(), strict=True):
        torch.testing.assert_close(ours.angles, theirs.angles, atol=1e-5, rtol=0)
        torch.testing.assert_close(ours.tip_error, theirs.tip_error, atol=1e-6, rtol=0)
        torch.testing.assert_close(ours.rotation_error, theirs.rotation_error, atol=1e-6, rtol=0)
        torch.testing.assert_close(ours.raw_tip_error, theirs.raw_tip_error, atol=1e-6, rtol=0)
        assert torch.equal(ours.restarted, theirs.restarted)


def test_stop_when_reached_must_be_a_bool(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)
    target = solver.arm.end_effector(solver.arm.random_poses(1, generator=torch.Generator().manual_seed(0)))
    with pytest.raises(ValueError, match="stop_when_reached: expected True or False, got 'yes'"):
        solver.solve(target, stop_when_reached="yes")
