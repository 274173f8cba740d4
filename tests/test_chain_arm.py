"""ChainArm: forward kinematics against pytorch_kinematics, the Jacobian against autograd, limits,
quaternion conventions, the config round trip, and damped least squares converging on it."""

import io
import math
from pathlib import Path

import pytest
import torch

from ikdp.arm import arm_from_config
from ikdp.chain_arm import ChainArm
from ikdp.refine import clamp_task_error, damped_least_squares, dls_step
from ikdp.robots import ROBOTS, example_robot_data_file, load_robot, robot_names, spatial_arm
from ikdp.rotations import matrix_to_quaternion, quaternion_to_matrix, rpy_to_matrix
from ikdp.urdf import parse_chain

# Every joint type, fixed joints with rotations between them, axes off the coordinate axes.
MIXED_URDF = """<robot name="mixed">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0.4"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.1 0 0.2" rpy="0.3 -0.2 0.1"/><axis xyz="1 1 0"/>
    <limit lower="-0.1" upper="0.2" effort="1" velocity="1"/></joint>
  <joint name="bend" type="fixed"><parent link="l2"/><child link="l3"/><origin xyz="0 0.25 0" rpy="1.2 0 -0.5"/></joint>
  <joint name="j3" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.2 0 0.1" rpy="0 0.7 0"/><axis xyz="0.3 -0.4 0.5"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l4"/><child link="tool"/>
    <origin xyz="0 0 0.15" rpy="0.2 0.3 0.4"/></joint>
</robot>"""


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


def mixed_arm(target: str = "pose") -> ChainArm:
    return ChainArm.from_description(parse_chain(MIXED_URDF, "tool"), target=target)


def pk_chain(urdf_text: str, ee_link: str):
    pk = pytest.importorskip("pytorch_kinematics")
    return pk.build_serial_chain_from_urdf(urdf_text, ee_link).to(dtype=torch.float64)


def poses(arm: ChainArm, count: int, seed: int = 0) -> torch.Tensor:
    return arm.random_poses(count, generator=torch.Generator().manual_seed(seed)).double()


def test_panda_forward_kinematics_matches_pytorch_kinematics(panda):
    chain = pk_chain(example_robot_data_file(ROBOTS["panda"].urdf).read_text(), "panda_hand")
    joints = poses(panda, 256)
    reference = chain.forward_kinematics(joints).get_matrix()  # (B, 4, 4)
    rotation, position = panda.end_effector_frame(joints)
    torch.testing.assert_close(position, reference[:, :3, 3], atol=1e-5, rtol=0)
    torch.testing.assert_close(rotation, reference[:, :3, :3], atol=1e-5, rtol=0)
    position32 = panda.end_effector(joints.float())[:, :3]  # the float32 path training uses
    torch.testing.assert_close(position32.double(), reference[:, :3, 3], atol=1e-5, rtol=0)


@pytest.mark.parametrize(
    ("urdf", "ee_link"),
    [
        ("z1_description/urdf/z1.urdf", "gripperStator"),
        ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),
    ],
)
def test_arms_a_user_brings_match_pytorch_kinematics(urdf, ee_link):
    """The Z1 (dynamics, a fixed tool link after the last joint), the Kinova (continuous joints, limits far from 0)."""
    arm = ChainArm.from_urdf(example_robot_data_file(urdf), ee_link)
    joints = poses(arm, 128)
    reference = pk_chain(example_robot_data_file(urdf).read_bytes(), ee_link).forward_kinematics(joints).get_matrix()
    rotation, position = arm.end_effector_frame(joints)
    torch.testing.assert_close(position, reference[:, :3, 3], atol=1e-5, rtol=0)
    torch.testing.assert_close(rotation, reference[:, :3, :3], atol=1e-5, rtol=0)


