"""Models the evaluation trains for itself, cached on disk under a folder the user names.

The paper-denoiser variants of Tables I and II go through ikdp's own `train`; the
learned baselines (MLP, Neural IK) are trained here. A cache entry's file name
holds every setting that shaped it, so a changed setting trains afresh.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

import torch
from tqdm import tqdm

import ikdp
from ikdp.baselines.mlp import MLPConfig, mlp_from_state, mlp_state, train_mlp
from ikdp.baselines.neural_ik import NeuralIKConfig, neural_ik_from_state, neural_ik_state, train_neural_ik
from ikdp.priors import PosePrior
from ikdp.train import TrainConfig, train

PAPER_TRAINING = dict(denoiser="paper", representation="angle", tip_loss_weight=0.0, snr_gamma=0.0, prediction="sample")


def paper_training_settings(reference_checkpoint: Path | None) -> dict:
    """The training settings of the shipped paper-denoiser checkpoint when there is one (so the variants
    differ from it only in joints, T and budget), else the paper's: transformer, raw theta, MSE on theta."""
    settings = dict(PAPER_TRAINING)
    if reference_checkpoint is not None and reference_checkpoint.exists():
        recorded = ikdp.load(reference_checkpoint).metadata["train"]
        names = {field.name for field in fields(TrainConfig)}
        keep = {"denoiser", "representation", "tip_loss_weight", "snr_gamma", "prediction", "schedule", "lr", "warmup"}
        settings.update({key: value for key, value in recorded.items() if key in names and key in keep})
    return settings


def ikdp_training_config(
    cache_dir: Path,
    *,
    joints: int,
    timesteps: int,
    steps: int,
    batch: int,
    seed: int,
    threads: int,
    settings: dict,
    prior: str = "uniform",
    hidden: int | None = None,
    tag: str = "paper",
) -> TrainConfig:
    """The TrainConfig of a cached IKDP model; its output file name holds every setting that shapes it."""
    digest = hashlib.sha1(repr(sorted(settings.items())).encode()).hexdigest()[:6]  # the training settings
    stem = f"{tag}_n{joints}_T{timesteps}_{prior}_s{steps}_b{batch}_seed{seed}_{digest}"
    overrides = dict(
        joints=joints,
        timesteps=timesteps,
        steps=steps,
        batch=batch,
        seed=seed,
        threads=threads,
        prior=prior,
        output=str(cache_dir / f"{stem}.pt"),
        log_dir=str(cache_dir / "logs" / stem),
        eval_targets=0,
        save_every=10**9,
        warmup=min(settings.get("warmup", 500), max(1, steps // 10)),
    )
    config = replace(TrainConfig(), **{**settings, **overrides})
    if hidden is not None:
        config = replace(config, hidden=hidden, blocks=1)
    return config


def cached_ikdp(cache_dir: Path, **arguments) -> Path:
    """Train (once, in this process) an IKDP model; returns its checkpoint path."""
    config = ikdp_training_config(cache_dir, **arguments)
    if not Path(config.output).exists():
        train(config)  # its own tqdm bar shows the progress
    return Path(config.output)


def _command_line(config: TrainConfig) -> list[str]:
    command = [sys.executable, "-m", "ikdp.train"]
    for field in fields(TrainConfig):
        value = getattr(config, field.name)
        flag = "--" + field.name.replace("_", "-")
        if isinstance(value, bool):
            command.append(flag if value else "--no-" + field.name.replace("_", "-"))
        elif isinstance(value, tuple):
            command += [flag, *map(str, value)]
        elif value is not None:
            command += [flag, str(value)]
    return command


def train_in_parallel(configs: list[TrainConfig], workers: int) -> None:
    """Train the configs whose output is missing, `workers` single-threaded `ikdp.train` processes at a time.

    Small models use a second thread poorly; two processes of one thread each use both cores.
    Each run's output goes to <output>.log beside its checkpoint.
    """
    if workers <= 1:  # in this process: no second interpreter to start (seconds each on a busy machine)
        for config in tqdm(configs, desc="training IKDP variants", leave=False):
            if not Path(config.output).exists():
                train(config)
        return
    todo = [replace(config, threads=1) for config in configs if not Path(config.output).exists()]
    running: list[tuple[subprocess.Popen, TrainConfig, object]] = []
    progress = tqdm(total=len(todo), desc="training IKDP variants", leave=False)
    while todo or running:
        while todo and len(running) < max(1, workers):
            config = todo.pop(0)
            Path(config.output).parent.mkdir(parents=True, exist_ok=True)
            log = open(f"{config.output}.log", "w")  # noqa: SIM115 (closed when the process ends)
            running.append((subprocess.Popen(_command_line(config), stdout=log, stderr=subprocess.STDOUT), config, log))
        time.sleep(0.5)
        for entry in list(running):
            process, config, log = entry
            if process.poll() is None:
                continue
            log.close()
            running.remove(entry)
            progress.update()
            if process.returncode != 0:
                raise RuntimeError(
                    f"training {config.output} failed (exit {process.returncode}); see {config.output}.log"
                )
    progress.close()


def cached_baseline(
    kind: str, cache_dir: Path, prior: PosePrior, lengths: torch.Tensor, *, steps: int, batch: int, seed: int
):
    """Train (once) the MLP or the Neural IK baseline on poses from `prior`; returns the model."""
    num_links = lengths.shape[0]
    path = cache_dir / f"{kind}_n{num_links}_{prior.kind}_s{steps}_b{batch}_seed{seed}.pt"
    if path.exists():
        state = torch.load(path, weights_only=True)
        return mlp_from_state(state) if kind == "mlp" else neural_ik_from_state(state)
    if kind == "mlp":
        model = train_mlp(MLPConfig(num_links=num_links, steps=steps, batch=batch), prior, lengths, seed=seed)
        state = mlp_state(model)
    else:
        model = train_neural_ik(
            NeuralIKConfig(num_links=num_links, steps=steps, batch=batch), prior, lengths, seed=seed
        )
        state = neural_ik_state(model)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(state, path)
    return model
