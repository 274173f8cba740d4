"""Solver benchmark: IKDP's accuracy and speed beside damped least squares and pytorch_kinematics.

Run from the repository root (docs/benchmarks.md, "Planar arms", shows the last run's tables):

    python -m benchmarks.solver_benchmark              # full sizes, a few minutes on 2 cores
    python -m benchmarks.solver_benchmark --quick      # reduced sizes, a smoke test

What it measures, each beside the damped-least-squares baseline from random starts
(16 restarts x 10 iterations) timed in the same run:
  1. accuracy: raw tip error of one 80-step DDPM sample per target, every checkpoint,
     and the share within 1e-4 after 5 refinement steps;
  2. latency: one target, K=16, 80-step DDPM with the trajectory;
  3. throughput: 10,000 targets, K=1, 80-step DDPM and 20-step DDIM;
  4. batch solving: 500 targets, K=16, DDIM-20 + 5 refinement steps, beside
     pytorch_kinematics' PseudoInverseIK with 16 retries on the same arm.
Targets are the tips of uniformly random poses drawn from a fixed seed. Every
timing is time.perf_counter around the public call, after warm-up calls, and the
median of the repeats is quoted. Tip errors are in bone lengths.

pytorch_kinematics is not an IKDP dependency. It lives in its own environment,

    python -m venv --system-site-packages benchmarks/.venv-pk
    benchmarks/.venv-pk/bin/pip install -r benchmarks/requirements-bench.txt

and this script runs benchmarks/pk_chain.py there as a subprocess (--pk-python),
so the library's import stays out of the process that times IKDP. Without that
environment the pytorch_kinematics row is skipped with a note.

Results go to benchmarks/results/solver.json (every number, sizes, seeds,
threads, versions, CPU, date), and the tables are printed; the docs' tables are
rendered from that JSON by benchmarks/render_docs_tables.py alone.
"""

from __future__ import annotations

import dataclasses
import hashlib
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
from ikdp.arm import PlanarArm, uniform_angles
from ikdp.baselines.random_starts import dls_polish, solve_from_random_starts
from ikdp.evaluation.machine import cpu_model

REPO_ROOT = Path(__file__).resolve().parents[1]
SUCCESS_TOLERANCE = 1e-4  # bone lengths: a target counts as solved when a pose's tip is this close


@dataclass(frozen=True)
class BenchmarkConfig:
    checkpoints: tuple[str, ...] = (
        "checkpoints/ikdp_n2.pt",
        "checkpoints/ikdp_n4.pt",
        "checkpoints/ikdp_n8.pt",
        "checkpoints/ikdp_paper_n4.pt",
    )  # models whose accuracy is measured; a missing file is skipped with a note
    speed_checkpoint: str = "checkpoints/ikdp_n4.pt"  # the model timed for latency, throughput and batch solving
    accuracy_targets: int = 2000  # targets per model in the accuracy table
    refine_steps: int = 5  # DLS refinement steps after the sampler, in accuracy and batch solving
    latency_samples: int = 16  # K for the one-target latency
    latency_repeats: int = 30  # timed calls for the latency median
    throughput_targets: int = 10_000  # targets per call in the throughput runs (K=1)
    throughput_repeats: int = 3  # timed calls per throughput median
    ddim_steps: int = 20  # DDIM steps in throughput and batch solving
    batch_targets: int = 500  # targets in batch solving
    batch_samples: int = 16  # K in batch solving: IKDP samples, DLS restarts and pytorch_kinematics retries alike
    batch_repeats: int = 5  # timed calls per batch-solving median
    dls_restarts: int = 16  # the baseline's random starts per target
    dls_iterations: int = 10  # the baseline's DLS iterations
    warmup: int = 2  # untimed calls before each timed series
    threads: int = 2  # torch CPU threads, here and in the pytorch_kinematics subprocess
    seed: int = 0  # targets come from seed; sampler, baseline and pytorch_kinematics starts from seed+1..3
    pk_python: str = "benchmarks/.venv-pk/bin/python"  # the interpreter with pytorch_kinematics; "" skips it
    output: str = "benchmarks/results/solver.json"  # where every number goes
    quick: bool = False  # reduced sizes (QUICK_SIZES, unless given) for a smoke test; the JSON and table say so


