"""A training step replayed from a recording takes the eager step (checked on a CPU with an eager recorder, and on a
GPU with a CUDA graph where one exists), its body asks the device nothing, and its data is drawn where the
generator lives."""

from dataclasses import replace

import numpy as np
import pytest
import torch
from device_recorders import HostCopyRecorder, HostSyncRecorder, RandomDraws
from gpu_machine import panda_chain

from ikdp.checkpoint import read_checkpoint, save_checkpoint
from ikdp.priors import make_prior
from ikdp.train import TrainConfig, TrainingLoss, build_model, train, with_arm_defaults
from ikdp.train_steps import EagerSteps, GraphedSteps, graph_applies, plain_optimizer_state

needs_cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device")

PLANAR = dict(joints=3, prior="relaxed", tip_loss_weight=0.5, snr_gamma=5.0, hidden=32, blocks=2, timesteps=20)
# the Panda with its kinematic features, the DLS skip and the limit-aware step: the chain's widest forward pass
PANDA = dict(**panda_chain(), hidden=32, blocks=1, timesteps=20, dls_skip=True, limit_aware_step=True)


def run_steps(kind, options: dict, count: int, device="cpu", record=None, seed=0):
    """`count` steps of `kind` (EagerSteps or GraphedSteps) from the same weights and data stream, at a rate
    changed every step -> (the weights, the averaged weights, the batches drawn)."""
    config = with_arm_defaults(TrainConfig(**options, batch=64, ema=0.9, prediction="sample"))
    torch.manual_seed(seed)
    model = build_model(config).to(device)
    prior = make_prior(config.prior, model.arm.num_joints)
    generator = torch.Generator(device).manual_seed(seed)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=0.0)
    averaged = torch.optim.swa_utils.AveragedModel(
        model, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(config.ema)
    )
    loss = TrainingLoss(model, config)
    draw = lambda: prior.sample(config.batch, model.arm, generator=generator)  # noqa: E731
    extra = {} if kind is EagerSteps else {"ema": config.ema, **({"record": record} if record else {})}
    steps = kind(loss, model, draw, generator, optimizer, averaged, **extra)
    batches = [steps(1e-3 * (1 + index % 3))[0].clone() for index in range(count)]
    flat = lambda module: torch.cat([p.detach().flatten() for p in module.parameters()])  # noqa: E731
    return flat(model), flat(averaged.module), torch.stack(batches), steps


def eager_recording(step, generator):
    """A recorder that records nothing: each 'replay' runs the step again, op by op (CPU tests)."""
    return step


@pytest.mark.parametrize("options", [PLANAR, PANDA], ids=["planar", "panda"])
def test_recorded_steps_take_the_eager_steps(options):
    """Three warm-up steps, the recording's first step, then replays: the same weights, averages and batches."""
    eager = run_steps(EagerSteps, options, 6)
    graphed = run_steps(GraphedSteps, options, 6, record=eager_recording)
    assert graphed[3].replay is not None  # the last three steps were replays
    torch.testing.assert_close(graphed[2], eager[2], atol=0, rtol=0)  # the same data stream
    torch.testing.assert_close(graphed[0], eager[0], atol=1e-6, rtol=0)
    torch.testing.assert_close(graphed[1], eager[1], atol=1e-6, rtol=0)
    assert not torch.equal(graphed[0], run_steps(EagerSteps, options, 5)[0])  # six steps, not five


@pytest.mark.parametrize("options", [PLANAR, PANDA], ids=["planar", "panda"])
def test_a_recorded_step_asks_the_device_nothing(options, monkeypatch):
    """The step a graph records, run on a CPU under a recorder of host syncs after the warm-up. AdamW's own step
    is left out: on a CPU it is not capturable (it reads its step count); on a GPU, `capturable=True` is torch's."""
    *_, steps = run_steps(GraphedSteps, options, 3, record=eager_recording)
    monkeypatch.setattr(steps.optimizer, "step", lambda: None)
    recorder = HostSyncRecorder()
    with recorder:
        steps.step(average=steps.lerp_average)
    assert recorder.found == []
    with recorder:  # the recorder sees what it must: the eager average checks its count on the host
        steps.step(average=steps.update_average)
    assert recorder.found


@pytest.mark.parametrize("options", [PLANAR, PANDA], ids=["planar", "panda"])
def test_a_recorded_step_copies_nothing_from_the_host(options, monkeypatch):
    """No constant kept on the CPU is moved to the device inside a step (a capture refuses a host copy; on a CPU
    a copy is a no-op, so the recorder finds them by origin). The Panda diffuses in the `joints` representation,
    whose index tensors were such copies."""
    *_, steps = run_steps(GraphedSteps, options, 3, record=eager_recording)
    monkeypatch.setattr(steps.optimizer, "step", lambda: None)
    own = [*steps.model.parameters(), *steps.model.buffers(), *steps.averaged.module.parameters()]
    recorder = HostCopyRecorder(own)
    with recorder:
        steps.step(average=steps.lerp_average)
    assert recorder.found == []


