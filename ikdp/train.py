"""Train an IKDP model: `python -m ikdp.train --joints 4 --output checkpoints/ikdp_n4.pt`.

Data is generated on the fly (poses from the prior, targets by FK), as in the
paper's Algorithm 1. A tqdm bar shows the running loss; TensorBoard gets the
paper's two curves (loss on theta, tip distance of the prediction) and the
learning rate, in `<output folder>/logs/<output stem>` unless `--log-dir` says
otherwise. The checkpoint is written atomically at intervals, at the end and on
Ctrl-C; `--resume` continues from it with the same data stream, reading the
training config saved in it (options given on the command line override it).

Several processes, one data stream each, gradients averaged (DistributedDataParallel):

    torchrun --standalone --nproc_per_node=2 -m ikdp.train --joints 4 --output checkpoints/my_n4.pt

`--batch` is per process. Without torchrun there is no process group and no wrapper:
the same loop runs in one process.
"""

from __future__ import annotations

import os
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Annotated, Literal

import torch
import torch.distributed as dist
import tyro.conf

from ikdp.checkpoint import CheckpointError, read_checkpoint, remove_stale_temporaries, save_checkpoint
from ikdp.denoisers import DenoiserConfig
from ikdp.device import checked_device
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior, make_prior
from ikdp.schedule import ScheduleConfig
from ikdp.solver import model_from_checkpoint, weight_differences
from ikdp.train_budget import TrainingBudget
from ikdp.train_progress import TrainingProgress, accuracy_text
from ikdp.train_recipes import RECIPE_FIELDS, Recipe, recipe_for, recipes_help
from ikdp.train_steps import EagerSteps, GraphedSteps, graph_applies, plain_optimizer_state


@dataclass(frozen=True)
class TrainConfig:
    """Train an IKDP conditional diffusion model for a planar N-link arm or a robot (--robot, --urdf)."""

    joints: int = 4  # number of links N of a planar arm (a robot's joints come from its URDF)
    robot: str = ""  # a robot by name instead of the planar arm: panda, ur5, z1, spatial<N> (ikdp.robots)
    urdf: str = ""  # or any serial chain from a URDF file (with --ee-link), or a tree (--ee-link given twice or more)
    # the end-effector link of --urdf; repeated for several (a humanoid's two hands: targets (B, E, 7), in this
    # order); with --robot, one other than its own (panda: panda_hand)
    ee_link: Annotated[tuple[str, ...], tyro.conf.UseAppendAction] = ()
    base_link: str = ""  # where --urdf's chain starts, the frame of the targets; empty: the root of ee_link's tree
    target: Literal["pose", "position"] = "pose"  # robots: full pose targets (B, 7) or positions (B, 3)
    lengths: tuple[float, ...] | None = None  # bone lengths, one per link; None: all 1
    timesteps: int | None = None  # diffusion steps T; None: the arm's recipe (see above), as every None here
    schedule: Literal["linear", "cosine", "karras"] | None = None  # noise schedule; karras: EDM's levels
    denoiser: Literal["film", "mlp", "paper"] = "film"  # film (ours; chain_film on a robot), mlp (plain), paper
    representation: Literal["cossin", "angle"] = "cossin"  # cossin or angle (paper's theta); robots: joint limits
    prediction: Literal["sample", "epsilon"] | None = None  # the denoiser predicts the clean sample (x_0) or the noise
    hidden: int | None = None  # film: MLP width
    blocks: int | None = None  # film: residual blocks
    kinematic_until: int = 0  # film: give the tip miss and DLS step features only at t < this (0: every t)
    kinematics_past_limits: bool = False  # robots: FK features and loss at unclamped joint values (keeps a gradient)
    dls_skip: bool | None = None  # robots: the DLS step reaches the estimate through a gain learned per timestep
    limit_aware_step: bool | None = None  # robots: the DLS step feature solved without joints a limit holds
    ema: float | None = None  # decay of an exponential moving average of the weights, saved for solving (0: none)
    prior: str = "uniform"  # pose prior: uniform, relaxed, or a .npy/.csv file of relative joint angles
    tip_loss_weight: float | None = None  # weight of the FK-consistency term (squared tip miss / reach^2); 0 = paper
    snr_gamma: float | None = None  # Min-SNR loss weighting min(SNR, gamma)/gamma; 0 = uniform over t, the paper's
    steps: int | None = None  # optimizer steps; None: the recipe's, or no step limit under --minutes
    minutes: float = 0.0  # wall-clock budget in minutes (evaluations at saves included); 0: steps alone
    batch: int | None = None  # poses per step and per process
    lr: float | None = None  # peak learning rate (AdamW), cosine decay to a tenth over the budget
    warmup: int | None = None  # linear warmup steps
    seed: int = 0  # seeds the weights and the data stream (process r draws from seed + r)
    device: str = "cpu"  # cpu, cuda, cuda:1, ...; under torchrun, cuda means each process's own GPU
    # each step replayed from one CUDA graph where one applies: --device cuda, one process (train_steps.py; on an H100
    # 3.5 x the eager loop's steps a second for the Panda); elsewhere, and with --no-graph, the eager loop
    graph: bool = True
    threads: int = 0  # torch CPU threads; 0 leaves torch's default
    output: str = "checkpoints/model.pt"  # checkpoint path
    log_dir: str = ""  # TensorBoard folder; empty: <output folder>/logs/<output stem>
    save_every: int = 1000  # steps between checkpoints
    eval_targets: int = 500  # targets in the accuracy measured at each save
    resume: bool = False  # continue from --output if it exists, with the training config saved in it
    init_from: str = ""  # start from this checkpoint's weights (same arm and network), fresh optimizer and data


