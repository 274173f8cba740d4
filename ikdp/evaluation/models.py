"""The data stage: every model the evaluation measures, loaded or trained.

The shipped checkpoints (or, in a quick run, small stand-ins trained where they are
missing), the paper-denoiser variants of Tables I and II, and the learned baselines.
Whatever must be trained is trained once, into the cache, in one pool of processes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import ikdp
from ikdp.arm import PlanarArm
from ikdp.evaluation.cache import config_digest, file_digest
from ikdp.evaluation.training import IKDPJob, baseline_job, ikdp_job, paper_training_settings, train_missing
from ikdp.priors import PosePrior

FIDELITY_JOINTS = 4  # the arm of the fidelity study and of Table III
STANDIN_SETTINGS = {"denoiser": "paper", "representation": "angle", "tip_loss_weight": 0.0, "snr_gamma": 0.0}


@dataclass(frozen=True)
class Sizes:
    joints: tuple[int, ...] = (2, 4, 8)  # arms evaluated (Table I)
    table2_timesteps: tuple[int, ...] = (40, 80, 100)  # T of the Table II variants (N = 4)
    accuracy_targets: int = 1000  # targets per target set, one solution each
    diversity_targets: int = 200  # targets for the diversity measure
    diversity_samples: int = 32  # K for diversity and the fans
    fidelity_targets: int = 64  # targets with a rejection-sampled reference
    fidelity_samples: int = 128  # K per target for MMD, and the size of each reference set
    reference_radius: float = 0.02  # rejection radius, as a fraction of the reach
    runtime_batch: int = 1000  # batch for the per-target runtime
    runtime_repeats: tuple[int, int] = (20, 3)  # repeats: single target, batch
    variant_steps: int = 2500  # training steps of each Table I/II paper-denoiser variant
    variant_batch: int = 256  # their batch
    baseline_steps: int = 2000  # MLP and Neural IK training steps
    baseline_batch: int = 512  # their batch
    standin_steps: int = 0  # 0: shipped checkpoints must exist; >0: train stand-ins this long where missing


FULL = Sizes()
QUICK = Sizes(
    accuracy_targets=64,
    diversity_targets=8,
    diversity_samples=8,
    fidelity_targets=4,
    fidelity_samples=16,
    reference_radius=0.05,
    runtime_batch=64,
    runtime_repeats=(3, 1),
    variant_steps=20,
    variant_batch=32,
    baseline_steps=30,
    baseline_batch=64,
    standin_steps=30,
)


@dataclass(frozen=True)
class ShippedModel:
    role: str  # its key in results["checkpoints"]
    stem: str  # its file name in the checkpoints folder, without .pt
    joints: int  # N
    prior: str  # the prior it was trained on: uniform or relaxed
    paper_denoiser: bool = False  # trained with the paper's denoiser and loss (a stand-in copies that)


def shipped_models(joints: tuple[int, ...]) -> list[ShippedModel]:
    """Our default model for each arm, the paper-denoiser model and the relaxed-prior model (N = 4)."""
    models = [ShippedModel(f"default_n{n}", f"ikdp_n{n}", n, "uniform") for n in joints]
    models.append(ShippedModel("paper_n4", "ikdp_paper_n4", FIDELITY_JOINTS, "uniform", paper_denoiser=True))
    models.append(ShippedModel("relaxed_n4", "ikdp_n4_relaxed", FIDELITY_JOINTS, "relaxed"))
    return models


@dataclass
class Models:
    """Every model of one evaluation, and what the report says about them."""

    default: dict[int, ikdp.Solver]  # joints -> our default model
    paper: ikdp.Solver  # the paper-denoiser model, N = 4
    relaxed: ikdp.Solver  # the relaxed-prior model, N = 4
    variants: dict[tuple[int, int], ikdp.Solver]  # (joints, T) -> paper-denoiser variant of Table I or II
    baselines: dict[tuple[str, int, str], object]  # (kind, joints, prior kind) -> MLP or Neural IK
    descriptions: dict[str, str]  # role -> where the checkpoint came from, for the report
    log_folders: dict[str, Path]  # label -> TensorBoard folder of each shipped model (or stand-in)
    variant_training: dict  # the variants' training settings and budget, for the report
    baseline_training: dict  # the baselines' budget, for the report
    fingerprint: str = field(default="")  # digest of every model used: keys the stage results computed from them


def _describe(path: Path, solver: ikdp.Solver) -> str:
    train = solver.metadata["train"]
    state = "" if train.get("finished") else ", unfinished"
    return f"{path} (step {train.get('step')} of {train.get('steps')}{state})"


def load_models(sizes: Sizes, *, checkpoints: Path, cache_dir: Path, seed: int, workers: int) -> Models:
    """The data stage: load the shipped models, train (once, cached) what is missing, load the rest."""
    shipped = shipped_models(sizes.joints)
    standins: dict[str, IKDPJob] = {}
    for model in shipped:
        path = checkpoints / f"{model.stem}.pt"
        if path.exists():
            continue
        if not sizes.standin_steps:
            hint = "train it first, or use --quick for stand-ins"
            raise FileNotFoundError(f"{path}: shipped checkpoint missing ({hint})")
        standins[model.role] = ikdp_job(
            cache_dir,
            label="standin_" + model.stem,
            joints=model.joints,
            timesteps=20,
            steps=sizes.standin_steps,
            batch=64,
            seed=seed,
            settings=STANDIN_SETTINGS if model.paper_denoiser else {},
            prior=model.prior,
            hidden=32,
        )
    files = {model.role: checkpoints / f"{model.stem}.pt" for model in shipped}
    # the relaxed baseline learns the relaxed model's own prior; a stand-in trains on the default spread
    relaxed_prior = ikdp.load(files["relaxed_n4"]).prior if files["relaxed_n4"].exists() else PosePrior("relaxed")
    paper_settings = paper_training_settings(files["paper_n4"])
    variant_grid = sorted({(n, 80) for n in sizes.joints} | {(FIDELITY_JOINTS, t) for t in sizes.table2_timesteps})
    variant_jobs = {
        (n, t): ikdp_job(
            cache_dir,
            label="paper",
            joints=n,
            timesteps=t,
            steps=sizes.variant_steps,
            batch=sizes.variant_batch,
            seed=seed,
            settings=paper_settings,
        )
        for n, t in variant_grid
    }
    budget = dict(steps=sizes.baseline_steps, batch=sizes.baseline_batch, seed=seed)
    uniform = PosePrior("uniform")
    baseline_specs = [(kind, n, uniform) for n in sizes.joints for kind in ("mlp", "neural_ik")]
    baseline_specs.append(("neural_ik", FIDELITY_JOINTS, relaxed_prior))
    baseline_jobs = {
        (kind, n, prior.kind): baseline_job(kind, cache_dir, prior, PlanarArm((1.0,) * n), **budget)
        for kind, n, prior in baseline_specs
    }
    train_missing([*standins.values(), *variant_jobs.values(), *baseline_jobs.values()], workers=workers)

    solvers, descriptions, log_folders, identities = {}, {}, {}, []
    for model in shipped:
        path = files[model.role]
        if model.role in standins:
            job = standins[model.role]
            solvers[model.role] = ikdp.load(job.output)
            descriptions[model.role] = f"{job.output} (stand-in: {path} missing)"
            log_folders[job.output.stem] = Path(job.config.log_dir)
            identities.append(job.output.name)
        else:
            solvers[model.role] = ikdp.load(path)
            descriptions[model.role] = _describe(path, solvers[model.role])
            log_folders[model.stem] = checkpoints / "logs" / model.stem
            identities.append(file_digest(path))
    relaxed = solvers["relaxed_n4"]
    if relaxed.prior.kind != "relaxed":
        raise ValueError(f"{descriptions['relaxed_n4']}: expected a relaxed-prior model, got {relaxed.prior.kind}")
    identities += [job.output.name for job in (*variant_jobs.values(), *baseline_jobs.values())]
    return Models(
        default={n: solvers[f"default_n{n}"] for n in sizes.joints},
        paper=solvers["paper_n4"],
        relaxed=relaxed,
        variants={key: ikdp.load(job.output) for key, job in variant_jobs.items()},
        baselines={key: job.load() for key, job in baseline_jobs.items()},
        descriptions=descriptions,
        log_folders=log_folders,
        variant_training={"settings": paper_settings, "steps": sizes.variant_steps, "batch": sizes.variant_batch},
        baseline_training={
            "steps": sizes.baseline_steps,
            "batch": sizes.baseline_batch,
            "optimizer": "Adam 1e-3, cosine",
        },
        fingerprint=config_digest(identities),
    )