def test_every_link_pose_matches_pytorch_kinematics_on_a_mixed_chain():
    arm = mixed_arm()
    joints = poses(arm, 64)
    joints[:, 2] = torch.linspace(-6, 6, 64, dtype=torch.float64)  # continuous: beyond one turn
    frames = pk_chain(MIXED_URDF, "tool").forward_kinematics(joints, end_only=False)
    link_poses = arm.link_poses(joints)
    assert link_poses.shape == (64, len(arm.link_names), 4, 4)
    for index, name in enumerate(arm.link_names):
        torch.testing.assert_close(link_poses[:, index], frames[name].get_matrix(), atol=1e-5, rtol=0)
    points = arm.forward_kinematics(joints)
    assert points.shape == (64, arm.num_joints + 1, 3)
    torch.testing.assert_close(points[:, -1], link_poses[:, -1, :3, 3])


def test_spatial_arm_closed_form():
    arm = spatial_arm(2)  # joints: yaw0, pitch0, yaw1, pitch1; bones of length 1 along x
    assert arm.num_joints == 4 and arm.target_dim == 3 and arm.reach == (0.0, 2.0)
    quarter = math.pi / 2
    cases = {
        (0.0, 0.0, 0.0, 0.0): (2.0, 0.0, 0.0),
        (quarter, 0.0, 0.0, 0.0): (0.0, 2.0, 0.0),
        (0.0, -quarter, 0.0, 0.0): (0.0, 0.0, 2.0),  # pitch about y: x turns towards -z for positive angles
        (0.0, 0.0, quarter, 0.0): (1.0, 1.0, 0.0),
        (0.0, 0.0, math.pi, 0.0): (0.0, 0.0, 0.0),
    }
    for joints, tip in cases.items():
        torch.testing.assert_close(arm.end_effector(torch.tensor(joints)), torch.tensor(tip), atol=1e-6, rtol=0)
    torch.testing.assert_close(
        arm.forward_kinematics(torch.tensor([quarter, 0.0, 0.0, 0.0])),
        torch.tensor([[0.0, 0, 0], [0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 2, 0]]),
        atol=1e-6,
        rtol=0,
    )


@pytest.mark.parametrize("name", ["panda", "mixed"])
def test_jacobian_matches_autograd(name, panda):
    arm = panda if name == "panda" else mixed_arm()
    joints = poses(arm, 4, seed=1)
    jacobian = arm.jacobian(joints)  # (B, 6, J)
    assert jacobian.shape == (4, 6, arm.num_joints)
    for row, pose in enumerate(joints):
        position_rows = torch.autograd.functional.jacobian(lambda q: arm.end_effector_frame(q)[1], pose)
        torch.testing.assert_close(jacobian[row, :3], position_rows, atol=1e-9, rtol=0)
        # At the target the error is zero, and a step dq changes the rotation error by -omega dq exactly.
        target = arm.end_effector_pose(pose).detach()
        error_rows = torch.autograd.functional.jacobian(lambda q, target=target: arm.task_error(q, target), pose)
        torch.testing.assert_close(-error_rows, jacobian[row], atol=1e-9, rtol=0)


@pytest.mark.parametrize("name", ["panda", "mixed", "position"])
def test_the_error_and_jacobian_from_one_kinematics_pass_are_the_separate_ones(name, panda):
    arm = {"panda": panda, "mixed": mixed_arm()}.get(name) or spatial_arm(3)
    joints = poses(arm, 6, seed=2).reshape(2, 3, -1)
    targets = arm.end_effector(poses(arm, 6, seed=3)).reshape(2, 3, -1)
    error, jacobian = arm.task_error_and_jacobian(joints, targets)
    assert torch.equal(error, arm.task_error(joints, targets)) and torch.equal(jacobian, arm.jacobian(joints))