TrainConfig.__doc__ = f"{TrainConfig.__doc__}\n\n{recipes_help()}"
NO_STEP_LIMIT = 10**12  # --minutes without --steps: the clock alone ends the run


def recipe_of(config: TrainConfig) -> Recipe:
    """The recipe that fills what `config` leaves out: planar, or a robot's (chain or tree) for its device."""
    return recipe_for(arm=arm_kind(config), device_type=config.device.split(":")[0])


def arm_kind(config: TrainConfig) -> str:
    """What `config` trains: "planar", "chain" (--robot, or --urdf with one --ee-link) or "tree" (--urdf with
    several, the arm build_chain_arm makes a TreeArm)."""
    if config.urdf and len(ee_links(config)) > 1:
        return "tree"
    return "chain" if config.robot or config.urdf else "planar"


def with_arm_defaults(config: TrainConfig) -> TrainConfig:
    """`config` with every option left out (None) taken from its arm's recipe."""
    recipe = recipe_of(config)
    chosen = {name: getattr(recipe, name) for name in RECIPE_FIELDS if getattr(config, name) is None}
    if config.steps is None and config.minutes > 0:
        chosen["steps"] = NO_STEP_LIMIT
    for name in ("dls_skip", "limit_aware_step"):
        # the robot recipe's film-only parts stay off for another denoiser the user picked; asked for, they still fail
        if name in chosen and config.denoiser != "film":
            chosen[name] = False
    return replace(config, **chosen)


def ee_links(config: TrainConfig) -> tuple[str, ...]:
    """The end-effector links a config names (a caller's single string is one link)."""
    value = config.ee_link
    if isinstance(value, str):
        return (value,) if value else ()
    return tuple(value)


def build_chain_arm(config: TrainConfig):
    """The robot a config names (--robot or --urdf with --ee-link; a TreeArm for several), or None for the planar
    arm."""
    links = ee_links(config)
    if config.robot and config.urdf:
        raise ValueError("robot: give --robot NAME or --urdf PATH, not both")
    if config.base_link and not config.urdf:
        raise ValueError("base_link: --base-link goes with --urdf (a --robot's chain is fixed)")
    if config.robot:
        from ikdp.robots import load_robot

        if len(links) > 1:
            raise ValueError(f"ee_link: --robot {config.robot} has one end effector, got {list(links)}; use --urdf")
        return load_robot(config.robot, target=config.target, ee_link=links[0] if links else None)
    if config.urdf:
        from ikdp.chain_arm import ChainArm
        from ikdp.urdf import link_names, links_phrase

        if not links:
            path = Path(config.urdf)
            known = f"; {links_phrase(link_names(path.read_text(encoding='utf-8')))}" if path.is_file() else ""
            raise ValueError(f"ee_link: --urdf needs --ee-link NAME, the end-effector link{known}")
        if len(links) > 1:
            from ikdp.tree_arm import TreeArm

            return TreeArm.from_urdf(config.urdf, links, target=config.target, base_link=config.base_link or None)
        return ChainArm.from_urdf(config.urdf, links[0], target=config.target, base_link=config.base_link or None)
    return None


