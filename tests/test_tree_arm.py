"""TreeArm: several end effectors on one base (the G1's two hands on its waist), its kinematics against
pytorch_kinematics and autograd, solve's shapes and errors, the command line, and bad input."""

import math

import pytest
import torch
from tree_helpers import TWO_ARMS_URDF, two_arms, untrained_solver

import ikdp
from ikdp.chain_arm import ChainArm
from ikdp.denoisers.int8 import int8_available
from ikdp.describe import training_command
from ikdp.refine import damped_least_squares
from ikdp.robot_data import example_robot_data_file
from ikdp.train import TrainConfig, build_chain_arm, main
from ikdp.tree_arm import TreeArm

G1_URDF = "g1_description/urdf/g1_29dof_rev_1_0.urdf"
G1_HANDS = ["left_rubber_hand", "right_rubber_hand"]


@pytest.fixture(scope="module")
def g1() -> TreeArm:
    return TreeArm.from_urdf(example_robot_data_file(G1_URDF), G1_HANDS, base_link="pelvis")


def poses(arm, count: int, seed: int = 0) -> torch.Tensor:
    return arm.random_poses(count, generator=torch.Generator().manual_seed(seed)).double()


def test_the_g1_hands_share_the_waist_once(g1):
    assert g1.ee_links == G1_HANDS
    assert g1.num_joints == 17
    assert g1.joint_names[:3] == ["waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint"]
    assert [name.split("_")[0] for name in g1.joint_names[3:]] == ["left"] * 7 + ["right"] * 7
    assert TreeArm.from_config(g1.to_config()) == g1


def test_g1_forward_kinematics_matches_pytorch_kinematics(g1, monkeypatch):
    pk = pytest.importorskip("pytorch_kinematics")
    import pytorch_kinematics.transforms as pk_transforms

    def origin_in_float64(origin):  # pytorch_kinematics reads each origin's rpy in float32: 3e-8 m off at the hand
        if origin is None:
            return pk_transforms.Transform3d(dtype=torch.float64)
        rpy = torch.tensor(origin.rpy, dtype=torch.float64)
        rotation = pk_transforms.quaternion_from_euler(rpy, "sxyz")
        return pk_transforms.Transform3d(rot=rotation, pos=origin.xyz, dtype=torch.float64)

    monkeypatch.setattr(pk.urdf, "_convert_transform", origin_in_float64)
    build_chain = pk.chain.Chain.__init__

    def chain_in_float64(self, root_frame, dtype=None, device="cpu"):  # its offsets are multiplied at construction
        build_chain(self, root_frame, dtype=torch.float64, device=device)

    monkeypatch.setattr(pk.chain.Chain, "__init__", chain_in_float64)
    text = example_robot_data_file(G1_URDF).read_bytes()
    joints = poses(g1, 128)
    rotation, position = g1.end_effector_frame(joints)  # (B, E, 3, 3), (B, E, 3)
    for effector, hand in enumerate(G1_HANDS):
        chain = pk.build_serial_chain_from_urdf(text, hand, "pelvis").to(dtype=torch.float64)
        order = [g1.joint_names.index(name) for name in chain.get_joint_parameter_names()]
        reference = chain.forward_kinematics(joints[:, order]).get_matrix()
        torch.testing.assert_close(position[:, effector], reference[:, :3, 3], atol=1e-9, rtol=0)
        torch.testing.assert_close(rotation[:, effector], reference[:, :3, :3], atol=1e-9, rtol=0)


def test_g1_forward_kinematics_matches_pinocchio(g1):
    """Pinocchio, a trusted reference (benchmarks/requirements-bench.txt), on the URDF with every joint off the
    tree held at zero: both hands' placements agree to 1e-9."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(example_robot_data_file(G1_URDF)))
    data = model.createData()
    slots = [model.joints[model.getJointId(name)].idx_q for name in g1.joint_names]
    frames = [model.getFrameId(hand) for hand in G1_HANDS]
    joints = poses(g1, 64, seed=4)
    rotation, position = g1.end_effector_frame(joints)  # (B, E, 3, 3), (B, E, 3)
    for row in range(len(joints)):
        q = pin.neutral(model)
        q[slots] = joints[row].numpy()
        pin.framesForwardKinematics(model, data, q)
        for effector, frame in enumerate(frames):
            placement = data.oMf[frame]
            torch.testing.assert_close(
                position[row, effector], torch.from_numpy(placement.translation), atol=1e-9, rtol=0
            )
            torch.testing.assert_close(rotation[row, effector], torch.from_numpy(placement.rotation), atol=1e-9, rtol=0)


@pytest.mark.parametrize("target", ["pose", "position"])
def test_the_stacked_jacobian_matches_autograd(g1, target):
    """Position rows: d position / d q; rotation rows: the angular velocity, vee(dR/dq R^T); every position's
    rows first, then every rotation's."""
    arm = g1 if target == "pose" else TreeArm(g1.chains, target="position")
    joints = poses(arm, 3, seed=1)
    jacobian = arm.jacobian(joints)  # (B, 6E or 3E, J)
    assert jacobian.shape == (3, 12 if target == "pose" else 6, 17)
    for row in range(3):
        rotation, position = arm.end_effector_frame(joints[row])  # (E, 3, 3), (E, 3)
        linear = torch.autograd.functional.jacobian(lambda q: arm.end_effector_frame(q)[1], joints[row])  # (E, 3, J)
        torch.testing.assert_close(jacobian[row, :6], linear.reshape(6, 17), atol=1e-10, rtol=0)
        if target == "pose":
            turning = torch.autograd.functional.jacobian(lambda q: arm.end_effector_frame(q)[0], joints[row])
            spin = torch.einsum("eabj,ecb->ejac", turning, rotation)  # dR/dq_j R^T, skew: (E, J, 3, 3)
            angular = torch.stack([spin[..., 2, 1], spin[..., 0, 2], spin[..., 1, 0]], dim=-2)  # (E, 3, J)
            torch.testing.assert_close(jacobian[row, 6:], angular.reshape(6, 17), atol=1e-10, rtol=0)
    # each hand's rows leave the other arm's joints out: a hand moves with its own chain only
    assert jacobian[:, 0:3, 10:].abs().max() == 0 and jacobian[:, 3:6, 3:10].abs().max() == 0