def test_angular_rows_are_the_quaternions_rate_anywhere(panda):
    # omega = 2 vec(dq/dt * conj(q)): the quaternion's own derivative, away from the target too.
    pose = poses(panda, 1, seed=2)[0]
    quaternion = panda.end_effector_pose(pose)[3:]
    rates = torch.autograd.functional.jacobian(lambda q: panda.end_effector_pose(q)[3:], pose)  # (4, J)
    w, x, y, z = quaternion
    conjugate_product = torch.stack(
        [
            -x * rates[0] + w * rates[1] - z * rates[2] + y * rates[3],
            -y * rates[0] + z * rates[1] + w * rates[2] - x * rates[3],
            -z * rates[0] - y * rates[1] + x * rates[2] + w * rates[3],
        ]
    )
    torch.testing.assert_close(2 * conjugate_product, panda.jacobian(pose)[3:], atol=1e-9, rtol=0)


def test_position_arm_has_three_rows_and_three_target_numbers():
    arm = mixed_arm("position")
    joints = poses(arm, 3)
    assert arm.end_effector(joints).shape == (3, 3) and arm.jacobian(joints).shape == (3, 3, 3)
    rows = torch.autograd.functional.jacobian(lambda q: arm.end_effector(q), joints[0])
    torch.testing.assert_close(arm.jacobian(joints[0]), rows, atol=1e-9, rtol=0)
    assert arm.condition_dim == 3 and arm.target_features(arm.end_effector(joints)).shape == (3, 3)


def test_random_poses_fill_the_limits_and_normalize_clamps_to_them(panda):
    limits = panda.joint_limits
    drawn = panda.random_poses(20000, generator=torch.Generator().manual_seed(3))
    assert drawn.dtype == torch.float32 and drawn.shape == (20000, 7)
    assert (drawn >= limits[:, 0]).all() and (drawn <= limits[:, 1]).all()
    width = limits[:, 1] - limits[:, 0]
    assert ((drawn.min(0).values - limits[:, 0]) < 0.01 * width).all()  # uniform: reaches both ends
    assert ((limits[:, 1] - drawn.max(0).values) < 0.01 * width).all()
    outside = torch.stack([limits[:, 0] - 0.5, limits[:, 1] + 0.5, limits.mean(1)])
    normalized = panda.normalize_joints(outside)
    torch.testing.assert_close(normalized, torch.stack([limits[:, 0], limits[:, 1], limits.mean(1)]))
    assert panda.limit_violations(outside).tolist() == [7, 7, 0]


def test_continuous_joints_wrap_instead_of_clamping():
    arm = mixed_arm()  # j1 revolute [-2, 2], j2 prismatic [-0.1, 0.2], j3 continuous
    normalized = arm.normalize_joints(torch.tensor([[3.0, 0.5, 3 * math.pi / 2], [-3.0, -0.5, -7.0]]))
    expected = torch.tensor([[2.0, 0.2, -math.pi / 2], [-2.0, -0.1, 2 * math.pi - 7.0]])
    torch.testing.assert_close(normalized, expected)
    assert arm.joint_limits[2].tolist() == pytest.approx([-math.pi, math.pi])


def test_a_locked_continuous_joint_is_held_at_its_wrapped_angle_and_a_limited_one_within_limits():
    import ikdp

    arm = mixed_arm()  # j1 revolute [-2, 2], j2 prismatic [-0.1, 0.2], j3 continuous
    bound = ikdp.LockedJoints({2: 7.0}).bind(arm, 1, 2)
    torch.testing.assert_close(bound.values[:, 2], torch.full((2,), 7.0 - 2 * math.pi))  # as normalize_joints holds it
    with pytest.raises(ValueError, match="outside its limits"):
        ikdp.LockedJoints({0: 3.0}).bind(arm, 1, 1)


