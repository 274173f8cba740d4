"""Distil a trained IKDP model into a few-step student: `python -m ikdp.distill --teacher ikdp_n4 --student-steps 2`.

The student is the teacher's network, copied, then trained so that DDIM on `student_steps` timesteps
(`spacing`: packed near t = 0 by default) lands where the teacher's deterministic sampler lands in
many more steps from the same noise x_T (Luhman & Luhman 2021's knowledge distillation of the ODE,
the few-step sampler unrolled and trained end to end, as in progressive distillation's single round):

    x_T ~ N(0, I); poses ~ prior; targets = FK(poses)
    teacher: x_T --(teacher_sampler, teacher_steps)--> x0_teacher                 (no gradient)
    student: x_T --(DDIM, student_steps, the student's x̂0 at each step)--> x0_student
    loss = match_weight * |x0_student - x0_teacher|^2 + tip_loss_weight * FK miss of x0_student, squared
           + tip_distance_weight * FK miss of x0_student                                (fk_distance)
           + spread_weight * (mean distance of a target's student poses - the teacher's)^2   (spread_miss)
           + distribution_weight * energy distance to the teacher's DDPM samples      (energy_distance)
             (or, with --reference posterior, to samples of the true posterior: ikdp.posterior_pool)

The noise picks the teacher's mode, so matching the teacher from the same x_T keeps the spread of
its samples (no averaging of elbow-up and elbow-down into neither); the FK term pulls the student's
pose onto the target where the teacher's ODE missed it. Poses and noise are drawn afresh each step.

The student checkpoint is an ordinary IKDP checkpoint (`ikdp.load` solves with it, with any sampler)
plus a `distill` record: the teacher, its sampler, and the student's (sampler, steps, spacing), which
`Solver.default_spacing` follows. The poses, the noise and a pool's picks are drawn on the training device
(`--device cuda`: nothing copied from the CPU per step), and there a step that runs no teacher (the one-step
recipe's: no match or spread term, the reference from a pool) is replayed from one CUDA graph, as `ikdp.train`'s
steps are (ikdp/distill_step.py, ikdp/train_steps.py). A tqdm bar shows the loss; TensorBoard logs go beside
the checkpoint (`<folder>/logs/<stem>`); the checkpoint is written atomically every `--save-every` steps, at the end
and on Ctrl-C or SIGTERM; `--resume` continues from it; `--minutes` bounds the wall clock.
"""

from __future__ import annotations

import copy
import math
import shlex
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

import torch
from tqdm import tqdm

from ikdp.checkpoint import CheckpointError, read_checkpoint, remove_stale_temporaries, save_checkpoint
from ikdp.device import checked_device
from ikdp.distill_reference import PoseStream
from ikdp.distill_step import DistillLoss, runs_the_teacher, student_sampler
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.posterior_pool import check_posterior_target
from ikdp.priors import PosePrior
from ikdp.solver import load, model_from_checkpoint
from ikdp.train import parse_config, save_on_interrupt
from ikdp.train_budget import TrainingBudget
from ikdp.train_steps import EagerSteps, GraphedSteps, graph_applies, plain_optimizer_state


