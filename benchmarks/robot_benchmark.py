"""IKDP on a real robot (the Franka Panda, or any chain model): accuracy, refinement, diversity and speed.

    OMP_NUM_THREADS=1 python benchmarks/robot_benchmark.py --checkpoint checkpoints/ikdp_panda.pt
    OMP_NUM_THREADS=1 python benchmarks/robot_benchmark.py --checkpoint runs/my_arm.pt --raw-only

On `targets` held-out pose targets (FK of joint values uniform within the limits, fixed seed):
1. the raw sampler, K=1: position (mm) and rotation (degrees) error, medians and means, limit violations;
   (a model of position targets, `--target position`: no rotation, and success is within 1 mm alone)
2. K=16 + `refine_steps` limit-aware damped-least-squares steps: share of targets with a solution within
   1 mm and 1 degree, valid solutions per target, time per target; beside 16 uniform random starts with
   the same steps and with more, and pytorch_kinematics' PseudoInverseIK (16 retries, 30 iterations,
   early stopping), all in the same run, one torch thread;
3. diversity: mean pairwise joint distance (radians) of a target's valid solutions;
4. the viewer's path for one target, K=16 (sampler + trajectory + x̂0 estimates + refinement).
`--raw-only` stops after 1 (a quick look at a model in training). Prints tables and writes
benchmarks/results/robot_<name>.json, <name> the checkpoint's file name without `ikdp_` (robot_panda.json).
"""

from __future__ import annotations

import json
import math
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
import tyro

import ikdp
from ikdp.evaluation.machine import machine_description
from ikdp.refine import damped_least_squares
from ikdp.restarts import restart_unreached

RESULTS = Path(__file__).resolve().parent / "results"
PUBLISHED = {  # mean position / rotation error of learned Panda IK, as published
    "IKFlow (Ames et al. 2022)": (6.66, 2.03),
    "GraphDiff-IK": (3.47, None),
}


@dataclass(frozen=True)
class RobotBenchmarkConfig:
    checkpoint: str = "ikdp_panda"  # a path or a shipped model's name
    targets: int = 1000  # held-out pose targets
    samples: int = 16  # K solutions per target
    refine_steps: int = 5  # limit-aware DLS steps after sampling
    samplers: tuple[str, ...] = ("ddpm", "dpmpp2m:10", "ddim:10")  # name[:steps] measured raw
    pipeline_sampler: str = "dpmpp2m:10"  # the sampler of the K=16 + refinement pipeline
    fast_pipelines: tuple[str, ...] = ("ddim:2+5", "ddim:3+5", "ddim:2+10", "dpmpp2m:3+10")  # name:steps+refine
    random_start_steps: tuple[int, ...] = (5, 10, 20, 50)  # DLS steps from 16 uniform random starts
    pk_retries: int = 16  # PseudoInverseIK starts per target
    pk_iterations: int = 30  # PseudoInverseIK iterations
    repeats: int = 3  # timing repeats (median quoted)
    latency_repeats: int = 15  # one-target viewer-path repeats
    seed: int = 0
    raw_only: bool = False  # only the raw sampler's table: no K=16 pipelines, baselines or latency
    output: Path | None = None  # the JSON; None: benchmarks/results/robot_<checkpoint name without ikdp_>.json


def default_output(checkpoint_path: str) -> Path:
    """benchmarks/results/robot_<name>.json for checkpoints/ikdp_<name>.pt (robot_panda.json for the Panda)."""
    stem = Path(checkpoint_path).stem
    return RESULTS / f"robot_{stem.removeprefix('ikdp_')}.json"


def parse_sampler(text: str) -> tuple[str, int | None]:
    """ "name[:steps]" -> (name, steps or None); the constraint benchmarks read their samplers with it too."""
    name, _, steps = text.partition(":")
    return name, int(steps) if steps else None


def median_seconds(run, repeats: int) -> tuple[float, object]:
    result, seconds = None, []
    for _ in range(repeats):
        started = time.perf_counter()
        result = run()
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds), result