def test_quaternions_are_w_first_unit_and_match_the_rotation():
    arm = mixed_arm()
    # Zero pose of a single-yaw robot: the hand's quaternion is (cos(a/2), 0, 0, sin(a/2)).
    yaw = spatial_arm(1, target="pose")
    pose = yaw.end_effector(torch.tensor([0.8, 0.0]))
    torch.testing.assert_close(
        pose, torch.tensor([math.cos(0.8), math.sin(0.8), 0.0, math.cos(0.4), 0, 0, math.sin(0.4)])
    )
    joints = poses(arm, 100)
    quaternions = arm.end_effector_pose(joints)[:, 3:]
    torch.testing.assert_close(quaternions.norm(dim=-1), torch.ones(100, dtype=torch.float64))
    assert (quaternions[:, 0] >= 0).all()
    torch.testing.assert_close(quaternion_to_matrix(quaternions), arm.end_effector_frame(joints)[0])


def test_matrix_to_quaternion_is_accurate_near_half_turns():
    angles = torch.tensor([0.0, 1e-7, 1.0, math.pi - 1e-6, math.pi], dtype=torch.float64)
    axis = torch.tensor([0.6, -0.48, 0.64], dtype=torch.float64)
    quaternions = torch.cat([torch.cos(angles / 2)[:, None], torch.sin(angles / 2)[:, None] * axis], dim=-1)
    round_trip = matrix_to_quaternion(quaternion_to_matrix(quaternions))
    torch.testing.assert_close(round_trip, quaternions, atol=1e-9, rtol=0)
    rpy = torch.tensor([0.3, -1.1, 2.5], dtype=torch.float64)
    x, y, z = (torch.tensor(row, dtype=torch.float64) for row in ([1, 0, 0], [0, 1, 0], [0, 0, 1]))

    def about(axis, angle):
        return quaternion_to_matrix(torch.cat([torch.cos(angle / 2)[None], torch.sin(angle / 2) * axis]))

    torch.testing.assert_close(rpy_to_matrix(rpy), about(z, rpy[2]) @ about(y, rpy[1]) @ about(x, rpy[0]))


def test_errors_in_metres_and_radians(panda):
    joints = poses(panda, 8, seed=4)
    targets = panda.end_effector_pose(joints)
    assert panda.position_error(joints, targets).abs().max() < 1e-7
    shifted = targets.clone()
    shifted[:, 2] += 0.03
    torch.testing.assert_close(panda.position_error(joints, shifted), torch.full((8,), 0.03), atol=1e-6, rtol=0)
    torch.testing.assert_close(panda.tip_error(joints, shifted), panda.position_error(joints, shifted))
    # Rotate every target by 0.7 rad about a fixed axis (on the left: a base-frame rotation).
    turn = torch.tensor([math.cos(0.35), 0.0, math.sin(0.35), 0.0], dtype=torch.float64)
    from ikdp.rotations import quaternion_multiply

    turned = torch.cat([targets[:, :3], quaternion_multiply(turn, targets[:, 3:])], dim=-1)
    torch.testing.assert_close(panda.rotation_error(joints, turned), torch.full((8,), 0.7), atol=1e-6, rtol=0)
    axis_angle = panda.task_error(joints, turned)[:, 3:]
    torch.testing.assert_close(axis_angle, torch.tensor([[0.0, 0.7, 0.0]] * 8, dtype=torch.float64))


def test_target_features_are_position_over_span_and_two_rotation_columns(panda):
    targets = panda.end_effector_pose(poses(panda, 5))
    features = panda.target_features(targets)
    assert features.shape == (5, panda.condition_dim) == (5, 9)
    torch.testing.assert_close(features[:, :3], targets[:, :3] / panda.span)
    rotation = quaternion_to_matrix(targets[:, 3:])
    torch.testing.assert_close(features[:, 3:6], rotation[:, :, 0])
    torch.testing.assert_close(features[:, 6:9], rotation[:, :, 1])


