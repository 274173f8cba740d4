"""Seeds for damped least squares on a robot with several hands: IKDP's samples against uniform random starts.

    OMP_NUM_THREADS=1 python -m benchmarks.tree_seeds --checkpoint /path/to/ikdp_g1.pt --targets 500

IKDiffuser's protocol: the same optimizer budget (K starts per target, a fixed number of DLS steps on the
stacked task of every end effector) from two kinds of starts, in the same run and on the same held-out
targets (poses uniform within the joint limits, every hand's pose by forward kinematics): the model's K
samples, and K poses uniform within the limits. A target is solved when one of its K poses has every end
effector within 1 mm and 1 degree. Also the raw samples' K = 1 median of the worse hand. Prints a table and
writes benchmarks/results/tree_seeds.json (machine, command, numbers).

Where Pinocchio is installed (benchmarks/requirements-bench.txt), a third row per budget: Pinocchio's own CLIK
(benchmarks/pinocchio_clik.py) from the same uniform starts, the same number of steps, scored by the same rule
through the same kinematics. The model samples without the self-collision check a solve has by default
(`--self-collision` turns it on): the protocol's targets come from poses uniform within the limits, most of
which put an elbow through the torso.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.machine import cpu_model
from ikdp.refine import damped_least_squares

RESULTS = Path(__file__).resolve().parent / "results" / "tree_seeds.json"


@dataclass(frozen=True)
class TreeSeedsConfig:
    checkpoint: str  # a tree model (trained with --ee-link given twice or more)
    targets: int = 500  # held-out targets
    num_samples: int = 16  # K starts per target, for both kinds of start
    dls_steps: tuple[int, ...] = (5, 20)  # the DLS budgets compared
    sampler: str = "ddpm"  # the model's sampler (solve's default)
    steps: int | None = None  # its steps; None: every timestep
    self_collision: bool = False  # sample with the tree's self-collision check (a solve's default)
    pinocchio: bool = True  # a Pinocchio CLIK row where pinocchio is installed
    seed: int = 0  # draws the targets and the uniform starts
    threads: int = 1  # torch CPU threads
    output: Path = field(default=RESULTS)


def solved(arm, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(B, K, J) poses, (B, target_dim) flat targets -> (B,) True where some pose has every end effector within
    the arm's tolerances."""
    position, rotation = arm.tip_and_rotation_errors(joints, targets[:, None])  # the worst end effector's
    ok = position < arm.position_tolerance
    if rotation is not None:
        ok = ok & (rotation < arm.rotation_tolerance)
    return ok.any(dim=-1)


def pinocchio_reference(arm):
    """The tree in Pinocchio (benchmarks/pinocchio_clik.py), or None where pinocchio is not installed."""
    try:
        import pinocchio  # noqa: F401
    except ImportError:
        return None
    from benchmarks.pinocchio_clik import PinocchioTree

    return PinocchioTree(arm, arm.chains[0].chain_description().urdf_path)


def pinocchio_clik(reference, starts: torch.Tensor, poses: torch.Tensor, steps: int) -> torch.Tensor:
    """starts (B, K, J), the poses that made the targets (B, J) -> Pinocchio's CLIK from each start, (B, K, J).
    Each target's hand placements are Pinocchio's own forward kinematics of its pose (equal to IKDP's to 1e-9)."""
    out = starts.double().clone()
    for row in range(len(starts)):
        goals = reference.forward(poses[row].double().numpy())
        for sample in range(starts.shape[1]):
            start = starts[row, sample].double().numpy()
            out[row, sample] = torch.from_numpy(reference.clik(start, goals, steps) if steps else start)
    return out


def main(config: TreeSeedsConfig) -> dict:
    torch.set_num_threads(config.threads)
    solver = ikdp.load(config.checkpoint)
    arm = solver.arm
    generator = torch.Generator().manual_seed(config.seed)
    poses_of_targets = arm.random_poses(config.targets, generator=generator)
    flat = arm.end_effector(poses_of_targets)  # (B, target_dim)
    stacked = arm.stacked_targets(flat) if arm.kind == "tree" else flat  # what a user passes
    started = time.perf_counter()
    out = solver.solve(
        stacked,
        num_samples=config.num_samples,
        sampler=config.sampler,
        steps=config.steps,
        generator=generator,
        constraints=[] if config.self_collision else [ikdp.SelfCollision(enabled=False)],
    )
    sampling_seconds = time.perf_counter() - started
    starts = {
        "ikdp": out.raw_angles,
        "uniform": arm.random_poses(config.targets * config.num_samples, generator=generator).reshape(
            config.targets, config.num_samples, -1
        ),
    }
    raw = out.raw_tip_error[:, 0]  # K = 1: the first sample, its worse hand
    raw_rotation = arm.tip_and_rotation_errors(out.raw_angles[:, :1], flat[:, None])[1]
    reference = pinocchio_reference(arm) if config.pinocchio else None
    rows = []
    for budget in config.dls_steps:
        for name, start in starts.items():
            started = time.perf_counter()
            refined = damped_least_squares(arm, start, flat[:, None], steps=budget) if budget else start
            seconds = time.perf_counter() - started
            share = float(solved(arm, refined, flat).float().mean())
            rows.append({"seeds": name, "dls_steps": budget, "solved": share, "refine_seconds": seconds})
        if reference is not None:
            started = time.perf_counter()
            refined = pinocchio_clik(reference, starts["uniform"], poses_of_targets, budget)
            seconds = time.perf_counter() - started
            share = float(solved(arm, refined, flat).float().mean())
            rows.append({"seeds": "pinocchio_clik", "dls_steps": budget, "solved": share, "refine_seconds": seconds})
    result = {
        "checkpoint": str(config.checkpoint),
        "arm": repr(arm),
        "train": {key: solver.metadata["train"].get(key) for key in ("step", "seconds", "minutes", "threads")},
        "targets": config.targets,
        "num_samples": config.num_samples,
        "sampler": config.sampler,
        "raw_k1_worse_hand_median_mm": float(raw.median()) * 1000,
        "raw_k1_worse_hand_rotation_median_deg": None
        if raw_rotation is None
        else math.degrees(float(raw_rotation.median())),
        "sampling_seconds": sampling_seconds,
        "self_collision": config.self_collision,
        "pinocchio": None if reference is None else reference.version,
        "rows": rows,
        "command": " ".join(sys.argv),
        "machine": f"{cpu_model()}, {config.threads} thread(s), load average {os.getloadavg()[0]:.1f}",
    }
    print(f"{arm!r}: {config.targets} held-out targets, K = {config.num_samples}")
    print(f"raw K=1, worse hand: median {result['raw_k1_worse_hand_median_mm']:.1f} mm")
    print(f"{'seeds':<15} {'DLS steps':>9} {'solved (1 mm, 1 deg, every hand)':>34} {'refine s':>9}")
    for row in rows:
        print(f"{row['seeds']:<15} {row['dls_steps']:>9} {100 * row['solved']:>33.1f}% {row['refine_seconds']:>9.2f}")
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main(tyro.cli(TreeSeedsConfig))