@dataclass(frozen=True)
class DistillConfig:
    """Distil an IKDP teacher into a student that samples in a few network evaluations."""

    teacher: str = "ikdp_n4"  # the teacher: a checkpoint path or a shipped model's name
    student_steps: int = 2  # network evaluations of the student's DDIM
    spacing: Literal["uniform", "quadratic"] = "quadratic"  # the student's timestep grid
    teacher_sampler: Literal["ddim", "dpmpp2m"] = "dpmpp2m"  # the teacher's deterministic sampler
    teacher_steps: int = 16  # its steps
    teacher_spacing: Literal["uniform", "quadratic"] = "quadratic"  # its grid
    # weight of the match to the teacher's ODE endpoint from the same noise (0: off, and the teacher's ODE is not run;
    # the distribution term then alone keeps the student's poses where the teacher's DDPM puts them)
    match_weight: float = 1.0
    # weight of the squared FK miss of the student's pose (training's consistency term; ikdp_n4's student's; 100 lost)
    tip_loss_weight: float = 2000.0
    # weight of the FK miss itself, its distance (smoothed below a millimetre; 0: off): the square's pull fades as a
    # pose nears its target, where the distribution term's pull does not
    tip_distance_weight: float = 0.0
    # weight of the spread term: the student's poses for one target as far apart on average as the teacher's from the
    # same noises (0: off). Without it a Panda student's K = 16 samples drew together (0.43 x the teacher's)
    spread_weight: float = 0.0
    noises_per_target: int = 1  # noises drawn for each target of a batch (the spread term needs 2 or more)
    # weight of the distribution term: the energy distance between a target's student poses and as many samples of
    # the teacher's DDPM for it, from other noises (0: off). Matching the teacher's ODE caps the student at the
    # ODE's fidelity, which on the relaxed planar model is 2-3 times further from the posterior than the DDPM's
    distribution_weight: float = 0.0
    # what the distribution term compares with: the teacher's DDPM samples, or the true posterior's, drawn by rejection
    # from the prior around the target (planar arms; needs --reference-pool): a student matched to the DDPM is capped
    # at the DDPM's distance from the posterior
    reference: Literal["teacher", "posterior"] = "teacher"
    # targets whose DDPM samples (noises_per_target each) are drawn once, before training, and reused by every step
    # (0: drawn afresh each step, where the teacher's DDPM costs most of a step)
    reference_pool: int = 0
    # damped least-squares steps taken from the teacher's pose before the student is asked to match it (0: none):
    # the goal then reaches the target in the teacher's own mode, so matching it and reaching the target agree
    refine_teacher_steps: int = 0
    # damped least-squares steps taken from each of the teacher's DDPM samples the distribution term compares with, in
    # its own mode (0: none): the student is then drawn toward the teacher's spread on the target, not off it
    refine_reference_steps: int = 0
    # what the student's network predicts: what its teacher's does, or the clean pose itself ("sample"). A
    # one-evaluation student of an epsilon teacher needs "sample": its x̂0 at t = T-1 divides the noise estimate's error
    # by sqrt(alpha-bar), 4.9e-4 for the Panda's schedule (2,000 times)
    student_prediction: Literal["teacher", "sample"] = "teacher"
    init: str = ""  # a student checkpoint of the same teacher to start from (empty: the teacher's weights)
    # a robot student with the denoiser's DLS skip (its gain, new and learnt, starts at 1 where the noise is small):
    # each evaluation may then add a damped least-squares step toward the target to its estimate
    dls_skip: bool = False
    steps: int = 2000  # optimizer steps (the run ends at this or at --minutes, whichever comes first)
    minutes: float = 0.0  # wall-clock budget of the whole run, resumes included (0: none)
    batch: int = 256  # poses per step
    lr: float = 1e-4  # peak learning rate (AdamW): the student starts from the teacher's weights
    warmup: int = 100  # linear warm-up steps, then cosine down to a tenth
    seed: int = 0  # seeds the data stream (poses and noise)
    device: str = "cpu"  # cpu, cuda, ...; the data (poses, noise, pool picks) is drawn there
    # each step replayed from one CUDA graph where one applies: --device cuda, and a step that runs no teacher (the
    # match and spread terms off, the distribution term's reference from a pool; ikdp/distill_step.py); elsewhere,
    # and with --no-graph, eager steps
    graph: bool = True
    threads: int = 0  # torch CPU threads; 0 leaves torch's default
    output: str = "runs/student.pt"  # the student's checkpoint
    log_dir: str = ""  # TensorBoard folder; empty: <output folder>/logs/<output stem>
    save_every: int = 200  # steps between checkpoints
    eval_targets: int = 500  # targets of the raw K = 1 accuracy measured at each save
    resume: bool = False  # continue from --output if it exists, with the config saved in it


