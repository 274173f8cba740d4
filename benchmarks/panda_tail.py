"""Where the raw Panda samples' tail comes from: one table per checkpoint, and what each candidate fix changes.

    OMP_NUM_THREADS=1 python benchmarks/panda_tail.py --checkpoints checkpoints/ikdp_panda.pt runs/other.pt

On `targets` held-out pose targets (robot_benchmark's: FK of joint values uniform within the limits, seed 0),
the raw DDPM, K = 1, for each checkpoint:
1. position / rotation error, median, mean, 90th percentile, and the share of samples more than 50 mm off;
2. joints within 0.05 rad of a limit, in the bad (> 50 mm) and the good samples;
3. where in the reverse process the bad samples leave the good ones: the median position error of x̂0 by step;
4. inference-side candidates on the same model and noise: no clamping of x̂0 until the last step, and a
   self-check that redraws a sample whose own FK error is out of line (reported apart from raw K = 1).
Prints tables and writes benchmarks/results/panda_tail.json.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.machine import machine_description
from ikdp.sampling import run_reverse_diffusion

RESULTS = Path(__file__).resolve().parent / "results" / "panda_tail.json"
BAD_MM = 50.0  # a sample this far off is the tail
NEAR_LIMIT_RAD = 0.05


@dataclass(frozen=True)
class TailConfig:
    checkpoints: tuple[str, ...] = ("ikdp_panda",)  # paths or shipped names
    targets: int = 1000  # held-out pose targets
    redraws: int = 3  # self-check: redraws at most this many times
    self_check_mm: float = 20.0  # self-check: a sample whose own FK miss is above this is redrawn
    output: Path = field(default=RESULTS)


def errors(arm, joints: torch.Tensor, targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, J) joints -> position error in mm and rotation error in degrees, (B,) each."""
    return arm.position_error(joints, targets) * 1000, torch.rad2deg(arm.rotation_error(joints, targets))


def summary(position: torch.Tensor, rotation: torch.Tensor) -> dict:
    return {
        "position_mm_median": float(position.median()),
        "position_mm_mean": float(position.mean()),
        "position_mm_p90": float(position.quantile(0.9)),
        "rotation_deg_median": float(rotation.median()),
        "rotation_deg_mean": float(rotation.mean()),
        "share_over_50mm": float((position > BAD_MM).double().mean()),
    }


@torch.inference_mode()
def reverse(model, targets: torch.Tensor, seed: int, *, clamp_estimates: bool = True, trajectory: bool = False):
    """The raw DDPM, K = 1, with the library's loop; `clamp_estimates=False` leaves x̂0 unclamped until the end."""
    representation = model.representation
    project = representation.project
    if not clamp_estimates:
        representation.project = lambda x: x  # the final decode still clamps into the limits
    try:
        return run_reverse_diffusion(
            model.denoiser,
            model.schedule,
            representation,
            model.sampler("ddpm"),
            targets,
            prediction=model.config.prediction,
            generator=torch.Generator().manual_seed(seed),
            return_trajectory=trajectory,
            return_estimates=trajectory,
        )
    finally:
        representation.project = project


def near_limits(arm, joints: torch.Tensor) -> torch.Tensor:
    """(B, J) -> (B,) joints within NEAR_LIMIT_RAD of a limit."""
    limits = arm.joint_limits
    near = ((joints - limits[:, 0]).abs() < NEAR_LIMIT_RAD) | ((joints - limits[:, 1]).abs() < NEAR_LIMIT_RAD)
    return near.sum(-1).double()


