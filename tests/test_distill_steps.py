"""A distillation step replayed from a recording takes the eager step, asks the device nothing, copies nothing from the
host and draws its data where the generator lives (what tests/test_train_steps.py checks of `ikdp.train`'s step);
a step that runs the teacher stays eager. On a CPU with an eager recorder; on a GPU with a CUDA graph."""

from dataclasses import replace

import pytest
import torch
from device_recorders import HostCopyRecorder, HostSyncRecorder, RandomDraws

import ikdp
from ikdp.checkpoint import read_checkpoint, save_checkpoint
from ikdp.distill import DistillConfig, distill, student_network
from ikdp.distill_reference import PoseStream
from ikdp.distill_step import DistillLoss, runs_the_teacher, student_sampler
from ikdp.train_steps import EagerSteps, GraphedSteps

needs_cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device")

# the one-step recipe's terms (docs/training.md): no teacher run in a step, the reference from a pool
POOL = dict(
    noises_per_target=4,
    match_weight=0.0,
    distribution_weight=10.0,
    reference_pool=32,
    tip_loss_weight=0.0,
    tip_distance_weight=60.0,
)


def eager_recording(step, generator):
    """A recorder that records nothing: each 'replay' runs the step again, op by op (CPU tests)."""
    return step


def build_steps(kind, checkpoint, device="cpu", record=None, seed=0, **changes):
    """`kind` (EagerSteps or GraphedSteps) of a student of `checkpoint` on the pool recipe (`changes` on top)."""
    config = DistillConfig(teacher=str(checkpoint), student_steps=2, batch=16, **(POOL | changes))
    solver = ikdp.load(checkpoint, device=device)
    path = solver.metadata["path"]
    torch.manual_seed(seed)
    student = student_network(read_checkpoint(path), path, False).to(device)
    stream = PoseStream(solver.model, solver.prior, config, torch.device(device))
    loss = DistillLoss(student, solver.model, student_sampler(student, config), config)
    generator = torch.Generator(device).manual_seed(seed)
    optimizer = torch.optim.AdamW(student.parameters(), lr=1e-4, weight_decay=0.0)
    extra = {"record": record} if record else {}
    return kind(loss, student, lambda: stream.draw(generator), generator, optimizer, **extra), stream


def run_steps(kind, checkpoint, count, **options):
    """`count` steps at a rate changed every step -> (the student's weights, the poses drawn, the step runner)."""
    steps, _ = build_steps(kind, checkpoint, **options)
    batches = [steps(1e-4 * (1 + index % 3))[0][0].clone() for index in range(count)]
    return torch.cat([p.detach().flatten() for p in steps.model.parameters()]), torch.stack(batches), steps


@pytest.fixture(params=["planar", "panda"])
def teacher(request, tiny_checkpoint, tiny_chain_checkpoint):
    return tiny_checkpoint if request.param == "planar" else tiny_chain_checkpoint


def test_recorded_distill_steps_take_the_eager_steps(teacher):
    """Three warm-up steps, the recording's first step, then replays: the same weights and the same poses drawn."""
    eager = run_steps(EagerSteps, teacher, 6)
    graphed = run_steps(GraphedSteps, teacher, 6, record=eager_recording)
    assert graphed[2].replay is not None
    torch.testing.assert_close(graphed[1], eager[1], atol=0, rtol=0)
    torch.testing.assert_close(graphed[0], eager[0], atol=1e-6, rtol=0)
    assert not torch.equal(graphed[0], run_steps(EagerSteps, teacher, 5)[0])  # six steps, not five


def test_a_recorded_distill_step_asks_the_device_nothing_and_copies_nothing_from_the_host(teacher, monkeypatch):
    steps, stream = build_steps(GraphedSteps, teacher, record=eager_recording)
    for _ in range(3):
        steps(1e-4)
    monkeypatch.setattr(steps.optimizer, "step", lambda: None)  # AdamW's capturable step is torch's (train's test)
    syncs = HostSyncRecorder()
    with syncs:
        steps.step(average=steps.lerp_average)
    assert syncs.found == []
    copies = HostCopyRecorder([*steps.model.parameters(), *steps.model.buffers(), *stream.pool])
    with copies:
        steps.step(average=steps.lerp_average)
    assert copies.found == []


def test_every_draw_of_a_distill_step_names_the_generators_device(teacher):
    steps, _ = build_steps(GraphedSteps, teacher, record=eager_recording)
    draws = RandomDraws()
    with draws:
        steps.step(average=steps.lerp_average)
    assert len(draws.draws) >= 2  # the pool's picks, the noise
    assert [name for name, _, generator in draws.draws if generator is not steps.generator] == []
    assert draws.off_device(steps.generator) == []


def test_only_steps_that_run_no_teacher_are_recorded():
    assert not runs_the_teacher(DistillConfig(**POOL))
    assert runs_the_teacher(DistillConfig())  # the match to the teacher's ODE, the default
    assert runs_the_teacher(DistillConfig(**(POOL | {"spread_weight": 1.0})))
    assert runs_the_teacher(DistillConfig(**(POOL | {"reference_pool": 0})))  # the teacher's DDPM every step


def small(tmp_path, teacher, **changes):
    values = dict(teacher=str(teacher), student_steps=2, steps=6, batch=16, save_every=100, eval_targets=8, threads=1)
    values |= dict(output=str(tmp_path / "student.pt"), log_dir=str(tmp_path / "tb"))
    return DistillConfig(**(values | POOL | changes))


def test_a_student_records_where_its_data_was_drawn_and_resumes_elsewhere_on_a_fresh_stream(
    tiny_checkpoint, tmp_path, capsys
):
    output = distill(small(tmp_path, tiny_checkpoint))
    payload = read_checkpoint(output)
    assert payload["train"]["data_device"] == "cpu"
    assert all(isinstance(group["lr"], float) for group in payload["optimizer"]["param_groups"])
    payload["train"]["data_device"] = "cuda"  # as a GPU run saves it: its stream's state is a CUDA generator's
    save_checkpoint(output, payload)
    distill(small(tmp_path, tiny_checkpoint, steps=9, resume=True))
    assert "saved on cuda: a new data stream" in capsys.readouterr().out
    assert read_checkpoint(output)["train"]["step"] == 9


@needs_cuda
def test_cuda_graph_distill_steps_follow_the_eager_ones(tiny_chain_checkpoint):
    """On a GPU: 10 steps replayed from a CUDA graph against 10 eager ones (capturable AdamW rounds differently)."""
    eager = run_steps(EagerSteps, tiny_chain_checkpoint, 10, device="cuda")
    graphed = run_steps(GraphedSteps, tiny_chain_checkpoint, 10, device="cuda")
    assert graphed[2].replay is not None
    torch.testing.assert_close(graphed[1], eager[1], atol=0, rtol=0)
    torch.testing.assert_close(graphed[0], eager[0], atol=1e-5, rtol=0)


@needs_cuda
def test_cuda_graph_distillation_saves_and_resumes(tiny_chain_checkpoint, tmp_path):
    config = replace(small(tmp_path, tiny_chain_checkpoint), device="cuda", steps=8)
    output = distill(replace(config, steps=5))
    distill(replace(config, resume=True))
    payload = read_checkpoint(output)
    assert payload["train"]["step"] == 8 and payload["train"]["data_device"] == "cuda"
    student = ikdp.load(output, device="cuda")
    assert (
        student.solve(student.arm.end_effector(student.arm.random_poses(4)), sampler="ddim", steps=2)
        .angles.isfinite()
        .all()
    )
