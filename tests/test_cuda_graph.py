"""The CUDA-graph replay of the reverse loop and of a whole solve gives the eager samples (needs CUDA; skipped without
it), and what a graph captures makes no host sync (checked on the CPU)."""

from dataclasses import replace

import pytest
import torch
from device_recorders import HostCopyRecorder, HostSyncRecorder
from gpu_machine import panda_chain

import ikdp
import ikdp.fused_chain
from ikdp.cuda_graph import CapturedReverseDiffusion, solve_without_sync
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.refine import damped_least_squares, dls_step
from ikdp.restarts import restart_every_target, within_tolerances
from ikdp.samplers import make_sampler
from ikdp.train import TrainConfig, train

needs_cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device")


def test_refuses_a_cpu_model():
    with pytest.raises(ValueError, match="model: expected a model on a CUDA device, got one on cpu"):
        CapturedReverseDiffusion(IKDiffusion(ModelConfig(lengths=(1.0, 1.0))), batch=1, num_samples=2)


@needs_cuda
@pytest.mark.parametrize("sampler, steps", [("ddpm", None), ("ddim", 10), ("dpmpp2m", 10)])
def test_replay_gives_the_eager_samples(sampler, steps):
    solver = ikdp.load("ikdp_n4", device="cuda")
    model = solver.model
    graphed = CapturedReverseDiffusion(model, batch=2, num_samples=16, sampler=sampler, steps=steps)
    for seed, targets in ((0, [[1.5, 1.0], [-0.5, 2.0]]), (7, [[0.0, -3.0], [2.5, 0.5]])):
        targets = torch.tensor(targets, device="cuda")
        eager = model.sample(
            targets,
            num_samples=16,
            sampler=sampler,
            steps=steps,
            generator=torch.Generator("cuda").manual_seed(seed),
            return_trajectory=True,
        )
        replayed = graphed(targets, seed=seed)
        torch.testing.assert_close(replayed.states, eager.states, atol=1e-5, rtol=0)
        torch.testing.assert_close(replayed.headings, eager.headings, atol=1e-5, rtol=0)


@needs_cuda
@pytest.mark.parametrize("name", ["ikdp_n4", "ikdp_panda"])
def test_replay_is_bit_identical_to_the_eager_loop(name):
    """The same kernels on the same inputs: not close, equal (a planar arm and a URDF chain)."""
    solver = ikdp.load(name, device="cuda")
    model = solver.model
    graphed = CapturedReverseDiffusion(model, batch=1, num_samples=16, sampler="dpmpp2m", steps=10)
    targets = solver.arm.end_effector(solver.arm.random_poses(1, generator=torch.Generator().manual_seed(3)))
    targets = targets.to("cuda")
    eager = model.sample(
        targets,
        num_samples=16,
        sampler="dpmpp2m",
        steps=10,
        generator=torch.Generator("cuda").manual_seed(5),
        return_trajectory=True,
    )
    replayed = graphed(targets, seed=5)
    assert torch.equal(replayed.states, eager.states)


# --- the whole solve as a graph: its body runs on a CPU too, and is checked there -------------------------------


def reachable_targets(solver, count, seed):
    """`count` targets the solver's arm reaches: the end effector at poses drawn from its joint ranges."""
    return solver.arm.end_effector(solver.arm.random_poses(count, generator=torch.Generator().manual_seed(seed)))


@pytest.mark.parametrize(
    "name, sampler, steps, restart_steps",
    [("ikdp_panda_fast", "ddim", 1, 0), ("ikdp_panda_fast", "ddim", 1, 5), ("ikdp_n4", "dpmpp2m", 3, 5)],
)
def test_the_captured_solve_asks_the_device_nothing(name, sampler, steps, restart_steps, monkeypatch):
    """What `capture` records must not sync: run on a CPU under a recorder, after a warm-up as capture does."""
    # a few rows on a CPU take NumPy's and the cached condition's paths, which a GPU never does: checked as a GPU runs
    monkeypatch.setattr(ikdp.fused_chain, "FUSED_ROWS", 0)
    solver = ikdp.load(name)
    loop = make_sampler(sampler, solver.model.schedule, steps, solver.default_spacing(sampler, steps))
    targets = reachable_targets(solver, 20, 0)
    generator = torch.Generator().manual_seed(0)
    options = dict(num_samples=4, refine_steps=3, restart_steps=restart_steps, generator=generator)
    solve_without_sync(solver, loop, targets, **options)  # warm-up: the per-device constants
    recorder = HostSyncRecorder()
    with recorder, torch.inference_mode():
        solve_without_sync(solver, loop, targets, **options)
    assert recorder.found == []
    with recorder, torch.inference_mode():  # the recorder sees what it must: solve's own restarts do sync
        solver.solve(targets, num_samples=4, sampler=sampler, steps=steps, refine_steps=3, restart_steps=5)
    assert recorder.found