QUICK_SIZES = dict(
    accuracy_targets=200,
    latency_repeats=10,
    throughput_targets=1000,
    throughput_repeats=1,
    batch_targets=100,
    batch_repeats=1,
    warmup=1,
)


# ---------------------------------------------------------------------------
# Targets, timing and error summaries


def random_targets(lengths, count: int, seed: int) -> torch.Tensor:
    """Tips of `count` poses with every link heading uniform on [-pi, pi): (count, 2)."""
    arm = PlanarArm(lengths)
    return arm.end_effector(arm.random_poses(count, generator=torch.Generator().manual_seed(seed)))


def seeded(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def time_call(function, *, repeats: int, warmup: int):
    """Call `function` warmup times untimed, then `repeats` times timed -> (seconds list, last result)."""
    for _ in range(warmup):
        function()
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        seconds.append(time.perf_counter() - start)
    return seconds, result


def error_summary(errors: torch.Tensor, reach: float) -> dict:
    """errors: (B,) tip errors in bone lengths -> median, mean, p95 (also as % of reach), share within 1e-4."""
    errors = errors.double()
    median, mean, p95 = errors.median().item(), errors.mean().item(), errors.quantile(0.95).item()
    return {
        "median": median,
        "mean": mean,
        "p95": p95,
        "median_percent_of_reach": 100 * median / reach,
        "mean_percent_of_reach": 100 * mean / reach,
        "p95_percent_of_reach": 100 * p95 / reach,
        "share_within_tolerance": (errors < SUCCESS_TOLERANCE).double().mean().item(),
    }


def timing_summary(seconds: list[float], count: int) -> dict:
    """Timed repeats of a call that solved `count` targets."""
    median = statistics.median(seconds)
    return {"seconds": seconds, "median_seconds": median, "median_ms_per_target": 1e3 * median / count}


def run_dls(targets: torch.Tensor, lengths, config: BenchmarkConfig, *, repeats: int) -> dict:
    """The baseline on `targets`, timed; its error is the best of its restarts."""
    reach = sum(lengths)
    polish = dls_polish(iterations=config.dls_iterations)

    def solve():
        return solve_from_random_starts(
            polish, targets, PlanarArm(lengths), restarts=config.dls_restarts, generator=seeded(config.seed + 2)
        )

    seconds, (_, tip_error) = time_call(solve, repeats=repeats, warmup=config.warmup)
    return timing_summary(seconds, len(targets)) | {"best_error": error_summary(tip_error.min(dim=1).values, reach)}


def checkpoint_identity(path: str, solver: ikdp.Solver) -> dict:
    """Enough to tell which training state produced a row."""
    digest = hashlib.sha256((REPO_ROOT / path).read_bytes()).hexdigest()[:12]
    model = solver.metadata["model"]
    return {
        "path": path,
        "sha256_12": digest,
        "num_links": solver.num_links,
        "lengths": list(solver.lengths),
        "denoiser": model["denoiser"]["kind"],
        "representation": model["representation"],
        "training_step": solver.metadata["metrics"].get("step"),
    }


# ---------------------------------------------------------------------------
# The four measurements


def measure_accuracy(path: str, config: BenchmarkConfig) -> dict:
    """Raw 80-step DDPM, K=1: tip error, and the share within 1e-4 after refinement; the baseline beside it."""
    solver = ikdp.load(REPO_ROOT / path)
    reach = sum(solver.lengths)
    targets = random_targets(solver.lengths, config.accuracy_targets, config.seed)

    def solve():
        return solver.solve(
            targets, num_samples=1, sampler="ddpm", refine_steps=config.refine_steps, generator=seeded(config.seed + 1)
        )

    seconds, out = time_call(solve, repeats=1, warmup=min(config.warmup, 1))
    return {
        "checkpoint": checkpoint_identity(path, solver),
        "targets": len(targets),
        "reach": reach,
        "raw_ddpm": error_summary(out.raw_tip_error[:, 0], reach),
        "refined": error_summary(out.tip_error[:, 0], reach),
        "ikdp": timing_summary(seconds, len(targets)),
        "dls": run_dls(targets, solver.lengths, config, repeats=1),
    }


def measure_latency(solver: ikdp.Solver, config: BenchmarkConfig) -> dict:
    """One target, K samples, the full DDPM chain with its trajectory: what the viewer asks for."""
    target = random_targets(solver.lengths, 1, config.seed)

    def solve():
        return solver.solve(
            target,
            num_samples=config.latency_samples,
            sampler="ddpm",
            generator=seeded(config.seed + 1),
            return_trajectory=True,
        )

    seconds, _ = time_call(solve, repeats=config.latency_repeats, warmup=max(config.warmup, 3))
    return {
        "samples": config.latency_samples,
        "repeats": config.latency_repeats,
        "ikdp": timing_summary(seconds, 1),
        "dls": run_dls(target, solver.lengths, config, repeats=config.latency_repeats),
    }


def measure_throughput(solver: ikdp.Solver, config: BenchmarkConfig) -> dict:
    """Many targets, one sample each: the 80-step DDPM and the DDIM shortcut."""
    targets = random_targets(solver.lengths, config.throughput_targets, config.seed)
    reach = sum(solver.lengths)
    runs = {}
    for name, sampler, steps in (("ddpm", "ddpm", None), (f"ddim{config.ddim_steps}", "ddim", config.ddim_steps)):

        def solve(sampler=sampler, steps=steps):
            return solver.solve(targets, num_samples=1, sampler=sampler, steps=steps, generator=seeded(config.seed + 1))

        seconds, out = time_call(solve, repeats=config.throughput_repeats, warmup=min(config.warmup, 1))
        runs[name] = timing_summary(seconds, len(targets)) | {
            "raw_error": error_summary(out.raw_tip_error[:, 0], reach)
        }
    return {
        "targets": len(targets),
        "repeats": config.throughput_repeats,
        **runs,
        "dls": run_dls(targets, solver.lengths, config, repeats=config.throughput_repeats),
    }


def measure_batch(solver: ikdp.Solver, config: BenchmarkConfig) -> dict:
    """K poses per target, DDIM + refinement; solved when one of the K is within 1e-4."""
    targets = random_targets(solver.lengths, config.batch_targets, config.seed)
    reach = sum(solver.lengths)

    def solve():
        return solver.solve(
            targets,
            num_samples=config.batch_samples,
            sampler="ddim",
            steps=config.ddim_steps,
            refine_steps=config.refine_steps,
            generator=seeded(config.seed + 1),
        )

    seconds, out = time_call(solve, repeats=config.batch_repeats, warmup=config.warmup)
    return {
        "targets": len(targets),
        "samples": config.batch_samples,
        "repeats": config.batch_repeats,
        "ikdp": timing_summary(seconds, len(targets))
        | {"best_error": error_summary(out.tip_error.min(dim=1).values, reach)},
        "dls": run_dls(targets, solver.lengths, config, repeats=config.batch_repeats),
        "pytorch_kinematics": run_pytorch_kinematics(targets, solver.lengths, config),
    }


def run_pytorch_kinematics(targets: torch.Tensor, lengths, config: BenchmarkConfig) -> dict:
    """PseudoInverseIK in its own environment (benchmarks/pk_chain.py); its answers are checked here, by ikdp's FK."""
    python = REPO_ROOT / config.pk_python if config.pk_python else None
    if python is None or not python.exists():
        note = f"skipped: no interpreter at {config.pk_python!r} (see benchmarks/requirements-bench.txt)"
        print(f"pytorch_kinematics {note}")
        return {"skipped": note}
    settings = PkSettings()
    # its default: R uniform starts within the joint range, shared by every target; drawn here so the seed is ours
    retry_configs = uniform_angles((config.batch_samples, len(lengths)), generator=seeded(config.seed + 3))
    request = {
        "targets": targets,
        "lengths": list(lengths),
        "retry_configs": retry_configs,
        "settings": asdict(settings),
        "repeats": config.batch_repeats,
        "warmup": config.warmup,
        "threads": config.threads,
    }
    with tempfile.TemporaryDirectory() as folder:
        request_path, result_path = Path(folder) / "request.pt", Path(folder) / "result.pt"
        torch.save(request, request_path)
        subprocess.run(
            [str(python), "-m", "benchmarks.pk_chain", str(request_path), str(result_path)], cwd=REPO_ROOT, check=True
        )
        result = torch.load(result_path, weights_only=True)
    headings = torch.cumsum(result["joint_angles"].double(), dim=-1)  # (B, R, N) relative -> absolute
    tip_error = PlanarArm(lengths).tip_error(headings, targets[:, None])
    return timing_summary(result["seconds"], len(targets)) | {
        "best_error": error_summary(tip_error.min(dim=1).values, sum(lengths)),
        "share_converged_by_its_own_check": result["converged_any"].double().mean().item(),
        "iterations_run": result["iterations"],
        "retries": config.batch_samples,
        "settings": result["settings"] | {"rot_tolerance": "inf", "orientation_weight": 0.0, "dtype": result["dtype"]},
        "version": result["library_version"],
        "torch_version": result["torch_version"],
        "threads": result["threads"],
    }


# ---------------------------------------------------------------------------
# The targets the planar solver is held to, the table and the environment


def goals(results: dict) -> list[dict]:
    """Each target the planar solver is held to, the number measured for it and whether it is met (None: quick
    sizes, not judged)."""
    config = results["config"]
    rows = []

    def goal(text: str, measured: str, met: bool) -> None:
        rows.append({"goal": text, "measured": measured, "met": None if config["quick"] else bool(met)})

    accuracy = results["accuracy"].get(Path(config["speed_checkpoint"]).stem, {})
    if "raw_ddpm" in accuracy:
        median, share = accuracy["raw_ddpm"]["median"], accuracy["refined"]["share_within_tolerance"]
        goal("N=4, raw DDPM-80, K=1: median tip error <= 0.01", f"{median:.4f}", median <= 0.01)
        steps = config["refine_steps"]
        goal(f"N=4, + {steps} refinement steps: share within 1e-4 >= 99.9 %", f"{100 * share:.2f} %", share >= 0.999)
    latency = results["latency"]["ikdp"]["median_seconds"]
    goal("latency, 1 target, K=16, DDPM-80 + trajectory: <= 10 ms", f"{1e3 * latency:.1f} ms", latency <= 0.010)
    throughput = results["throughput"]
    ddim = throughput[f"ddim{config['ddim_steps']}"]["median_seconds"]
    goal(
        f"throughput, {throughput['targets']:,} targets, DDIM-{config['ddim_steps']}: <= 1 s",
        f"{ddim:.2f} s",
        ddim <= 1,
    )
    batch, pk = results["batch"]["ikdp"], results["batch"]["pytorch_kinematics"]
    if "skipped" not in pk:
        ikdp_ms, pk_ms = batch["median_ms_per_target"], pk["median_ms_per_target"]
        ikdp_share = batch["best_error"]["share_within_tolerance"]
        pk_share = pk["best_error"]["share_within_tolerance"]
        goal(
            "batch solving: IKDP faster per target than pytorch_kinematics, at an equal or higher share within 1e-4",
            f"{ikdp_ms:.3f} vs {pk_ms:.3f} ms/target; {100 * ikdp_share:.2f} vs {100 * pk_share:.2f} %",
            ikdp_ms < pk_ms and ikdp_share >= pk_share,
        )
    return rows


def format_error(value: float) -> str:
    return f"{value:.4f}" if value >= 1e-3 else f"{value:.1e}"


def format_share(summary: dict) -> str:
    return f"{100 * summary['share_within_tolerance']:.2f} %"


def format_repeats(count: int) -> str:
    return f"{count} repeat" + ("s" if count != 1 else "")


def format_ratio(ikdp_run: dict, baseline_run: dict) -> str:
    return f"{ikdp_run['median_seconds'] / baseline_run['median_seconds']:.1f}x"


def render_accuracy(results: dict, baseline: str) -> list[str]:
    config = results["config"]
    lines = [
        f"**Accuracy**: {config['accuracy_targets']:,} targets per model, one 80-step DDPM sample each (K=1), "
        f"raw tip error in bone lengths; then the share within 1e-4 after {config['refine_steps']} refinement "
        f"steps. Beside it the baseline ({baseline}), best of its starts, and the time ratio of the two calls.",
        "",
        "| model | N | training step | median | mean | p95 | median, % of reach | within 1e-4 refined "
        "| baseline median | baseline within 1e-4 | time IKDP / baseline |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, row in results["accuracy"].items():
        if "skipped" in row:
            lines.append(f"| {name} | | | {row['skipped']} | | | | | | | |")
            continue
        raw, dls = row["raw_ddpm"], row["dls"]
        lines.append(
            f"| {name} | {row['checkpoint']['num_links']} | {row['checkpoint']['training_step']} "
            f"| {format_error(raw['median'])} | {format_error(raw['mean'])} | {format_error(raw['p95'])} "
            f"| {raw['median_percent_of_reach']:.2f} % | {format_share(row['refined'])} "
            f"| {format_error(dls['best_error']['median'])} | {format_share(dls['best_error'])} "
            f"| {format_ratio(row['ikdp'], dls)} |"
        )
    return lines


def render_speed(results: dict, baseline: str) -> list[str]:
    config, latency, throughput = results["config"], results["latency"], results["throughput"]
    lines = [
        f"**Speed** of {Path(config['speed_checkpoint']).name}: medians of the timed repeats, after warm-up. "
        f"The baseline ({baseline}) is timed on the same targets in the same run.",
        "",
        "| measurement | IKDP | baseline | IKDP / baseline |",
        "|---|---|---|---|",
        f"| latency: 1 target, K={latency['samples']}, DDPM-80 + trajectory, {format_repeats(latency['repeats'])} "
        f"| {1e3 * latency['ikdp']['median_seconds']:.1f} ms | {1e3 * latency['dls']['median_seconds']:.1f} ms "
        f"| {format_ratio(latency['ikdp'], latency['dls'])} |",
    ]
    for name, label in (("ddpm", "DDPM-80"), (f"ddim{config['ddim_steps']}", f"DDIM-{config['ddim_steps']}")):
        run = throughput[name]
        lines.append(
            f"| throughput: {throughput['targets']:,} targets, K=1, {label}, {format_repeats(throughput['repeats'])} "
            f"(raw median error {format_error(run['raw_error']['median'])}) "
            f"| {run['median_seconds']:.2f} s | {throughput['dls']['median_seconds']:.2f} s "
            f"| {format_ratio(run, throughput['dls'])} |"
        )
    return lines


def render_batch(results: dict, baseline: str) -> list[str]:
    config, batch = results["config"], results["batch"]
    lines = [
        f"**Batch solving**: {batch['targets']:,} targets, K={batch['samples']} per target, "
        f"{format_repeats(batch['repeats'])}; a target is solved when one of its K poses has its tip within 1e-4.",
        "",
        "| solver | ms / target | within 1e-4 | median best error |",
        "|---|---|---|---|",
    ]
    solvers = [
        (f"IKDP, DDIM-{config['ddim_steps']} + {config['refine_steps']} refinement steps", batch["ikdp"]),
        (baseline, batch["dls"]),
    ]
    pk = batch["pytorch_kinematics"]
    if "skipped" in pk:
        label = f"pytorch_kinematics PseudoInverseIK: {pk['skipped']}"
    else:
        label = (
            f"pytorch_kinematics {pk['version']} PseudoInverseIK, {pk['retries']} retries, position only, "
            f"at most {pk['settings']['max_iterations']} it. ({pk['iterations_run']} run)"
        )
        solvers.append((label, pk))
    for name, run in solvers:
        lines.append(
            f"| {name} | {run['median_ms_per_target']:.3f} | {format_share(run['best_error'])} "
            f"| {format_error(run['best_error']['median'])} |"
        )
    if "skipped" in pk:
        lines.append(f"| {label} | | | |")
    return lines


def render_markdown(results: dict) -> str:
    """The tables printed after a run, from the JSON alone."""
    config, env = results["config"], results["environment"]
    baseline = f"DLS from random starts, {config['dls_restarts']} starts x {config['dls_iterations']} it."
    lines = [
        f"Run {env['date']} on {env['cpu_model']} ({env['usable_cpus']} usable cores; load average "
        f"{env['load_average_at_start']:.1f} at start, {env['load_average_at_end']:.1f} at end), "
        f"torch {env['torch']}, {env['threads']} threads, git {env['git_commit']}, seed {config['seed']}."
        + (" **Quick run: reduced sizes.**" if config["quick"] else ""),
        "",
        *render_accuracy(results, baseline),
        "",
        *render_speed(results, baseline),
        "",
        *render_batch(results, baseline),
        "",
        "**The targets**",
        "",
        "| target | measured | met |",
        "|---|---|---|",
    ]
    for row in results["goals"]:
        met = {True: "yes", False: "**no**", None: "not judged: quick sizes"}[row["met"]]
        lines.append(f"| {row['goal']} | {row['measured']} | {met} |")
    return "\n".join(lines)


def git_commit() -> str:
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO_ROOT, capture_output=True, text=True)
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO_ROOT, capture_output=True, text=True
        )
    except OSError:
        return "unknown"
    return commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def environment() -> dict:
    return {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "cpu_model": cpu_model(),
        "logical_cpus": os.cpu_count(),
        "usable_cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "load_average_at_start": os.getloadavg()[0],
        "threads": torch.get_num_threads(),
        "torch": torch.__version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "ikdp": ikdp.__version__,
        "git_commit": git_commit(),
    }


