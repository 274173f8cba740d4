"""Random restarts (solve's restart_steps): a numerical fallback for the targets a solve left unreached."""

import math

import pytest
import torch

import ikdp
from ikdp.arm import PlanarArm
from ikdp.guidance import ConstraintSet
from ikdp.kinematics import wrap_angle
from ikdp.restarts import restart_unreached, within_tolerances


def targets_of(arm, count, seed):
    return arm.end_effector(arm.random_poses(count, generator=torch.Generator().manual_seed(seed)))


def test_restarts_reach_the_targets_a_weak_model_missed_and_leave_the_reached_ones_alone(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)  # five training steps: its poses miss
    targets = targets_of(solver.arm, 40, seed=0)
    options = {"num_samples": 4, "sampler": "ddim", "steps": 2, "refine_steps": 3}
    plain = solver.solve(targets, **options, generator=torch.Generator().manual_seed(1))
    restarted = solver.solve(targets, **options, restart_steps=25, generator=torch.Generator().manual_seed(1))
    goals = targets[:, None].expand(-1, 4, -1)
    reached_before = within_tolerances(solver.arm, plain.angles, goals).any(1)
    reached_after = within_tolerances(solver.arm, restarted.angles, goals).any(1)
    assert plain.restarted is None
    assert torch.equal(restarted.restarted, ~reached_before)  # exactly the unreached targets restart
    assert restarted.restarted.sum() >= 10  # the weak model leaves many (the test means something)
    assert reached_after.float().mean() >= reached_before.float().mean() + 0.5  # measured 0.05 -> 0.85
    assert torch.equal(restarted.angles[reached_before], plain.angles[reached_before])
    assert torch.equal(restarted.raw_angles, plain.raw_angles)  # the sampler's poses are reported as they were
    # the reported errors are those of the poses returned
    assert torch.allclose(restarted.tip_error, solver.arm.tip_error(restarted.angles, goals))
    assert restarted.rotation_error.max() <= math.pi + 1e-4
    assert solver.arm.limit_violations(restarted.angles).sum() == 0


def test_a_near_miss_is_never_traded_for_a_worse_start():
    arm = PlanarArm([1.0] * 3)
    poses = arm.random_poses(6, generator=torch.Generator().manual_seed(0)).reshape(2, 3, 3)
    goals = arm.end_effector(poses) + torch.tensor([0.01, 0.0])  # each pose misses by 0.01 (tolerance 0.003)
    refined, restarted = restart_unreached(arm, poses, goals, steps=0)
    assert not restarted.any() and torch.equal(refined, poses)  # no steps: nothing happens
    refined, restarted = restart_unreached(arm, poses, goals, steps=1, generator=torch.Generator().manual_seed(1))
    assert restarted.all()
    before = arm.task_error(poses, goals).norm(dim=-1)
    after = arm.task_error(refined, goals).norm(dim=-1)
    reached = within_tolerances(arm, refined, goals)
    assert bool(((after <= before + 1e-6) | reached).all())


def test_a_bad_restart_steps_is_refused_in_one_line_before_any_work(tiny_chain_checkpoint, monkeypatch):
    solver = ikdp.load(tiny_chain_checkpoint)
    monkeypatch.setattr(solver.model, "sample", lambda *args, **kwargs: pytest.fail("sampling started"))
    for bad in (-1, 2.5, "3"):
        with pytest.raises(ValueError, match="restart_steps: expected a non-negative integer") as error:
            solver.solve(targets_of(solver.arm, 2, seed=0), restart_steps=bad)
        assert "\n" not in str(error.value)


def test_restarts_keep_locked_joints_and_clear_obstacles(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)  # five training steps: its poses miss
    arm = solver.arm
    # targets the arm reaches with joint 1 at 0.3: a locked solve can succeed
    poses = arm.random_poses(24, generator=torch.Generator().manual_seed(4))
    poses[:, 0] = 0.3
    targets = arm.end_effector(poses)
    goals = targets[:, None].expand(-1, 4, -1)
    locked = ikdp.LockedJoints({"panda_joint1": 0.3})
    obstacle = ikdp.Obstacles(centers=[[0.2, 0.06, 0.4]], radii=0.12)  # in the way of many of those poses
    options = {"num_samples": 4, "sampler": "ddim", "steps": 2, "refine_steps": 3}

    def solve(constraints, restart_steps):
        return solver.solve(
            targets, **options, constraints=constraints, restart_steps=restart_steps,
            generator=torch.Generator().manual_seed(1),
        )  # fmt: skip

    plain, out = solve([locked, obstacle], 0), solve([locked, obstacle], 30)
    assert torch.equal(out.angles[..., 0], torch.full_like(out.angles[..., 0], 0.3))  # every pose, fresh ones too
    reached_before = (within_tolerances(arm, plain.angles, goals) & (plain.constraint_violation == 0)).any(1)
    reached_after = (within_tolerances(arm, out.angles, goals) & (out.constraint_violation == 0)).any(1)
    assert torch.equal(out.restarted, ~reached_before)  # reaching means meeting the constraints too
    assert out.restarted.sum() >= 10  # the weak model leaves many (the test means something)
    assert reached_after.float().mean() >= reached_before.float().mean() + 0.2  # measured 0 -> 0.29
    assert torch.equal(out.angles[reached_before], plain.angles[reached_before])
    assert arm.limit_violations(out.angles).sum() == 0
    # the obstacle bites: restarted without it, poses reach through it (measured 12); with it, none does
    penetrating = ConstraintSet(arm, [obstacle], len(targets), 4).violation
    unaware = solve([locked], 30).angles
    assert (within_tolerances(arm, unaware, goals) & (penetrating(unaware) > 0)).sum() >= 3
    assert (within_tolerances(arm, out.angles, goals) & (penetrating(out.angles) > 0)).sum() == 0


