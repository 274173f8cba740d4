"""Few-step sampling: raw accuracy and diversity per network evaluation, by timestep grid.

    OMP_NUM_THREADS=1 python -m benchmarks.few_step --checkpoints ikdp_panda ikdp_z1 ikdp_n4
    OMP_NUM_THREADS=1 python -m benchmarks.few_step --checkpoints ikdp_panda --samplers ddpm student ddim:4
    OMP_NUM_THREADS=1 python -m benchmarks.few_step --checkpoints runs/n4_student.pt --samplers ddpm ddim:2
    OMP_NUM_THREADS=1 python -m benchmarks.few_step --checkpoints ikdp_panda --precisions float32 int8

For each model and each sampler `name:steps` (DDIM, DPM-Solver++(2M) and the strided ancestral DDPM at
2, 4, 8 and 16 network evaluations by default), once per timestep spacing (`uniform`, evenly spaced, and
`quadratic`, packed near t = 0):
1. raw accuracy, K = 1: a robot's `targets` held-out pose targets as benchmarks/robot_benchmark.py draws
   them (FK of joint values uniform within the limits, seed 0): position mm and rotation degrees, median
   and mean; a planar arm's targets from its own prior, tip error in bone lengths;
2. diversity: the mean pairwise joint distance of K = 16 raw samples of `diversity_targets` targets
   (radians; planar headings compared on the circle), beside the 100-step DDPM's in the same run;
3. the network evaluations each solve reported (`out.network_evaluations`).
The DDPM rows (all T steps) are the reference. Prints a table per model and writes
benchmarks/results/few_step.json.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from benchmarks.robot_benchmark import parse_sampler, write
from ikdp.evaluation.machine import machine_description

RESULTS = Path(__file__).resolve().parent / "results" / "few_step.json"
GRIDS_OF_THEIR_OWN = {"ddpm": ("uniform",), "student": (None,)}  # spacing None: the student's distilled grid
FEW_STEP_SAMPLERS = tuple(f"{name}:{steps}" for name in ("ddim", "dpmpp2m", "ancestral") for steps in (2, 4, 8, 16))


@dataclass(frozen=True)
class FewStepConfig:
    checkpoints: tuple[str, ...] = ("ikdp_panda", "ikdp_z1", "ikdp_n4")  # paths or shipped names
    precisions: tuple[str, ...] = ("float32",)  # each checkpoint at each (int8: robots only, ikdp.load's precision)
    samplers: tuple[str, ...] = ("ddpm",) + FEW_STEP_SAMPLERS  # name[:steps]
    spacings: tuple[str, ...] = ("uniform", "quadratic")  # timestep grids compared (ddpm: all T steps, one row)
    targets: int = 1000  # raw K = 1 targets (a planar arm: 2000 is the core benchmark's count)
    diversity_targets: int = 200  # targets of the K = 16 diversity measure
    diversity_samples: int = 16
    seed: int = 0
    output: Path = field(default=RESULTS)


def evaluation_targets(solver, count: int, seed: int) -> torch.Tensor:
    """A robot's held-out targets as robot_benchmark draws them; a planar arm's from its own prior."""
    arm = solver.arm
    generator = torch.Generator().manual_seed(seed)
    if arm.kind == "chain":
        return arm.end_effector(arm.random_poses(count, generator=generator))
    return arm.end_effector(solver.prior.sample(count, arm, generator=generator))


def mean_pairwise_distance(arm, joints: torch.Tensor) -> float:
    """joints (B, K, J) -> the mean over targets and pairs of the joint-space distance, radians."""
    difference = joints[:, :, None] - joints[:, None, :]  # (B, K, K, J)
    if arm.kind == "planar":  # headings live on the circle
        difference = torch.atan2(difference.sin(), difference.cos())
    distance = difference.double().norm(dim=-1)
    pairs = joints.shape[1] * (joints.shape[1] - 1)
    return float((distance.sum((1, 2)) / pairs).mean())


def raw_row(solver, targets: torch.Tensor, name: str, steps: int | None, spacing: str, seed: int) -> dict:
    arm = solver.arm
    out = solver.solve(
        targets, num_samples=1, sampler=name, steps=steps, spacing=spacing, generator=torch.Generator().manual_seed(1)
    )
    error = out.raw_tip_error[:, 0]
    scale, unit = (1000.0, "mm") if arm.kind == "chain" else (1.0, "bone lengths")
    row = {
        "network_evaluations": out.network_evaluations,
        "timesteps": out.timesteps,
        "position_unit": unit,
        "position_median": float(error.median() * scale),
        "position_mean": float(error.mean() * scale),
        "position_p95": float(error.quantile(0.95) * scale),
    }
    if out.rotation_error is not None:
        rotation = torch.rad2deg(out.rotation_error[:, 0])
        row |= {"rotation_deg_median": float(rotation.median()), "rotation_deg_mean": float(rotation.mean())}
    return row


def measure(solver, config: FewStepConfig) -> dict:
    targets = evaluation_targets(solver, config.targets, config.seed)
    diversity_targets = targets[: config.diversity_targets]
    rows = {}
    for text in config.samplers:
        name, steps = parse_sampler(text)
        # the DDPM runs every timestep; a folded student (sampler "student") its own distilled grid
        grids = GRIDS_OF_THEIR_OWN.get(name, config.spacings)
        for spacing in grids:
            row = raw_row(solver, targets, name, steps, spacing, config.seed)
            diverse = solver.solve(
                diversity_targets,
                num_samples=config.diversity_samples,
                sampler=name,
                steps=steps,
                spacing=spacing,
                generator=torch.Generator().manual_seed(2),
            )
            row["diversity_rad"] = mean_pairwise_distance(solver.arm, diverse.raw_angles)
            rows[f"{text} {spacing}" if name not in GRIDS_OF_THEIR_OWN else text] = row
    reference = rows.get("ddpm", {}).get("diversity_rad")
    for row in rows.values():
        row["diversity_vs_ddpm"] = row["diversity_rad"] / reference if reference else math.nan
    return rows


def print_rows(name: str, rows: dict) -> None:
    unit = next(iter(rows.values()))["position_unit"]
    print(f"\n{name}: raw K = 1, position error ({unit}) median / mean / p95; diversity of K = 16 (rad, × DDPM's)")
    print("| sampler | evaluations | position | rotation deg median / mean | diversity |")
    print("|---|---|---|---|---|")
    for label, row in rows.items():
        rotation = (
            f"{row['rotation_deg_median']:.2f} / {row['rotation_deg_mean']:.2f}" if "rotation_deg_median" in row else ""
        )
        print(
            f"| {label} | {row['network_evaluations']} | {row['position_median']:.4g} / {row['position_mean']:.4g} "
            f"/ {row['position_p95']:.4g} | {rotation} | {row['diversity_rad']:.3f} ({row['diversity_vs_ddpm']:.2f}) |"
        )


def main(config: FewStepConfig) -> dict:
    torch.set_num_threads(1)
    results: dict = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1)}
    models = {}
    for checkpoint in config.checkpoints:
        for precision in config.precisions:
            solver = ikdp.load(checkpoint, precision=precision)
            name = checkpoint if precision == "float32" else f"{checkpoint} ({precision})"
            models[name] = {"path": solver.metadata["path"], "precision": precision, "rows": measure(solver, config)}
            print_rows(name, models[name]["rows"])
    results["models"] = models
    write(results, config.output)
    return results


if __name__ == "__main__":
    main(tyro.cli(FewStepConfig, description=__doc__.splitlines()[0]))
