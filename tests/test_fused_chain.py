"""FusedChain (ikdp/fused_chain.py): a chain's kinematics, Jacobian, errors and refinement as a few fused
operations give ChainArm's numbers, and a solve through them the general path's answers."""

import dataclasses

import pytest
import torch

import ikdp
import ikdp.denoisers.chain_film
import ikdp.fused_chain
from ikdp.arm import PlanarArm
from ikdp.chain_arm import ChainArm
from ikdp.fused_chain import FusedChain
from ikdp.refine import damped_least_squares
from ikdp.robots import load_robot, spatial_arm
from ikdp.urdf import parse_chain

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


def arm_named(name: str) -> ChainArm:
    if name == "mixed":  # revolute, prismatic and continuous joints, axes off the coordinate axes
        return ChainArm.from_description(parse_chain(MIXED_URDF, "tool"))
    if name == "position":
        return spatial_arm(3)
    return load_robot(name)


ARMS = ["panda", "z1", "mixed", "position"]


def joints_and_targets(arm, count: int, dtype: torch.dtype, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    joints = arm.random_poses(count, generator=generator).to(dtype)
    targets = arm.end_effector(arm.random_poses(count, generator=generator).double()).to(dtype)
    return joints, targets


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("dtype, tolerance", [(torch.float64, 1e-9), (torch.float32, 1e-5)])
def test_the_fused_kinematics_jacobian_and_errors_are_the_chains(name, dtype, tolerance):
    arm = arm_named(name)
    fused = arm.small_batch_kinematics()
    assert isinstance(fused, FusedChain) and fused is arm.small_batch_kinematics()  # built once
    joints, targets = joints_and_targets(arm, 48, dtype)
    joints, targets = joints.reshape(4, 12, -1), targets.reshape(4, 12, -1)  # any batch shape
    close = lambda a, b: torch.testing.assert_close(a, b, atol=tolerance, rtol=0)  # noqa: E731
    for ours, theirs in zip(fused.end_effector_frame(joints), arm.end_effector_frame(joints), strict=True):
        close(ours, theirs)
    close(fused.jacobian(joints), arm.jacobian(joints))
    close(fused.task_error(joints, targets), arm.task_error(joints, targets))
    error, jacobian = fused.task_error_and_jacobian(joints, targets)
    close(error, arm.task_error(joints, targets))
    close(jacobian, arm.jacobian(joints))
    position, rotation = fused.tip_and_rotation_errors(joints, targets)
    reference_position, reference_rotation = arm.tip_and_rotation_errors(joints, targets)
    close(position, reference_position)
    if rotation is None:
        assert reference_rotation is None
    else:
        close(rotation, reference_rotation)
    # one target broadcast over several poses, as tracking asks
    close(fused.tip_error(joints[0], targets[0, :1]), arm.tip_error(joints[0], targets[0, :1]))


def test_near_half_turns_the_rotation_error_is_the_chains():
    """Shepperd's choice of formula as a linear map: right where the relative rotation's w nears zero. At a half
    turn exactly, +pi and -pi about the axis are the same rotation: either is the log map."""
    from ikdp.rotations import matrix_to_quaternion, quaternion_to_matrix

    arm = load_robot("panda")
    fused = arm.small_batch_kinematics()
    joints = arm.random_poses(64, generator=torch.Generator().manual_seed(4)).double()
    rotation, position = arm.end_effector_frame(joints)
    for angle in (torch.pi - 1e-4, torch.pi - 1e-7, torch.pi):
        half = torch.tensor([torch.cos(torch.tensor(angle / 2)), 0.6, 0.0, 0.8], dtype=torch.float64)
        half[1:] *= torch.sin(torch.tensor(angle / 2, dtype=torch.float64))
        targets = torch.cat([position, matrix_to_quaternion(quaternion_to_matrix(half) @ rotation)], dim=-1)
        ours, theirs = fused.task_error(joints, targets), arm.task_error(joints, targets)
        if angle < torch.pi:
            torch.testing.assert_close(ours, theirs, atol=1e-6, rtol=0)
        else:
            torch.testing.assert_close(ours[:, 3:].norm(dim=-1), theirs[:, 3:].norm(dim=-1), atol=1e-9, rtol=0)
            sign = torch.where((ours[:, 3:] * theirs[:, 3:]).sum(-1, keepdim=True) < 0, -1.0, 1.0)
            torch.testing.assert_close(ours[:, 3:] * sign, theirs[:, 3:], atol=1e-6, rtol=0)
        torch.testing.assert_close(
            fused.tip_and_rotation_errors(joints, targets)[1], arm.tip_and_rotation_errors(joints, targets)[1]
        )


@pytest.mark.parametrize("name", ARMS)
def test_the_fused_refinement_is_damped_least_squares(name):
    arm = arm_named(name)
    joints, targets = joints_and_targets(arm, 32, torch.float64, seed=1)
    # half the starts on a limit, where a step that pushes further out takes the active-set candidate too
    limits = arm.joint_limits.to(joints)
    joints[::2, 0] = limits[0, 1]
    joints, targets = joints.reshape(2, 16, -1), targets.reshape(2, 16, -1)
    # each step solves with the damped inverse, whose gain up to 1 / damping^2 = 1e6 carries rounding differences
    # of 1e-16 from one step to the next: 1e-9 after a step, 1e-9 x 1e3 allowed after five from far starts
    for steps, tolerance in ((1, 1e-9), (5, 1e-6)):
        ours = arm.small_batch_kinematics().refine(joints, targets, steps=steps)
        theirs = damped_least_squares(arm, joints, targets, steps=steps)
        torch.testing.assert_close(ours, theirs, atol=tolerance, rtol=0)
    assert arm.small_batch_kinematics().refine(joints.float(), targets.float(), steps=0).dtype == torch.float32


def test_a_planar_arm_is_its_own_small_batch_kinematics():
    arm = PlanarArm([1.0, 1.0, 1.0])
    assert arm.small_batch_kinematics() is arm
    headings = arm.random_poses(8, generator=torch.Generator().manual_seed(0))
    targets = arm.end_effector(arm.random_poses(8, generator=torch.Generator().manual_seed(1)))
    assert torch.equal(arm.refine(headings, targets, steps=3), damped_least_squares(arm, headings, targets, steps=3))


def solve_both_ways(solver, targets, monkeypatch, **options):
    """solver.solve one target a call, through the fused path and with it off (FUSED_ROWS = 0), the same seeds.

    The network's kinematic features come from the arm's own kinematics both times: the fused ones differ from
    them by float rounding, which the features' damped inverse carries into the raw poses
    (`test_the_denoisers_features_from_the_fused_kinematics_are_the_arms_own`); here the refinement is compared.
    """
    monkeypatch.setattr(ikdp.denoisers.chain_film, "small_batch", lambda rows, device: False)
    answers = []
    for rows in (ikdp.fused_chain.FUSED_ROWS, 0):
        monkeypatch.setattr(ikdp.fused_chain, "FUSED_ROWS", rows)
        answers.append(
            [
                solver.solve(target[None], generator=torch.Generator().manual_seed(index), **options)
                for index, target in enumerate(targets)
            ]
        )
    return answers


def test_a_one_target_solve_gives_the_general_paths_answers(tiny_chain_checkpoint, monkeypatch):
    solver = ikdp.load(tiny_chain_checkpoint)
    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(4, generator=torch.Generator().manual_seed(2)))
    options = {"num_samples": 8, "sampler": "ddim", "steps": 2, "refine_steps": 4, "restart_steps": 3}
    fused, general = solve_both_ways(solver, targets, monkeypatch, **options)
    for ours, theirs in zip(fused, general, strict=True):
        assert torch.equal(ours.raw_angles, theirs.raw_angles)  # the same network input: the refinement compared
        torch.testing.assert_close(ours.angles, theirs.angles, atol=1e-5, rtol=0)
        torch.testing.assert_close(ours.tip_error, theirs.tip_error, atol=1e-6, rtol=0)
        torch.testing.assert_close(ours.rotation_error, theirs.rotation_error, atol=1e-6, rtol=0)
        assert torch.equal(ours.restarted, theirs.restarted)


