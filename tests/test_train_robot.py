"""`ikdp.train --robot/--urdf`: a chain model trains, saves, loads and solves pose targets within the limits."""

import math
from dataclasses import replace

import pytest
import torch

import ikdp
from ikdp.describe import describe
from ikdp.robots import example_robot_data_file, spatial_arm_urdf
from ikdp.train import TrainConfig, build_chain_arm, train


def robot_config(tmp_path, **changes) -> TrainConfig:
    values = dict(
        robot="panda",
        steps=12,
        batch=32,
        hidden=24,  # at least the Panda's 20 input features
        blocks=1,
        timesteps=8,
        eval_targets=8,
        save_every=100,
        output=str(tmp_path / "robot.pt"),
        log_dir=str(tmp_path / "tb"),
        threads=1,
    )
    values.update(changes)
    return TrainConfig(**values)


@pytest.fixture(scope="module")
def panda_checkpoint(tmp_path_factory):
    torch.manual_seed(0)
    return train(robot_config(tmp_path_factory.mktemp("panda")))


def test_a_panda_model_solves_pose_targets_within_the_limits(panda_checkpoint):
    solver = ikdp.load(panda_checkpoint)
    arm = solver.arm
    assert arm.ee_link == "panda_hand" and arm.num_joints == 7
    assert arm.urdf_path is not None and arm.urdf_path.endswith("panda.urdf")
    targets = arm.end_effector(arm.random_poses(3, generator=torch.Generator().manual_seed(1)))
    assert targets.shape == (3, 7)
    out = solver.solve(targets, num_samples=4, refine_steps=2, generator=torch.Generator().manual_seed(0))
    assert out.angles.shape == (3, 4, 7)
    assert out.position_error.shape == out.rotation_error.shape == (3, 4)
    assert int(arm.limit_violations(out.raw_angles).sum()) == 0
    assert int(arm.limit_violations(out.angles).sum()) == 0
    # the errors are the arm's own measures of the returned joints
    assert torch.allclose(out.position_error, arm.position_error(out.angles, targets[:, None]), atol=1e-6)
    assert torch.allclose(out.rotation_error, arm.rotation_error(out.angles, targets[:, None]), atol=1e-6)
    assert float(out.rotation_error.max()) <= math.pi + 1e-6


def test_a_robot_checkpoint_records_pose_metrics_and_describes_itself(panda_checkpoint):
    payload = torch.load(panda_checkpoint, weights_only=True)
    assert payload["model"]["arm"]["kind"] == "chain"
    assert payload["metrics"]["rotation_error_median"] >= 0
    assert payload["metrics"]["limit_violations"] == 0
    row = describe([str(panda_checkpoint)]).splitlines()[2]
    assert "panda (panda_hand), 7 joints, pose targets" in row
    assert " mm / " in row and "°" in row


def test_any_urdf_trains_with_its_end_effector_link(tmp_path):
    urdf = tmp_path / "two_links.urdf"
    urdf.write_text(spatial_arm_urdf(2))
    arm_checkpoint = train(robot_config(tmp_path, robot="", urdf=str(urdf), ee_link="tip", target="position", steps=4))
    solver = ikdp.load(arm_checkpoint)
    assert solver.arm.target_dim == 3 and solver.arm.num_joints == 4
    out = solver.solve([[1.0, 0.5, 0.2]], num_samples=2)
    assert out.angles.shape == (1, 2, 4) and out.rotation_error is None
    assert "| two_links.urdf (tip), 4 joints, position targets |" in describe([str(arm_checkpoint)])


def test_a_robot_needs_its_end_effector_link(tmp_path):
    urdf = example_robot_data_file("panda_description/urdf/panda.urdf")
    with pytest.raises(ValueError, match="ee-link"):
        train(robot_config(tmp_path, robot="", urdf=str(urdf), ee_link=""))


def test_a_film_denoiser_narrower_than_its_features_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"hidden \(16\) must be at least its 20 input features"):
        train(robot_config(tmp_path, hidden=16))


def test_a_missing_end_effector_link_lists_the_urdfs_links(tmp_path):
    urdf = tmp_path / "two_links.urdf"
    urdf.write_text(spatial_arm_urdf(2))
    with pytest.raises(ValueError, match=r"--ee-link NAME.*its links: base, bone0_yaw, .*, tip$"):
        train(robot_config(tmp_path, robot="", urdf=str(urdf), ee_link=""))


def test_base_link_starts_the_chain_below_the_root(tmp_path):
    urdf = tmp_path / "two_links.urdf"
    urdf.write_text(spatial_arm_urdf(2))
    config = robot_config(tmp_path, robot="", urdf=str(urdf), ee_link="tip", base_link="bone0_pitch", target="position")
    solver = ikdp.load(train(replace(config, steps=2)))
    assert solver.arm.base_link == "bone0_pitch" and solver.arm.joint_names == ["joint1_yaw", "joint1_pitch"]
    with pytest.raises(ValueError, match="base_link: --base-link goes with --urdf"):
        train(robot_config(tmp_path, base_link="panda_link0"))


def test_a_joint_locked_by_equal_limits_is_refused_before_training(tmp_path):
    urdf = tmp_path / "locked.urdf"
    urdf.write_text(
        spatial_arm_urdf(1)
        .replace('type="continuous"', 'type="revolute"', 1)
        .replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 1"/><limit lower="0.5" upper="0.5"/>', 1)
    )
    with pytest.raises(ValueError, match="joint 'joint0_yaw' has equal lower and upper limits"):
        train(robot_config(tmp_path, robot="", urdf=str(urdf), ee_link="tip", target="position"))
    assert not (tmp_path / "robot.pt").exists()


def test_a_robots_end_effector_link_is_honoured_or_refused_not_ignored(tmp_path):
    with pytest.raises(ValueError, match=r"^ee_link: no link 'nope' in the URDF; its links: panda_link0, "):
        train(robot_config(tmp_path, ee_link="nope"))
    assert not (tmp_path / "tb").exists() and not (tmp_path / "robot.pt").exists()  # refused before training
    assert build_chain_arm(robot_config(tmp_path, ee_link="panda_link8")).ee_link == "panda_link8"
    assert build_chain_arm(robot_config(tmp_path)).ee_link == "panda_hand"  # the robot's own when none is given
    with pytest.raises(ValueError, match="ee_link: the spatial arm ends at its tip, got 'tip'"):
        build_chain_arm(robot_config(tmp_path, robot="spatial2", ee_link="tip"))