# ---------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> None:
    config = tyro.cli(BenchmarkConfig, args=argv, description=__doc__.splitlines()[0])
    output = REPO_ROOT / config.output
    if config.quick:  # a size given on the command line wins over the quick one
        given = {word[2:].split("=")[0].replace("-", "_") for word in (argv or sys.argv[1:]) if word.startswith("--")}
        config = dataclasses.replace(config, **{name: size for name, size in QUICK_SIZES.items() if name not in given})
    if not (REPO_ROOT / config.speed_checkpoint).exists():
        raise SystemExit(f"speed_checkpoint: {config.speed_checkpoint} not found")
    torch.set_num_threads(config.threads)
    results = {"config": asdict(config), "environment": environment(), "success_tolerance": SUCCESS_TOLERANCE}
    print(f"{results['environment']['cpu_model']}, torch {torch.__version__}, {torch.get_num_threads()} threads")

    results["accuracy"] = {}
    for path in config.checkpoints:
        name = Path(path).stem
        if not (REPO_ROOT / path).exists():
            print(f"accuracy: {path} not found, skipped")
            results["accuracy"][name] = {"skipped": "checkpoint not found"}
            continue
        print(f"accuracy: {name} ...", flush=True)
        results["accuracy"][name] = measure_accuracy(path, config)

    solver = ikdp.load(REPO_ROOT / config.speed_checkpoint)
    print("latency ...", flush=True)
    results["latency"] = measure_latency(solver, config)
    print("throughput ...", flush=True)
    results["throughput"] = measure_throughput(solver, config)
    print("batch solving ...", flush=True)
    results["batch"] = measure_batch(solver, config)
    results["environment"]["load_average_at_end"] = os.getloadavg()[0]
    results["goals"] = goals(results)

    table = render_markdown(results)
    print()
    print(table)
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(results, indent=2) + "\n")
    print(f"\nresults: {output}")


if __name__ == "__main__":
    main()