def test_refinement_reaches_both_hands_from_nearby(g1):
    joints = poses(g1, 64, seed=2)
    targets = g1.end_effector(joints)
    start = g1.normalize_joints(joints + 0.1 * torch.randn(joints.shape, generator=torch.Generator().manual_seed(3)))
    refined = damped_least_squares(g1, start, targets, steps=20)
    position, rotation = g1.errors_by_effector(refined, targets)  # (B, E) each
    assert position.shape == (64, 2) and rotation.shape == (64, 2)
    reached = (position < 1e-3).all(-1) & (rotation < math.radians(1)).all(-1)
    assert reached.float().mean() > 0.9
    assert int(g1.limit_violations(refined).sum()) == 0


def test_solve_gives_each_end_effectors_errors_and_the_worst(tmp_path):
    arm = two_arms()
    solver = untrained_solver(arm)
    joints = poses(arm, 5).float()
    targets = arm.stacked_targets(arm.end_effector(joints))  # (B, E, 7)
    assert targets.shape == (5, 2, 7)
    torch.testing.assert_close(arm.validate_targets(targets), arm.end_effector(joints), atol=1e-6, rtol=0)
    out = solver.solve(targets, num_samples=3, sampler="ddim", steps=4, refine_steps=30)
    assert out.angles.shape == (5, 3, 6) and out.raw_angles.shape == (5, 3, 6)
    assert out.tip_error.shape == (5, 3) and out.rotation_error.shape == (5, 3)
    assert out.tip_error_by_effector.shape == (5, 3, 2) and out.rotation_error_by_effector.shape == (5, 3, 2)
    torch.testing.assert_close(out.tip_error, out.tip_error_by_effector.amax(-1))
    torch.testing.assert_close(out.rotation_error, out.rotation_error_by_effector.amax(-1))
    for effector, chain in enumerate(arm.chains):  # each hand's error is its own chain's
        own = out.angles[..., [arm.joint_names.index(name) for name in chain.joint_names]]
        position, rotation = chain.tip_and_rotation_errors(own, targets[:, None, effector])
        torch.testing.assert_close(out.tip_error_by_effector[..., effector], position)
        torch.testing.assert_close(out.rotation_error_by_effector[..., effector], rotation)
    # four joints for six pose constraints per hand: not every target is reachable, but the refinement gets
    # each target's best sample within the arms' rounding of its own pose
    assert float(out.tip_error.amin(1).median()) < 1e-3


def test_a_single_end_effector_keeps_the_chain(tmp_path):
    config = TrainConfig(urdf=str(tmp_path / "two.urdf"), ee_link=("left_hand",))
    (tmp_path / "two.urdf").write_text(TWO_ARMS_URDF)
    arm = build_chain_arm(config)
    assert isinstance(arm, ChainArm) and arm.ee_links == ["left_hand"]