def refuse_locked_joints(arm) -> None:
    """ValueError when a joint's limits are equal: the model scales every joint by its range, here zero."""
    limits = arm.joint_limits
    locked = [name for name, (lower, upper) in zip(arm.joint_names, limits.tolist(), strict=True) if not upper > lower]
    if locked:
        raise ValueError(
            f"urdf: joint {locked[0]!r} has equal lower and upper limits (it cannot move): "
            f"make it a fixed joint in the URDF, or pick a chain without it"
        )


def build_model(config: TrainConfig) -> IKDiffusion:
    chain = build_chain_arm(config)
    if chain is not None:
        refuse_locked_joints(chain)
    lengths = config.lengths or (1.0,) * config.joints
    if chain is None and len(lengths) != config.joints:
        raise ValueError(f"lengths: got {len(lengths)} bone lengths for {config.joints} joints")
    # a robot's joints have limits: they are diffused scaled to [-1, 1], and film means its spatial form
    denoiser = "chain_film" if chain is not None and config.denoiser == "film" else config.denoiser
    model_config = ModelConfig(
        lengths=tuple(float(length) for length in lengths),
        representation="joints" if chain is not None else config.representation,
        prediction=config.prediction,
        schedule=ScheduleConfig(timesteps=config.timesteps, kind=config.schedule),
        denoiser=DenoiserConfig(
            kind=denoiser,
            hidden=config.hidden,
            blocks=config.blocks,
            kinematic_until=config.kinematic_until,
            kinematics_past_limits=config.kinematics_past_limits,
            dls_skip=bool(config.dls_skip) and denoiser == "chain_film",
            limit_aware_step=bool(config.limit_aware_step) and denoiser == "chain_film",
        ),
        arm=chain.to_config() if chain is not None else None,
    )
    return IKDiffusion(model_config)


@torch.no_grad()
def measure_accuracy(model: IKDiffusion, prior: PosePrior, count: int, device: torch.device) -> dict[str, float]:
    """Tip error of the raw DDPM sampler, K=1, on `count` targets drawn from the prior (fixed seed)."""
    generator = torch.Generator().manual_seed(12345)
    arm = model.arm
    targets = arm.end_effector(prior.sample(count, arm, generator=generator))
    model.eval()
    poses = model.sample(targets.to(device), generator=torch.Generator(device).manual_seed(1)).headings[:, 0]
    model.train()
    error = arm.tip_error(poses.cpu(), targets)
    metrics = {
        "eval_targets": count,
        "tip_error_median": float(error.median()),
        "tip_error_mean": float(error.mean()),
        "tip_error_p95": float(error.quantile(0.95)),
        "sampler": "ddpm raw, K=1",
        "tip_error_units": "bone lengths" if arm.kind == "planar" else "m",
    }
    if arm.target_dim > arm.position_dim:  # pose targets: the rotation error too, radians
        rotation = arm.rotation_error(poses.cpu(), targets)
        metrics.update(rotation_error_median=float(rotation.median()), rotation_error_mean=float(rotation.mean()))
    if arm.kind != "planar":  # joints outside their limits, summed over the targets
        metrics["limit_violations"] = (
            int(arm.limit_violations(poses.cpu()).sum()) if hasattr(arm, "limit_violations") else 0
        )
    return metrics


