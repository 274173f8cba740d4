"""solver.stream: one target a call, warm-started from the last answer; continuous on a smooth path, a tracking
solve where the warm start does not reach, one-line errors for bad input."""

import pytest
import torch

import ikdp
from ikdp.constraint_base import joint_difference
from ikdp.stream import PoseStream


def smooth_path(arm, steps: int, seed: int = 0, share: float = 0.5):
    """A straight joint-space sweep over `share` of the way between two uniform poses, its end effector at `steps`
    points: (the start pose, (steps, target_dim) targets)."""
    first, second = arm.random_poses(2, generator=torch.Generator().manual_seed(seed))
    second = first + share * (second - first)
    fractions = torch.linspace(0, 1, steps)[:, None]
    return first, arm.end_effector(first + fractions * (second - first))


@pytest.fixture(scope="module")
def panda_solver(tiny_chain_checkpoint):
    return ikdp.load(tiny_chain_checkpoint)


@pytest.fixture(scope="module")
def planar_solver(tiny_checkpoint):
    return ikdp.load(tiny_checkpoint)


@pytest.mark.parametrize("which", ["panda", "planar"])
def test_a_smooth_path_is_followed_within_the_tolerances_without_a_jump(which, panda_solver, planar_solver):
    solver = panda_solver if which == "panda" else planar_solver
    arm = solver.arm
    start, path = smooth_path(arm, 200)
    stream = solver.stream(start)
    assert isinstance(stream, PoseStream)
    poses, previous = [], start
    for target in path:
        pose = stream(target)
        assert pose.shape == (arm.num_joints,)
        assert stream.reached
        poses.append(pose)
    poses = torch.stack(poses)
    goals = path[:, None]
    position, rotation = arm.tip_and_rotation_errors(poses[:, None], goals)
    assert (position < arm.position_tolerance).all()
    if rotation is not None:
        assert (rotation < arm.rotation_tolerance).all()
    # each call moves the joints about as much as the path's step asks: no change of branch
    before = torch.cat([previous[None], poses[:-1]])
    steps = joint_difference(arm, poses, before).abs().amax(dim=-1)  # headings the short way round
    assert float(steps.max()) < 0.05
    assert stream.fallbacks == 0 and stream.calls == len(path)
    assert 1 <= stream.steps <= stream.max_steps
    if arm.kind == "chain":
        assert arm.limit_violations(poses).sum() == 0


def test_a_target_the_warm_start_cannot_reach_falls_back_to_a_tracking_solve(panda_solver):
    arm = panda_solver.arm
    start, path = smooth_path(arm, 2, share=1.0)  # a jump across the workspace in one call
    stream = panda_solver.stream(start, max_steps=1, num_samples=4, sampler="ddim", steps=2, refine_steps=5)
    pose = stream(path[-1])
    assert stream.fallbacks == 1 and stream.calls == 1
    assert torch.equal(pose, stream.pose)
    position, rotation = arm.tip_and_rotation_errors(pose[None], path[-1:])
    assert stream.position_error == pytest.approx(float(position[0]), abs=1e-6)
    assert stream.reached == bool(position[0] < arm.position_tolerance and rotation[0] < arm.rotation_tolerance)


def test_a_jump_larger_than_max_jump_is_not_taken_from_the_warm_start(panda_solver):
    arm = panda_solver.arm
    start, path = smooth_path(arm, 50)
    stream = panda_solver.stream(start, max_jump=1e-6, num_samples=2, sampler="ddim", steps=1)
    stream(path[10])
    assert stream.fallbacks == 1


@pytest.mark.parametrize(
    "options, message",
    [
        ({"start_pose": [0.0, 0.0]}, r"start_pose: expected shape \(7,\), got \(2,\)"),
        ({"start_pose": [float("nan")] * 7}, "start_pose: expected finite joint values"),
        ({"max_steps": 0}, "max_steps: expected a positive integer, got 0"),
        ({"max_steps": 2.5}, "max_steps: expected a positive integer, got 2.5"),
        ({"max_jump": -1.0}, "max_jump: expected a positive number of radians, got -1.0"),
        ({"max_jump": float("inf")}, "max_jump: expected a positive number of radians, got inf"),
    ],
)
def test_bad_stream_options_get_one_line_errors(panda_solver, options, message):
    options = {"start_pose": [0.0] * 7, **options}
    with pytest.raises(ValueError, match=message):
        panda_solver.stream(options.pop("start_pose"), **options)


@pytest.mark.parametrize(
    "target, message",
    [
        ([0.3, 0.0, 0.5], r"target: expected one target of shape \(7,\) or \(1, 7\), got \(1, 3\)"),
        ([[0.3, 0.0, 0.5, 1, 0, 0, 0]] * 2, r"target: expected one target of shape \(7,\) or \(1, 7\), got \(2, 7\)"),
        ([0.3, 0.0, 0.5, 0.5, 0, 0, 0], "targets: row 0 has quaternion"),
        ([0.3, float("nan"), 0.5, 1, 0, 0, 0], "targets"),
    ],
)
def test_bad_targets_get_one_line_errors_and_leave_the_stream_as_it_was(panda_solver, target, message):
    stream = panda_solver.stream([0.0] * 7)
    start = stream.pose.clone()
    assert torch.equal(start, panda_solver.arm.normalize_joints(torch.zeros(7)))  # clamped into the limits
    with pytest.raises(ValueError, match=message):
        stream(target)
    assert stream.calls == 0 and torch.equal(stream.pose, start)
