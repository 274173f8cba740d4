"""Which sampling settings a robot's viewer should open on: the pose the viewer shows, by setting, and its time.

    OMP_NUM_THREADS=1 python benchmarks/viz_robot_settings.py               # the shipped ikdp_panda

For `targets` pose targets (FK of joint values uniform within the limits, fixed seed), the
viewer's solve of each (K = 16, trajectory and x̂0 kept, as `ikdp_viz/solving.py` asks)
with each setting: the median over targets of the highlighted ("best") sample's and of the
K samples' median position (mm) and rotation (degrees) error, and the solve's median time
on one torch thread. Prints a table and writes benchmarks/results/viz_robot_settings.json.
"""

from __future__ import annotations

import json
import statistics
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.machine import machine_description

RESULTS = Path(__file__).resolve().parent / "results" / "viz_robot_settings.json"


@dataclass(frozen=True)
class SettingsConfig:
    checkpoint: str = "ikdp_panda"  # a path or a shipped model's name
    targets: int = 20  # pose targets
    samples: int = 16  # K, the viewer's default
    settings: tuple[str, ...] = (
        "dpmpp2m:10:0",
        "dpmpp2m:10:5",
        "ddim:20:5",
        "ddpm::0",
        "ddpm::5",
    )  # sampler:steps:refine
    # (steps empty: all T)
    seed: int = 0
    output: Path = field(default=RESULTS)


@dataclass(frozen=True)
class Row:
    setting: str  # sampler:steps:refine_steps
    best_mm: float  # the best sample's position error, median over targets
    best_deg: float  # and its rotation error
    median_mm: float  # the K samples' median position error, median over targets
    median_deg: float
    solve_ms: float  # median time of one viewer solve


def measure(config: SettingsConfig) -> list[Row]:
    torch.set_num_threads(1)
    solver = ikdp.load(config.checkpoint)
    arm = solver.arm
    generator = torch.Generator().manual_seed(config.seed)
    targets = arm.end_effector_pose(arm.random_poses(config.targets, generator=generator).double()).float()
    rows = []
    for setting in config.settings:
        sampler, steps, refine = setting.split(":")
        best_mm, best_deg, median_mm, median_deg, times = [], [], [], [], []
        for index, target in enumerate(targets):
            started = time.perf_counter()
            result = solver.solve(
                target[None], num_samples=config.samples, sampler=sampler, steps=int(steps) if steps else None,
                refine_steps=int(refine), generator=torch.Generator().manual_seed(index), return_trajectory=True,
                return_estimates=True,
            )  # fmt: skip
            times.append(time.perf_counter() - started)
            position = 1000 * result.tip_error[0].double()  # (K,) mm
            rotation = torch.rad2deg(result.rotation_error[0].double())  # (K,) degrees
            best = int(torch.argmin(position / 1000 + 0.1 * torch.deg2rad(rotation)))  # chain_scene's "best"
            best_mm.append(float(position[best]))
            best_deg.append(float(rotation[best]))
            median_mm.append(float(position.median()))
            median_deg.append(float(rotation.median()))
        rows.append(
            Row(
                setting,
                statistics.median(best_mm),
                statistics.median(best_deg),
                statistics.median(median_mm),
                statistics.median(median_deg),
                1000 * statistics.median(times),
            )  # fmt: skip
        )
    return rows


def main() -> None:
    config = tyro.cli(SettingsConfig)
    rows = measure(config)
    print(f"{config.checkpoint}, K = {config.samples}, {config.targets} targets, medians over targets")
    print("| sampler:steps:refine | best mm | best deg | median mm | median deg | solve ms |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        print(f"| {row.setting} | {row.best_mm:.1f} | {row.best_deg:.2f} | {row.median_mm:.1f} | "
              f"{row.median_deg:.2f} | {row.solve_ms:.0f} |")  # fmt: skip
    config.output.parent.mkdir(parents=True, exist_ok=True)
    payload = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1),
               "rows": [asdict(row) for row in rows]}  # fmt: skip
    config.output.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {config.output}")


if __name__ == "__main__":
    main()