@pytest.mark.slow
def test_the_shipped_fast_pipeline_gives_the_same_answers_one_target_a_call(monkeypatch):
    from benchmarks.one_target_latency import MODELS, PANDA_FAST

    solver = ikdp.load(PANDA_FAST)
    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(40, generator=torch.Generator().manual_seed(0)))
    fused, general = solve_both_ways(solver, targets, monkeypatch, num_samples=16, **MODELS[PANDA_FAST])
    for ours, theirs in zip(fused, general, strict=True):
        torch.testing.assert_close(ours.angles, theirs.angles, atol=1e-5, rtol=0)
        valid = lambda out: (out.tip_error < 1e-3) & (out.rotation_error < arm.rotation_tolerance)  # noqa: E731
        assert torch.equal(valid(ours), valid(theirs)) and valid(ours).any()


@pytest.mark.parametrize("limit_aware_step", [True, False])
def test_the_denoisers_features_from_the_fused_kinematics_are_the_arms_own(
    tiny_chain_checkpoint, monkeypatch, limit_aware_step
):
    denoiser = ikdp.load(tiny_chain_checkpoint).model.denoiser
    # without the limit-aware step the features need no Jacobian: the error and the step come from NumPy's kernels
    denoiser.config = dataclasses.replace(denoiser.config, limit_aware_step=limit_aware_step)
    arm = denoiser.arm
    x = torch.randn(16, denoiser.representation.dim, generator=torch.Generator().manual_seed(3))
    targets = arm.end_effector(arm.random_poses(16, generator=torch.Generator().manual_seed(4)))
    calls = []
    fused = arm.small_batch_kinematics()
    for name in ("task_error_and_jacobian", "task_error_and_dls_step"):
        monkeypatch.setattr(type(fused), name, counted(calls, getattr(type(fused), name)))
    with torch.no_grad():  # a few rows without gradients: the fused kinematics
        ours = denoiser.features_and_step(x, targets)
    assert len(calls) == 1
    theirs = denoiser.features_and_step(x, targets)  # with gradients (training): the arm's own
    assert len(calls) == 1
    for mine, reference in zip(ours, theirs, strict=True):
        # float32 rounding; the DLS step's damped inverse multiplies it by up to 1 / damping^2
        torch.testing.assert_close(mine, reference.detach(), atol=1e-4, rtol=1e-4)


def counted(calls: list, method):
    def wrapper(*args, **kwargs):
        calls.append(1)
        return method(*args, **kwargs)

    return wrapper


def test_large_or_gpu_batches_keep_the_arms_own_kinematics():
    from ikdp.fused_chain import small_batch

    assert small_batch(16, torch.device("cpu")) and small_batch(ikdp.fused_chain.FUSED_ROWS, "cpu")
    assert not small_batch(ikdp.fused_chain.FUSED_ROWS + 1, "cpu")
    assert not small_batch(16, torch.device("cuda"))
