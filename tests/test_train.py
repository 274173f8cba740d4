import os
import re
import signal
import socket
import subprocess
import sys
import time
from dataclasses import fields, replace

import numpy as np
import pytest
import torch

import ikdp
from ikdp.checkpoint import read_checkpoint
from ikdp.priors import PosePrior, load_pose_file, make_prior
from ikdp.train import TrainConfig, parse_config, recipe_of, train, validate, with_arm_defaults
from ikdp.train_budget import TrainingBudget
from ikdp.train_recipes import RECIPE_FIELDS, recipe_for


def small_config(tmp_path, **changes):
    values = dict(
        joints=2,
        steps=20,
        batch=32,
        hidden=16,
        blocks=1,
        timesteps=10,
        eval_targets=10,
        save_every=10,
        output=str(tmp_path / "model.pt"),
        log_dir=str(tmp_path / "tb"),
        threads=1,
    )
    values.update(changes)
    return TrainConfig(**values)


def test_training_is_repeatable_and_resumable(tmp_path):
    straight = train(small_config(tmp_path / "a"))
    torch.manual_seed(123)  # global randomness must not matter: the seed is passed in
    train(small_config(tmp_path / "b", steps=10))
    resumed = train(small_config(tmp_path / "b", steps=20, resume=True))
    a = torch.load(straight, weights_only=True)["state_dict"]
    b = torch.load(resumed, weights_only=True)["state_dict"]
    assert a.keys() == b.keys()
    for name in a:
        torch.testing.assert_close(a[name], b[name], rtol=0, atol=0)


def test_init_from_starts_at_another_runs_weights_and_refuses_another_shape(tmp_path):
    first = train(small_config(tmp_path / "a", steps=10))
    fine_tune = small_config(tmp_path / "b", steps=1, lr=1e-9, warmup=0, init_from=str(first), schedule="karras")
    start = torch.load(first, weights_only=True)["state_dict"]
    tuned = torch.load(train(fine_tune), weights_only=True)
    assert tuned["train"]["init_from"] == str(first)
    for name, value in start.items():  # one step at lr 1e-9: still the first run's weights
        torch.testing.assert_close(tuned["state_dict"][name], value, atol=1e-6, rtol=0)
    with pytest.raises(ValueError, match="init_from: .* another network shape"):
        train(small_config(tmp_path / "c", hidden=32, init_from=str(first)))
    with pytest.raises(ValueError, match="init_from: .* another arm"):
        train(small_config(tmp_path / "d", joints=3, init_from=str(first)))


def test_training_writes_tensorboard_curves_beside_the_checkpoint(tmp_path, capsys):
    stale = tmp_path / ".model.pt.zz_9x8y7.tmp"  # a save killed by SIGKILL left it
    stale.write_bytes(b"")
    train(small_config(tmp_path, steps=50, log_dir=""))
    assert not stale.exists()
    logs = tmp_path / "logs" / "model"
    assert list(logs.glob("events.out.tfevents.*"))
    assert str(logs) in capsys.readouterr().err  # training says where its logs are
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    accumulator = EventAccumulator(str(logs))
    accumulator.Reload()
    assert {"train/theta_loss", "train/tip_distance", "train/lr"} <= set(accumulator.Tags()["scalars"])


def test_cli_is_generated_from_the_dataclass():
    config = parse_config(["--joints", "3", "--lengths", "1", "0.5", "2", "--no-resume", "--log-dir", ""])
    assert config.joints == 3 and config.lengths == (1.0, 0.5, 2.0) and config.resume is False
    assert config.timesteps == TrainConfig.timesteps  # defaults come from the dataclass only