def test_validate_targets_shapes_and_unit_quaternions(panda):
    good = panda.validate_targets([[0.3, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0], [0.3, 0.1, 0.5, 0.0, 0.0, 0.0, 1.0002]])
    assert good.dtype == torch.float32 and good.shape == (2, 7)
    assert good[1, 3:].norm() == pytest.approx(1.0, abs=1e-6)  # renormalised within the tolerance
    with pytest.raises(ValueError, match="row 1 has quaternion"):
        panda.validate_targets([[0.3, 0, 0.5, 1, 0, 0, 0], [0.3, 0, 0.5, 0, 0, 0, 0.5]])
    with pytest.raises(ValueError, match=r"expected shape \(B, 7\)"):
        panda.validate_targets([[0.3, 0.0, 0.5]])
    with pytest.raises(ValueError, match=r"wrap one target"):
        panda.validate_targets([0.3, 0.0, 0.5, 1, 0, 0, 0])
    position_arm = load_robot("panda", target="position")
    assert position_arm.validate_targets([[0.3, 0.0, 0.5]]).shape == (1, 3)
    with pytest.raises(ValueError, match="target"):
        load_robot("panda", target="orientation")


def test_reach_ball_is_conservative_and_clamping_pulls_onto_it(panda):
    targets = panda.end_effector_pose(poses(panda, 2000, seed=5)).float()
    assert panda.is_reachable(targets).all()  # every pose the arm takes is inside the ball
    far = targets[:2].clone()
    far[:, :3] = panda.reach_center + torch.tensor([[3.0, 0.0, 0.0], [0.0, -2.0, 0.0]])
    assert not panda.is_reachable(far).any()
    clamped = panda.clamp_to_workspace(far)
    distance = (clamped[:, :3] - panda.reach_center).norm(dim=-1)
    torch.testing.assert_close(distance, torch.full((2,), panda.reach[1]))
    torch.testing.assert_close(clamped[:, 3:], far[:, 3:])
    torch.testing.assert_close(panda.clamp_to_workspace(targets), targets)


def test_config_round_trip_without_the_urdf(panda):
    config = panda.to_config()
    config["urdf_path"] = "/nowhere/panda.urdf"  # the file is not needed to rebuild
    buffer = io.BytesIO()
    torch.save({"arm": config}, buffer)
    buffer.seek(0)
    loaded = torch.load(buffer, weights_only=True)["arm"]
    rebuilt = arm_from_config(loaded)
    assert isinstance(rebuilt, ChainArm) and rebuilt.description is None
    assert rebuilt.joint_names == panda.joint_names and rebuilt.ee_link == "panda_hand"
    assert rebuilt.recorded_urdf_path == "/nowhere/panda.urdf" and rebuilt.target == "pose"
    assert rebuilt.urdf_path is None  # never a path that is not on this machine
    joints = poses(panda, 16)
    torch.testing.assert_close(rebuilt.end_effector(joints), panda.end_effector(joints), atol=0, rtol=0)
    torch.testing.assert_close(rebuilt.link_poses(joints), panda.link_poses(joints), atol=0, rtol=0)
    assert rebuilt.to_config() == config
    assert rebuilt.chain_description() is None  # no file to read meshes from
    with pytest.raises(ValueError, match="kind"):
        ChainArm.from_config({**config, "kind": "planar"})
    with_file = ChainArm.from_config(panda.to_config())
    assert [link.name for link in with_file.chain_description().links] == panda.link_names


def test_a_checkpoints_urdf_path_from_another_machine_finds_the_installed_copy(panda):
    # A shipped checkpoint records the absolute path of the venv it was trained in; here that venv is gone.
    elsewhere = "/home/someone/venv/lib/python3.11/site-packages/cmeel.prefix/share/example-robot-data/robots/"
    moved = ChainArm.from_config({**panda.to_config(), "urdf_path": elsewhere + ROBOTS["panda"].urdf})
    assert [link.name for link in moved.chain_description().links] == panda.link_names
    assert moved.urdf_path == panda.urdf_path and Path(moved.urdf_path).is_file()  # this machine's copy
    assert moved.recorded_urdf_path.startswith("/home/someone/")  # what it was trained on, kept for the record
    assert moved.to_config()["urdf_path"] == moved.recorded_urdf_path  # a re-saved checkpoint records it unchanged
    missing = ChainArm.from_config({**panda.to_config(), "urdf_path": elsewhere + "no_robot/urdf/none.urdf"})
    assert missing.chain_description() is None and missing.urdf_path is None


