"""The compiled refinement loop and feature (ikdp/chain_refine_kernel.c) give the numbers of NumPy's loop
(ikdp/small_refine.py) to rounding, on every kind of chain, and without the kernel NumPy's loop runs."""

import os

import numpy as np
import pytest
import torch

import ikdp.compiled_chain
from ikdp.fused_chain import FusedChain
from tests.test_fused_chain import ARMS, arm_named, joints_and_targets


@pytest.fixture(scope="module")
def kernel():
    library = ikdp.compiled_chain.load_kernel()
    if library is None:
        if os.environ.get("CI"):  # CI installs a C compiler: there the fast path must build
            pytest.fail("the compiled chain kernel did not build (is a C compiler installed?)")
        pytest.skip("no C compiler here")
    return library


def both_loops(arm):
    """(compiled, NumPy's) SmallRefine of the arm, each its own."""
    compiled, numpy_loop = FusedChain(arm).small_refine(), FusedChain(arm).small_refine()
    numpy_loop._compiled = None
    assert compiled.compiled() is not None
    return compiled, numpy_loop


def starts_on_limits(arm, seed: int):
    """32 starts, half of them with the first joint on its upper limit (a step there may be blocked), and 2 targets
    of 16 rows each."""
    joints, targets = joints_and_targets(arm, 32, torch.float64, seed=seed)
    joints[::2, 0] = arm.joint_limits.to(joints)[0, 1]
    return joints, targets


@pytest.mark.parametrize("name", ARMS)
def test_the_compiled_refinement_is_numpys(kernel, name):
    arm = arm_named(name)
    compiled, numpy_loop = both_loops(arm)
    joints, targets = starts_on_limits(arm, seed=1)
    # the damped inverse's gain (up to 1 / damping^2) carries rounding differences from step to step (as
    # tests/test_fused_chain.py allows between the fused and the general loops)
    for steps, tolerance in ((0, 0), (1, 1e-9), (5, 1e-6)):
        for dtype in (torch.float64, torch.float32):
            ours = compiled.refine_scored(joints, targets, steps, 1e-3, 0.2, scored=True, output_dtype=dtype)
            theirs = numpy_loop.refine_scored(joints, targets, steps, 1e-3, 0.2, scored=True, output_dtype=dtype)
            torch.testing.assert_close(ours[0], theirs[0], atol=tolerance, rtol=0)
            for part in ("position", "rotation", "first_position"):
                mine, reference = getattr(ours[1], part), getattr(theirs[1], part)
                assert (mine is None) == (reference is None) == (part == "rotation" and arm.target == "position")
                if mine is not None:
                    torch.testing.assert_close(mine, reference, atol=max(tolerance, 1e-6), rtol=1e-6)
    assert not torch.allclose(ours[0], joints)  # the poses moved: the comparison is not of two no-ops
    unscored = compiled.refine_scored(joints, targets, 5, 1e-3, 0.2)
    assert unscored[1] is None and torch.equal(unscored[0], compiled.refine(joints, targets, 5, 1e-3, 0.2))


@pytest.mark.parametrize("name", ["panda", "z1", "mixed"])
def test_the_compiled_refinement_stops_where_numpys_does(kernel, name):
    arm = arm_named(name)
    compiled, numpy_loop = both_loops(arm)
    generator = torch.Generator().manual_seed(4)
    pose = arm.random_poses(1, generator=generator).double()
    joints = arm.normalize_joints(pose + 0.05 * torch.randn(16, arm.num_joints, generator=generator).double())
    targets = arm.end_effector(pose).expand(16, -1)
    within = (16, arm.position_tolerance, arm.rotation_tolerance)
    ours, our_scores = compiled.refine_scored(joints, targets, 20, 1e-3, 0.2, scored=True, until_within=within)
    theirs, their_scores = numpy_loop.refine_scored(joints, targets, 20, 1e-3, 0.2, scored=True, until_within=within)
    full = compiled.refine_scored(joints, targets, 20, 1e-3, 0.2)[0]
    assert not torch.allclose(ours, full, atol=1e-9)  # it stopped before the twentieth step
    torch.testing.assert_close(ours, theirs, atol=1e-6, rtol=0)
    torch.testing.assert_close(our_scores.position, their_scores.position, atol=1e-7, rtol=1e-5)
    assert bool(((our_scores.position < arm.position_tolerance) & (our_scores.rotation < arm.rotation_tolerance)).any())


@pytest.mark.parametrize("name", ARMS)
def test_the_compiled_error_and_step_are_numpys(kernel, name):
    arm = arm_named(name)
    compiled, numpy_loop = both_loops(arm)
    joints, targets = starts_on_limits(arm, seed=2)
    for ours, theirs in zip(
        compiled.error_and_step(joints, targets, 0.01), numpy_loop.error_and_step(joints, targets, 0.01), strict=True
    ):
        assert ours.shape == theirs.shape and ours.abs().max() > 0
        torch.testing.assert_close(ours, theirs, atol=1e-9, rtol=1e-9)


def test_the_callers_joints_are_left_alone(kernel):
    arm = arm_named("panda")
    compiled, _ = both_loops(arm)
    joints, targets = starts_on_limits(arm, seed=3)
    before = joints.clone()
    compiled.refine_scored(joints, targets, 3, 1e-3, 0.2)
    assert torch.equal(joints, before)
    nothing, scores = compiled.refine_scored(joints[:0], targets[:0], 3, 1e-3, 0.2, scored=True)
    assert nothing.shape == (0, arm.num_joints) and scores.position.shape == (0,)


def test_without_the_kernel_numpys_loop_runs(monkeypatch, caplog):
    monkeypatch.setenv("IKDP_COMPILED", "0")
    monkeypatch.setattr(ikdp.compiled_chain, "_tried", False)
    monkeypatch.setattr(ikdp.compiled_chain, "_library", None)
    arm = arm_named("panda")
    refine = FusedChain(arm).small_refine()
    with caplog.at_level("INFO", logger="ikdp.compiled_chain"):
        assert refine.compiled() is None
    assert "IKDP_COMPILED=0" in caplog.text
    joints, targets = starts_on_limits(arm, seed=5)
    refined, scores = refine.refine_scored(joints, targets, 2, 1e-3, 0.2, scored=True)
    assert refined.shape == joints.shape and np.isfinite(scores.position.numpy()).all()