def validate(config: DistillConfig) -> None:
    """ValueError naming the option when a value cannot distil."""
    positive = {"student_steps": config.student_steps, "teacher_steps": config.teacher_steps}
    positive |= {"batch": config.batch, "lr": config.lr, "save_every": config.save_every}  # steps: TrainingBudget
    positive |= {"noises_per_target": config.noises_per_target}
    for name, value in positive.items():
        if not value > 0:
            raise ValueError(f"{name}: got {value}, expected a positive number")
    nonnegative = {"threads": config.threads, "eval_targets": config.eval_targets}
    nonnegative |= {
        "refine_teacher_steps": config.refine_teacher_steps,
        "refine_reference_steps": config.refine_reference_steps,
        "distribution_weight": config.distribution_weight,
        "reference_pool": config.reference_pool,
    }
    nonnegative |= {"tip_loss_weight": config.tip_loss_weight, "spread_weight": config.spread_weight}
    nonnegative |= {"tip_distance_weight": config.tip_distance_weight}
    nonnegative |= {"match_weight": config.match_weight}
    for name, value in nonnegative.items():
        if value < 0:
            raise ValueError(f"{name}: got {value}, expected 0 or more")
    checked_device(config.device)  # before the teacher loads: the option as the user wrote it, in one line
    if config.batch % config.noises_per_target:
        raise ValueError(
            f"batch: got {config.batch}, expected a multiple of noises_per_target {config.noises_per_target}"
        )
    for name in ("spread_weight", "distribution_weight"):
        if getattr(config, name) > 0 and config.noises_per_target < 2:
            raise ValueError(f"{name}: needs noises_per_target 2 or more (pairs of poses for one target)")
    if config.match_weight == 0 and config.distribution_weight == 0:
        raise ValueError("match_weight: with 0 nothing ties the student to its teacher; give distribution_weight > 0")
    if config.refine_reference_steps > 0 and config.distribution_weight == 0:
        raise ValueError("refine_reference_steps: it refines the DDPM's samples; give distribution_weight > 0")
    if config.reference_pool > 0 and config.distribution_weight == 0:
        raise ValueError("reference_pool: the pool is the distribution term's reference; give distribution_weight > 0")
    if config.reference == "posterior":
        if config.distribution_weight == 0:
            raise ValueError("reference: the posterior feeds the distribution term; give distribution_weight > 0")
        if config.reference_pool == 0:
            raise ValueError("reference: posterior samples are drawn once, into a pool; give reference_pool > 0")
        if config.refine_reference_steps:
            raise ValueError("refine_reference_steps: the posterior's samples reach their targets already; leave it 0")


@torch.no_grad()
def measure_student(model: IKDiffusion, prior: PosePrior, config: DistillConfig, device: torch.device) -> dict:
    """The student's raw accuracy, its own sampler, K = 1, on `eval_targets` targets from the prior (fixed seed)."""
    arm = model.arm
    targets = arm.end_effector(prior.sample(config.eval_targets, arm, generator=torch.Generator().manual_seed(12345)))
    model.eval()
    poses = model.sample(
        targets.to(device),
        sampler="ddim",
        steps=config.student_steps,
        spacing=config.spacing,
        generator=torch.Generator(device).manual_seed(1),
    ).headings[:, 0]
    model.train()
    error = arm.tip_error(poses.cpu(), targets)
    metrics = {
        "eval_targets": config.eval_targets,
        "tip_error_median": float(error.median()),
        "tip_error_mean": float(error.mean()),
        "tip_error_p95": float(error.quantile(0.95)),
        "sampler": f"ddim {config.student_steps} steps ({config.spacing}) raw, K=1",
    }
    if arm.target_dim == 7:
        rotation = arm.rotation_error(poses.cpu(), targets)
        metrics.update(rotation_error_median=float(rotation.median()), rotation_error_mean=float(rotation.mean()))
    return metrics


SKIP_WEIGHTS = {"denoiser.step_gain.weight", "denoiser.step_gain.bias"}  # the DLS skip's gain: what --dls-skip adds