@pytest.mark.parametrize("options", [PLANAR, PANDA, dict(joints=2, prior="uniform")], ids=["relaxed", "panda", "n2"])
def test_every_draw_of_a_step_names_the_generators_device(options):
    """A draw that names no device is made on the CPU: on a GPU it would be a host copy per step (and a capture
    would refuse it). So each draw must take the data generator and name its device."""
    *_, steps = run_steps(GraphedSteps, options, 1, record=eager_recording)
    draws = RandomDraws()
    with draws:
        steps.step(average=steps.lerp_average)
    assert len(draws.draws) >= 3  # the poses, the timesteps, the noise
    assert [name for name, _, generator in draws.draws if generator is not steps.generator] == []
    assert draws.off_device(steps.generator) == []


def test_a_file_prior_copies_its_poses_to_a_device_once(tmp_path):
    poses = tmp_path / "poses.npy"
    np.save(poses, np.random.default_rng(0).uniform(-1, 1, (50, 3)))
    prior = make_prior(str(poses), 3)
    generator = torch.Generator().manual_seed(0)
    first = prior.sample(8, 3, generator=generator)
    assert prior.poses_on(torch.device("cpu")) is prior.poses_on(torch.device("cpu"))
    assert first.shape == (8, 3)


def small(tmp_path, **changes):
    options = dict(joints=2, steps=6, batch=16, hidden=16, blocks=1, timesteps=10, eval_targets=5, save_every=100)
    config = TrainConfig(**options, output=str(tmp_path / "m.pt"), log_dir=str(tmp_path / "tb"), threads=1)
    return replace(config, **changes)


def test_graphed_steps_apply_on_one_cuda_process_only():
    assert graph_applies(True, torch.device("cuda", 0), world_size=1)
    assert not graph_applies(False, torch.device("cuda", 0), world_size=1)  # --no-graph
    assert not graph_applies(True, torch.device("cpu"), world_size=1)
    assert not graph_applies(True, torch.device("cuda", 0), world_size=2)  # under torchrun: DDP's eager steps


def test_the_default_graph_on_a_cpu_trains_the_eager_steps(tmp_path):
    """`--graph` is on by default; on a CPU it takes the eager steps, so the weights are --no-graph's to the bit."""
    assert TrainConfig().graph
    default = read_checkpoint(train(small(tmp_path / "a")))
    eager = read_checkpoint(train(replace(small(tmp_path / "b"), graph=False)))
    assert default["state_dict"].keys() == eager["state_dict"].keys()
    for name, value in default["state_dict"].items():
        torch.testing.assert_close(value, eager["state_dict"][name], atol=0, rtol=0)


def test_a_checkpoint_records_where_its_data_was_drawn_and_a_plain_optimizer(tmp_path):
    output = train(small(tmp_path))
    payload = read_checkpoint(output)
    assert payload["train"]["data_device"] == "cpu"
    assert all(isinstance(group["lr"], float) for group in payload["optimizer"]["param_groups"])


def test_resuming_data_drawn_on_another_device_starts_fresh_streams(tmp_path, capsys):
    """A run saved on a GPU resumed on a CPU: its generator state is a CUDA one, so the streams start anew."""
    output = train(small(tmp_path))
    payload = read_checkpoint(output)
    payload["train"]["data_device"] = "cuda"
    save_checkpoint(output, payload)
    train(replace(small(tmp_path), steps=9, resume=True))
    assert "on cuda: new data streams" in capsys.readouterr().out
    assert read_checkpoint(output)["train"]["step"] == 9


def test_a_graphed_optimizer_state_saves_plain_values():
    model = torch.nn.Linear(3, 2)
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-3)
    for group in optimizer.param_groups:
        group["lr"], group["capturable"] = torch.tensor(2e-3), True
    state = plain_optimizer_state(optimizer)
    assert state["param_groups"][0]["lr"] == pytest.approx(2e-3) and not state["param_groups"][0]["capturable"]
    assert torch.is_tensor(optimizer.param_groups[0]["lr"])  # the live optimizer keeps its tensor


@needs_cuda
@pytest.mark.parametrize("options", [PLANAR, PANDA], ids=["planar", "panda"])
def test_cuda_graph_steps_take_the_eager_steps(options):
    """On a GPU: 10 steps replayed from a CUDA graph against 10 eager ones (AdamW capturable vs not: float32
    rounding apart)."""
    eager = run_steps(EagerSteps, options, 10, device="cuda")
    graphed = run_steps(GraphedSteps, options, 10, device="cuda")
    assert graphed[3].replay is not None
    torch.testing.assert_close(graphed[2], eager[2], atol=0, rtol=0)
    torch.testing.assert_close(graphed[0], eager[0], atol=1e-5, rtol=0)
    torch.testing.assert_close(graphed[1], eager[1], atol=1e-5, rtol=0)


@needs_cuda
def test_cuda_graph_training_saves_and_resumes(tmp_path):
    config = replace(small(tmp_path, device="cuda"), graph=True, **panda_chain(), hidden=32)
    output = train(config)
    assert read_checkpoint(output)["train"]["data_device"] == "cuda"
    train(replace(config, steps=12, resume=True))
    assert read_checkpoint(output)["metrics"]["step"] == 12