def test_restarts_with_a_partial_target_judge_only_what_it_asks(tiny_chain_checkpoint):
    solver = ikdp.load(tiny_chain_checkpoint)
    positions = targets_of(solver.arm, 24, seed=5)[:, :3]  # position only: (B, 3)
    options = {"num_samples": 4, "sampler": "ddim", "steps": 2, "refine_steps": 2}
    out = solver.solve(
        positions, **options, constraints=[ikdp.PositionOnly()], restart_steps=20,
        generator=torch.Generator().manual_seed(2),
    )  # fmt: skip
    reached = (out.tip_error < solver.arm.position_tolerance).any(1)
    assert out.rotation_error is None and out.restarted.sum() >= 5
    assert reached.float().mean() >= 0.9  # no orientation asked, none demanded
    tips = solver.arm.end_effector(out.angles)[..., :3]
    assert torch.allclose(out.tip_error, (tips - positions[:, None]).norm(dim=-1), atol=1e-6)


def test_restarts_under_a_near_pose_start_from_it_and_stay_near(tiny_chain_checkpoint):
    """The robot at `current` moves its hand a little: a weak model's restarts find the nearby solution when they
    start from the pose to stay near, where uniform starts land anywhere."""
    solver = ikdp.load(tiny_chain_checkpoint)  # five training steps: its poses miss, every target restarts
    arm = solver.arm
    current = arm.random_poses(20, generator=torch.Generator().manual_seed(6))
    nudged = (current + 0.05).clamp(arm.joint_limits[:, 0], arm.joint_limits[:, 1])
    targets = arm.end_effector(nudged)
    goals = targets[:, None].expand(-1, 4, -1)
    options = {"num_samples": 4, "sampler": "ddim", "steps": 2, "refine_steps": 2, "restart_steps": 20}

    def nearest_reaching(constraints):
        out = solver.solve(targets, **options, constraints=constraints, generator=torch.Generator().manual_seed(1))
        assert out.restarted.sum() >= 15  # the weak model misses (the test means something)
        reached = within_tolerances(arm, out.angles, goals)
        distance = (out.angles - current[:, None]).norm(dim=-1).masked_fill(~reached, math.inf)
        return distance.min(dim=1).values, reached.any(1)

    near, near_reached = nearest_reaching([ikdp.NearPose(current, weight=0.3)])
    anywhere, _ = nearest_reaching([])
    assert near_reached.float().mean() >= 0.9
    # measured: all 20 reached, the nearest 0.131 rad away (the nudge itself: 0.05 rad a joint, 0.13 in all);
    # uniform starts (the restarts before they knew the pose): 85 % reached, 4.47 rad away
    assert float(near[near_reached].median()) < 0.3
    assert float(anywhere[anywhere.isfinite()].median()) > 3 * float(near[near_reached].median())


def test_a_near_pose_restarts_from_the_pose_then_a_growing_share_of_the_way_to_the_draws():
    arm = PlanarArm([1.0] * 3)
    pose = torch.tensor([0.2, -0.4, 0.6])
    bound = ikdp.NearPose(pose).bind(arm, batch=2, num_samples=3)
    draws = arm.random_poses(6, generator=torch.Generator().manual_seed(0)).reshape(2, 3, 3)
    starts = bound.restart_from(draws)
    assert torch.allclose(starts[:, 0], pose.expand(2, 3))  # the first start is the pose itself
    assert torch.allclose(starts[:, 2], pose + wrap_angle(draws[:, 2] - pose))  # the last one the draw
    assert torch.allclose(starts[:, 1], pose + wrap_angle(draws[:, 1] - pose) / 2)


def test_a_planar_solve_restarts_its_unreached_targets_too(tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)  # 3 links, thirty training steps: its raw poses miss
    targets = targets_of(solver.arm, 30, seed=2)
    out = solver.solve(
        targets, num_samples=4, sampler="ddim", steps=2, restart_steps=20, generator=torch.Generator().manual_seed(3)
    )
    goals = targets[:, None].expand(-1, 4, -1)
    assert out.restarted.sum() >= 20 and out.rotation_error is None  # measured: all 30, then every one reached
    assert within_tolerances(solver.arm, out.angles, goals).any(1).float().mean() >= 0.9
    assert torch.allclose(out.tip_error, solver.arm.tip_error(out.angles, goals))


def test_a_constraint_set_cut_to_some_targets_keeps_those_targets_rows():
    arm = PlanarArm([1.0] * 3)
    batch, samples = 3, 2
    poses = torch.tensor([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]])  # one pose to stay near per target
    centers = torch.tensor([[[1.0, 1.0]], [[2.0, 0.0]], [[0.0, 2.0]]])  # one disc per target
    locks = {0: [0.5, -0.5, 1.0]}
    constraints = [ikdp.NearPose(poses), ikdp.Obstacles(centers, radii=0.2), ikdp.LockedJoints(locks)]
    bound = ConstraintSet(arm, constraints, batch, samples)
    chosen = torch.tensor([False, True, True])
    subset = bound.of_targets(chosen)
    near, discs = subset.others
    assert subset.batch == 2 and subset.num_samples == samples
    assert torch.equal(near.pose, poses[1:].repeat_interleave(samples, dim=0))
    assert torch.equal(discs.centers, centers[1:].repeat_interleave(samples, dim=0))
    assert torch.equal(subset.locked.values[:, 0], torch.tensor([-0.5, -0.5, 1.0, 1.0]))
    joints = torch.zeros(2, samples, 3)
    assert torch.equal(subset.violation(joints), bound.violation(torch.zeros(batch, samples, 3))[chosen])