def student_network(
    teacher_payload: dict, teacher_path: str, dls_skip: bool, prediction: str = "teacher"
) -> IKDiffusion:
    """The teacher's network with its weights, to be trained as the student; with `dls_skip`, plus the DLS skip (its
    gain's new layer starts at zero, so the gain starts at its schedule: 1 at low noise, 0 at high); with `prediction`
    other than "teacher", its output read as that ("sample": the clean pose itself) from the first step on."""
    if not dls_skip and prediction == "teacher":
        return model_from_checkpoint(teacher_payload, teacher_path)
    description = copy.deepcopy(teacher_payload["model"])
    if dls_skip:
        denoiser = description.get("denoiser") or {}
        if denoiser.get("kind") != "chain_film":
            raise ValueError(
                f"dls_skip: for a robot's chain_film denoiser; {Path(teacher_path).stem} has {denoiser.get('kind')!r}"
            )
        if denoiser.get("dls_skip"):
            raise ValueError(f"dls_skip: {Path(teacher_path).stem} has the DLS skip already; leave the option out")
        denoiser["dls_skip"] = True
    if prediction != "teacher":
        description["prediction"] = prediction
    student = IKDiffusion(ModelConfig.from_dict(description))
    student.load_state_dict(model_from_checkpoint(teacher_payload, teacher_path).state_dict(), strict=False)
    return student


def starting_student(path: str, teacher_path: str, student: IKDiffusion) -> dict:
    """The weights of the student checkpoint `path` to start from; ValueError unless it is a student of the same
    teacher's file, with the student's network (the same weights' names and shapes: a config written by a later
    version of ikdp lists more defaults), or that network less the DLS skip's gain that `student` adds."""
    payload = read_checkpoint(path)  # CheckpointError names a missing or broken file
    record = payload.get("distill")
    if not isinstance(record, dict):
        raise ValueError(f"init: {path} is not a student (no distill record)")
    if Path(str(record.get("teacher_path", ""))).name != Path(teacher_path).name:
        raise ValueError(f"init: {path} is a student of {record.get('teacher')}, not of {Path(teacher_path).stem}")
    start = model_from_checkpoint(payload, path)

    def shapes(model: IKDiffusion) -> dict:
        return {name: tuple(value.shape) for name, value in model.state_dict().items()}

    wanted = shapes(student)
    if shapes(start) not in (wanted, {name: shape for name, shape in wanted.items() if name not in SKIP_WEIGHTS}):
        raise ValueError(f"init: {path} has another network than its teacher {Path(teacher_path).stem}")
    return start.state_dict()


def log_folder(config: DistillConfig) -> Path:
    output = Path(config.output)
    return Path(config.log_dir) if config.log_dir else output.parent / "logs" / output.stem


