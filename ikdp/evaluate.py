"""Evaluate IKDP beside its baselines and regenerate the paper's tables and figures.

    python -m ikdp.evaluate --cache-dir .eval_cache            # full run, writes docs/
    python -m ikdp.evaluate --quick --out-dir /tmp/eval        # small sizes, under two minutes

Trains what it compares against (the paper-denoiser variants of Tables I and II,
the MLP and Neural IK baselines) once, into --cache-dir; measures accuracy,
diversity, fidelity (MMD to rejection-sampled references) and runtime; writes
RESULTS.md, results.json (every number behind every table and figure) and
figures/*.png into --out-dir.
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from tqdm import tqdm

import ikdp
from ikdp._cli import parse_into
from ikdp.evaluation import experiments, figures, tables
from ikdp.evaluation.methods import (
    REFINE_STEPS,
    Method,
    classical_methods,
    dls_from_prior,
    ikdp_method,
    learned_method,
    random_pose,
)
from ikdp.evaluation.mmd import KERNEL_DESCRIPTION, mmd2
from ikdp.evaluation.reference import rejection_reference, targets_from_prior, targets_in_disk
from ikdp.evaluation.training import (
    baseline_job,
    cached_baseline,
    cached_ikdp,
    ikdp_job,
    ikdp_training_config,
    paper_training_settings,
    run_in_parallel,
)
from ikdp.priors import PosePrior
from ikdp.schedule import DiffusionSchedule, ScheduleConfig
from ikdp.train import train


@dataclass(frozen=True)
class EvaluateConfig:
    quick: bool = False  # small sizes (under two minutes): a smoke run, used by the tests
    out_dir: str = "docs"  # RESULTS.md, results.json and figures/ are written here
    cache_dir: str = ".eval_cache"  # trained variants and baselines are cached here
    checkpoints: str = "checkpoints"  # folder of the shipped checkpoints (and their TensorBoard logs/)
    seed: int = 0  # seeds the targets, the samplers and every training run
    threads: int = 2  # torch CPU threads


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
SHIPPED = {"default": "ikdp_n{n}.pt", "paper": "ikdp_paper_n4.pt", "relaxed": "ikdp_n4_relaxed.pt"}
PAPER = {  # the paper's tables as published (units not stated there)
    "table1": {2: (0.499, 1.982), 4: (0.32, 1.283), 8: (0.243, 8.03)},  # joints: (angle distance, target distance)
    "table2": {40: (1.382, 4.361), 80: (1.283, 3.611), 100: (1.37, 3.44)},  # T: (angle distance, target distance)
    "table3": {"MLP": (12.3, 0.04), "IKNet": (2.3, 0.007), "IKDP": (1.98, 0.065)},  # (target distance, runtime)
}
FIDELITY_JOINTS = 4


def machine_description(threads: int) -> dict:
    model = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": model,
        "cpu_count": os.cpu_count(),
        "torch_threads": threads,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "torch": str(torch.__version__),
    }


def load_ikdp(
    checkpoints: Path, cache: Path, name: str, sizes: Sizes, seed: int, threads: int, *, joints: int, prior: str
):
    """A shipped checkpoint, or in a quick run a small stand-in trained where it is missing."""
    path = checkpoints / name
    if path.exists():
        solver = ikdp.load(path)
        train = solver.metadata["train"]
        state = "" if train.get("finished") else ", unfinished"
        return solver, f"{path} (step {train.get('step')} of {train.get('steps')}{state})"
    if not sizes.standin_steps:
        raise FileNotFoundError(f"{path}: shipped checkpoint missing (train it first, or use --quick for stand-ins)")
    settings = (
        {"denoiser": "paper", "representation": "angle", "tip_loss_weight": 0.0, "snr_gamma": 0.0}
        if "paper" in name
        else {}
    )
    stand_in = cached_ikdp(
        cache,
        joints=joints,
        timesteps=20,
        steps=sizes.standin_steps,
        batch=64,
        seed=seed,
        threads=threads,
        settings=settings,
        prior=prior,
        hidden=32,
        tag="standin_" + Path(name).stem,
    )
    return ikdp.load(stand_in), f"{stand_in} (stand-in: {path} missing)"


def ikdp_variants(prefix: str, solver) -> list[Method]:
    """Raw and refined, DDPM and DDIM (T/4 steps) of one checkpoint."""
    ddim_steps = max(1, solver.timesteps // 4)
    return [
        ikdp_method(f"{prefix}, DDPM", solver),
        ikdp_method(f"{prefix}, DDPM + DLS", solver, refine=REFINE_STEPS),
        ikdp_method(f"{prefix}, DDIM {ddim_steps}", solver, sampler="ddim", steps=ddim_steps),
        ikdp_method(
            f"{prefix}, DDIM {ddim_steps} + DLS", solver, sampler="ddim", steps=ddim_steps, refine=REFINE_STEPS
        ),
    ]


def forward_noising_histograms(num_links: int, timesteps: int, seed: int, count: int = 20000) -> dict:
    """arccos(t_x / N) of forward-noised poses at several diffusion times (paper Fig. "gaussian").

    The paper's diffused vector is theta / pi (representation `angle`); at each time t the
    noisy vector is read back as headings and its tip's x gives arccos(t_x / N).
    """
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=timesteps))
    generator = torch.Generator().manual_seed(seed)
    headings = PosePrior().sample(count, num_links, generator=generator)
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


def training_curves(checkpoints: Path, stems: list[str]) -> dict:
    """The TensorBoard scalars of each shipped checkpoint, from <checkpoints>/logs/<stem>/."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator  # slow import, only here

    curves = {}
    for stem in stems:
        folder = checkpoints / "logs" / stem
        if not folder.is_dir():
            continue
        accumulator = EventAccumulator(str(folder), size_guidance={"scalars": 0})
        accumulator.Reload()
        tags = accumulator.Tags().get("scalars", [])
        curves[stem] = {
            tag: [[event.step, event.value] for event in accumulator.Scalars(tag)]
            for tag in ("train/theta_loss", "train/tip_distance", "train/lr", "eval/tip_error_median")
            if tag in tags
        }
    return curves


