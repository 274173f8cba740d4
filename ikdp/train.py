"""Train an IKDP model: `python -m ikdp.train --joints 4 --output checkpoints/ikdp_n4.pt`.

Data is generated on the fly (poses from the prior, targets by FK), as in the
paper's Algorithm 1. A tqdm bar shows the running loss; TensorBoard gets the
paper's two curves (loss on theta, tip distance of the prediction) and the
learning rate. The checkpoint is written atomically at intervals, at the end and
on Ctrl-C; `--resume` continues from it with the same data stream.
"""

from __future__ import annotations

import math
import signal
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from tqdm import tqdm

from ikdp._cli import parse_into
from ikdp.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from ikdp.denoisers import DenoiserConfig
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior, make_prior
from ikdp.schedule import ScheduleConfig
from ikdp.solver import model_from_checkpoint


@dataclass(frozen=True)
class TrainConfig:
    joints: int = 4  # number of links N
    lengths: tuple[float, ...] | None = None  # bone lengths, one per link; default all 1
    timesteps: int = 80  # diffusion steps T
    schedule: str = "linear"  # beta schedule: linear or cosine
    denoiser: str = "film"  # film (ours) or paper (the paper's transformer)
    representation: str = "cossin"  # cossin (wrap-free) or angle (the paper's raw theta)
    prediction: str = "sample"  # the denoiser predicts sample (x_0) or epsilon
    hidden: int = 128  # film: MLP width
    blocks: int = 3  # film: residual blocks
    kinematic_until: int = 0  # film: give the tip miss and DLS step features only at t < this (0: every t)
    ema: float = 0.0  # decay of an exponential moving average of the weights, saved for solving (0: none)
    prior: str = "uniform"  # pose prior: uniform, relaxed, or a .npy/.csv file of relative joint angles
    tip_loss_weight: float = 100.0  # weight of the FK-consistency term (squared tip miss / reach^2); 0 = paper
    snr_gamma: float = 5.0  # Min-SNR loss weighting min(SNR, gamma)/gamma; 0 = uniform over t, the paper's
    steps: int = 20_000  # optimizer steps
    batch: int = 1024  # poses per step
    lr: float = 1e-3  # peak learning rate (AdamW), cosine decay to a tenth
    warmup: int = 500  # linear warmup steps
    seed: int = 0  # seeds the weights and the data stream
    device: str = "cpu"  # cpu, cuda, cuda:1, ...
    threads: int = 0  # torch CPU threads; 0 leaves torch's default
    output: str = "checkpoints/model.pt"  # checkpoint path
    log_dir: str = ""  # TensorBoard folder; default runs/<output stem>
    save_every: int = 1000  # steps between checkpoints
    eval_targets: int = 500  # targets in the accuracy measured at each save
    resume: bool = False  # continue from --output if it exists


def build_model(config: TrainConfig) -> IKDiffusion:
    lengths = config.lengths or (1.0,) * config.joints
    if len(lengths) != config.joints:
        raise ValueError(f"lengths: got {len(lengths)} bone lengths for {config.joints} joints")
    model_config = ModelConfig(
        lengths=tuple(float(length) for length in lengths),
        representation=config.representation,
        prediction=config.prediction,
        schedule=ScheduleConfig(timesteps=config.timesteps, kind=config.schedule),
        denoiser=DenoiserConfig(
            kind=config.denoiser, hidden=config.hidden, blocks=config.blocks, kinematic_until=config.kinematic_until
        ),
    )
    return IKDiffusion(model_config)


def learning_rate_factor(step: int, config: TrainConfig) -> float:
    if step < config.warmup:
        return (step + 1) / config.warmup
    progress = (step - config.warmup) / max(1, config.steps - config.warmup)
    return 0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * min(1.0, progress)))


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
    return {
        "eval_targets": count,
        "tip_error_median": float(error.median()),
        "tip_error_mean": float(error.mean()),
        "tip_error_p95": float(error.quantile(0.95)),
        "sampler": "ddpm raw, K=1",
    }


