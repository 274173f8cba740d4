"""The measuring stages of the evaluation, each a function from the models to a typed result.

Every result holds JSON-ready values only, its field names are the keys it fills in
results.json, so a result can be cached and read back (`to_json` / `from_json`) and
the report is the union of them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import torch
from tqdm import tqdm

from ikdp.evaluation import experiments
from ikdp.evaluation.methods import (
    Method,
    classical_methods,
    dls_from_prior,
    ikdp_method,
    ikdp_variants,
    learned_method,
    random_pose,
    random_start_methods,
)
from ikdp.evaluation.mmd import mmd2
from ikdp.evaluation.models import FIDELITY_JOINTS, Models, Sizes
from ikdp.evaluation.reference import rejection_reference, targets_from_prior, targets_in_disk
from ikdp.priors import PosePrior
from ikdp.schedule import DiffusionSchedule, ScheduleConfig

UNIFORM = PosePrior("uniform")
FANS = 3  # targets drawn per method in the solution-fans figure


class StageResult:
    """A stage's output: JSON-ready fields named as the results.json keys they fill."""

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict):
        return cls(**{field.name: data[field.name] for field in dataclasses.fields(cls)})


def arm_methods(models: Models, joints: int) -> list[Method]:
    """Every method compared on one arm, in the order of its tables; the random pose last."""
    default = models.default[joints]
    paper = models.paper if joints == FIDELITY_JOINTS else models.variants[joints, 80]
    arm = default.arm
    methods = ikdp_variants("IKDP ours", default) + ikdp_variants("IKDP paper denoiser", paper)
    methods += [
        learned_method("MLP regression", models.baselines["mlp", joints, "uniform"], "one forward pass", several=False),
        learned_method(
            "Neural IK (MDN)",
            models.baselines["neural_ik", joints, "uniform"],
            f"{joints} sequential MDN draws",
            several=True,
        ),
    ]
    return methods + classical_methods(arm) + [random_pose(arm)]


def measures_diversity(method: Method) -> bool:
    # raw IKDP samples seldom reach 1e-2 R; their refined twins carry the diversity measure
    return method.several and (method.family != "ikdp" or method.refine_steps > 0)


@dataclass
class AccuracyResult(StageResult):
    arms: dict  # str(N) -> reach, which paper-denoiser model, and per method: accuracy on both target sets, diversity
    fans: dict  # N = 4: K solutions of a few targets per method, for the fans figure


def measure_accuracy(models: Models, sizes: Sizes, seed: int) -> AccuracyResult:
    """Accuracy on both target sets, and diversity, for every method and arm."""
    arms, fans = {}, {"num_links": FIDELITY_JOINTS, "targets": [], "headings": {}}
    for n in sizes.joints:
        arm = models.default[n].arm
        reach = arm.span
        generator = torch.Generator().manual_seed(seed + n)
        fk_targets, fk_truth = targets_from_prior(UNIFORM, sizes.accuracy_targets, arm, generator=generator)
        disk_targets = targets_in_disk(sizes.accuracy_targets, arm, generator=generator)
        diversity_targets = fk_targets[: sizes.diversity_targets]
        which = "shipped" if n == FIDELITY_JOINTS else "Table I variant"
        entry = {"reach": reach, "paper_denoiser_checkpoint": which, "methods": {}}
        for method in tqdm(arm_methods(models, n), desc=f"accuracy N={n}", leave=False):
            measured = {
                "family": method.family,
                "settings": method.settings,
                "fk_uniform": experiments.accuracy(method, fk_targets, fk_truth, reach, seed),
                "disk": experiments.accuracy(method, disk_targets, None, reach, seed),
            }
            if measures_diversity(method):
                measured["diversity"], headings = experiments.diversity(
                    method, diversity_targets, sizes.diversity_samples, reach, seed
                )
                if n == FIDELITY_JOINTS:
                    fans["headings"][method.name] = headings[:FANS].tolist()
                    fans["targets"] = diversity_targets[:FANS].tolist()
            entry["methods"][method.name] = measured
        arms[str(n)] = entry
    return AccuracyResult(arms=arms, fans=fans)


@dataclass
class VariantResult(StageResult):
    variants: dict  # "n{N}_T{T}" -> joints, timesteps and the accuracy of one DDPM sample per target


