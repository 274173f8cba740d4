"""Models the evaluation trains for itself, cached on disk under a folder the user names.

Two kinds of job: an IKDP model (the paper-denoiser variants of Tables I and II, and
the small stand-ins of a quick run) trained by ikdp's own `train`, and a learned
baseline (MLP, Neural IK). Each job's cache file is named by the digest of its whole
configuration (ikdp.evaluation.cache), so a changed setting trains afresh. Missing
jobs run in a pool of single-threaded processes: small models use a second thread
poorly, and two processes of one thread each use both cores.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, fields, replace
from pathlib import Path

import torch
from tqdm import tqdm

import ikdp
from ikdp.arm import PlanarArm
from ikdp.baselines.mlp import MLPConfig, mlp_from_state, mlp_state, train_mlp
from ikdp.baselines.neural_ik import NeuralIKConfig, neural_ik_from_state, neural_ik_state, train_neural_ik
from ikdp.evaluation.cache import config_digest
from ikdp.evaluation.pool import single_threaded_pool
from ikdp.priors import PosePrior
from ikdp.train import TrainConfig, train

PAPER_TRAINING = dict(denoiser="paper", representation="angle", tip_loss_weight=0.0, snr_gamma=0.0, prediction="sample")
# the shipped paper checkpoint's settings the variants copy
RECORDED_SETTINGS = ("denoiser", "representation", "tip_loss_weight", "snr_gamma", "prediction", "schedule", "lr")
RECORDED_SETTINGS += ("warmup",)
# TrainConfig fields that say where and how fast a model trains, not what it learns: left out of its cache key
NOT_IN_KEY = ("output", "log_dir", "threads", "device", "graph", "resume", "save_every")


def paper_training_settings(reference_checkpoint: Path | None) -> dict:
    """The training settings of the shipped paper-denoiser checkpoint when there is one (so the variants
    differ from it only in joints, T and budget), else the paper's: transformer, raw theta, MSE on theta."""
    settings = dict(PAPER_TRAINING)
    if reference_checkpoint is not None and reference_checkpoint.exists():
        recorded = ikdp.load(reference_checkpoint).metadata["train"]
        names = {field.name for field in fields(TrainConfig)}
        settings.update({key: value for key, value in recorded.items() if key in names and key in RECORDED_SETTINGS})
    return settings


@dataclass(frozen=True)
class IKDPJob:
    """One IKDP model to train; its output path holds the digest of every setting that shapes it."""

    config: TrainConfig  # the full training configuration, output and log_dir included

    @property
    def joints(self) -> int:
        return self.config.joints

    @property
    def output(self) -> Path:
        return Path(self.config.output)

    def run(self) -> None:
        train(self.config)