def test_the_captured_solve_of_a_newly_trained_robot_copies_nothing_from_the_host(tmp_path):
    """A robot trained by today's command diffuses its joints in the `joints` representation (the shipped ones
    in `limits`), whose index tensors were copied to the device on every call: a capture refuses that. On a CPU a
    copy is a no-op, so the recorder finds copies by origin (a tensor made before the solve, moved by `.to`)."""
    config = TrainConfig(**panda_chain(), steps=2, batch=16, hidden=32, blocks=1, timesteps=10, eval_targets=0)
    solver = ikdp.load(train(replace(config, output=str(tmp_path / "m.pt"), log_dir=str(tmp_path / "tb"))))
    assert solver.model.representation.kind == "joints"
    loop = make_sampler("ddim", solver.model.schedule, 2, "quadratic")
    targets = reachable_targets(solver, 10, 0)
    options = dict(num_samples=4, refine_steps=3, restart_steps=5, generator=torch.Generator().manual_seed(0))
    solve_without_sync(solver, loop, targets, **options)  # warm-up: the per-device constants
    recorder = HostCopyRecorder(own=[*solver.model.parameters(), *solver.model.buffers()])
    with recorder, torch.inference_mode():
        solve_without_sync(solver, loop, targets, **options)
    assert recorder.found == []
    solver.model.representation._indices_by_device.clear()  # the recorder sees what it must: a first copy
    with recorder, torch.inference_mode():
        solve_without_sync(solver, loop, targets, **options)
    assert recorder.found


def test_the_captured_solve_gives_solves_poses():
    """Same seed, same poses as `solve` on this CPU (no restarts: theirs are drawn differently)."""
    solver = ikdp.load("ikdp_panda_fast")
    targets = reachable_targets(solver, 30, 1)
    sampler = make_sampler("ddim", solver.model.schedule, 1, "quadratic")
    generator = torch.Generator().manual_seed(4)
    body = solve_without_sync(
        solver, sampler, targets, num_samples=8, refine_steps=6, restart_steps=0, generator=generator
    )
    eager = solver.solve(
        targets, num_samples=8, sampler="ddim", steps=1, refine_steps=6, generator=torch.Generator().manual_seed(4)
    )
    # the CPU's eager solve runs the FiLM denoiser through its fused workspace: equal to float32's rounding
    torch.testing.assert_close(body.raw_angles, eager.raw_angles, atol=1e-5, rtol=0)
    # six DLS steps on near-singular poses amplify those 1e-6 rad differences a hundredfold, no more
    torch.testing.assert_close(body.angles, eager.angles, atol=1e-3, rtol=0)
    torch.testing.assert_close(body.tip_error, eager.tip_error, atol=1e-4, rtol=0)  # 0.1 mm
    assert float(body.tip_error.median()) < 1e-3  # refined: most poses within a millimetre
    assert body.network_evaluations == eager.network_evaluations == 1


def test_sync_free_refinement_moves_blocked_poses_as_the_default_does():
    """Poses with joints on their limits, pushed further out: the dense path picks what the subset path picks."""
    solver = ikdp.load("ikdp_panda")
    arm = solver.arm
    limits = arm.joint_limits
    poses = arm.random_poses(400, generator=torch.Generator().manual_seed(2))
    poses[::2, 3] = limits[3, 1]  # half of them on joint 4's upper limit, some will be pushed on past it
    poses[::3, 5] = limits[5, 0]
    goals = reachable_targets(solver, 400, 3)
    default = damped_least_squares(arm, poses, goals, steps=4)
    dense = damped_least_squares(arm, poses, goals, steps=4, sync_free=True)
    error, jacobian = arm.task_error_and_jacobian(poses.double(), goals.double())
    blocked = arm.blocked_by_limits(poses.double(), dls_step(jacobian, error, 1e-6))
    assert 0 < int(blocked.any(-1).sum()) < 400  # the case the two paths treat differently, and not every pose
    assert torch.equal(dense, default)


