"""Continuous joints (no limits, e.g. the Kinova's): diffused as (cos, sin) so samples wrap, refined across +-pi,
trained and solved from a URDF that has them."""

import math

import pytest
import torch

import ikdp
from ikdp.chain_arm import ChainArm
from ikdp.refine import damped_least_squares
from ikdp.representation import AngleRepresentation
from ikdp.robots import example_robot_data_file, load_robot
from ikdp.train import TrainConfig, train
from ikdp.urdf import parse_chain

KINOVA = "kinova_description/robots/kinova.urdf"  # Jaco 2, 6 joints: 1, 4 and 6 continuous
KINOVA_HAND = "j2s6s200_end_effector"


def joints_representation(arm) -> AngleRepresentation:
    return AngleRepresentation("joints", arm.num_joints, limits=arm.joint_limits, continuous=arm.continuous_joints)


@pytest.fixture(scope="module")
def kinova() -> ChainArm:
    path = example_robot_data_file(KINOVA)
    return ChainArm.from_description(parse_chain(open(path).read(), KINOVA_HAND))


def test_continuous_joints_are_a_pair_that_wraps_and_limited_joints_one_scaled_number(kinova):
    assert kinova.continuous_joints.tolist() == [True, False, False, True, False, True]
    representation = joints_representation(kinova)
    assert representation.dim == 9  # 3 continuous x 2 + 3 limited
    joints = kinova.random_poses(64, generator=torch.Generator().manual_seed(0)).float()  # (64, 6)
    encoded = representation.encode(joints)
    torch.testing.assert_close(representation.decode(encoded), joints, atol=1e-5, rtol=0)
    turned = joints + 2 * math.pi * kinova.continuous_joints.float()  # one more turn of each continuous joint
    torch.testing.assert_close(representation.encode(turned), encoded, atol=1e-5, rtol=0)
    # a pair pushed past the seam decodes past it (wrapped), where a scaled joint would be clamped at pi
    beyond = torch.zeros(6)
    beyond[0] = math.pi + 0.3
    assert representation.decode(representation.encode(beyond))[0] == pytest.approx(0.3 - math.pi, abs=1e-5)
    assert representation.coordinate_mask(torch.tensor([True, False, False, False, False, True])).tolist() == [
        True, True, False, False, False, False, False, True, True,
    ]  # fmt: skip


def test_projection_puts_pairs_back_on_the_circle_and_clamps_the_rest(kinova):
    representation = joints_representation(kinova)
    noisy = torch.randn(32, representation.dim, generator=torch.Generator().manual_seed(3)) * 2
    projected = representation.project(noisy)
    pairs = representation.coordinate_mask(kinova.continuous_joints)
    torch.testing.assert_close(projected[:, pairs].unflatten(-1, (3, 2)).norm(dim=-1), torch.ones(32, 3))
    assert projected[:, ~pairs].abs().max() <= 1.0
    torch.testing.assert_close(representation.project(projected), projected, atol=1e-5, rtol=0)  # idempotent


def test_without_continuous_joints_it_is_the_limits_representation_number_for_number():
    panda = load_robot("panda")
    joints = panda.random_poses(16, generator=torch.Generator().manual_seed(1)).float()
    mixed, scaled = joints_representation(panda), AngleRepresentation("limits", 7, limits=panda.joint_limits)
    assert mixed.dim == scaled.dim == 7
    torch.testing.assert_close(mixed.encode(joints), scaled.encode(joints))
    torch.testing.assert_close(mixed.decode(mixed.encode(joints) * 1.3), scaled.decode(scaled.encode(joints) * 1.3))


def test_refinement_crosses_the_seam_of_a_continuous_joint_the_short_way(kinova):
    start = kinova.random_poses(1, generator=torch.Generator().manual_seed(5)).double()
    start[0, 0] = math.pi - 0.1  # joint 1 just short of +pi
    goal = start.clone()
    goal[0, 0] = -math.pi + 0.1  # 0.2 rad further on, across the seam
    target = kinova.end_effector(goal)
    refined = damped_least_squares(kinova, start, target, steps=20)
    assert float(kinova.position_error(refined, target)) < 1e-5
    assert float(refined[0, 0]) == pytest.approx(-math.pi + 0.1, abs=1e-4)  # wrapped through pi, not back round


def test_a_urdf_with_continuous_joints_trains_and_solves(tmp_path):
    config = TrainConfig(
        urdf=str(example_robot_data_file(KINOVA)),
        ee_link=KINOVA_HAND,
        steps=30,
        batch=64,
        hidden=32,
        blocks=1,
        timesteps=10,
        eval_targets=8,
        threads=1,
        output=str(tmp_path / "kinova.pt"),
        log_dir=str(tmp_path / "tb"),
    )
    solver = ikdp.load(train(config))
    assert solver.model.representation.kind == "joints" and solver.noise_dim == 9
    arm = solver.arm
    poses = arm.random_poses(4, generator=torch.Generator().manual_seed(2))
    out = solver.solve(
        arm.end_effector(poses), num_samples=8, refine_steps=3, generator=torch.Generator().manual_seed(0)
    )
    continuous = out.angles[..., arm.continuous_joints]
    assert continuous.abs().max() <= math.pi + 1e-6 and int(arm.limit_violations(out.angles).sum()) == 0
    # samples spread round the whole circle: a clamped representation piles them up at +-pi
    raw = solver.solve(arm.end_effector(poses), num_samples=64, generator=torch.Generator().manual_seed(1))
    at_seam = (raw.raw_angles[..., arm.continuous_joints].abs() > math.pi - 1e-3).float().mean()
    assert float(at_seam) < 0.05