def verdict(arm, joints: torch.Tensor, targets: torch.Tensor) -> dict:
    """joints (B, K, J) for targets (B, 7) or (B, 3): success within 1 mm (and 1 degree), and diversity of the valid."""
    goals = targets[:, None].expand(-1, joints.shape[1], -1)
    valid = arm.position_error(joints, goals) < 1e-3
    if arm.target_dim == 7:
        valid &= arm.rotation_error(joints, goals) < math.radians(1)
    pairwise = torch.cdist(joints.double(), joints.double())  # (B, K, K)
    pair_valid = (
        valid[:, :, None] & valid[:, None, :] & ~torch.eye(joints.shape[1], dtype=torch.bool, device=valid.device)
    )
    per_target = (pairwise * pair_valid).sum((1, 2)) / pair_valid.sum((1, 2)).clamp(min=1)
    several = pair_valid.sum((1, 2)) > 0
    return {
        "success_share": float(valid.any(1).double().mean()),
        "valid_per_target": float(valid.sum(1).double().mean()),
        "diversity_rad": float(per_target[several].mean()) if several.any() else float("nan"),
        "limit_violations": int(arm.limit_violations(joints).sum()),
    }


def dls_from_random_starts(arm, goals: torch.Tensor, dls_steps: int, restart_steps: int = 0, with_restarted=False):
    """goals (B, K, target_dim) -> (B, K, J): `dls_steps` damped least-squares steps from uniform random starts within
    the limits (the same starts every call), our own numerical baseline; the starts are drawn inside a timing of it,
    as IKDP's noise is. `restart_steps`: the targets still unreached restart as solve's `restart_steps` do;
    `with_restarted`: return (joints, restarted (B,), None without restarts) to say which."""
    generator = torch.Generator().manual_seed(3)
    starts = arm.random_poses(goals.shape[0] * goals.shape[1], generator=generator)
    joints = damped_least_squares(arm, starts.unflatten(0, goals.shape[:2]), goals, steps=dls_steps)
    joints, restarted = restart_unreached(arm, joints, goals, restart_steps, generator)
    return (joints, restarted if restart_steps else None) if with_restarted else joints


def pseudo_inverse(arm, targets: torch.Tensor, retries: int, iterations: int, seed: int):
    """PseudoInverseIK for pose targets (B, 7), built once: a call returns its solutions, (B, retries, J)."""
    import pytorch_kinematics as pk

    chain = pk.build_serial_chain_from_urdf(Path(arm.urdf_path).read_bytes(), arm.ee_link)
    limits = arm.joint_limits
    retry = torch.rand(retries, arm.num_joints, generator=torch.Generator().manual_seed(seed + 9))
    retry = limits[:, 0] + retry * (limits[:, 1] - limits[:, 0])
    solver = pk.PseudoInverseIK(
        chain,
        retry_configs=retry,
        joint_limits=limits,
        max_iterations=iterations,
        pos_tolerance=1e-3,
        rot_tolerance=math.radians(1),
        early_stopping_any_converged=True,
    )
    goal = pk.Transform3d(pos=targets[:, :3], rot=targets[:, 3:])  # pk's quaternions are (w, x, y, z) too
    return lambda: solver.solve(goal).solutions.detach().float()


def run_pytorch_kinematics(arm, targets: torch.Tensor, config: RobotBenchmarkConfig) -> dict:
    solve = pseudo_inverse(arm, targets, config.pk_retries, config.pk_iterations, config.seed)
    seconds, joints = median_seconds(solve, config.repeats)  # (B, R, J)
    return {"seconds_per_target": seconds / len(targets), **verdict(arm, joints, targets)}