def test_a_recorded_urdf_copy_that_exists_here_yields_to_the_installed_one(panda, tmp_path):
    # ikdp_panda.pt was trained on a GPU machine from a bare copy of the URDF: on the machine that copy came
    # from it exists, without meshes beside it, and the 3-D view drew no robot (CI caught it)
    bare = tmp_path / "example-robot-data/robots" / ROBOTS["panda"].urdf
    bare.parent.mkdir(parents=True)
    bare.write_text(Path(panda.urdf_path).read_text())
    arm = ChainArm.from_config({**panda.to_config(), "urdf_path": str(bare)})
    assert arm.urdf_path == panda.urdf_path != str(bare)  # example-robot-data's own file, meshes and all
    assert arm.recorded_urdf_path == str(bare)


@pytest.mark.parametrize("name", ["ikdp_panda", "ikdp_panda_fast"])  # one trained on a GPU machine, from a copy
def test_the_shipped_panda_model_names_this_machines_urdf(name):
    import ikdp

    arm = ikdp.load(name).arm
    assert Path(arm.urdf_path).is_file() and arm.urdf_path.endswith("panda_description/urdf/panda.urdf")
    assert [link.name for link in arm.chain_description().links][:2] == ["panda_link0", "panda_link1"]


def test_robot_names_load(panda):
    assert {"panda", "ur5"} <= set(robot_names())
    assert panda.urdf_path.endswith("panda.urdf") and panda.joint_names[0] == "panda_joint1"
    ur5 = load_robot("ur5")
    assert ur5.num_joints == 6 and ur5.ee_link == "tool0"
    z1 = load_robot("z1")
    assert z1.num_joints == 6 and z1.ee_link == "gripperStator" and z1.base_link == "world"
    assert load_robot("spatial3").num_joints == 6
    with pytest.raises(ValueError, match="unknown robot"):
        load_robot("pr2")


@pytest.mark.parametrize("name", ["panda", "mixed", "spatial"])
def test_damped_least_squares_converges_from_a_nearby_start(name, panda):
    arm = {"panda": panda, "mixed": mixed_arm(), "spatial": spatial_arm(3)}[name]
    generator = torch.Generator().manual_seed(6)
    limits = arm.joint_limits.double()
    middle, half = limits.mean(1), (limits[:, 1] - limits[:, 0]) / 2
    solutions = middle + 0.6 * half * (2 * torch.rand(16, arm.num_joints, generator=generator, dtype=torch.float64) - 1)
    targets = arm.end_effector(solutions)  # (B, 7) poses, or (B, 3) positions for the spatial arm
    rows = 6 if arm.target == "pose" else 3
    joints = arm.normalize_joints(
        solutions + 0.15 * torch.randn(solutions.shape, generator=generator, dtype=torch.float64)
    )
    damping = 1e-3
    for _ in range(30):
        jacobian = arm.jacobian(joints)  # (B, rows, J)
        error = arm.task_error(joints, targets)  # (B, rows)
        system = jacobian @ jacobian.transpose(-1, -2) + damping**2 * torch.eye(rows, dtype=torch.float64)
        step = jacobian.transpose(-1, -2) @ torch.linalg.solve(system, error.unsqueeze(-1))
        joints = arm.normalize_joints(joints + step.squeeze(-1))
    assert arm.position_error(joints, targets).max() < 1e-6
    if arm.target == "pose":
        assert arm.rotation_error(joints, targets).max() < 1e-6
    assert arm.limit_violations(joints).sum() == 0