def test_restarting_every_target_keeps_the_reached_and_restarts_the_rest():
    solver = ikdp.load("ikdp_panda")
    arm = solver.arm
    targets = reachable_targets(solver, 12, 5)
    reached = solver.solve(
        targets, num_samples=4, sampler="ddpm", refine_steps=10, generator=torch.Generator().manual_seed(0)
    )
    angles = reached.angles.clone()
    angles[6:] = arm.random_poses(6 * 4, generator=torch.Generator().manual_seed(1)).reshape(6, 4, -1)  # far off
    goals = targets[:, None].expand(-1, 4, -1)
    before = within_tolerances(arm, angles, goals).any(-1)
    restarted = ~before
    out = restart_every_target(arm, angles, goals, restarted, 30, torch.Generator().manual_seed(2))
    assert torch.equal(out[before], angles[before])  # nothing reached is touched
    assert bool(restarted[6:].all())
    assert within_tolerances(arm, out[6:], goals[6:]).any(-1).float().mean() >= 0.5  # 30 DLS steps from 4 starts


@pytest.mark.parametrize("name", ["ikdp_n4", "ikdp_panda"])
def test_random_poses_like_draw_within_the_limits_where_asked(name):
    arm = ikdp.load(name).arm
    like = torch.zeros(50, 3, arm.num_joints, dtype=torch.float64)
    poses = arm.random_poses_like(like, generator=torch.Generator().manual_seed(0))
    assert poses.shape == like.shape and poses.dtype == torch.float64
    torch.testing.assert_close(arm.normalize_joints(poses), poses, atol=1e-9, rtol=0)  # nothing clamped or wrapped
    assert float(poses.std()) > 0.3  # drawn, not a constant


def test_capture_refuses_a_cpu_solver():
    with pytest.raises(ValueError, match="solver: expected one loaded on a CUDA device, got one on cpu"):
        ikdp.load("ikdp_n4").capture(4)


def test_fused_capture_without_triton_says_so(monkeypatch):
    import importlib.util

    found = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *rest: None if name == "triton" else found(name, *rest)
    )
    with pytest.raises(ValueError, match="fused: torch.compile needs Triton on a GPU, which is not installed"):
        ikdp.load("ikdp_n4").capture(4, fused=True)


@pytest.mark.parametrize(
    "batch, options, message",
    [
        (0, {}, "batch: expected a positive integer"),
        (2.5, {}, "batch: expected a positive integer"),
        (4, {"restart_steps": True}, "restart_steps: expected a non-negative integer"),
        (4, {"sampler": "euler"}, "sampler: expected one of"),
        (4, {"refine_steps": -1}, "refine_steps: expected a non-negative integer"),
    ],
)
def test_capture_names_a_bad_option_before_anything_else(batch, options, message):
    with pytest.raises(ValueError, match=message):
        ikdp.load("ikdp_n4").capture(batch, **options)


@needs_cuda
@pytest.mark.parametrize(
    "name, sampler, steps",
    [("ikdp_panda_fast", "ddim", 1), ("ikdp_n4", "dpmpp2m", 10), ("ikdp_panda", "student", None)],
)
def test_the_captured_solve_replays_the_eager_solve(name, sampler, steps):
    solver = ikdp.load(name, device="cuda")
    targets = reachable_targets(solver, 64, 6).cuda()
    captured = solver.capture(64, num_samples=16, sampler=sampler, steps=steps, refine_steps=5)
    for seed in (0, 9):
        eager = solver.solve(
            targets,
            num_samples=16,
            sampler=sampler,
            steps=steps,
            refine_steps=5,
            generator=torch.Generator("cuda").manual_seed(seed),
        )
        replayed = captured(targets, seed=seed)
        torch.testing.assert_close(replayed.raw_angles, eager.raw_angles, atol=1e-5, rtol=0)
        torch.testing.assert_close(replayed.angles, eager.angles, atol=1e-4, rtol=0)