def measure_variants(models: Models, sizes: Sizes, seed: int) -> VariantResult:
    """Tables I and II: the paper-denoiser variants, one DDPM sample per FK-of-uniform target."""
    variants = {}
    for (n, t), solver in tqdm(models.variants.items(), desc="variants", leave=False):
        arm = solver.arm
        generator = torch.Generator().manual_seed(seed + n)
        fk_targets, fk_truth = targets_from_prior(UNIFORM, sizes.accuracy_targets, arm, generator=generator)
        accuracy = experiments.accuracy(ikdp_method("variant", solver), fk_targets, fk_truth, arm.span, seed)
        variants[f"n{n}_T{t}"] = {"joints": n, "timesteps": t, **accuracy}
    return VariantResult(variants=variants)


@dataclass
class RuntimeResult(StageResult):
    runtime: dict  # num_links and per method: single-target and per-target-in-batch milliseconds


def measure_runtime(models: Models, sizes: Sizes, seed: int) -> RuntimeResult:
    """Runtime of every N = 4 method but the random pose (Table III)."""
    runtime = {"num_links": FIDELITY_JOINTS, "methods": {}}
    if FIDELITY_JOINTS not in sizes.joints:
        return RuntimeResult(runtime=runtime)
    arm = models.default[FIDELITY_JOINTS].arm
    generator = torch.Generator().manual_seed(seed + 99)
    batch_targets, _ = targets_from_prior(UNIFORM, sizes.runtime_batch, arm, generator=generator)
    methods = [method for method in arm_methods(models, FIDELITY_JOINTS) if method.family != "reference"]
    for method in tqdm(methods, desc=f"runtime N={FIDELITY_JOINTS}", leave=False):
        runtime["methods"][method.name] = experiments.runtime(
            method,
            batch_targets[:1],
            batch_targets,
            repeats_single=sizes.runtime_repeats[0],
            repeats_batch=sizes.runtime_repeats[1],
            seed=seed,
        )
    return RuntimeResult(runtime=runtime)


@dataclass
class FidelityResult(StageResult):
    fidelity: dict  # prior name -> targets, reference, noise floor and per method MMD^2 to the reference


def fidelity_setups(models: Models) -> dict[str, tuple[PosePrior, list[Method]]]:
    """Per prior, the methods whose K solutions are compared with p(theta | t) of that prior (N = 4)."""
    arm = models.relaxed.arm
    neural_ik = models.baselines["neural_ik", FIDELITY_JOINTS, "uniform"]
    neural_ik_relaxed = models.baselines["neural_ik", FIDELITY_JOINTS, "relaxed"]
    uniform_methods = [
        *ikdp_variants("IKDP ours", models.default[FIDELITY_JOINTS])[:2],  # DDPM, raw and refined
        ikdp_variants("IKDP paper denoiser", models.paper)[0],
        learned_method("Neural IK (MDN)", neural_ik, "", several=True),
    ]
    relaxed_methods = [
        *ikdp_variants("IKDP relaxed", models.relaxed)[:2],
        learned_method("Neural IK (MDN), relaxed", neural_ik_relaxed, "", several=True),
        dls_from_prior(models.relaxed.prior, arm),
    ]
    return {"uniform": (UNIFORM, uniform_methods), "relaxed": (models.relaxed.prior, relaxed_methods)}


def measure_fidelity(models: Models, sizes: Sizes, seed: int) -> FidelityResult:
    """MMD^2 to rejection-sampled references of p(theta | t), uniform and relaxed priors, N = 4."""
    arm = models.relaxed.arm
    reach, k = arm.span, sizes.fidelity_samples
    fidelity = {}
    for prior_name, (prior, methods) in tqdm(fidelity_setups(models).items(), desc="fidelity", leave=False):
        generator = torch.Generator().manual_seed(seed + 1000)
        targets, _ = targets_from_prior(prior, sizes.fidelity_targets, arm, generator=generator)
        radius = sizes.reference_radius * reach
        reference, complete, draws = rejection_reference(
            prior, targets, arm, count=2 * k, radius=radius, generator=generator
        )
        targets = targets[complete]
        reference_a, reference_b = reference[:, :k], reference[:, k:]
        floor = mmd2(reference_b, reference_a)
        entry = {
            "targets": int(complete.sum()),
            "targets_asked": sizes.fidelity_targets,
            "samples": k,
            "reference_radius": radius,
            "prior_draws": draws,
            "noise_floor": {"mmd2": float(floor.mean()), "mmd2_sem": float(floor.std() / len(floor) ** 0.5)},
            "methods": {},
        }
        for method in methods + random_start_methods(arm):
            entry["methods"][method.name] = experiments.fidelity(method, targets, reference_a, reach, seed)
        fidelity[prior_name] = entry
    return FidelityResult(fidelity=fidelity)