def test_ee_link_twice_on_the_command_line_trains_a_two_hand_model(tmp_path):
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_ARMS_URDF)
    output = tmp_path / "two.pt"
    main(
        [
            *("--urdf", str(urdf), "--ee-link", "left_hand", "--ee-link", "right_hand", "--target", "position"),
            *("--steps", "3", "--batch", "16", "--hidden", "24", "--blocks", "1", "--timesteps", "8"),
            *("--eval-targets", "4", "--threads", "1", "--output", str(output), "--log-dir", str(tmp_path / "tb")),
        ]
    )
    solver = ikdp.load(output)
    assert solver.arm.kind == "tree" and solver.arm.ee_links == ["left_hand", "right_hand"]
    assert solver.arm.joint_names == [
        "waist",
        "left_shoulder",
        "left_elbow",
        "left_wrist",
        "right_shoulder",
        "right_elbow",
    ]
    out = solver.solve(torch.tensor([[[0.2, 0.3, 0.5], [0.2, -0.3, 0.5]]]), num_samples=2, steps=2, sampler="ddim")
    assert out.angles.shape == (1, 2, 6) and out.tip_error_by_effector.shape == (1, 2, 2)
    assert out.rotation_error is None
    assert "--ee-link left_hand --ee-link right_hand" in training_command(solver.metadata["train"])
    if not int8_available():  # the int8 weights' kernel where this torch has one
        quantized = ikdp.load(output, precision="int8").solve(
            out.angles.new_tensor([[[0.2, 0.3, 0.5], [0.2, -0.3, 0.5]]])
        )
        assert quantized.tip_error_by_effector.shape == (1, 16, 2)


@pytest.mark.parametrize(
    ("hands", "message"),
    [
        (["left_hand", "nope"], "ee_link: no link 'nope'"),
        (["left_hand", "l1"], "ee_links: 'l1' is an ancestor of 'left_hand'"),
        (["left_hand", "left_hand"], "ee_links: each end effector once"),
        (["left_hand"], "ee_links: a tree has two or more end effectors"),
    ],
)
def test_bad_end_effectors_are_refused_naming_them(tmp_path, hands, message):
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_ARMS_URDF)
    with pytest.raises(ValueError, match=message):
        TreeArm.from_urdf(urdf, hands)


@pytest.mark.parametrize(
    ("targets", "message"),
    [
        (torch.zeros(3, 7), r"targets: expected shape \(B, 2, 7\)"),
        (torch.zeros(3, 2, 3), r"targets: expected shape \(B, 2, 7\)"),
        (torch.zeros(3, 3, 7), r"targets: expected shape \(B, 2, 7\)"),
        (torch.tensor([[[0, 0, 0, 1, 0, 0, 0], [0, 0, 0, 0.5, 0, 0, 0]]]), "end effector 'right_hand' has quaternion"),
        (torch.full((1, 2, 7), math.nan), "NaN or inf"),
    ],
)
def test_bad_targets_are_refused_naming_them(targets, message):
    with pytest.raises(ValueError, match=message):
        two_arms().validate_targets(targets)


def test_locks_a_pose_to_stay_near_restarts_and_tracking_work_on_a_tree():
    arm = two_arms()
    solver = untrained_solver(arm)
    joints = poses(arm, 4, seed=5).float()
    targets = arm.stacked_targets(arm.end_effector(joints))
    locked = solver.solve(
        targets,
        num_samples=3,
        sampler="ddim",
        steps=2,
        refine_steps=10,
        constraints=[ikdp.LockedJoints({"waist": 0.25})],
    )
    assert bool((locked.angles[..., 0] == 0.25).all()) and float(locked.constraint_violation.max()) == 0
    near = solver.solve(
        targets[:1], num_samples=3, sampler="ddim", steps=2, refine_steps=10, constraints=[ikdp.NearPose(joints[0])]
    )
    assert float(near.tip_error.amin()) < 1e-4  # pulled to the pose that made the target, both hands on it
    restarted = solver.solve(targets, num_samples=3, sampler="ddim", steps=2, restart_steps=40)
    assert restarted.restarted.shape == (4,)
    assert bool(((restarted.tip_error.amin(1) < 1e-3) | ~restarted.restarted).all())
    path = arm.stacked_targets(arm.end_effector(joints[:1] + torch.linspace(0, 0.2, 4)[:, None]))  # (P, E, 7)
    tracked = solver.track(path, joints[0], num_samples=3)
    assert tracked.angles.shape == (4, 6) and bool(tracked.reached.all())


def test_the_pinocchio_clik_baseline_reaches_both_hands_from_nearby(g1):
    """The benchmark's Pinocchio row (benchmarks/pinocchio_clik.py) is a working solver: from 0.1 rad off, 20 steps
    put both hands within 1 mm and 1 degree, as IKDP's own DLS does (test_refinement_reaches_both_hands_...)."""
    pytest.importorskip("pinocchio")
    from benchmarks.pinocchio_clik import PinocchioTree

    reference = PinocchioTree(g1, example_robot_data_file(G1_URDF))
    joints = poses(g1, 16, seed=2)
    start = g1.normalize_joints(joints + 0.1 * torch.randn(joints.shape, generator=torch.Generator().manual_seed(3)))
    solved = torch.stack(
        [
            torch.from_numpy(reference.clik(start[row].numpy(), reference.forward(joints[row].numpy()), 20))
            for row in range(len(joints))
        ]
    )
    position, rotation = g1.tip_and_rotation_errors(solved, g1.end_effector(joints))
    assert float(((position < 1e-3) & (rotation < math.radians(1))).float().mean()) > 0.9
    assert int(g1.limit_violations(solved).sum()) == 0