def test_help_shows_each_option_once_with_its_default():
    result = subprocess.run([sys.executable, "-m", "ikdp.train", "--help"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    options = re.findall(r"^\W*(--[a-z-]+)", result.stdout, flags=re.MULTILINE)  # the flag opening each entry
    expected = ["--" + field.name.replace("_", "-") for field in fields(TrainConfig)]
    assert sorted(options) == sorted(expected)
    assert "--joints INT" in result.stdout and "--no-resume" in result.stdout
    # a repeatable option (--ee-link) says so in place of a default
    assert result.stdout.count("(default:") + result.stdout.count("(repeatable)") == len(fields(TrainConfig))


def test_resume_reads_the_training_config_from_the_checkpoint(tmp_path):
    first = small_config(tmp_path, steps=10, hidden=8, prior="relaxed", lr=3e-3)
    output = train(first)
    assert read_checkpoint(output)["train"]["world_size"] == 1
    config = parse_config(["--output", str(output), "--resume", "--steps", "20"])
    assert config == with_arm_defaults(replace(first, steps=20, resume=True))  # the line overrides, the file fills in
    assert parse_config(["--output", str(output), "--steps", "20"]).hidden == TrainConfig.hidden  # no --resume


def test_learning_rate_warms_up_then_decays_to_a_tenth():
    budget = TrainingBudget(steps=1100, warmup=100)
    rates = [1e-3 * budget.lr_factor(step, seconds=0.0) for step in range(budget.steps)]
    assert rates[0] == pytest.approx(1e-5)  # lr / warmup
    assert rates[49] == pytest.approx(0.5e-3)  # (step + 1) / warmup of the peak
    assert rates[99] == pytest.approx(1e-3) and rates[100] == pytest.approx(1e-3)
    assert rates[600] == pytest.approx(0.55e-3)  # half-way down the cosine: between the peak and a tenth
    assert rates[-1] == pytest.approx(1e-4, rel=1e-3)  # a tenth of the peak at the end


def test_a_clock_budget_decays_the_rate_and_ends_by_minutes():
    budget = TrainingBudget(steps=10**12, minutes=2.0, warmup=10)
    assert budget.lr_factor(5, seconds=1.0) == pytest.approx(0.6)  # the warm-up is in steps either way
    assert budget.lr_factor(50, seconds=60.0) == pytest.approx(0.55)  # half the clock: half-way down the cosine
    assert budget.progress(50, seconds=30.0) == pytest.approx(0.25)
    assert not budget.finished(10**6, seconds=119.9) and budget.finished(10, seconds=120.0)
    assert budget.lr_factor(10**6, seconds=500.0) == pytest.approx(0.1)  # past the end: a tenth, no further
    both = TrainingBudget(steps=100, minutes=2.0)
    assert both.finished(100, seconds=1.0) and both.progress(50, seconds=90.0) == pytest.approx(0.75)  # first wins
    with pytest.raises(ValueError, match="minutes"):
        TrainingBudget(steps=10, minutes=-1.0)


def budget_record(budget: TrainingBudget) -> dict:
    return {"steps": budget.steps, "minutes": budget.minutes, "warmup": budget.warmup, "lr_decay": budget.record()}


def test_a_longer_budget_on_resume_decays_on_from_the_rate_reached():
    first = TrainingBudget(steps=10**12, minutes=10.0, warmup=10)
    step, seconds = 500, 300.0  # half the clock: half-way down the cosine
    reached = first.lr_factor(step, seconds)
    longer = TrainingBudget(steps=10**12, minutes=20.0, warmup=10).resumed(budget_record(first), step, seconds)
    assert longer.lr_factor(step, seconds) == pytest.approx(reached)  # no jump
    assert TrainingBudget(steps=10**12, minutes=20.0, warmup=10).lr_factor(step, seconds) > reached + 0.1  # refitted
    rates = [longer.lr_factor(step + 10 * i, seconds + 9 * i) for i in range(101)]  # to the new end, 1200 s
    assert all(later <= earlier for earlier, later in zip(rates, rates[1:], strict=False))
    assert rates[-1] == pytest.approx(0.1) and rates[50] < reached
    # resumed again with the same budget: the record carries the extension on
    again = TrainingBudget(steps=10**12, minutes=20.0, warmup=10).resumed(budget_record(longer), step + 50, 400.0)
    assert again == longer
    assert first.resumed(budget_record(first), step, seconds) == first  # the budget it had: as it was
    assert longer.resumed({"steps": "many"}, step, seconds) == longer  # an unreadable record: the budget as given
    assert longer.resumed({"steps": 10, "lr_decay": "?"}, step, seconds) == longer


def test_a_resumed_training_with_more_steps_keeps_its_rate_going_down(tmp_path):
    output = train(small_config(tmp_path, steps=8, warmup=2, hidden=8))
    resumed = train(small_config(tmp_path, steps=16, warmup=2, hidden=8, resume=True))
    decay = read_checkpoint(resumed)["train"]["lr_decay"]
    assert decay["from_step"] == 8 and decay["decay_from"] == pytest.approx(1.0)  # the first run ended at a tenth
    assert read_checkpoint(output)["train"]["step"] == 16


def test_minutes_end_a_training_by_its_clock_and_record_the_curve(tmp_path):
    output = train(small_config(tmp_path, steps=None, minutes=0.03, save_every=20))
    payload = read_checkpoint(output)
    record = payload["train"]
    assert record["finished"] and 1.8 <= record["seconds"] < 30  # 0.03 min = 1.8 s, and it stopped
    assert record["step"] > 0 and record["minutes"] == 0.03
    history = payload["history"]
    assert history and history[-1]["step"] == record["step"]  # the last point is the final save
    assert [point["step"] for point in history] == sorted(point["step"] for point in history)
    assert all(point["cpu_seconds"] > 0 and "tip_error_median" in point for point in history)


def test_options_left_out_come_from_the_arms_recipe():
    planar = with_arm_defaults(TrainConfig())
    assert (planar.timesteps, planar.prediction, planar.hidden, planar.steps) == (80, "sample", 128, 20_000)
    robot_cpu = with_arm_defaults(TrainConfig(robot="spatial2"))
    assert (robot_cpu.timesteps, robot_cpu.prediction, robot_cpu.schedule) == (100, "sample", "karras")
    assert (robot_cpu.hidden, robot_cpu.batch, robot_cpu.tip_loss_weight) == (256, 1024, 100.0)
    robot_gpu = with_arm_defaults(TrainConfig(robot="spatial2", device="cuda:1"))
    assert (robot_gpu.hidden, robot_gpu.batch, robot_gpu.prediction, robot_gpu.tip_loss_weight) == (
        512, 8192, "epsilon", 0.0,
    )  # fmt: skip
    given = with_arm_defaults(TrainConfig(robot="spatial2", hidden=64, schedule="karras"))
    assert (given.hidden, given.schedule, given.blocks) == (64, "karras", 4)  # what is given wins
    assert with_arm_defaults(TrainConfig(minutes=5.0)).steps > 10**9  # the clock alone ends it
    filled = with_arm_defaults(TrainConfig(robot="spatial2"))
    assert all(getattr(filled, name) is not None for name in RECIPE_FIELDS)


def test_a_tree_on_a_cpu_takes_the_tree_recipe_and_one_hand_of_it_the_chains():
    hands = ("left_hand", "right_hand")
    tree = with_arm_defaults(TrainConfig(urdf="two_arms.urdf", ee_link=hands))
    assert (recipe_of(tree).name, tree.batch, tree.ema) == ("tree, CPU", 512, 0.995)
    assert (tree.hidden, tree.prediction, tree.dls_skip) == (256, "sample", True)  # the rest: the CPU robot's
    chain = with_arm_defaults(TrainConfig(urdf="two_arms.urdf", ee_link=hands[:1]))
    assert (recipe_of(chain).name, chain.batch, chain.ema) == ("robot, CPU", 1024, 0.999)
    on_gpu = with_arm_defaults(TrainConfig(urdf="two_arms.urdf", ee_link=hands, device="cuda"))
    assert (recipe_of(on_gpu).name, on_gpu.batch) == ("robot, GPU", 8192)
    assert with_arm_defaults(TrainConfig(urdf="two_arms.urdf", ee_link=hands, batch=2048)).batch == 2048
    with pytest.raises(ValueError, match="^arm: got 'humanoid', expected one of planar, chain, tree$"):
        recipe_for(arm="humanoid", device_type="cpu")


def test_a_robot_with_another_denoiser_leaves_the_film_only_recipe_parts_off(tmp_path):
    places = {"output": str(tmp_path / "model.pt"), "log_dir": str(tmp_path / "runs")}
    plain = with_arm_defaults(TrainConfig(robot="spatial2", denoiser="mlp", **places))
    assert (plain.dls_skip, plain.limit_aware_step) == (False, False)
    validate(plain)  # the recipe alone never makes a config that cannot train
    asked = with_arm_defaults(TrainConfig(robot="spatial2", denoiser="mlp", dls_skip=True, **places))
    with pytest.raises(ValueError, match="^dls_skip: goes with a robot"):
        validate(asked)


def test_the_checkpoint_records_every_value_used_and_the_recipe(tmp_path):
    config = replace(small_config(tmp_path), robot="spatial1", target="position", hidden=None, blocks=None, batch=None)
    config = replace(config, steps=2, prediction=None, schedule=None, ema=None)
    record = read_checkpoint(train(config))["train"]
    assert record["recipe"] == "robot, CPU"
    assert (record["hidden"], record["blocks"], record["batch"]) == (256, 4, 1024)
    assert (record["prediction"], record["schedule"], record["ema"]) == ("sample", "karras", 0.999)
    assert all(record[name] is not None for name in RECIPE_FIELDS)


def test_cli_bad_option_exits_with_a_message(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "ikdp.train",
            "--joints",
            "2",
            "--lengths",
            "1",
            "1",
            "1",
            "--output",
            str(tmp_path / "x.pt"),
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 2
    assert "lengths" in result.stderr and "Traceback" not in result.stderr


def test_interrupted_training_leaves_a_loadable_checkpoint_even_started_with_sigint_ignored(tmp_path):
    output = tmp_path / "model.pt"
    command = [
        sys.executable,
        "-m",
        "ikdp.train",
        "--joints",
        "2",
        "--steps",
        "1000000",
        "--batch",
        "16",
        "--hidden",
        "16",
        "--blocks",
        "1",
        "--timesteps",
        "10",
        "--eval-targets",
        "5",
        "--threads",
        "1",
        "--save-every",
        "5",
        "--output",
        str(output),
        "--log-dir",
        str(tmp_path / "tb"),
    ]
    # as `nohup ... &` or a CI runner starts it: SIGINT ignored, so Python installs no Ctrl-C handler of its own
    # (without it the trainer ran on through Ctrl-C); main() installs one
    ignore_sigint = lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ignore_sigint
    )
    deadline = time.monotonic() + 120
    while not output.exists() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.1)  # wait until the loop runs: the first periodic checkpoint
    process.send_signal(signal.SIGINT)  # what Ctrl-C sends
    try:
        _, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr[-500:]
    assert "Traceback" not in stderr
    solver = ikdp.load(output)
    assert 5 <= solver.metadata["train"]["step"] < 1_000_000
    assert solver.metadata["train"]["finished"] is False


def test_priors(tmp_path):
    generator = torch.Generator().manual_seed(0)
    relaxed = PosePrior(kind="relaxed").sample(20000, 4, generator=generator)
    bends = ikdp.absolute_to_relative(relaxed)[:, 1:]
    assert abs(bends.std().item() - np.pi / 4) < 0.02
    poses = np.array([[0.1, 0.2, 0.3], [0.0, -0.5, 1.0]])
    np.save(tmp_path / "poses.npy", poses)
    prior = make_prior(str(tmp_path / "poses.npy"), 3)
    drawn = ikdp.absolute_to_relative(prior.sample(50, 3, generator=generator))
    assert all(
        any(torch.allclose(row, torch.tensor(p, dtype=torch.float32), atol=1e-5) for p in poses) for row in drawn
    )


@pytest.mark.parametrize(
    "content, suffix, message",
    [
        ("", ".csv", "no poses"),
        ("0.1,0.2\n0.3,0.4\n", ".csv", "expected 3 joint angles"),
        ("0.1,0.2,nan\n", ".csv", "row 0 holds NaN"),
        ("0.1,0.2,0.3\n", ".txt", "expected a .npy or .csv"),
    ],
)
def test_pose_file_errors(tmp_path, content, suffix, message):
    path = tmp_path / f"poses{suffix}"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        load_pose_file(path, 3)


def test_describe_rebuilds_the_training_command(tiny_checkpoint):
    import shlex

    from ikdp.describe import describe, training_command

    train = torch.load(tiny_checkpoint, weights_only=True)["train"]
    command = training_command(train)
    rebuilt = parse_config(shlex.split(command)[3:])
    for name in ("joints", "steps", "batch", "hidden", "blocks", "timesteps", "threads", "output", "log_dir"):
        assert getattr(rebuilt, name) == train[name], name
    assert str(tiny_checkpoint) in describe([str(tiny_checkpoint)])


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _distributed_worker(rank: int, world_size: int, port: int, folder: str) -> None:
    """One of the processes torchrun would start: its environment, then the real training entry point."""
    os.environ.update(
        MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), LOCAL_RANK=str(rank), WORLD_SIZE=str(world_size)
    )
    records = []

    def watch(step, model, headings):
        weights = torch.cat([parameter.detach().flatten() for parameter in model.parameters()])
        records.append({"step": step, "weights": weights.clone(), "batch": headings.clone()})

    config = TrainConfig(
        joints=2, steps=4, batch=16, hidden=16, blocks=1, timesteps=10, eval_targets=5, threads=1, save_every=100
    )
    train(replace(config, output=f"{folder}/model.pt"), on_step=watch)
    torch.save(records, f"{folder}/rank{rank}.pt")


