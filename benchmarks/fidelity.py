"""Fidelity and raw accuracy of IKDP models on their own pose prior, beside DLS from random starts.

    python benchmarks/fidelity.py --checkpoints checkpoints/ikdp_n4_relaxed.pt runs/relaxed_gated.pt

For each model (all must share one planar arm and prior):
- raw accuracy: the raw sampler (no refinement), K=1, median tip error on `accuracy_targets`
  targets drawn by FK from the model's own prior;
- fidelity: for `targets` targets from the prior, K = `samples` raw solutions, and the biased
  MMD^2 (ikdp/evaluation/mmd.py) to a reference set drawn from p(theta | target) by rejection
  from the prior. The "excess" is MMD^2 minus the noise floor (two reference sets against each
  other), and the ratio divides a model's excess by that of DLS from uniformly random starts
  (10 iterations), measured in the same run: 0 is perfectly faithful, 1 is no better than DLS.
Prints a table and writes benchmarks/results/fidelity.json.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.mmd import mmd2
from ikdp.evaluation.reference import rejection_reference
from ikdp.refine import damped_least_squares

RESULTS = Path(__file__).resolve().parent / "results" / "fidelity.json"


@dataclass(frozen=True)
class FidelityConfig:
    checkpoints: tuple[str, ...] = ("ikdp_n4_relaxed",)  # paths or shipped names; one arm and prior for all
    sampler: str = "ddpm"  # the raw sampler measured
    steps: int | None = None  # its steps (None: the sampler's default)
    spacing: str | None = None  # its timestep grid, uniform or quadratic (None: the model's default)
    targets: int = 96  # fidelity targets drawn from the prior
    samples: int = 128  # K per target, and the size of each reference set
    reference_radius: float = 0.02  # rejection radius, as a fraction of the reach
    accuracy_targets: int = 2000  # targets for the raw median tip error
    dls_iterations: int = 10  # the baseline's DLS steps from each random start
    seed: int = 0
    output: Path = field(default=RESULTS)  # where the JSON goes


def main(config: FidelityConfig) -> dict:
    torch.set_num_threads(1)
    solvers = {name: ikdp.load(name) for name in config.checkpoints}
    first = next(iter(solvers.values()))
    arm, prior = first.arm, first.prior
    started = time.perf_counter()

    generator = torch.Generator().manual_seed(config.seed)
    targets = arm.end_effector(prior.sample(config.targets, arm, generator=generator))
    reference, complete, draws = rejection_reference(
        prior,
        targets,
        arm,
        count=2 * config.samples,
        radius=config.reference_radius * arm.span,
        generator=generator,
    )
    targets = targets[complete]
    reference_a, reference_b = reference[:, : config.samples], reference[:, config.samples :]
    floor = float(mmd2(reference_b, reference_a).mean())

    starts = arm.random_poses(len(targets) * config.samples, generator=generator).unflatten(0, (len(targets), -1))
    goals = targets[:, None].expand(-1, config.samples, -1)
    dls = damped_least_squares(arm, starts, goals, steps=config.dls_iterations)
    dls_excess = float(mmd2(dls, reference_a).mean()) - floor

    accuracy_targets = arm.end_effector(
        prior.sample(config.accuracy_targets, arm, generator=torch.Generator().manual_seed(config.seed + 1))
    )
    rows = {}
    for name, solver in solvers.items():
        out = solver.solve(
            targets,
            num_samples=config.samples,
            sampler=config.sampler,
            steps=config.steps,
            spacing=config.spacing,
            generator=torch.Generator().manual_seed(config.seed + 2),
        )
        excess = float(mmd2(out.raw_angles, reference_a).mean()) - floor
        raw = solver.solve(
            accuracy_targets,
            num_samples=1,
            sampler=config.sampler,
            steps=config.steps,
            spacing=config.spacing,
            generator=torch.Generator().manual_seed(config.seed + 3),
        )
        rows[name] = {
            "raw_median_tip_error": float(raw.raw_tip_error.median()),
            "mmd2_excess": excess,
            "ratio_to_dls": excess / dls_excess,
            "denoiser": solver.metadata["model"]["denoiser"],
            "train_steps": solver.metadata["train"].get("step"),
        }

    result = {
        "config": {**asdict(config), "output": str(config.output)},
        "arm": arm.to_config(),
        "prior": {"kind": prior.kind, "relaxed_std": prior.relaxed_std},
        "fidelity_targets": int(complete.sum()),
        "prior_draws": draws,
        "noise_floor_mmd2": floor,
        "dls_random_starts_excess": dls_excess,
        "models": rows,
        "seconds": time.perf_counter() - started,
    }
    print(f"fidelity: {int(complete.sum())} targets, K={config.samples}, noise floor {floor:.5f}, ", end="")
    print(f"DLS random starts excess {dls_excess:.5f}")
    print(f"| model | raw median tip error (K=1, {config.accuracy_targets} targets) | excess MMD^2 | ratio to DLS |")
    print("|---|---|---|---|")
    for name, row in rows.items():
        print(f"| {name} | {row['raw_median_tip_error']:.4f} | {row['mmd2_excess']:.5f} | {row['ratio_to_dls']:.3f} |")
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main(tyro.cli(FidelityConfig, description=__doc__.splitlines()[0]))