@dataclass
class FigureData(StageResult):
    reverse_process: dict  # str(N) -> one target's reverse-diffusion trajectory (paper Fig. "vis")
    forward_noising: dict  # histograms of forward-noised poses (paper Fig. "gaussian")
    training_curves: dict  # label -> TensorBoard scalars of each shipped model (paper Fig. "train_loss")


def forward_noising_histograms(num_links: int, timesteps: int, seed: int, count: int = 20000) -> dict:
    """arccos(t_x / N) of forward-noised poses at several diffusion times (paper Fig. "gaussian").

    The paper's diffused vector is theta / pi (representation `angle`); at each time t the
    noisy vector is read back as headings and its tip's x gives arccos(t_x / N).
    """
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=timesteps))
    generator = torch.Generator().manual_seed(seed)
    headings = UNIFORM.sample(count, num_links, generator=generator)
    clean = headings / torch.pi
    noise = torch.randn(clean.shape, generator=generator)
    bins = torch.linspace(0, torch.pi, 41)
    result = {"bins": bins.tolist(), "num_links": num_links, "timesteps": timesteps, "times": {}}
    for t in sorted({0, timesteps // 8, timesteps // 4, timesteps // 2, timesteps - 1}):
        noisy = schedule.add_noise(clean, noise, torch.full((count,), t))
        tip_x = torch.cos(noisy * torch.pi).sum(-1)
        angle = torch.arccos((tip_x / num_links).clamp(-1, 1))
        first = noisy[:, 0]
        result["times"][t] = {
            "arccos_counts": torch.histogram(angle, bins).hist.tolist(),
            "first_coordinate_counts": torch.histogram(first.clamp(-4, 4), torch.linspace(-4, 4, 41)).hist.tolist(),
            "alpha_cumprod": float(schedule.alphas_cumprod[t]),
        }
    return result


def training_curves(log_folders: dict[str, Path]) -> dict:
    """The TensorBoard scalars of each model, read from its log folder; folders that do not exist are skipped."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator  # slow import, only here

    curves = {}
    for label, folder in log_folders.items():
        if not folder.is_dir():
            continue
        accumulator = EventAccumulator(str(folder), size_guidance={"scalars": 0})
        accumulator.Reload()
        tags = accumulator.Tags().get("scalars", [])
        curves[label] = {
            tag: [[event.step, event.value] for event in accumulator.Scalars(tag)]
            for tag in ("train/theta_loss", "train/tip_distance", "train/lr", "eval/tip_error_median")
            if tag in tags
        }
    return curves


def figure_data(models: Models, sizes: Sizes, seed: int) -> FigureData:
    """What the figures draw besides the accuracy results: reverse process, forward noising, training curves."""
    reverse = {}
    for n in sizes.joints:
        solver = models.default[n]
        generator = torch.Generator().manual_seed(seed + 7)
        target, _ = targets_from_prior(UNIFORM, 1, solver.arm, generator=generator)
        out = solver.solve(target, num_samples=1, return_trajectory=True, generator=torch.Generator().manual_seed(seed))
        reverse[str(n)] = {
            "target": target[0].tolist(),
            "lengths": list(solver.lengths),
            "checkpoint": models.descriptions[f"default_n{n}"],
            "trajectory": out.trajectory[:, 0, 0].tolist(),
            "final_tip_error": float(out.tip_error[0, 0]),
        }
    return FigureData(
        reverse_process=reverse,
        forward_noising=forward_noising_histograms(FIDELITY_JOINTS, 80, seed),
        training_curves=training_curves(models.log_folders),
    )