def train(config: TrainConfig) -> Path:
    if config.threads:
        torch.set_num_threads(config.threads)
    device = torch.device(config.device)
    output = Path(config.output)
    torch.manual_seed(config.seed)
    model = build_model(config).to(device)
    prior = make_prior(config.prior, config.joints)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=0.0)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda step: learning_rate_factor(step, config))
    data_generator = torch.Generator().manual_seed(config.seed)
    step, seconds_before = 0, 0.0
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
        scheduler.load_state_dict(payload["scheduler"])
        data_generator.set_state(payload["data_generator"])
        step = int(payload["train"]["step"])
        seconds_before = float(payload["train"]["seconds"])
        print(f"resuming {output} at step {step}", file=sys.stderr)

    from torch.utils.tensorboard import SummaryWriter  # imported late: slow, and only training needs it

    log_dir = Path(config.log_dir or Path("runs") / output.stem)
    writer = SummaryWriter(str(log_dir), purge_step=step)
    started = time.perf_counter()
    metrics: dict = {}

    def save(final: bool) -> None:
        nonlocal metrics
        solving_model = averaged.module if averaged is not None else model
        metrics = measure_accuracy(solving_model, prior, config.eval_targets, device) if config.eval_targets else {}
        metrics["step"] = step
        train_record = {**asdict(config), "step": step, "seconds": seconds_before + time.perf_counter() - started}
        train_record["finished"] = final
        train_record["torch_version"] = str(torch.__version__)
        train_record["threads"] = torch.get_num_threads()
        save_checkpoint(
            output,
            {
                "model": model.config.to_dict(),
                "prior": prior.to_config(),
                "train": train_record,
                "metrics": metrics,
                "state_dict": solving_model.state_dict(),
                **({"raw_state_dict": model.state_dict()} if averaged is not None else {}),
                "optimizer": optimizer.state_dict(),
                "scheduler": scheduler.state_dict(),
                "data_generator": data_generator.get_state(),
            },
        )
        writer.add_scalar("eval/tip_error_median", metrics.get("tip_error_median", float("nan")), step)

    interrupted = False
    progress = tqdm(total=config.steps, initial=step, desc=output.stem, dynamic_ncols=True)
    model.train()
    try:
        while step < config.steps:
            headings = prior.sample(config.batch, model.arm, generator=data_generator).to(device)
            losses = model.compute_loss(
                headings, tip_loss_weight=config.tip_loss_weight, snr_gamma=config.snr_gamma, generator=data_generator
            )
            optimizer.zero_grad(set_to_none=True)
            losses["loss"].backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            optimizer.step()
            scheduler.step()
            if averaged is not None:
                averaged.update_parameters(model)
            step += 1
            if step % 50 == 0 or step == config.steps:
                writer.add_scalar("train/theta_loss", float(losses["theta_loss"]), step)
                writer.add_scalar("train/tip_distance", float(losses["tip_distance"]), step)
                writer.add_scalar("train/lr", scheduler.get_last_lr()[0], step)
                progress.set_postfix(
                    loss=f"{float(losses['theta_loss']):.4f}", tip=f"{float(losses['tip_distance']):.4f}"
                )
            progress.update(1)
            if step % config.save_every == 0 and step < config.steps:
                save(final=False)
    except KeyboardInterrupt:
        interrupted = True
    progress.close()
    save(final=not interrupted)
    writer.close()
    state = "interrupted, resumable with --resume" if interrupted else "done"
    print(
        f"{output}: {state} at step {step}; median tip error {metrics.get('tip_error_median', float('nan')):.4g}",
        file=sys.stderr,
    )
    if interrupted:
        raise SystemExit(130)
    return output


def main(argv: list[str] | None = None) -> None:
    config = parse_into(TrainConfig, "Train an IKDP conditional diffusion model for a planar N-link arm.", argv)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a kill saves a checkpoint as Ctrl-C does
    try:
        train(config)
    except (ValueError, CheckpointError) as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
