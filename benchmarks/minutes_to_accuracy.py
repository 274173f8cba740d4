"""Minutes to accuracy of robot trainings: each run's curve and its final model on held-out targets.

    OMP_NUM_THREADS=1 python -m benchmarks.minutes_to_accuracy --checkpoints runs/xarm7.pt runs/kinova.pt

For each checkpoint written by `python -m ikdp.train --urdf ...` (which records, at every save, the step,
the wall and CPU seconds and the median error of 200-500 targets from the training prior):
1. the curve: minutes (wall, and the process's CPU time, which on a shared machine is the honest measure
   of "one CPU thread") against that median;
2. the final model on `targets` held-out pose targets (FK of joint values uniform within the limits,
   seed 0, as benchmarks/robot_benchmark.py draws them): the raw DDPM sampler, K=1 (median, mean, share
   over 50 mm), and K=16 + 5 limit-aware DLS steps (share of targets with a solution within 1 mm and 1°,
   valid solutions per target; the same rule as robot_benchmark's `verdict`).
Prints a table and writes benchmarks/results/minutes_to_accuracy.json (or --output).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
import tyro

import ikdp
from benchmarks.few_step import evaluation_targets
from benchmarks.robot_benchmark import verdict
from ikdp.checkpoint import read_checkpoint
from ikdp.evaluation.machine import machine_description

RESULTS = Path(__file__).resolve().parent / "results"
OPTIONS_REPORTED = ("hidden", "blocks", "batch", "prediction", "schedule", "lr", "dls_skip", "limit_aware_step")


@dataclass(frozen=True)
class MinutesConfig:
    checkpoints: tuple[str, ...] = ()  # trainings to report (paths)
    targets: int = 1000  # held-out targets of the final evaluation
    samples: int = 16  # K of the refined pipeline
    refine_steps: int = 5  # DLS steps after sampling
    seed: int = 0
    output: Path = RESULTS / "minutes_to_accuracy.json"


def curve(payload: dict) -> list[dict]:
    """The recorded saves as (wall minutes, CPU minutes, step, median mm, median degrees)."""
    points = []
    for point in payload.get("history", []):
        rotation = point.get("rotation_error_median")
        points.append(
            {
                "step": point["step"],
                "wall_minutes": point["seconds"] / 60,
                "cpu_minutes": point.get("cpu_seconds", math.nan) / 60,
                "median_mm": 1000 * point["tip_error_median"],
                "median_deg": math.degrees(rotation) if rotation is not None else math.nan,
            }
        )
    return points


def final_accuracy(path: str, config: MinutesConfig) -> dict:
    solver = ikdp.load(path)
    arm = solver.arm
    targets = evaluation_targets(solver, config.targets, config.seed)
    raw = solver.solve(targets, num_samples=1, generator=torch.Generator().manual_seed(1))
    position = raw.raw_tip_error[:, 0] * 1000
    rotation = torch.rad2deg(raw.rotation_error[:, 0]) if arm.target_dim == 7 else torch.full_like(position, math.nan)
    refined = solver.solve(
        targets,
        num_samples=config.samples,
        refine_steps=config.refine_steps,
        generator=torch.Generator().manual_seed(2),
    )
    return {
        "arm": f"{Path(arm.urdf_path or '?').name} ({arm.ee_link}), {arm.num_joints} joints",
        "continuous_joints": int(arm.continuous_joints.sum()),
        "raw_k1": {
            "position_mm_median": float(position.median()),
            "position_mm_mean": float(position.mean()),
            "over_50mm_share": float((position > 50).double().mean()),
            "rotation_deg_median": float(rotation.median()),
            "rotation_deg_mean": float(rotation.mean()),
        },
        f"k{config.samples}_refined_{config.refine_steps}": verdict(arm, refined.angles, targets),
    }


def main(config: MinutesConfig) -> dict:
    torch.set_num_threads(1)
    runs = {}
    for path in config.checkpoints:
        payload = read_checkpoint(Path(path))
        record = payload["train"]
        runs[path] = {
            "recipe": record.get("recipe", "?"),
            "device": record["device"],
            "steps": record["step"],
            "wall_minutes": record["seconds"] / 60,
            "cpu_minutes": record.get("cpu_seconds", math.nan) / 60,
            "options": {name: record.get(name) for name in OPTIONS_REPORTED},  # None: not an option of that run
            "curve": curve(payload),
            **final_accuracy(path, config),
        }
        print_run(path, runs[path], config)
    results = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1)}
    results["runs"] = runs
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(results, indent=2) + "\n")
    print(f"\nwrote {config.output}")
    return results


def print_run(path: str, run: dict, config: MinutesConfig) -> None:
    raw, refined = run["raw_k1"], run[f"k{config.samples}_refined_{config.refine_steps}"]
    print(f"\n{path}: {run['arm']}, recipe {run['recipe']} on {run['device']}, {run['steps']} steps")
    print(f"  {'step':>6} {'wall min':>8} {'CPU min':>8} {'median mm':>10} {'median deg':>10}")
    for point in run["curve"]:
        print(
            f"  {point['step']:>6} {point['wall_minutes']:>8.1f} {point['cpu_minutes']:>8.1f}"
            f" {point['median_mm']:>10.1f} {point['median_deg']:>10.2f}"
        )
    print(
        f"  final, {config.targets} held-out targets: raw DDPM K=1 {raw['position_mm_median']:.1f} / "
        f"{raw['position_mm_mean']:.1f} mm (median / mean), {raw['rotation_deg_median']:.2f} / "
        f"{raw['rotation_deg_mean']:.2f}°, {100 * raw['over_50mm_share']:.1f} % over 50 mm; "
        f"K={config.samples} + {config.refine_steps} DLS: {100 * refined['success_share']:.1f} % within 1 mm and 1°, "
        f"{refined['valid_per_target']:.1f} valid per target"
    )


if __name__ == "__main__":
    main(tyro.cli(MinutesConfig))
