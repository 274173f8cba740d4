"""Models the evaluation trains for itself, cached on disk under a folder the user names.

The paper-denoiser variants of Tables I and II go through ikdp's own `train`; the
learned baselines (MLP, Neural IK) are trained here. A cache entry's file name
holds every setting that shaped it, so a changed setting trains afresh.
"""

from __future__ import annotations

import hashlib
import os
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


def run_in_parallel(jobs: list[tuple[Path, list[str]]], workers: int) -> None:
    """Run the (output, command) jobs whose output is missing, `workers` single-threaded processes at a time.

    Small models use a second thread poorly; two processes of one thread each use both cores.
    Each job's output goes to <output>.log beside its result.
    """
    todo = [(Path(output), command) for output, command in jobs if not Path(output).exists()]
    running: list = []
    progress = tqdm(total=len(todo), desc=f"training ({workers} processes)", leave=False)
    environment = {**os.environ, "OMP_NUM_THREADS": "1"}
    while todo or running:
        while todo and len(running) < max(1, workers):
            output, command = todo.pop(0)
            output.parent.mkdir(parents=True, exist_ok=True)
            log = open(f"{output}.log", "w")  # noqa: SIM115 (closed when the process ends)
            process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=environment)
            running.append((process, output, log))
        time.sleep(0.5)
        for entry in list(running):
            process, output, log = entry
            if process.poll() is None:
                continue
            log.close()
            running.remove(entry)
            progress.update()
            if process.returncode != 0:
                raise RuntimeError(f"training {output} failed (exit {process.returncode}); see {output}.log")
    progress.close()


def ikdp_job(config: TrainConfig) -> tuple[Path, list[str]]:
    return Path(config.output), _command_line(replace(config, threads=1))


def baseline_path(kind: str, cache_dir: Path, prior: PosePrior, num_links: int, steps: int, batch: int, seed: int):
    return Path(cache_dir) / f"{kind}_n{num_links}_{prior.kind}_s{steps}_b{batch}_seed{seed}.pt"


def baseline_job(
    kind: str, cache_dir: Path, prior: PosePrior, lengths: torch.Tensor, *, steps: int, batch: int, seed: int
):
    """A job for run_in_parallel that trains one baseline (uniform or relaxed prior) in its own process."""
    if prior.kind not in ("uniform", "relaxed"):
        raise ValueError(f"prior: baselines train in a separate process for uniform or relaxed, got {prior.kind!r}")
    output = baseline_path(kind, cache_dir, prior, lengths.shape[0], steps, batch, seed)
    command = [
        sys.executable,
        "-m",
        "ikdp.evaluation.training",
        kind,
        str(cache_dir),
        prior.kind,
        repr(prior.relaxed_std),
    ]
    command += [str(steps), str(batch), str(seed), *map(repr, lengths.tolist())]
    return output, command


def cached_baseline(
    kind: str, cache_dir: Path, prior: PosePrior, lengths: torch.Tensor, *, steps: int, batch: int, seed: int
):
    """Train (once) the MLP or the Neural IK baseline on poses from `prior`; returns the model."""
    num_links = lengths.shape[0]
    path = baseline_path(kind, cache_dir, prior, num_links, steps, batch, seed)
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


if (
    __name__ == "__main__"
):  # one baseline, for run_in_parallel: kind cache prior relaxed_std steps batch seed lengths...
    kind, cache, prior_kind, relaxed_std, steps, batch, seed, *bone_lengths = sys.argv[1:]
    torch.set_num_threads(1)
    cached_baseline(
        kind,
        Path(cache),
        PosePrior(kind=prior_kind, relaxed_std=float(relaxed_std)),
        torch.tensor([float(length) for length in bone_lengths]),
        steps=int(steps),
        batch=int(batch),
        seed=int(seed),
    )