def load_initial_weights(model: IKDiffusion, path: str) -> None:
    """--init-from: the (averaged) weights of another run, for a fine-tune; ValueError if they do not fit."""
    source = model_from_checkpoint(read_checkpoint(Path(path)), path)
    if source.arm != model.arm:
        raise ValueError(f"init_from: {path} was trained for another arm ({source.arm!r})")
    differences = weight_differences(model.state_dict(), source.state_dict())
    if differences:
        raise ValueError(f"init_from: {path} has another network shape ({differences})")
    model.load_state_dict(source.state_dict())


def validate(config: TrainConfig) -> None:
    """ValueError naming the option when a value cannot train."""
    positive = {"joints": config.joints, "timesteps": config.timesteps, "steps": config.steps}
    positive |= {"batch": config.batch, "save_every": config.save_every, "lr": config.lr}
    for name, value in positive.items():
        if not value > 0:
            raise ValueError(f"{name}: got {value}, expected a positive number")
    for name, value in {
        "warmup": config.warmup,
        "eval_targets": config.eval_targets,
        "threads": config.threads,
        "minutes": config.minutes,
    }.items():
        if value < 0:
            raise ValueError(f"{name}: got {value}, expected 0 or more")
    for name in ("dls_skip", "limit_aware_step"):
        if getattr(config, name) and not ((config.robot or config.urdf) and config.denoiser == "film"):
            raise ValueError(f"{name}: goes with a robot (--robot or --urdf) and its film denoiser")
    if config.dls_skip and config.prediction != "sample":
        raise ValueError("dls_skip: adds a step to the estimate of x_0, so it needs --prediction sample")
    checked_device(config.device)
    if Path(config.output).is_dir():
        raise ValueError(f"output: {config.output!r} is a folder, expected the path of a checkpoint file")
    # checked now, not at the first save: a run that cannot save its checkpoint loses all its training
    check_writable(Path(config.output).parent, "output")
    check_writable(log_folder(config), "log_dir")


def check_writable(folder: Path, what: str) -> None:
    """ValueError naming the option `what` unless files can be written in `folder` (made if missing): the nearest
    folder that exists above it is probed with a temporary file, so nothing is left behind."""
    existing = folder.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        if existing == folder.absolute():
            raise ValueError(f"{what}: {str(folder)!r} is a file, where a folder was expected")
        raise ValueError(f"{what}: cannot make the folder {str(folder)!r}: {str(existing)!r} is a file")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as error:
        raise ValueError(f"{what}: cannot write in {str(existing)!r} ({error.strerror or error})") from None


def plain_values(config: TrainConfig) -> dict:
    """The config as plain data for the checkpoint: a Path given by a caller is written as its string (a Path
    object would be pickled code, which read_checkpoint refuses: the run would be lost at its first save)."""
    return {
        name: os.fspath(value) if isinstance(value, os.PathLike) else value for name, value in asdict(config).items()
    }


def log_folder(config: TrainConfig) -> Path:
    """Where TensorBoard events go: beside the checkpoint unless --log-dir says otherwise."""
    output = Path(config.output)
    return Path(config.log_dir) if config.log_dir else output.parent / "logs" / output.stem


def saved_config(payload: dict, config_class: type = TrainConfig):
    """The config a checkpoint was trained with (its `train` record; unknown or missing keys are skipped).

    `config_class`: TrainConfig, or another command's (ikdp.distill's DistillConfig).
    """
    record = payload["train"]
    values = {field.name: record[field.name] for field in fields(config_class) if field.name in record}
    if isinstance(values.get("lengths"), list):
        values["lengths"] = tuple(values["lengths"])
    if "ee_link" in values:  # one link was recorded as a string
        link = values["ee_link"]
        values["ee_link"] = ((link,) if link else ()) if isinstance(link, str) else tuple(link)
    return replace(config_class(), **values)