def distill(config: DistillConfig, command: str = "") -> Path:
    """Train the student and return its checkpoint's path."""
    validate(config)
    budget = TrainingBudget(config.steps, config.minutes, config.warmup)  # ValueError naming a bad one
    if config.threads:
        torch.set_num_threads(config.threads)
    device = torch.device(config.device)
    output = Path(config.output)
    teacher_solver = load(config.teacher, device=device)
    teacher_path = teacher_solver.metadata["path"]
    teacher_payload = read_checkpoint(teacher_path)
    teacher, prior = teacher_solver.model, teacher_solver.prior
    if config.reference == "posterior":
        check_posterior_target(teacher.arm, Path(teacher_path).stem)
    student = student_network(teacher_payload, teacher_path, config.dls_skip, config.student_prediction).to(device)
    if config.init and not (config.resume and output.exists()):
        student.load_state_dict(starting_student(config.init, teacher_path, student), strict=False)
    sampler = student_sampler(student, config)
    optimizer = torch.optim.AdamW(student.parameters(), lr=config.lr, weight_decay=0.0)
    data_generator = torch.Generator(device).manual_seed(config.seed)  # the data is made where the student trains
    step, seconds_before = 0, 0.0
    remove_stale_temporaries(output)
    if config.resume and output.exists():
        payload = read_checkpoint(output)
        student.load_state_dict(model_from_checkpoint(payload, str(output)).state_dict())
        optimizer.load_state_dict(payload["optimizer"])
        step, seconds_before = int(payload["train"]["step"]), float(payload["train"]["seconds"])
        saved_on = payload["train"].get("data_device", "cpu")  # runs before data was made on the GPU: the CPU
        if saved_on == device.type:
            data_generator.set_state(payload["data_generator"])
        else:  # a generator's state is its device's kind: a fresh stream, as `ikdp.train` takes on another device
            data_generator.manual_seed(config.seed + 1_000_003 * step)
            print(f"resuming on {device.type}, saved on {saved_on}: a new data stream")
        budget = budget.resumed(payload["train"], step, seconds_before)  # a longer budget decays on from here
        print(f"resuming {output} at step {step}", file=sys.stderr)

    try:
        from torch.utils.tensorboard import SummaryWriter  # imported late: slow, and only training needs it
    except ImportError:
        raise ValueError("TensorBoard is not installed: pip install 'ikdp[train]'") from None
    writer = SummaryWriter(str(log_folder(config)), purge_step=step)
    print(f"TensorBoard logs: {log_folder(config)}", file=sys.stderr)
    started = time.perf_counter()
    metrics: dict = {}

    def elapsed() -> float:
        return seconds_before + time.perf_counter() - started

    def save(final: bool) -> None:
        nonlocal metrics
        metrics = measure_student(student, prior, config, device) if config.eval_targets else {}
        metrics["step"] = step
        record = {**asdict(config), "step": step, "seconds": elapsed(), "finished": final, "lr_decay": budget.record()}
        record |= {"torch_version": str(torch.__version__), "threads": torch.get_num_threads(), "command": command}
        record["data_device"] = device.type  # where the data stream saved below draws
        save_checkpoint(
            output,
            {
                "model": student.config.to_dict(),
                "prior": prior.to_config(),
                "train": record,
                "metrics": metrics,
                "distill": {
                    "teacher": str(config.teacher),
                    # the file name: a path of the training machine means nothing elsewhere
                    "teacher_path": Path(teacher_path).name,
                    "teacher_metrics": teacher_payload["metrics"],
                    "teacher_train": teacher_payload["train"],
                    "teacher_sampler": config.teacher_sampler,
                    "teacher_steps": config.teacher_steps,
                    "teacher_spacing": config.teacher_spacing,
                    "sampler": "ddim",
                    "steps": config.student_steps,
                    "spacing": config.spacing,
                },
                "state_dict": student.state_dict(),
                "optimizer": plain_optimizer_state(optimizer),
                "data_generator": data_generator.get_state(),
            },
        )
        writer.add_scalar("eval/tip_error_median", metrics.get("tip_error_median", float("nan")), step)

    # a reference pool is drawn here, before the first step, or read where an earlier run of this teacher drew it
    stream = PoseStream(teacher, prior, config, device, teacher_path, pool_folder=output.parent / "reference_pools")
    loss = DistillLoss(student, teacher, sampler, config)
    draw = lambda: stream.draw(data_generator)  # noqa: E731  (poses (B, J), the reference's samples or None)
    if graph_applies(config.graph, device, world_size=1) and not runs_the_teacher(config):
        steps = GraphedSteps(loss, student, draw, data_generator, optimizer)
    else:
        steps = EagerSteps(loss, student, draw, data_generator, optimizer)
    interrupted = False
    progress = tqdm(total=config.steps, initial=step, desc=output.stem, dynamic_ncols=True)
    student.train()
    try:
        while not budget.finished(step, elapsed()):
            _, losses = steps(config.lr * budget.lr_factor(step, elapsed()))
            step += 1
            if step % 10 == 0:
                for name in ("loss", "teacher_match", "spread_miss", "energy_distance", "tip_distance"):
                    writer.add_scalar(f"train/{name}", float(losses[name]), step)
                writer.add_scalar("train/lr", float(optimizer.param_groups[0]["lr"]), step)
                progress.set_postfix(loss=f"{float(losses['loss']):.4f}", tip=f"{float(losses['tip_distance']):.4f}")
            progress.update(1)
            if step % config.save_every == 0:
                save(final=False)
    except KeyboardInterrupt:
        interrupted = True
    progress.close()
    save(final=not interrupted)
    writer.close()
    state = "interrupted, resumable with --resume" if interrupted else "done"
    print(f"{output}: {state} at step {step}; median tip error {metrics.get('tip_error_median', math.nan):.4g}")
    if interrupted:
        raise SystemExit(130)
    return output


def main(argv: list[str] | None = None) -> None:
    save_on_interrupt()
    arguments = sys.argv[1:] if argv is None else argv
    try:
        config = parse_config(argv, DistillConfig, "ikdp-distill")  # with --resume, the saved config's defaults
        distill(config, command=shlex.join(["python", "-m", "ikdp.distill", *arguments]))
    except (ValueError, CheckpointError) as error:
        print(f"ikdp-distill: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