def ikdp_job(
    cache_dir: Path,
    *,
    label: str,
    joints: int,
    timesteps: int,
    steps: int,
    batch: int,
    seed: int,
    settings: dict,
    prior: str = "uniform",
    hidden: int | None = None,
) -> IKDPJob:
    """The job of a cached IKDP model; `label` starts its file name (for people), the digest ends it."""
    overrides = dict(
        joints=joints,
        timesteps=timesteps,
        steps=steps,
        batch=batch,
        seed=seed,
        threads=1,
        prior=prior,
        eval_targets=0,
        save_every=10**9,
        warmup=min(settings.get("warmup", 500), max(1, steps // 10)),
    )
    config = replace(TrainConfig(), **{**settings, **overrides})
    if hidden is not None:
        config = replace(config, hidden=hidden, blocks=1)
    digest = config_digest({name: value for name, value in vars(config).items() if name not in NOT_IN_KEY})
    stem = f"{label}_n{joints}_T{timesteps}_{prior}_{digest}"
    config = replace(config, output=str(Path(cache_dir) / f"{stem}.pt"), log_dir=str(Path(cache_dir) / "logs" / stem))
    return IKDPJob(config)


@dataclass(frozen=True)
class BaselineJob:
    """One learned baseline to train: the model's config, the arm, the prior and the seed."""

    kind: str  # "mlp" or "neural_ik"
    model: MLPConfig | NeuralIKConfig  # the network and its training budget
    lengths: tuple[float, ...]  # the arm's bone lengths
    prior_kind: str  # "uniform" or "relaxed": the poses it learns from
    relaxed_std: float  # the relaxed prior's spread (keyed even for uniform, which ignores it)
    seed: int  # seeds the weights and the data stream
    cache_dir: str  # folder of the cached state

    def __post_init__(self):
        if self.kind not in ("mlp", "neural_ik"):
            raise ValueError(f"kind: expected 'mlp' or 'neural_ik', got {self.kind!r}")
        if self.prior_kind not in ("uniform", "relaxed"):
            raise ValueError(f"prior_kind: baselines train on 'uniform' or 'relaxed' poses, got {self.prior_kind!r}")

    @property
    def joints(self) -> int:
        return len(self.lengths)

    @property
    def prior(self) -> PosePrior:
        return PosePrior(kind=self.prior_kind, relaxed_std=self.relaxed_std)

    @property
    def output(self) -> Path:
        digest = config_digest(replace(self, cache_dir=""))
        return Path(self.cache_dir) / f"{self.kind}_n{self.joints}_{self.prior_kind}_{digest}.pt"

    def run(self) -> None:
        arm = PlanarArm(self.lengths)
        if self.kind == "mlp":
            state = mlp_state(train_mlp(self.model, self.prior, arm, seed=self.seed))
        else:
            state = neural_ik_state(train_neural_ik(self.model, self.prior, arm, seed=self.seed))
        self.output.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.output.with_suffix(".partial")
        torch.save(state, temporary)
        temporary.replace(self.output)  # a killed run leaves no half-written file under the cached name

    def load(self):
        """The trained model; ValueError if it has not been trained."""
        if not self.output.exists():
            raise ValueError(f"baseline {self.output}: not trained yet (run its job first)")
        state = torch.load(self.output, weights_only=True)
        return mlp_from_state(state) if self.kind == "mlp" else neural_ik_from_state(state)


def baseline_job(
    kind: str, cache_dir: Path, prior: PosePrior, arm: PlanarArm, *, steps: int, batch: int, seed: int
) -> BaselineJob:
    """The job of the MLP or Neural IK baseline for `arm`, trained on poses from `prior`."""
    config_class = MLPConfig if kind == "mlp" else NeuralIKConfig
    return BaselineJob(
        kind=kind,
        model=config_class(num_links=arm.num_joints, steps=steps, batch=batch),
        lengths=arm.lengths,
        prior_kind=prior.kind,
        relaxed_std=float(prior.relaxed_std),
        seed=seed,
        cache_dir=str(cache_dir),
    )


Job = IKDPJob | BaselineJob


def _run_quietly(job: Job) -> Path:
    """Run one job in a worker process, its progress bars and prints into <output>.log."""
    torch.set_num_threads(1)
    job.output.parent.mkdir(parents=True, exist_ok=True)
    with open(f"{job.output}.log", "w") as log, contextlib.redirect_stderr(log), contextlib.redirect_stdout(log):
        job.run()
    return job.output


def train_missing(jobs: list[Job], *, workers: int) -> list[Path]:
    """Run the jobs whose output is missing; returns the outputs trained.

    With workers > 1 and more than one job to do, they run in a pool of `workers`
    single-threaded processes, the longest (most joints) first; otherwise here, in turn.
    """
    if workers < 1:
        raise ValueError(f"workers: expected a positive integer, got {workers}")
    todo = sorted({job.output: job for job in jobs if not job.output.exists()}.values(), key=lambda job: -job.joints)
    if workers == 1 or len(todo) < 2:
        threads = torch.get_num_threads()
        for job in tqdm(todo, desc="training", leave=False):
            job.run()
            torch.set_num_threads(threads)  # a training sets its own thread count; the evaluation keeps ours
        return [job.output for job in todo]
    with single_threaded_pool(workers) as pool:
        futures = [pool.submit(_run_quietly, job) for job in todo]
        for future in tqdm(futures, desc=f"training ({workers} processes)", leave=False):
            future.result()  # a failed job raises here; its log is at <output>.log
    return [job.output for job in todo]