@dataclass(frozen=True)
class Distributed:
    """Where this process stands among the training processes; one process (no torchrun) is rank 0 of 1."""

    rank: int = 0  # this process's index
    world_size: int = 1  # processes in the run
    device: torch.device = torch.device("cpu")  # the device this process trains on

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def start_processes(config: TrainConfig) -> Distributed:
    """Join torchrun's process group when torchrun started us (gloo on CPU, nccl on GPUs); else one process."""
    device = torch.device(config.device)
    if "WORLD_SIZE" not in os.environ:  # not under torchrun: the plain one-process path, no process group
        return Distributed(device=device)
    local_rank = int(os.environ.get("LOCAL_RANK", "0"))
    if device.type == "cuda":
        device = torch.device("cuda", local_rank)  # one GPU per process, whatever index --device named
        torch.cuda.set_device(device)
    if not dist.is_initialized():
        dist.init_process_group(backend="nccl" if device.type == "cuda" else "gloo")
    return Distributed(rank=dist.get_rank(), world_size=dist.get_world_size(), device=device)


class TrainingLoss(torch.nn.Module):
    """The model's loss as a forward pass, so DistributedDataParallel sees it and averages the gradients."""

    def __init__(self, model: IKDiffusion, config: TrainConfig):
        super().__init__()
        self.model = model
        self.tip_loss_weight = config.tip_loss_weight
        self.snr_gamma = config.snr_gamma

    def forward(self, headings: torch.Tensor, generator: torch.Generator) -> dict[str, torch.Tensor]:
        return self.model.compute_loss(
            headings, tip_loss_weight=self.tip_loss_weight, snr_gamma=self.snr_gamma, generator=generator
        )


def gather_data_states(data_generator: torch.Generator, processes: Distributed) -> list[torch.Tensor]:
    """Every process's data-stream state, in rank order (a collective: every process must call it)."""
    if processes.world_size == 1:
        return [data_generator.get_state()]
    states: list = [None] * processes.world_size
    dist.all_gather_object(states, data_generator.get_state())
    return states


def agreed_seconds(seconds: float, processes: Distributed, budget: TrainingBudget) -> float:
    """The training's clock, the same in every process (the slowest one's), so all stop and set the same rate."""
    if processes.world_size == 1 or budget.minutes == 0:  # without a clock, the rate and the end are by steps
        return seconds
    clock = torch.tensor([seconds], dtype=torch.float64, device=processes.device)
    dist.all_reduce(clock, op=dist.ReduceOp.MAX)
    return float(clock)


StepHook = Callable[[int, IKDiffusion, torch.Tensor], None]  # (step just taken, model, the batch it drew)


def train(config: TrainConfig, on_step: StepHook | None = None) -> Path:
    """Train (in every process torchrun started, if it did) and return the checkpoint's path.

    `on_step`, when given, is called in every process after each optimizer step, to watch a run.
    """
    config = with_arm_defaults(config)
    validate(config)
    if config.threads:
        torch.set_num_threads(config.threads)
    joins_group = "WORLD_SIZE" in os.environ and not dist.is_initialized()
    processes = start_processes(config)
    try:
        output = _train(config, processes, on_step)
        if joins_group:
            # leave together: no rank tears down its gloo connections while rank 0 is still saving (the
            # SIGABRT once seen in CI came later, in Python's teardown: see leave_without_finalizing)
            dist.barrier()
        return output
    finally:
        if joins_group:
            dist.destroy_process_group()


