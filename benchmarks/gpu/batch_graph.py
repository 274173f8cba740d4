"""GPU: the Panda's K = 16 + refinement for 1000 and 10,000 targets, eager `solve` against its CUDA graph
(`solver.capture`, ikdp/cuda_graph.py), beside pytorch_kinematics' PseudoInverseIK on the same GPU and in the same
process: what capturing the whole solve saves where kernel launches, not arithmetic, set the pace. A target is
solved when one of its poses is within 1 mm and 1 degree.

    python -m benchmarks.gpu.batch_graph PANDA_URDF      # JSON to $OUT/batch_graph.json (else /tmp)
    python -m benchmarks.gpu.batch_graph PANDA_URDF cpu  # a dry run of the script: every graph row an error

Every row is timed `repeats` times after a warm-up, the median quoted, with a CUDA synchronize inside the timing;
poses are judged by robot_benchmark's own `verdict`, the rule of the CPU rows.
"""

# ruff: noqa: B023  (each lambda is timed at once, inside its loop turn)
from __future__ import annotations

import json
import math
import os
import sys
import time
import traceback
from pathlib import Path

import torch

import ikdp
from benchmarks.robot_benchmark import median_seconds, verdict

URDF = sys.argv[1] if len(sys.argv) > 1 else ".gpu/panda.urdf"
DEVICE = sys.argv[2] if len(sys.argv) > 2 else "cuda"
synchronize = torch.cuda.synchronize if DEVICE == "cuda" else (lambda: None)
OUT = Path(os.environ.get("OUT", "/tmp")) / "batch_graph.json"
COUNTS = tuple(int(c) for c in os.environ.get("COUNTS", "1000,10000").split(","))
SAMPLES = 16
SKIP = set(os.environ.get("SKIP", "").split(","))  # pipeline labels "name sampler:steps+refine[rRESTART]" to leave out
# (checkpoint, sampler, steps, refine, restart): the CPU's fastest rows, and the teacher rows measured before
PIPELINES = (
    ("ikdp_panda_fast", "ddim", 1, 8, 0),
    ("ikdp_panda_fast", "ddim", 1, 5, 0),
    ("ikdp_panda_fast", "ddim", 1, 10, 0),
    ("ikdp_panda_fast", "ddim", 1, 4, 10),
    ("ikdp_panda_fast", "ddim", 1, 6, 10),
    ("ikdp_panda_fast", "ddim", 1, 8, 10),
    ("ikdp_panda", "ddim", 3, 5, 0),
    ("ikdp_panda", "dpmpp2m", 10, 5, 0),
)
PK_SETTINGS = tuple(
    tuple(int(n) for n in text.split("x")) for text in os.environ.get("PK", "16x30,16x20,8x30").split(",") if text
)
GRAPHS = tuple(os.environ.get("GRAPHS", "graph,fused").split(","))  # fused: each DLS step torch.compile'd

results: dict = {
    "gpu": torch.cuda.get_device_name() if DEVICE == "cuda" else DEVICE,
    "torch": torch.__version__,
    "samples": SAMPLES,
    "rule": "solved: a pose within 1 mm and 1 degree; seconds: median per whole batch",
    "rows": {},
}


def save() -> None:
    OUT.write_text(json.dumps(results, indent=1))


def timed(run, repeats: int) -> tuple[float, object]:
    """robot_benchmark's median of `repeats` runs, after a warm-up, each run waited for on the GPU."""

    def synced():
        answer = run()
        synchronize()
        return answer

    synced()
    return median_seconds(synced, repeats)


def row(name: str, values: dict) -> None:
    results["rows"][name] = values
    save()
    print(f"{name:58s} {json.dumps(values)}", flush=True)


solvers = {name: ikdp.load(name, device=DEVICE) for name in {p[0] for p in PIPELINES}}
arm = solvers["ikdp_panda"].arm
all_targets = arm.end_effector(arm.random_poses(max(COUNTS), generator=torch.Generator().manual_seed(0))).to(DEVICE)

# one target, K = 16: the latency a GPU viewer would see
for name, sampler, steps, refine, restart in PIPELINES[:1]:
    solver = solvers[name]
    one = all_targets[:1]
    options = dict(num_samples=SAMPLES, sampler=sampler, steps=steps, refine_steps=refine, restart_steps=restart)
    values = {}
    try:
        values["eager_ms"] = (
            1e3 * timed(lambda: solver.solve(one, generator=torch.Generator(DEVICE).manual_seed(0), **options), 15)[0]
        )
        captured = solver.capture(1, **options)
        values["graph_ms"] = 1e3 * timed(lambda: captured(one, seed=0), 15)[0]
    except Exception:
        values["error"] = traceback.format_exc()[-1500:]
    row(f"one target {name} {sampler}:{steps}+{refine}r{restart}", values)

