"""Self-collision on a tree: how many samples put one link of a branch through another, with the check and without.

    OMP_NUM_THREADS=1 python -m benchmarks.tree_self_collision --checkpoint /path/to/ikdp_g1.pt --targets 200

The same held-out targets (poses uniform within the limits and, by default, free of self-collision: what the
robot can hold; every hand's pose by forward kinematics) are solved
twice in one run, alternating in rounds so the machine's load falls on both alike: with the default constraints
(SelfCollision on, where the tree's links can meet) and with `SelfCollision(enabled=False)`. For each: the share
of the B x K returned poses whose checked sphere pairs overlap (the constraint's violation > 0, at zero
clearance) and of the raw samples, the share of targets solved (a pose with every hand within 1 mm and 1 degree
and no overlap, and without the overlap condition), and the median wall time of a round. Writes
benchmarks/results/tree_self_collision.json.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.machine import cpu_model

RESULTS = Path(__file__).resolve().parent / "results" / "tree_self_collision.json"


@dataclass(frozen=True)
class TreeSelfCollisionConfig:
    checkpoint: str  # a tree model (trained with --ee-link given twice or more)
    targets: int = 200  # held-out targets
    num_samples: int = 16  # K per target
    refine_steps: int = 5  # DLS steps after sampling
    rounds: int = 3  # each setting solved this many times, alternating; the median time is reported
    apart_targets: bool = True  # targets from poses free of self-collision (what the robot can hold); else any
    seed: int = 0
    threads: int = 1
    output: Path = field(default=RESULTS)


def main(config: TreeSelfCollisionConfig) -> dict:
    torch.set_num_threads(config.threads)
    solver = ikdp.load(config.checkpoint)
    arm = solver.arm
    if not arm.links_can_meet:
        raise ValueError(f"checkpoint: {arm!r} has no links that can meet (or its geometry cannot be read)")
    check = ikdp.SelfCollision().bind(arm, config.targets, config.num_samples)
    drawn = arm.random_poses(20 * config.targets, generator=torch.Generator().manual_seed(config.seed))
    colliding = check.violation(drawn) > 0
    poses = drawn[~colliding] if config.apart_targets else drawn
    if len(poses) < config.targets:
        raise ValueError(f"targets: only {len(poses)} of {len(drawn)} uniform poses are free of self-collision")
    flat = arm.end_effector(poses[: config.targets])
    targets = arm.stacked_targets(flat)
    settings = {"self_collision_on": [], "self_collision_off": [ikdp.SelfCollision(enabled=False)]}
    times = {name: [] for name in settings}
    outs = {}
    for _ in range(config.rounds):
        for name, constraints in settings.items():
            started = time.perf_counter()
            outs[name] = solver.solve(
                targets,
                num_samples=config.num_samples,
                refine_steps=config.refine_steps,
                constraints=constraints,
                generator=torch.Generator().manual_seed(config.seed + 1),
            )
            times[name].append(time.perf_counter() - started)
    rows = []
    for name, out in outs.items():
        overlap = check.violation(out.angles.reshape(-1, arm.num_joints)).reshape(out.angles.shape[:2]) > 0
        raw_overlap = check.violation(out.raw_angles.reshape(-1, arm.num_joints)).reshape(overlap.shape) > 0
        within = out.tip_error < arm.position_tolerance
        if out.rotation_error is not None:  # a pose model
            within &= out.rotation_error < arm.rotation_tolerance
        rows.append(
            {
                "setting": name,
                "poses_in_self_collision": float(overlap.float().mean()),
                "raw_samples_in_self_collision": float(raw_overlap.float().mean()),
                "solved_free_of_collision": float((within & ~overlap).any(-1).float().mean()),
                "solved_any": float(within.any(-1).float().mean()),
                "median_seconds": statistics.median(times[name]),
                "seconds": times[name],
            }
        )
    base = rows[1]["median_seconds"]
    result = {
        "checkpoint": str(config.checkpoint),
        "arm": repr(arm),
        "pairs_checked": len(check.pairs),
        "uniform_poses_in_self_collision": float(colliding.float().mean()),
        "apart_targets": config.apart_targets,
        "targets": config.targets,
        "num_samples": config.num_samples,
        "refine_steps": config.refine_steps,
        "rows": rows,
        "time_ratio_on_over_off": rows[0]["median_seconds"] / base,
        "command": " ".join(sys.argv),
        "machine": f"{cpu_model()}, {config.threads} thread(s), load average {os.getloadavg()[0]:.1f}",
    }
    print(f"{arm!r}: {config.targets} targets, K = {config.num_samples}, {len(check.pairs)} sphere pairs checked")
    print(f"uniform poses in self-collision: {100 * result['uniform_poses_in_self_collision']:.1f}%")
    print(
        f"{'setting':<20} {'poses overlapping':>17} {'raw overlapping':>15} {'solved, apart':>13} "
        f"{'solved':>7} {'s':>7}"
    )
    for row in rows:
        print(
            f"{row['setting']:<20} {100 * row['poses_in_self_collision']:>16.1f}% "
            f"{100 * row['raw_samples_in_self_collision']:>14.1f}% {100 * row['solved_free_of_collision']:>12.1f}% "
            f"{100 * row['solved_any']:>6.1f}% {row['median_seconds']:>7.2f}"
        )
    print(f"time on / off: {result['time_ratio_on_over_off']:.2f}")
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main(tyro.cli(TreeSelfCollisionConfig))