def _train(config: TrainConfig, processes: Distributed, on_step: StepHook | None) -> Path:
    device = processes.device
    output = Path(config.output)
    torch.manual_seed(config.seed)  # the same initial weights in every process
    model = build_model(config).to(device)
    if config.init_from and not (config.resume and output.exists()):
        load_initial_weights(model, config.init_from)
    prior = make_prior(config.prior, model.arm.num_joints)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=0.0)
    budget = TrainingBudget(steps=config.steps, minutes=config.minutes, warmup=config.warmup)
    # the data is made where the model trains: on a GPU, no batch is drawn on the CPU and copied over
    data_generator = torch.Generator(device).manual_seed(config.seed + processes.rank)
    step, seconds_before, cpu_seconds_before = 0, 0.0, 0.0
    history: list[dict] = []  # (step, seconds, metrics) at every save: the run's minutes-to-accuracy curve
    if processes.is_main:
        remove_stale_temporaries(output)  # a save killed mid-write (SIGKILL) left its temp file
    # the averaged weights are the ones a solver loads; the raw ones continue training on --resume
    averaged = (
        torch.optim.swa_utils.AveragedModel(model, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(config.ema))
        if config.ema > 0
        else None
    )

    if config.resume and output.exists():
        payload = read_checkpoint(output)
        resumed = model_from_checkpoint(payload, str(output))
        model.load_state_dict(resumed.state_dict())
        if averaged is not None:
            averaged.module.load_state_dict(resumed.state_dict())
            averaged.n_averaged.fill_(int(payload["train"]["step"]))
            model.load_state_dict(payload["raw_state_dict"])
        optimizer.load_state_dict(payload["optimizer"])
        step = int(payload["train"]["step"])
        seconds_before = float(payload["train"]["seconds"])
        budget = budget.resumed(payload["train"], step, seconds_before)  # a longer budget decays on from here
        cpu_seconds_before = float(payload["train"].get("cpu_seconds", 0.0))
        history = list(payload.get("history", []))
        states = payload.get("data_generators") or [payload["data_generator"]]
        saved_on = payload["train"].get("data_device", "cpu")  # runs before data was made on the GPU: the CPU
        if len(states) == processes.world_size and saved_on == device.type:
            data_generator.set_state(states[processes.rank])
        else:  # another number of processes or another device than the run saved: fresh streams, one per process
            data_generator.manual_seed(config.seed + processes.rank + 1_000_003 * step)
            if processes.is_main:
                print(
                    f"resuming with {processes.world_size} process(es) on {device.type}, saved with {len(states)} "
                    f"on {saved_on}: new data streams"
                )
        if processes.is_main:
            print(f"resuming {output} at step {step}", file=sys.stderr)

    loss = TrainingLoss(model, config)
    if processes.world_size > 1:
        loss = torch.nn.parallel.DistributedDataParallel(loss, device_ids=[device] if device.type == "cuda" else None)

    def draw() -> torch.Tensor:  # one batch of ground-truth poses, (batch, J), on the training device
        return prior.sample(config.batch, model.arm, generator=data_generator)

    if graph_applies(config.graph, device, processes.world_size):
        steps = GraphedSteps(loss, model, draw, data_generator, optimizer, averaged, ema=config.ema)
    else:
        steps = EagerSteps(loss, model, draw, data_generator, optimizer, averaged)

    writer = None
    if processes.is_main:
        try:
            from torch.utils.tensorboard import SummaryWriter  # imported late: slow, and only training needs it
        except ImportError:
            raise ValueError("TensorBoard is not installed: pip install 'ikdp[train]'") from None
        writer = SummaryWriter(str(log_folder(config)), purge_step=step)
        print(f"TensorBoard logs: {log_folder(config)}", file=sys.stderr)
    started, cpu_started = time.perf_counter(), time.process_time()

    def wall_seconds() -> float:  # this run's training time, with the runs it resumes
        return seconds_before + time.perf_counter() - started

    metrics: dict = {}

    def save(final: bool, data_states: list[torch.Tensor] | None) -> None:
        nonlocal metrics
        solving_model = averaged.module if averaged is not None else model
        metrics = measure_accuracy(solving_model, prior, config.eval_targets, device) if config.eval_targets else {}
        metrics["step"] = step
        train_record = {**plain_values(config), "step": step, "seconds": wall_seconds(), "lr_decay": budget.record()}
        # the process's CPU time too: on a shared machine the wall clock also counts other programs' turns
        train_record["cpu_seconds"] = cpu_seconds_before + time.process_time() - cpu_started
        if metrics.get("tip_error_median") is not None:
            clock = {name: train_record[name] for name in ("seconds", "cpu_seconds")}
            history.append({"step": step, **clock, **metrics})
        train_record["finished"] = final
        train_record["torch_version"] = str(torch.__version__)
        train_record["threads"] = torch.get_num_threads()
        train_record["world_size"] = processes.world_size
        train_record["data_device"] = device.type  # where the data streams saved below draw
        train_record["recipe"] = recipe_of(config).name  # where the options left out came from
        payload = {
            "model": model.config.to_dict(),
            "prior": prior.to_config(),
            "train": train_record,
            "metrics": metrics,
            "history": history,
            "state_dict": solving_model.state_dict(),  # the averaged weights when --ema: what a solver loads
            **({"raw_state_dict": model.state_dict()} if averaged is not None else {}),
            "optimizer": plain_optimizer_state(optimizer),
            "data_generator": data_generator.get_state(),
        }
        if data_states is not None:
            payload["data_generators"] = data_states
        save_checkpoint(output, payload)
        writer.add_scalar("eval/tip_error_median", metrics.get("tip_error_median", float("nan")), step)

    interrupted = False
    seconds = seconds_before
    progress = TrainingProgress(budget, step=step, seconds=seconds, name=output.stem, enabled=processes.is_main)
    model.train()
    try:
        while not budget.finished(step, seconds):
            lr = config.lr * budget.lr_factor(step, seconds)
            headings, losses = steps(lr)
            step += 1
            seconds = agreed_seconds(wall_seconds(), processes, budget)
            if on_step is not None:
                on_step(step, model, headings)
            if processes.is_main and (step % 50 == 0 or budget.finished(step, seconds)):
                writer.add_scalar("train/theta_loss", float(losses["theta_loss"]), step)
                writer.add_scalar("train/tip_distance", float(losses["tip_distance"]), step)
                writer.add_scalar("train/lr", lr, step)
                progress.show_losses(step, float(losses["theta_loss"]), float(losses["tip_distance"]))
            progress.advance(step, seconds)
            if step % config.save_every == 0 and not budget.finished(step, seconds):
                data_states = gather_data_states(data_generator, processes)
                if processes.is_main:
                    save(final=False, data_states=data_states)
                    progress.show_accuracy(metrics)
        data_states = gather_data_states(data_generator, processes)
    except KeyboardInterrupt:
        interrupted = True  # no collective now: the other processes may be gone; they resume on fresh streams
        data_states = None if processes.world_size > 1 else [data_generator.get_state()]
    progress.close()
    if processes.is_main:
        save(final=not interrupted, data_states=data_states)
        writer.close()
        state = "interrupted, resumable with --resume" if interrupted else "done"
        minutes = wall_seconds() / 60
        print(
            f"{output}: {state} at step {step} ({minutes:.1f} min); held-out median {accuracy_text(metrics)}",
            file=sys.stderr,
        )
    if interrupted:
        raise SystemExit(130)
    return output