@pytest.mark.slow
def test_two_processes_average_their_gradients(tmp_path, monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    torch.multiprocessing.spawn(_distributed_worker, args=(2, _free_port(), str(tmp_path)), nprocs=2, join=True)
    first, second = (torch.load(tmp_path / f"rank{rank}.pt", weights_only=True) for rank in (0, 1))
    assert [record["step"] for record in first] == [record["step"] for record in second] == [1, 2, 3, 4]
    for a, b in zip(first, second, strict=True):
        assert not torch.equal(a["batch"], b["batch"])  # each process drew its own data
        torch.testing.assert_close(a["weights"], b["weights"], rtol=0, atol=0)  # yet they took the same step
    assert not torch.equal(first[0]["weights"], first[-1]["weights"])  # and the steps did move the weights
    payload = read_checkpoint(tmp_path / "model.pt")
    assert payload["train"]["world_size"] == 2 and payload["train"]["step"] == 4
    assert len(payload["data_generators"]) == 2 and not torch.equal(*payload["data_generators"])


def failed_workers(stderr: str) -> str:
    """A failed torchrun's stderr: the workers' own messages first (their cause), then the launcher's summary.

    The summary alone (the last lines) said only that a worker was aborted (SIGABRT), once in CI.
    """
    return stderr[:3000] + "\n[...]\n" + stderr[-1500:] if len(stderr) > 4500 else stderr


@pytest.mark.slow
def test_torchrun_trains_and_resumes(tmp_path):
    output = tmp_path / "model.pt"
    torchrun = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2", "-m", "ikdp.train"]
    options = ["--joints", "2", "--batch", "16", "--hidden", "16", "--blocks", "1", "--timesteps", "10"]
    options += ["--eval-targets", "5", "--threads", "1", "--save-every", "3", "--output", str(output)]
    environment = {**os.environ, "OMP_NUM_THREADS": "1"}
    first = subprocess.run([*torchrun, *options, "--steps", "6"], capture_output=True, text=True, env=environment)
    assert first.returncode == 0, failed_workers(first.stderr)
    assert first.stderr.count("TensorBoard logs:") == 1  # rank 0 alone reports
    resumed = subprocess.run(
        [*torchrun, "--output", str(output), "--resume", "--steps", "9"],
        capture_output=True,
        text=True,
        env=environment,
    )
    assert resumed.returncode == 0, failed_workers(resumed.stderr)
    assert "resuming" in resumed.stderr and "new data streams" not in resumed.stdout
    payload = read_checkpoint(output)
    assert payload["train"]["step"] == 9 and payload["train"]["world_size"] == 2
    assert payload["train"]["hidden"] == 16  # read back from the checkpoint, not given again
    assert ikdp.load(output).num_links == 2


def test_paths_given_as_path_objects_save_a_loadable_checkpoint(tmp_path):
    output = train(small_config(tmp_path, steps=2, output=tmp_path / "as_path.pt", log_dir=tmp_path / "tb"))
    assert ikdp.load(output).arm.num_joints == 2  # a Path in the record would be refused as pickled code


def test_a_cuda_device_without_cuda_is_refused_before_training(tmp_path, monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ValueError, match=r"^device: got 'cuda', but torch finds no CUDA GPU here; use 'cpu'$"):
        train(small_config(tmp_path, device="cuda"))
    with pytest.raises(ValueError, match=r"^device: expected 'cpu', 'cuda' or 'cuda:N', got 'gpu'$"):
        train(small_config(tmp_path, device="gpu"))
    assert not (tmp_path / "tb").exists()


def test_an_output_that_cannot_be_written_is_refused_before_training(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("not a folder")
    under_file = str(a_file / "model.pt")
    for log_dir in ("", str(tmp_path / "tb")):  # with its own --log-dir the run used to train until its first save
        with pytest.raises(ValueError, match=rf"^output: '{a_file}' is a file, where a folder was expected$"):
            train(small_config(tmp_path, output=under_file, log_dir=log_dir))
    with pytest.raises(ValueError, match=rf"^log_dir: cannot make the folder '{a_file}/logs': '{a_file}' is a file$"):
        train(small_config(tmp_path, log_dir=str(a_file / "logs")))
    with pytest.raises(ValueError, match="^output: .* is a folder, expected the path of a checkpoint file"):
        train(small_config(tmp_path, output=str(tmp_path)))
    assert sorted(path.name for path in tmp_path.iterdir()) == ["a_file"]  # nothing trained, nothing made


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes in any folder")
def test_an_output_in_a_read_only_folder_is_refused_before_training(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    with pytest.raises(ValueError, match=rf"^output: cannot write in '{locked}' \(Permission denied\)"):
        train(small_config(tmp_path, output=str(locked / "sub" / "model.pt")))


def test_cli_refuses_an_output_under_a_file_in_one_line(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    command = [sys.executable, "-m", "ikdp.train", "--joints", "2", "--output", str(a_file / "x.pt")]
    result = subprocess.run(command, capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr == f"ikdp-train: error: output: '{a_file}' is a file, where a folder was expected\n"