def test_chain_arm_offers_everything_planar_arm_does(panda):
    from ikdp.arm import PlanarArm

    planar_only = {"lengths", "lengths_like"}  # bone lengths are the planar arm's own description
    shared = {name for name in dir(PlanarArm) if not name.startswith("_")} - planar_only
    assert shared <= {name for name in dir(panda) if not name.startswith("_")}
    assert panda.kind == "chain" and panda.target_dim == 7 and panda.position_dim == 3


def test_blocked_by_limits_marks_only_limited_joints_pushed_outward(panda):
    limits = panda.joint_limits.double()
    joints = limits.mean(1).repeat(3, 1)
    joints[0, 3], joints[1, 5] = limits[3, 1], limits[5, 0]  # the elbow on its upper limit, the wrist on its lower
    step = torch.full_like(joints, 0.1)
    step[1] = -0.1
    blocked = panda.blocked_by_limits(joints, step)
    assert blocked.nonzero().tolist() == [[0, 3], [1, 5]]  # pushed out; the same joints pushed back in are free
    assert not panda.blocked_by_limits(joints, -step).any()
    wrapping = spatial_arm(3)  # continuous joints wrap: nothing holds them
    assert not wrapping.blocked_by_limits(torch.full((1, 6), math.pi, dtype=torch.float64), torch.ones(1, 6)).any()


def test_refinement_moves_the_free_joints_when_one_is_held_by_its_limit(panda):
    """Targets reached with two joints on their limits, starts nearby: the clamped step alone stalls more poses."""
    generator = torch.Generator().manual_seed(6)
    limits = panda.joint_limits.double()
    solutions = panda.random_poses(64, generator=generator).double()
    solutions[:, 3], solutions[:, 5] = limits[3, 1], limits[5, 0]
    targets = panda.end_effector(solutions)
    starts = panda.normalize_joints(solutions + 0.1 * torch.randn(solutions.shape, generator=generator).double())

    def clamped_only(joints, steps):  # the refinement before the active set: step, then clamp
        for _ in range(steps):
            error = clamp_task_error(panda.task_error(joints, targets), 3, 0.2 * panda.span, math.pi / 4)
            joints = panda.normalize_joints(joints + dls_step(panda.jacobian(joints), error, 1e-6))
        return joints

    one_step = damped_least_squares(panda, starts, targets, steps=1)
    miss = lambda joints: panda.task_error(joints, targets).norm(dim=-1)  # noqa: E731
    assert (miss(one_step) <= miss(clamped_only(starts, 1)) + 1e-12).all()  # per pose, never worse than clamping
    refined, clamped = damped_least_squares(panda, starts, targets, steps=8), clamped_only(starts, 8)
    reached = lambda joints: (panda.position_error(joints, targets) < 1e-6).double().mean()  # noqa: E731
    assert reached(refined) > reached(clamped) + 0.15  # 0.52 against 0.20 when written
    assert panda.limit_violations(refined).sum() == 0


def test_a_few_targets_reach_checks_are_a_batchs():
    """A few CPU targets are read through NumPy (one target's solve), a batch through torch: the same answers."""
    arm = load_robot("panda")
    targets = arm.end_effector(arm.random_poses(40, generator=torch.Generator().manual_seed(6)))
    targets[::3, :3] = arm.reach_center + 3 * (targets[::3, :3] - arm.reach_center)  # out of reach: pulled in
    targets[1, :3] = arm.reach_center  # at the centre: no direction to pull in
    few = targets[:10]
    assert bool((~arm.is_reachable(targets)).any()) and bool(arm.is_reachable(targets).any())
    assert torch.equal(arm.is_reachable(few), arm.is_reachable(targets)[:10])
    torch.testing.assert_close(arm.clamp_to_workspace(few), arm.clamp_to_workspace(targets)[:10])