def main(config: RobotBenchmarkConfig) -> dict:
    torch.set_num_threads(1)
    solver = ikdp.load(config.checkpoint)
    arm = solver.arm
    output = config.output or default_output(solver.metadata["path"])
    targets = arm.end_effector(arm.random_poses(config.targets, generator=torch.Generator().manual_seed(config.seed)))
    results: dict = {
        "config": {**asdict(config), "output": str(output)},
        "checkpoint": solver.metadata["path"],
        "machine": machine_description(threads=1),  # the load average says how shared the CPU was
    }

    raw = {}
    for text in config.samplers:
        name, steps = parse_sampler(text)
        seeded = torch.Generator().manual_seed(1)
        out = solver.solve(targets, num_samples=1, sampler=name, steps=steps, generator=seeded)
        position = out.raw_tip_error[:, 0] * 1000
        # a model of position targets has no rotation error: NaN in the table
        rotation = (
            torch.rad2deg(out.rotation_error[:, 0]) if arm.target_dim == 7 else torch.full_like(position, math.nan)
        )
        raw[text] = {
            "position_mm_median": float(position.median()),
            "position_mm_mean": float(position.mean()),
            "rotation_deg_median": float(rotation.median()),
            "rotation_deg_mean": float(rotation.mean()),
            "limit_violations": int(arm.limit_violations(out.raw_angles).sum()),
        }
    results["raw_k1"] = raw
    if config.raw_only:
        print_raw(raw, config.targets, arm.target)
        write(results, output)
        return results

    pipelines = {}
    name, steps = parse_sampler(config.pipeline_sampler)

    def ikdp_pipeline():
        return solver.solve(
            targets,
            num_samples=config.samples,
            sampler=name,
            steps=steps,
            refine_steps=config.refine_steps,
            generator=torch.Generator().manual_seed(2),
        )

    seconds, out = median_seconds(ikdp_pipeline, config.repeats)
    label = f"IKDP {config.pipeline_sampler}, K={config.samples} + {config.refine_steps} DLS steps"
    pipelines[label] = {"seconds_per_target": seconds / len(targets), **verdict(arm, out.angles, targets)}
    for text in config.fast_pipelines:  # few sampler steps, the refinement finishing: the CPU's fastest
        sampler_text, _, refine = text.partition("+")
        fast_name, fast_steps = parse_sampler(sampler_text)
        seconds, out = median_seconds(
            lambda fast_name=fast_name, fast_steps=fast_steps, refine=int(refine): solver.solve(
                targets,
                num_samples=config.samples,
                sampler=fast_name,
                steps=fast_steps,
                refine_steps=refine,
                generator=torch.Generator().manual_seed(2),
            ),
            config.repeats,
        )
        label = f"IKDP {sampler_text}, K={config.samples} + {refine} DLS steps"
        pipelines[label] = {"seconds_per_target": seconds / len(targets), **verdict(arm, out.angles, targets)}
    goals = targets[:, None].expand(-1, config.samples, -1)
    for dls_steps in config.random_start_steps:
        seconds, joints = median_seconds(
            lambda dls_steps=dls_steps: dls_from_random_starts(arm, goals, dls_steps), config.repeats
        )
        label = f"{config.samples} uniform random starts + {dls_steps} DLS steps"
        pipelines[label] = {"seconds_per_target": seconds / len(targets), **verdict(arm, joints, targets)}
    try:
        label = f"pytorch_kinematics PseudoInverseIK, {config.pk_retries} retries, {config.pk_iterations} iterations"
        if arm.target_dim == 7:  # PseudoInverseIK solves for poses; a position model has no such row
            pipelines[label] = run_pytorch_kinematics(arm, targets, config)
    except ImportError:
        pass
    results["pipelines"] = pipelines

    one = targets[:1]
    latency = {}
    for text in (config.pipeline_sampler, "ddpm"):
        name, steps = parse_sampler(text)
        seconds, _ = median_seconds(
            lambda name=name, steps=steps: solver.solve(
                one,
                num_samples=config.samples,
                sampler=name,
                steps=steps,
                refine_steps=config.refine_steps,
                return_trajectory=True,
                return_estimates=True,
            ),
            config.latency_repeats,
        )
        latency[text] = seconds * 1000
    results["viewer_path_ms"] = latency
    results["published_mean_mm_deg"] = PUBLISHED

    print_raw(raw, config.targets, arm.target)
    print("\n| pipeline | within 1 mm and 1 deg | valid of K | diversity (rad) | ms per target | limit violations |")
    print("|---|---|---|---|---|---|")
    for label, row in pipelines.items():
        print(
            f"| {label} | {100 * row['success_share']:.1f} % | {row['valid_per_target']:.1f} "
            f"| {row['diversity_rad']:.2f} | {1000 * row['seconds_per_target']:.2f} | {row['limit_violations']} |"
        )
    print("\nviewer path, one target, K=16 (+ trajectory, estimates, refinement):", latency)
    write(results, output)
    return results


def print_raw(raw: dict, targets: int, kind: str) -> None:
    print(f"raw sampler, K=1, {targets} {kind} targets")
    print("| sampler | position mm median / mean | rotation deg median / mean | limit violations |")
    print("|---|---|---|---|")
    for text, row in raw.items():
        print(
            f"| {text} | {row['position_mm_median']:.2f} / {row['position_mm_mean']:.2f} "
            f"| {row['rotation_deg_median']:.2f} / {row['rotation_deg_mean']:.2f} | {row['limit_violations']} |"
        )


def write(results: dict, output: Path) -> None:
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(results, indent=2))
    print(f"wrote {output}")


if __name__ == "__main__":
    main(tyro.cli(RobotBenchmarkConfig, description=__doc__.splitlines()[0]))
