"""Core v2 benchmark: the fast reverse loop, the few-step samplers, and batch solving beside pytorch_kinematics.

Run from the repository root, with one torch thread (the last run: benchmarks/results/core.json):

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.core_benchmark
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.core_benchmark --quick   # a smoke test

(a) latency: one target, K=16, the 80-step DDPM with the trajectory, beside batched damped
    least squares (16 random starts, 10 iterations), the same solve on the torch workspace (no
    compiled step) and on the plain denoiser path (no workspace), all timed round-robin in the
    same run so the machine's load hits every case alike; also K=1, K=64, DDIM-20, DPM-Solver++(2M)-10 and the viewer's
    end-to-end solve (trajectory + x̂0 estimates + 5 refinement steps);
(b) few-step samplers: DDIM and DPM-Solver++(2M) at 5, 10 and 20 steps (and DDPM-80 for
    reference), raw median tip error, K=1, targets from each model's own prior;
(c) batch solving: 500 targets, K=16, few-step samplers (1 to 10 steps) + 5 refinement steps,
    time per target, share of targets with a pose within 1e-4 and how many of its returned poses
    are, beside pytorch_kinematics' PseudoInverseIK
    (benchmarks/pk_chain.py, early stopping on) at several retry counts, run as a subprocess so
    its import stays out of this process.

Every time is a median over repeats of time.perf_counter around the public call after warm-up.
Results go to benchmarks/results/core.json.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path

import torch
import tyro

import ikdp
from benchmarks.pk_chain import PkSettings
from ikdp.arm import uniform_angles
from ikdp.denoisers.film_compiled import load_kernel
from ikdp.refine import damped_least_squares

REPO_ROOT = Path(__file__).resolve().parents[1]
SUCCESS_TOLERANCE = 1e-4  # bone lengths: a target is solved when one of its poses' tips is this close


@dataclass(frozen=True)
class CoreBenchmarkConfig:
    model: str = "ikdp_n4"  # the model timed in (a) and (c): a shipped name or a path
    few_step_models: tuple[str, ...] = ("ikdp_n4", "ikdp_n4_relaxed")  # models measured in (b)
    latency_repeats: int = 30  # timed rounds in (a); each round times every case once
    warmup: int = 3  # untimed calls before timing
    accuracy_targets: int = 2000  # targets per model in (b)
    batch_targets: int = 500  # targets in (c)
    batch_samples: int = 16  # K in (c)
    batch_repeats: int = 3  # timed calls per configuration in (c)
    refine_steps: int = 5  # DLS refinement steps in (c) and the viewer's path
    pk_retries: tuple[int, ...] = (2, 4, 8, 16)  # PseudoInverseIK retry counts tried in (c); the fastest at >= 99.9 %
    pk_python: str = ""  # interpreter with pytorch_kinematics ("" = this one); "none" skips it
    seed: int = 0  # seeds targets, starts and samplers
    quick: bool = False  # reduced sizes: a smoke test, not a measurement
    output: str = "benchmarks/results/core.json"  # where the JSON goes


def seeded(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def round_robin(cases: dict, *, repeats: int, warmup: int) -> dict[str, list[float]]:
    """Time every case once per round: load that varies over the run hits each case alike."""
    for function in cases.values():
        for _ in range(warmup):
            function()
    seconds = {name: [] for name in cases}
    for _ in range(repeats):
        for name, function in cases.items():
            start = time.perf_counter()
            function()
            seconds[name].append(time.perf_counter() - start)
    return seconds


def denoiser_path(solver: ikdp.Solver, path: str):
    """The same solver's calls on another denoiser path: "plain" (no workspace: every op allocates) or
    "torch" (the torch workspace: buffers allocated once, but not the compiled step)."""
    denoiser = solver.model.denoiser
    default = type(denoiser).workspace

    class Path:
        def __enter__(self):
            if path == "plain":
                denoiser.workspace = lambda rows, like: None
            else:
                denoiser.workspace = lambda rows, like: default(denoiser, rows, like, compiled=False)

        def __exit__(self, *errors):
            del denoiser.workspace

    return Path()


def measure_latency(solver: ikdp.Solver, config: CoreBenchmarkConfig) -> dict:
    arm = solver.arm
    target = arm.end_effector(arm.random_poses(1, generator=seeded(config.seed)))  # (1, 2)

    def solve(**options):
        return lambda: solver.solve(target, generator=seeded(config.seed), **options)

    def dls():
        starts = uniform_angles((1, 16, arm.num_joints), generator=seeded(config.seed))
        return damped_least_squares(arm, starts, target[:, None].expand(-1, 16, -1), steps=10)

    ddpm16 = solve(num_samples=16, return_trajectory=True)

    def ddpm16_plain():
        with denoiser_path(solver, "plain"):
            return ddpm16()

    def ddpm16_torch():
        with denoiser_path(solver, "torch"):
            return ddpm16()

    cases = {
        "DDPM-80, K=16, trajectory": ddpm16,
        "DDPM-80, K=16, trajectory, torch workspace": ddpm16_torch,
        "DDPM-80, K=16, trajectory, plain path": ddpm16_plain,
        "batched DLS, 16 starts x 10 iterations": dls,
        "DDPM-80, K=1, trajectory": solve(num_samples=1, return_trajectory=True),
        "DDPM-80, K=64, trajectory": solve(num_samples=64, return_trajectory=True),
        "DDIM-20, K=16, trajectory": solve(num_samples=16, sampler="ddim", steps=20, return_trajectory=True),
        "DPM-Solver++(2M)-10, K=16, trajectory": solve(
            num_samples=16, sampler="dpmpp2m", steps=10, return_trajectory=True
        ),
        "viewer: DDPM-80, K=16, trajectory + estimates + refine 5": solve(
            num_samples=16, return_trajectory=True, return_estimates=True, refine_steps=config.refine_steps
        ),
    }
    seconds = round_robin(cases, repeats=config.latency_repeats, warmup=config.warmup)
    dls_median = statistics.median(seconds["batched DLS, 16 starts x 10 iterations"])
    return {
        name: {
            "median_ms": 1e3 * statistics.median(values),
            "ratio_to_dls": statistics.median(values) / dls_median,
            "repeats": len(values),
        }
        for name, values in seconds.items()
    }


FEW_STEP = (("ddim", 5), ("ddim", 10), ("ddim", 20), ("dpmpp2m", 5), ("dpmpp2m", 10), ("dpmpp2m", 20), ("ddpm", None))


def measure_few_step(name: str, config: CoreBenchmarkConfig) -> dict:
    solver = ikdp.load(name)
    poses = solver.prior.sample(config.accuracy_targets, solver.arm, generator=seeded(config.seed + 1))
    targets = solver.arm.end_effector(poses)
    rows = {}
    for sampler, steps in FEW_STEP:
        out = solver.solve(targets, num_samples=1, sampler=sampler, steps=steps, generator=seeded(config.seed + 2))
        errors = out.raw_tip_error[:, 0].double()
        label = f"{sampler}-{steps or solver.timesteps}"
        rows[label] = {"median_raw_error": errors.median().item(), "p95_raw_error": errors.quantile(0.95).item()}
    return {"prior": solver.prior.kind, "targets": config.accuracy_targets, "samplers": rows}


def measure_batch(solver: ikdp.Solver, targets: torch.Tensor, config: CoreBenchmarkConfig) -> dict:
    rows = {}
    # DDIM-1 is the denoiser's one-shot x̂0 from noise (raw median ~0.17 on ikdp_n4): the refinement does the
    # rest; it is here to show how much of the work the diffusion steps do, not as IKDP's answer
    few_steps = (("dpmpp2m", 2), ("dpmpp2m", 3), ("dpmpp2m", 5), ("dpmpp2m", 10), ("ddim", 1), ("ddim", 2), ("ddim", 3))
    for sampler, steps in few_steps + (("ddim", 10),):

        def solve(sampler=sampler, steps=steps):
            return solver.solve(
                targets,
                num_samples=config.batch_samples,
                sampler=sampler,
                steps=steps,
                refine_steps=config.refine_steps,
                generator=seeded(config.seed + 4),
            )

        seconds = round_robin({"solve": solve}, repeats=config.batch_repeats, warmup=1)["solve"]
        errors = solve().tip_error.double()
        rows[f"{sampler}-{steps} + refine {config.refine_steps}"] = {
            "median_us_per_target": 1e6 * statistics.median(seconds) / len(targets),
            **tolerance_shares(errors),
        }
    return rows


def tolerance_shares(errors: torch.Tensor) -> dict:
    """errors (B, K) -> the share of targets with a pose within tolerance, and how many of its K poses are."""
    within = errors <= SUCCESS_TOLERANCE
    return {
        "share_within_tolerance": within.any(dim=1).double().mean().item(),
        "solutions_per_target": within.sum(dim=1).double().mean().item(),
    }


def run_pytorch_kinematics(targets: torch.Tensor, lengths, retries: int, config: CoreBenchmarkConfig) -> dict:
    """PseudoInverseIK with `retries` uniform starts, timed in a subprocess; its answers checked here by our FK."""
    python = config.pk_python or sys.executable
    retry_configs = uniform_angles((retries, len(lengths)), generator=seeded(config.seed + 3))
    request = {
        "targets": targets,
        "lengths": list(lengths),
        "retry_configs": retry_configs,
        "settings": asdict(PkSettings()),
        "repeats": config.batch_repeats,
        "warmup": 1,
        "threads": 1,
    }
    with tempfile.TemporaryDirectory() as folder:
        request_path, result_path = Path(folder) / "request.pt", Path(folder) / "result.pt"
        torch.save(request, request_path)
        command = [python, "-m", "benchmarks.pk_chain", str(request_path), str(result_path)]
        subprocess.run(command, cwd=REPO_ROOT, check=True)
        result = torch.load(result_path, weights_only=True)
    headings = torch.cumsum(result["joint_angles"].double(), dim=-1)  # relative joint angles -> headings
    errors = (ikdp.tip_position(headings, torch.tensor(lengths).double()) - targets[:, None].double()).norm(dim=-1)
    return {
        "median_us_per_target": 1e6 * statistics.median(result["seconds"]) / len(targets),
        **tolerance_shares(errors),
        "iterations_run": result["iterations"],
        "version": result["library_version"],
    }


def print_table(title: str, header: tuple[str, ...], rows: list[tuple]) -> None:
    print(f"\n{title}")
    print(" | ".join(header))
    for row in rows:
        print(" | ".join(str(cell) for cell in row))


def main(argv: list[str] | None = None) -> None:
    config = tyro.cli(CoreBenchmarkConfig, args=argv, description=__doc__.splitlines()[0])
    if config.quick:
        config = CoreBenchmarkConfig(
            **(asdict(config) | {"latency_repeats": 3, "warmup": 1, "accuracy_targets": 100, "batch_targets": 20})
            | {"batch_repeats": 1, "pk_retries": (4,), "few_step_models": config.few_step_models[:1]}
        )
    torch.set_num_threads(1)
    solver = ikdp.load(config.model)
    results: dict = {"config": asdict(config)}

    results["latency"] = measure_latency(solver, config)
    print_table(
        "(a) latency, one target, one thread (medians, round-robin in one run)",
        ("case", "median ms", "x batched DLS"),
        [(name, f"{row['median_ms']:.2f}", f"{row['ratio_to_dls']:.1f}") for name, row in results["latency"].items()],
    )

    results["few_step"] = {name: measure_few_step(name, config) for name in config.few_step_models}
    labels = [f"{sampler}-{steps or 80}" for sampler, steps in FEW_STEP]
    print_table(
        f"(b) raw median tip error, K=1, {config.accuracy_targets} targets from each model's prior",
        ("sampler", *config.few_step_models),
        [
            (
                label,
                *(
                    f"{results['few_step'][m]['samplers'][label]['median_raw_error']:.4f}"
                    for m in config.few_step_models
                ),
            )
            for label in labels
        ],
    )

    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(config.batch_targets, generator=seeded(config.seed + 5)))
    batch = {"ikdp": measure_batch(solver, targets, config), "pytorch_kinematics": {}}
    if config.pk_python != "none":
        for retries in config.pk_retries:
            batch["pytorch_kinematics"][f"PseudoInverseIK, {retries} retries"] = run_pytorch_kinematics(
                targets, arm.lengths, retries, config
            )
    results["batch"] = batch
    rows = [
        (
            name,
            f"{row['median_us_per_target']:.1f}",
            f"{100 * row['share_within_tolerance']:.2f}",
            f"{row['solutions_per_target']:.2f}",
        )
        for group in batch.values()
        for name, row in group.items()
    ]
    print_table(
        f"(c) {config.batch_targets} targets, K={config.batch_samples}, one thread",
        ("solver", "median us/target", f"% within {SUCCESS_TOLERANCE:g}", "poses within, per target"),
        rows,
    )

    results["environment"] = {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "cpu": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "compiled_film_step": load_kernel() is not None,  # else the first row ran the torch workspace too
    }
    output = REPO_ROOT / config.output
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(results, indent=2) + "\n")
    print(f"\nwrote {output}")


if __name__ == "__main__":
    main()