def self_checked(model, arm, targets: torch.Tensor, first: torch.Tensor, config: TailConfig) -> tuple:
    """Redraw (new noise) the samples whose own FK miss is above the threshold; keep each one's best draw."""
    best = first.clone()
    position, rotation = errors(arm, best, targets)
    score = position / config.self_check_mm + rotation  # mm against the threshold, degrees
    draws = torch.ones(len(targets))
    for redraw in range(config.redraws):
        again = position > config.self_check_mm
        if not again.any():
            break
        draws[again] += 1
        joints = reverse(model, targets[again], seed=100 + redraw).headings[:, 0]
        new_position, new_rotation = errors(arm, joints, targets[again])
        new_score = new_position / config.self_check_mm + new_rotation
        better = new_score < score[again]
        index = again.nonzero()[:, 0][better]
        best[index], position[index], rotation[index] = joints[better], new_position[better], new_rotation[better]
        score[index] = new_score[better]
    return best, float(draws.mean())


def study(path: str, targets_count: int, config: TailConfig) -> dict:
    torch.manual_seed(0)
    solver = ikdp.load(path)
    model, arm = solver.model, solver.arm
    poses = arm.random_poses(targets_count, generator=torch.Generator().manual_seed(0))
    targets = arm.end_effector(poses)
    run = reverse(model, targets, seed=1, trajectory=True)
    joints = run.headings[:, 0]
    position, rotation = errors(arm, joints, targets)
    bad = position > BAD_MM
    by_step = {}
    for index in sorted({*range(0, len(run.timesteps), 10), len(run.timesteps) - 1}):
        estimate_error = arm.position_error(run.estimates[index][:, 0], targets) * 1000
        by_step[int(run.timesteps[index])] = {
            "good_mm_median": float(estimate_error[~bad].median()) if (~bad).any() else math.nan,
            "bad_mm_median": float(estimate_error[bad].median()) if bad.any() else math.nan,
            "bad_joints_near_limit": float(near_limits(arm, run.estimates[index][:, 0])[bad].mean())
            if bad.any()
            else 0.0,
        }
    near = near_limits(arm, joints)
    unclamped = reverse(model, targets, seed=1, clamp_estimates=False).headings[:, 0]
    checked, draws = self_checked(model, arm, targets, joints, config)
    train = solver.metadata["train"]
    return {
        "checkpoint": path,
        "recipe": {k: train.get(k) for k in ("denoiser", "prediction", "schedule", "hidden", "blocks", "device")},
        "raw_ddpm_k1": summary(position, rotation),
        "joints_near_limit": {"bad": float(near[bad].mean()), "good": float(near[~bad].mean())},
        "estimate_error_by_timestep": by_step,
        "no_clamp_until_last_step": summary(*errors(arm, unclamped, targets)),
        "self_check": {**summary(*errors(arm, checked, targets)), "draws_per_target": draws},
    }


def main(config: TailConfig) -> dict:
    torch.set_num_threads(1)
    results = {"machine": machine_description(threads=1), "targets": config.targets, "rows": []}
    print(
        "| checkpoint | raw median / mean / p90 mm | rot median / mean deg | > 50 mm | near-limit joints bad / good "
        "| no x̂0 clamp: mean mm | self-check: mean mm / deg, draws |"
    )
    print("|---|---|---|---|---|---|---|")
    for path in config.checkpoints:
        row = study(path, config.targets, config)
        results["rows"].append(row)
        raw, free, checked = row["raw_ddpm_k1"], row["no_clamp_until_last_step"], row["self_check"]
        print(
            f"| {Path(path).stem} | {raw['position_mm_median']:.1f} / {raw['position_mm_mean']:.1f} / "
            f"{raw['position_mm_p90']:.1f} | {raw['rotation_deg_median']:.2f} / {raw['rotation_deg_mean']:.2f} "
            f"| {100 * raw['share_over_50mm']:.1f} % | {row['joints_near_limit']['bad']:.2f} / "
            f"{row['joints_near_limit']['good']:.2f} | {free['position_mm_mean']:.1f} | "
            f"{checked['position_mm_mean']:.1f} / {checked['rotation_deg_mean']:.2f}, "
            f"{checked['draws_per_target']:.2f} |",
            flush=True,
        )
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main(tyro.cli(TailConfig, description=__doc__.splitlines()[0]))