def evaluate(config: EvaluateConfig, argv: list[str] | None = None, sizes: Sizes | None = None) -> dict:
    """Run everything and write the files; `sizes` overrides the quick/full sizes (for tests)."""
    torch.set_num_threads(config.threads)
    started = time.perf_counter()
    sizes = sizes or (QUICK if config.quick else FULL)
    out_dir, cache, checkpoints = Path(config.out_dir), Path(config.cache_dir), Path(config.checkpoints)
    seed = config.seed
    command = "python -m ikdp.evaluate " + " ".join(
        shlex.quote(argument) for argument in (argv if argv is not None else sys.argv[1:])
    )
    results: dict = {
        "command": command.strip(),
        "config": asdict(config),
        "sizes": asdict(sizes),
        "machine": machine_description(torch.get_num_threads()),
        "kernel": KERNEL_DESCRIPTION,
        "paper": {name: {str(key): value for key, value in table.items()} for name, table in PAPER.items()},
        "checkpoints": {},
    }
    stage = tqdm(total=8, desc="evaluate", dynamic_ncols=True)
    results["stage_seconds"] = {}
    last = [started]

    def mark(name: str) -> None:
        now = time.perf_counter()
        results["stage_seconds"][name.split("=")[-1].strip(" ,")] = round(now - last[0], 1)
        last[0] = now

    # 1. the shipped checkpoints (or stand-ins) and the models we train ourselves
    stage.set_postfix_str("models")
    default, paper_shipped = {}, None
    for n in sizes.joints:
        default[n], results["checkpoints"][f"default_n{n}"] = load_ikdp(
            checkpoints, cache, SHIPPED["default"].format(n=n), sizes, seed, config.threads, joints=n, prior="uniform"
        )
    paper_shipped, results["checkpoints"]["paper_n4"] = load_ikdp(
        checkpoints, cache, SHIPPED["paper"], sizes, seed, config.threads, joints=4, prior="uniform"
    )
    relaxed, results["checkpoints"]["relaxed_n4"] = load_ikdp(
        checkpoints, cache, SHIPPED["relaxed"], sizes, seed, config.threads, joints=4, prior="relaxed"
    )
    if relaxed.prior.kind != "relaxed":
        raise ValueError(
            f"{results['checkpoints']['relaxed_n4']}: expected a relaxed-prior model, got {relaxed.prior.kind}"
        )
    paper_settings = paper_training_settings(checkpoints / SHIPPED["paper"])
    variant_grid = sorted({(n, 80) for n in sizes.joints} | {(4, t) for t in sizes.table2_timesteps})
    variant_configs = {
        (n, t): ikdp_training_config(
            cache,
            joints=n,
            timesteps=t,
            steps=sizes.variant_steps,
            batch=sizes.variant_batch,
            seed=seed,
            threads=config.threads,
            settings=paper_settings,
        )
        for n, t in variant_grid
    }
    uniform, relaxed_prior = PosePrior("uniform"), relaxed.prior
    baseline_specs = [(kind, n, uniform) for n in sizes.joints for kind in ("mlp", "neural_ik")]
    baseline_specs.append(("neural_ik", FIDELITY_JOINTS, relaxed_prior))
    if not config.quick and config.threads > 1:
        # everything trainable, in parallel single-threaded processes; the longest jobs (most joints) first
        jobs = [ikdp_job(train_config) for train_config in variant_configs.values()]
        jobs += [
            baseline_job(
                kind, cache, prior, torch.ones(n), steps=sizes.baseline_steps, batch=sizes.baseline_batch, seed=seed
            )
            for kind, n, prior in baseline_specs
        ]
        jobs.sort(key=lambda job: -int(job[0].name.split("_n")[1].split("_")[0]))
        run_in_parallel(jobs, workers=config.threads)
    for train_config in tqdm(variant_configs.values(), desc="paper-denoiser variants", leave=False):
        if not Path(train_config.output).exists():
            train(train_config)
    variants = {key: ikdp.load(train_config.output) for key, train_config in variant_configs.items()}
    results["variant_training"] = {
        "settings": paper_settings,
        "steps": sizes.variant_steps,
        "batch": sizes.variant_batch,
    }
    baselines = {}
    for kind, n, prior in tqdm(baseline_specs, desc="baselines", leave=False):
        baselines[kind, n, prior.kind] = cached_baseline(
            kind, cache, prior, torch.ones(n), steps=sizes.baseline_steps, batch=sizes.baseline_batch, seed=seed
        )
    results["baseline_training"] = {
        "steps": sizes.baseline_steps,
        "batch": sizes.baseline_batch,
        "optimizer": "Adam 1e-3, cosine",
    }
    stage.update()
    mark(stage.postfix)

    # 2. accuracy on both target sets, and diversity, for every method and arm
    stage.set_postfix_str("accuracy")
    methods_by_arm: dict[int, list[Method]] = {}
    results["arms"] = {}
    fans = {"num_links": 4, "targets": [], "headings": {}}
    for n in sizes.joints:
        lengths = default[n].model.lengths.cpu()
        reach = float(lengths.sum())
        paper_solver = paper_shipped if n == 4 else variants[n, 80]
        methods = ikdp_variants("IKDP ours", default[n]) + ikdp_variants("IKDP paper denoiser", paper_solver)
        methods += [
            learned_method("MLP regression", baselines["mlp", n, "uniform"], "one forward pass", several=False),
            learned_method(
                "Neural IK (MDN)", baselines["neural_ik", n, "uniform"], f"{n} sequential MDN draws", several=True
            ),
        ]
        methods += classical_methods(lengths) + [random_pose(lengths)]
        methods_by_arm[n] = methods
        generator = torch.Generator().manual_seed(seed + n)
        fk_targets, fk_truth = targets_from_prior(uniform, sizes.accuracy_targets, lengths, generator=generator)
        disk_targets = targets_in_disk(sizes.accuracy_targets, lengths, generator=generator)
        diversity_targets = fk_targets[: sizes.diversity_targets]
        arm = {"reach": reach, "paper_denoiser_checkpoint": "shipped" if n == 4 else "Table I variant", "methods": {}}
        for method in tqdm(methods, desc=f"accuracy N={n}", leave=False):
            entry = {
                "family": method.family,
                "settings": method.settings,
                "fk_uniform": experiments.accuracy(method, fk_targets, fk_truth, reach, seed),
                "disk": experiments.accuracy(method, disk_targets, None, reach, seed),
            }
            # raw IKDP samples seldom reach 1e-2 R; their refined twins carry the diversity measure
            if method.several and (method.family != "ikdp" or "+ DLS" in method.name):
                entry["diversity"], headings = experiments.diversity(
                    method, diversity_targets, sizes.diversity_samples, reach, seed
                )
                if n == 4:
                    fans["headings"][method.name] = headings[:3].tolist()
                    fans["targets"] = diversity_targets[:3].tolist()
            arm["methods"][method.name] = entry
        results["arms"][str(n)] = arm
    results["fans"] = fans
    stage.update()
    mark(stage.postfix)

    # 3. Tables I and II: the paper-denoiser variants, one DDPM sample per FK-of-uniform target
    stage.set_postfix_str("tables I, II")
    results["variants"] = {}
    for (n, t), solver in tqdm(variants.items(), desc="variants", leave=False):
        lengths = solver.model.lengths.cpu()
        fk_targets, fk_truth = targets_from_prior(
            uniform, sizes.accuracy_targets, lengths, generator=torch.Generator().manual_seed(seed + n)
        )
        method = ikdp_method("variant", solver)
        results["variants"][f"n{n}_T{t}"] = {
            "joints": n,
            "timesteps": t,
            **experiments.accuracy(method, fk_targets, fk_truth, float(lengths.sum()), seed),
        }
    stage.update()
    mark(stage.postfix)

    # 4. runtime of every N = 4 method
    stage.set_postfix_str("runtime")
    results["runtime"] = {"num_links": 4, "methods": {}}
    if 4 in sizes.joints:
        lengths = default[4].model.lengths.cpu()
        batch_targets, _ = targets_from_prior(
            uniform, sizes.runtime_batch, lengths, generator=torch.Generator().manual_seed(seed + 99)
        )
        for method in tqdm(methods_by_arm[4][:-1], desc="runtime N=4", leave=False):
            results["runtime"]["methods"][method.name] = experiments.runtime(
                method,
                batch_targets[:1],
                batch_targets,
                repeats_single=sizes.runtime_repeats[0],
                repeats_batch=sizes.runtime_repeats[1],
                seed=seed,
            )
    stage.update()
    mark(stage.postfix)

    # 5. fidelity: MMD to rejection-sampled references, uniform and relaxed priors, N = 4
    stage.set_postfix_str("fidelity")
    results["fidelity"] = {}
    lengths = relaxed.model.lengths.cpu()
    reach = float(lengths.sum())
    k = sizes.fidelity_samples
    fidelity_setups = {
        "uniform": (
            uniform,
            [
                *ikdp_variants("IKDP ours", default[FIDELITY_JOINTS])[:2],
                ikdp_variants("IKDP paper denoiser", paper_shipped)[0],
                learned_method("Neural IK (MDN)", baselines["neural_ik", FIDELITY_JOINTS, "uniform"], "", several=True),
            ],
        ),
        "relaxed": (
            relaxed_prior,
            [
                *ikdp_variants("IKDP relaxed", relaxed)[:2],
                learned_method(
                    "Neural IK (MDN), relaxed", baselines["neural_ik", FIDELITY_JOINTS, "relaxed"], "", several=True
                ),
                Method(
                    "DLS, starts from the prior (told the prior)",
                    "classical",
                    dls_from_prior(relaxed_prior, lengths),
                    "",
                ),
            ],
        ),
    }
    for prior_name, (prior, methods) in tqdm(fidelity_setups.items(), desc="fidelity", leave=False):
        generator = torch.Generator().manual_seed(seed + 1000)
        targets, _ = targets_from_prior(prior, sizes.fidelity_targets, lengths, generator=generator)
        reference, complete, draws = rejection_reference(
            prior, targets, lengths, count=2 * k, radius=sizes.reference_radius * reach, generator=generator
        )
        targets = targets[complete]
        reference_a, reference_b = reference[:, :k], reference[:, k:]
        floor = mmd2(reference_b, reference_a)
        entry = {
            "targets": int(complete.sum()),
            "targets_asked": sizes.fidelity_targets,
            "samples": k,
            "reference_radius": sizes.reference_radius * reach,
            "prior_draws": draws,
            "noise_floor": {"mmd2": float(floor.mean()), "mmd2_sem": float(floor.std() / len(floor) ** 0.5)},
            "methods": {},
        }
        for method in methods + classical_methods(lengths)[:3]:
            entry["methods"][method.name] = experiments.fidelity(method, targets, reference_a, reach, seed)
        results["fidelity"][prior_name] = entry
    stage.update()
    mark(stage.postfix)

    # 6. figure data: reverse process, forward noising, training curves
    stage.set_postfix_str("figure data")
    results["reverse_process"] = {}
    for n in sizes.joints:
        solver = default[n]
        target, _ = targets_from_prior(
            uniform, 1, solver.model.lengths.cpu(), generator=torch.Generator().manual_seed(seed + 7)
        )
        out = solver.solve(target, num_samples=1, return_trajectory=True, generator=torch.Generator().manual_seed(seed))
        results["reverse_process"][str(n)] = {
            "target": target[0].tolist(),
            "lengths": list(solver.lengths),
            "checkpoint": results["checkpoints"][f"default_n{n}"],
            "trajectory": out.trajectory[:, 0, 0].tolist(),
            "final_tip_error": float(out.tip_error[0, 0]),
        }
    results["forward_noising"] = forward_noising_histograms(4, 80, seed)
    stems = [Path(SHIPPED["default"].format(n=n)).stem for n in sizes.joints] + [
        Path(SHIPPED["paper"]).stem,
        Path(SHIPPED["relaxed"]).stem,
    ]
    results["training_curves"] = training_curves(checkpoints, stems)
    if not results["training_curves"]:  # stand-ins keep their logs in the cache
        results["training_curves"] = training_curves(cache, [p.stem for p in sorted(cache.glob("standin_*.pt"))])
    stage.update()
    mark(stage.postfix)

    # 7. files
    stage.set_postfix_str("writing")
    results["wall_seconds"] = time.perf_counter() - started
    figure_dir = out_dir / "figures"
    figure_dir.mkdir(parents=True, exist_ok=True)
    results["figures"] = figures.draw_all(results, figure_dir)
    stage.update()
    mark(stage.postfix)
    results["wall_seconds"] = time.perf_counter() - started
    (out_dir / "results.json").write_text(json.dumps(results, indent=1))
    (out_dir / "RESULTS.md").write_text(tables.render(results))
    stage.update()
    mark(stage.postfix)
    stage.close()
    return results


def main(argv: list[str] | None = None) -> None:
    config = parse_into(
        EvaluateConfig, "Evaluate IKDP beside its baselines; regenerate the paper's tables and figures.", argv
    )
    try:
        results = evaluate(config, argv)
    except (ValueError, FileNotFoundError, ikdp.CheckpointError) as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    print(f"wrote {Path(config.out_dir) / 'RESULTS.md'} in {results['wall_seconds']:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
