"""A tree's partial targets, per end effector (`PositionOnly(effectors=...)`): one hand's pose, the other's position
only or free; the errors count the asked parts alone; and the captured solve's per-hand errors."""

import math

import pytest
import torch
from device_recorders import HostSyncRecorder
from tree_helpers import two_arms, untrained_solver

import ikdp
from ikdp.cuda_graph import solve_without_sync
from ikdp.samplers import make_sampler

SOLVE = dict(num_samples=4, sampler="ddim", steps=2, refine_steps=30)


def reachable_targets(arm, count: int, seed: int) -> torch.Tensor:
    joints = arm.random_poses(count, generator=torch.Generator().manual_seed(seed))
    return arm.stacked_targets(arm.end_effector(joints)).clone()  # (B, E, 7)


def test_a_position_only_hand_reaches_its_position_whatever_rotation_was_written():
    arm = two_arms()
    solver = untrained_solver(arm)
    targets = reachable_targets(arm, 6, 0)
    targets[:, 1, 3:] = torch.tensor([0.0, 1.0, 0.0, 0.0])  # a rotation the right hand cannot hold there
    full = solver.solve(targets, **SOLVE)
    assert float(full.tip_error.amin(1).min()) > 0.1  # every hand's pose asked: out of reach
    out = solver.solve(targets, **SOLVE, constraints=[ikdp.PositionOnly(effectors={"right_hand": "position"})])
    best = out.tip_error.argmin(1)
    rows = torch.arange(6)
    assert float(out.tip_error[rows, best].max()) < 1e-6  # both hands' positions
    assert float(out.rotation_error[rows, best].max()) < 1e-6  # the left hand's rotation: it counts
    assert bool(out.rotation_error_by_effector[..., 1].isnan().all())  # the right's does not
    torch.testing.assert_close(out.rotation_error, out.rotation_error_by_effector[..., 0])
    torch.testing.assert_close(out.tip_error, out.tip_error_by_effector.amax(-1))


def test_a_free_hand_is_ignored_whatever_its_row_holds():
    arm = two_arms()
    solver = untrained_solver(arm)
    targets = reachable_targets(arm, 5, 1)
    targets[:, 0] = torch.tensor([50.0, 0, 0, 3, 0, 0, 0])  # far away and no unit quaternion: never read
    out = solver.solve(targets, **SOLVE, constraints=[ikdp.PositionOnly(effectors={"left_hand": "free"})])
    assert bool(out.reachable.all())
    assert bool(out.tip_error_by_effector[..., 0].isnan().all())
    assert bool(out.rotation_error_by_effector[..., 0].isnan().all())
    torch.testing.assert_close(out.tip_error, out.tip_error_by_effector[..., 1])
    torch.testing.assert_close(out.rotation_error, out.rotation_error_by_effector[..., 1])
    assert float(out.tip_error.amin(1).max()) < 1e-6 and float(out.rotation_error.amin(1).max()) < 1e-6
    # positions only, (B, E, 3): a free left hand and a right hand's position, restarts judged by those alone
    positions = solver.solve(
        targets[..., :3],
        **SOLVE,
        restart_steps=10,
        constraints=[ikdp.PositionOnly(effectors={"left_hand": "free", "right_hand": "position"})],
    )
    assert positions.rotation_error is None and not bool(positions.restarted.any())
    assert float(positions.tip_error.amin(1).max()) < 1e-6


def test_each_sample_is_conditioned_on_the_asked_parts_and_a_pose_of_the_tree_for_the_rest():
    arm = two_arms()
    bound = ikdp.PositionOnly(effectors={"right_hand": "position", "left_hand": "free"}).bind(arm, 2, 3)
    targets = arm.validate_targets(reachable_targets(arm, 2, 2))
    conditions = arm.stacked_targets(bound.conditions(targets, 3, torch.Generator().manual_seed(0)))  # (B*K, E, 7)
    asked = arm.stacked_targets(targets).repeat_interleave(3, dim=0)
    torch.testing.assert_close(conditions[:, 1, :3], asked[:, 1, :3])  # the right hand's position as given
    assert not torch.allclose(conditions[:, 0], asked[:, 0])  # the rest from the tree's own poses
    torch.testing.assert_close(conditions[..., 3:].norm(dim=-1), torch.ones(6, 2))
    assert bound.rows.tolist() == [3, 4, 5] and bound.position_dim == 3  # the right hand's position rows alone


@pytest.mark.parametrize(
    ("constraint", "targets", "message"),
    [
        (ikdp.PositionOnly(effectors={"nope": "free"}), None, "effectors: unknown end effector 'nope'"),
        (ikdp.PositionOnly(effectors={"left_hand": "rotation"}), None, "effectors: expected parts in"),
        (ikdp.PositionOnly(effectors={"left_hand": "free", "right_hand": "free"}), None, "every end effector is free"),
        (ikdp.PositionOnly(effectors={"left_hand": "free"}), torch.zeros(1, 2, 3), "'right_hand''s pose counts"),
        (ikdp.PositionOnly(), torch.zeros(1, 3, 3), r"targets: expected shape \(B, 2, 7 or 3\)"),
        (ikdp.FreeAxis(), None, "a tree's partial targets are PositionOnly"),
    ],
)
def test_bad_partial_targets_are_refused_naming_them(constraint, targets, message):
    arm = two_arms()
    targets = reachable_targets(arm, 1, 0) if targets is None else targets
    with pytest.raises(ValueError, match=message):
        untrained_solver(arm).solve(targets, num_samples=2, constraints=[constraint])


def test_a_chain_refuses_effectors():
    with pytest.raises(ValueError, match="effectors names the end effectors of a tree"):
        ikdp.load("ikdp_z1").solve(torch.zeros(1, 3), constraints=[ikdp.PositionOnly(effectors={"x": "free"})])


def test_the_captured_solve_gives_each_hands_errors(monkeypatch):
    """The body a CUDA graph holds, run eagerly here: the same errors per hand as `solve` for the same seed."""
    arm = two_arms()
    solver = untrained_solver(arm)
    targets = arm.validate_targets(reachable_targets(arm, 4, 3))
    sampler = make_sampler("ddim", solver.model.schedule, 2, solver.default_spacing("ddim", 2))
    body = solve_without_sync(
        solver, sampler, targets, num_samples=3, refine_steps=20, restart_steps=0, generator=torch.Generator()
    )
    assert body.tip_error_by_effector.shape == (4, 3, 2) and body.rotation_error_by_effector.shape == (4, 3, 2)
    torch.testing.assert_close(body.tip_error, body.tip_error_by_effector.amax(-1))
    torch.testing.assert_close(body.rotation_error, body.rotation_error_by_effector.amax(-1))
    position, rotation = arm.errors_by_effector(body.angles, targets[:, None])
    torch.testing.assert_close(body.tip_error_by_effector, position)
    torch.testing.assert_close(body.rotation_error_by_effector, rotation)
    reached = (body.tip_error < 1e-3) & (body.rotation_error < math.radians(1))
    assert bool(reached.any())  # refined poses within 1 mm and 1 degree on both hands
    # on a GPU, where a graph is captured, no target is read through NumPy (a CPU's shortcut for a few rows)
    monkeypatch.setattr("ikdp.arm_inputs.FEW_ROWS", 0)
    recorder = HostSyncRecorder()  # what a CUDA graph holds may not wait for the device: the tree's errors neither
    options = dict(num_samples=3, refine_steps=3, restart_steps=4, generator=torch.Generator().manual_seed(0))
    with recorder, torch.inference_mode():
        solve_without_sync(solver, sampler, targets, **options)
    assert recorder.found == []