for count in COUNTS:
    targets = all_targets[:count]
    for name, sampler, steps, refine, restart in PIPELINES:
        solver = solvers[name]
        pipeline = f"{name} {sampler}:{steps}+{refine}" + (f"r{restart}" if restart else "")
        if pipeline in SKIP:
            continue
        label = f"{count} x {SAMPLES} {pipeline}"
        options = dict(num_samples=SAMPLES, sampler=sampler, steps=steps, refine_steps=refine, restart_steps=restart)
        values: dict = {}
        try:
            seconds, eager = timed(
                lambda: solver.solve(targets, generator=torch.Generator(DEVICE).manual_seed(2), **options), 3
            )
            values["eager_ms"] = seconds * 1e3
            values["eager"] = verdict(arm, eager.angles, targets)
            for kind in GRAPHS:
                start = time.perf_counter()
                captured = solver.capture(count, fused=kind == "fused", **options)
                synchronize()
                values[f"{kind}_capture_s"] = time.perf_counter() - start
                seconds, replayed = timed(lambda: captured(targets, seed=2), 15)
                values[f"{kind}_ms"] = seconds * 1e3
                values[kind] = verdict(arm, replayed.angles, targets)
                if not restart:  # the same seed, the same noise: the graph must give the eager poses
                    values[f"{kind}_raw_max_abs_diff_rad"] = float((replayed.raw_angles - eager.raw_angles).abs().max())
                    values[f"{kind}_max_abs_diff_rad"] = float((replayed.angles - eager.angles).abs().max())
                row(label, values)
            values["network_evaluations"] = replayed.network_evaluations
            values["peak_memory_gb"] = torch.cuda.max_memory_allocated() / 1e9 if DEVICE == "cuda" else None
        except Exception:
            values["error"] = traceback.format_exc()[-1500:]
        row(label, values)
        if DEVICE == "cuda":
            torch.cuda.empty_cache()

    try:
        import pytorch_kinematics as pk

        chain = pk.build_serial_chain_from_urdf(Path(URDF).read_bytes(), arm.ee_link).to(device=DEVICE)
        limits = arm.joint_limits.to(DEVICE)
        goal = pk.Transform3d(pos=targets[:, :3], rot=targets[:, 3:], device=DEVICE)
        for retries, iterations in PK_SETTINGS:
            unit = torch.rand(retries, arm.num_joints, generator=torch.Generator().manual_seed(9)).to(DEVICE)
            ik = pk.PseudoInverseIK(
                chain,
                retry_configs=limits[:, 0] + unit * (limits[:, 1] - limits[:, 0]),
                joint_limits=limits,
                max_iterations=iterations,
                pos_tolerance=1e-3,
                rot_tolerance=math.radians(1),
                early_stopping_any_converged=True,
            )
            seconds, solution = timed(lambda: ik.solve(goal), 5)
            joints = solution.solutions.detach().float()
            row(
                f"{count} x {retries} PseudoInverseIK {retries}x{iterations}",
                {"ms": seconds * 1e3, **verdict(arm, joints, targets)},
            )
    except Exception:
        row(f"{count} PseudoInverseIK", {"error": traceback.format_exc()[-1500:]})
print(json.dumps(results), flush=True)

if os.environ.get("PROFILE"):  # where a fused solve's GPU time goes, kernel by kernel (the eager body, compiled parts)
    from ikdp.cuda_graph import solve_without_sync
    from ikdp.refine import sync_free_iteration
    from ikdp.samplers import make_sampler

    name, sampler, steps, refine, restart = PIPELINES[3]
    solver = solvers[name]
    targets = all_targets[: COUNTS[0]]
    fused = dict(
        iteration=torch.compile(sync_free_iteration, dynamic=False),
        errors=torch.compile(solver.arm.tip_and_rotation_errors, dynamic=False),
    )
    loop = make_sampler(sampler, solver.model.schedule, steps, solver.default_spacing(sampler, steps))
    body = dict(num_samples=SAMPLES, refine_steps=refine, restart_steps=restart, **fused)
    for _ in range(2):
        solve_without_sync(solver, loop, targets, generator=torch.Generator(DEVICE).manual_seed(0), **body)
    synchronize()
    activity = torch.profiler.ProfilerActivity.CUDA if DEVICE == "cuda" else torch.profiler.ProfilerActivity.CPU
    with torch.profiler.profile(activities=[activity]) as profile:
        solve_without_sync(solver, loop, targets, generator=torch.Generator(DEVICE).manual_seed(0), **body)
        synchronize()
    table = profile.key_averages().table(sort_by=f"{DEVICE}_time_total", row_limit=25, max_name_column_width=70)
    (OUT.parent / "profile.txt").write_text(table)
    print(table, flush=True)