def parse_config(argv: list[str] | None = None, config_class: type = TrainConfig, prog: str = "ikdp-train"):
    """The command line as a TrainConfig (or `config_class`); with --resume, options not given come from the
    checkpoint's own record."""
    import tyro  # imported here: only the command line needs it

    config = tyro.cli(config_class, args=argv, prog=prog)
    output = Path(config.output)
    if config.resume and output.exists():
        saved = replace(saved_config(read_checkpoint(output), config_class), output=config.output, resume=True)
        config = tyro.cli(config_class, args=argv, prog=prog, default=saved)
    return config


def save_on_interrupt() -> None:
    """Ctrl-C and a kill (SIGTERM) raise KeyboardInterrupt, on which a training saves its checkpoint."""
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    # Started with SIGINT ignored (`nohup ... &`, a CI runner), Python installs no Ctrl-C handler: install it
    signal.signal(signal.SIGINT, signal.default_int_handler)


def main(argv: list[str] | None = None) -> None:
    save_on_interrupt()
    try:
        train(parse_config(argv))
    except (ValueError, CheckpointError) as error:
        print(f"ikdp-train: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    if "WORLD_SIZE" in os.environ:
        leave_without_finalizing()


def leave_without_finalizing() -> None:
    """End a torchrun worker that finished cleanly (checkpoint written, logs closed, group destroyed) at once.

    Python's own shutdown afterwards tears down torch's C++ state, and a worker sometimes aborts there
    ("terminate called without an active exception", SIGABRT, faulthandler: no Python frame left), failing the
    whole torchrun after a good run: 4 of 146 two-process runs on a loaded 2-core machine, 1 in CI. Nothing is
    left to finish, so that teardown is skipped (0 of 70 under the same load).
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
