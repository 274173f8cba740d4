"""One target at a time on one CPU thread, as a control loop asks: a solve's latency from the call to the answer,
and a 1000-step stream, for the planar arm, the Panda and the Z1, beside pytorch_kinematics in the same run.

    OMP_NUM_THREADS=1 python -m benchmarks.one_target_latency

For each model, `targets` held-out targets (the end effector of uniform poses within the limits) are solved one
call each, K = 16, by the model's fastest verified pipeline (`MODELS`: its refinement stops once a pose is within
the tolerances), through `solver.solve` three times per target in turn: as it runs (`fused`: a few poses on a CPU
take the fused kinematics of ikdp/fused_chain.py, the network's condition from its table), the same through every
refinement step (`every step`), and with the fused path switched off (`general`: the code before it), so that the
machine's load hits all alike. The
same targets in one batch call give the batch figure (the fused path leaves it alone: above FUSED_ROWS poses).
A target is solved when one of its poses is within the arm's tolerances (1 mm and 1 degree on a robot).
pytorch_kinematics' PseudoInverseIK (16 retries x 50 iterations, its solver built once) answers the same
robot targets one call each, and TRAC-IK (its `pytracik` bindings, when installed: not an IKDP dependency)
from the middle of the limits with its default 5 ms timeout and 1e-5 tolerance.

The stream: a smooth path of `stream_steps` targets (a straight joint-space sweep's end-effector poses, 1 ms
apart at 1 kHz), followed by `solver.stream` (fused and general), by `solver.track` over its first
`track_steps` targets, by PseudoInverseIK warm-started from the last answer (one retry, `pk_stream_iterations`),
and by TRAC-IK seeded with the last answer. Medians per call, the share of targets reached, the largest joint
jump between calls. Writes benchmarks/results/one_target_latency.json.
"""

from __future__ import annotations

import importlib.util
import json
import math
import statistics
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import tyro

import ikdp
import ikdp.fused_chain
import ikdp.sampling
from ikdp.constraint_base import joint_difference
from ikdp.evaluation.machine import machine_description

RESULTS = Path(__file__).resolve().parent / "results" / "one_target_latency.json"

# the 1-step seed of the fastest CPU Panda pipeline (checkpoints/README.md), under its shipped name
PANDA_FAST = "ikdp_panda_fast"
# model -> solve's options: each model's fastest pipeline at >= 99.5 % of targets within the tolerances; the
# refinement stops once one of the K poses is within them (at most 4 steps)
MODELS = {
    "ikdp_n4": {"sampler": "ddim", "steps": 2, "refine_steps": 4, "restart_steps": 10, "stop_when_reached": True},
    PANDA_FAST: {"sampler": "ddim", "steps": 1, "refine_steps": 4, "restart_steps": 10, "stop_when_reached": True},
    "ikdp_z1": {"sampler": "ddim", "steps": 1, "refine_steps": 4, "restart_steps": 10, "stop_when_reached": True},
}


@dataclass(frozen=True)
class LatencyConfig:
    models: tuple[str, ...] = tuple(MODELS)
    targets: int = 200
    samples: int = 16
    stream_steps: int = 1000
    track_steps: int = 30
    pk_retries: int = 16
    pk_iterations: int = 50
    pk_stream_iterations: int = 10
    trac_ik_timeout: float = 0.005  # seconds: TRAC-IK's default; its rows need `pip install pytracik`
    seed: int = 0
    output: Path = field(default=RESULTS)


@contextmanager
def general_path():
    """solve, stream and track as before the fused path: the arm's own kinematics for every batch, and the
    conditions sized by a call of their own."""
    rows, few = ikdp.fused_chain.FUSED_ROWS, ikdp.sampling.FEW_CONDITIONS
    ikdp.fused_chain.FUSED_ROWS, ikdp.sampling.FEW_CONDITIONS = 0, 0
    try:
        yield
    finally:
        ikdp.fused_chain.FUSED_ROWS, ikdp.sampling.FEW_CONDITIONS = rows, few


def within(arm, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """joints (B, K, J), targets (B, target_dim) -> (B, K) True within the arm's tolerances."""
    goals = targets[:, None].expand(-1, joints.shape[1], -1)
    position, rotation = arm.tip_and_rotation_errors(joints, goals)
    ok = position < arm.position_tolerance
    return ok if rotation is None else ok & (rotation < arm.rotation_tolerance)


def timing_row(seconds: list[float], solved: torch.Tensor | None = None, valid: torch.Tensor | None = None) -> dict:
    ordered = sorted(seconds)
    row = {
        "median_ms": statistics.median(seconds) * 1e3,
        # on a shared machine the low tail is what a quiet one gives more nearly
        "p10_ms": ordered[int(0.1 * (len(ordered) - 1))] * 1e3,
        "p90_ms": ordered[int(0.9 * (len(ordered) - 1))] * 1e3,
        "calls": len(seconds),
    }
    if solved is not None:
        row["success_share"] = float(solved.double().mean())
    if valid is not None:
        row["valid_per_target"] = float(valid.double().mean())
    return row


def one_target_rows(solver, targets: torch.Tensor, options: dict, samples: int) -> dict:
    """The fused and general solves, and the fused one through every refinement step, one target a call, in turn;
    then the whole batch in one call."""
    arm = solver.arm
    every_step = {**options, "stop_when_reached": False}
    seconds = {"IKDP solve, fused": [], "IKDP solve, fused, every step": [], "IKDP solve, general (before)": []}
    answers = {label: [] for label in seconds}
    for index in range(len(targets)):
        for label in seconds:
            generator = torch.Generator().manual_seed(index)
            with general_path() if "general" in label else _nothing():
                started = time.perf_counter()
                out = solver.solve(
                    targets[index : index + 1],
                    num_samples=samples,
                    generator=generator,
                    **(every_step if "every step" in label else options),
                )
                seconds[label].append(time.perf_counter() - started)
            answers[label].append(out.angles)
    rows = {}
    for label, angles in answers.items():
        ok = within(arm, torch.cat(angles), targets)
        rows[label] = timing_row(seconds[label], ok.any(-1), ok.sum(-1))
    started = time.perf_counter()
    out = solver.solve(targets, num_samples=samples, generator=torch.Generator().manual_seed(0), **options)
    elapsed = time.perf_counter() - started
    ok = within(arm, out.angles, targets)
    rows[f"IKDP batch of {len(targets)}, per target"] = {
        "median_ms": elapsed * 1e3 / len(targets),
        "success_share": float(ok.any(-1).double().mean()),
        "valid_per_target": float(ok.sum(-1).double().mean()),
        "calls": 1,
    }
    return rows


@contextmanager
def _nothing():
    yield


def pk_solver(arm, retries: int, iterations: int, seed: int):
    import pytorch_kinematics as pk

    chain = pk.build_serial_chain_from_urdf(Path(arm.urdf_path).read_bytes(), arm.ee_link)
    limits = arm.joint_limits
    retry = torch.rand(retries, arm.num_joints, generator=torch.Generator().manual_seed(seed + 9))
    retry = limits[:, 0] + retry * (limits[:, 1] - limits[:, 0])
    return pk, pk.PseudoInverseIK(
        chain,
        retry_configs=retry,
        joint_limits=limits,
        max_iterations=iterations,
        pos_tolerance=arm.position_tolerance,
        rot_tolerance=arm.rotation_tolerance,
        early_stopping_any_converged=True,
    )


def pk_one_target_row(arm, targets: torch.Tensor, config: LatencyConfig) -> dict:
    pk, solver = pk_solver(arm, config.pk_retries, config.pk_iterations, config.seed)
    seconds, answers = [], []
    for target in targets:
        started = time.perf_counter()
        goal = pk.Transform3d(pos=target[None, :3], rot=target[None, 3:])  # pk's quaternions are (w, x, y, z)
        answers.append(solver.solve(goal).solutions.detach().float())
        seconds.append(time.perf_counter() - started)
    ok = within(arm, torch.cat(answers), targets)
    return timing_row(seconds, ok.any(-1), ok.sum(-1))


def trac_ik_solver(arm, timeout: float):
    """TRAC-IK (the `pytracik` wheel's bindings) for the arm's chain, its limits set from the arm's (its URDF
    reader read the Panda's as zero); None where the package is not installed."""
    if importlib.util.find_spec("pytracik") is None:
        return None
    import pytracik

    solver = pytracik.TRAC_IK(
        arm.base_link, arm.ee_link, Path(arm.urdf_path).read_text(), timeout, 1e-5, pytracik.SolveType.Speed
    )
    limits = arm.joint_limits.double().numpy()
    pytracik.set_joint_limits(solver, limits[:, 0], limits[:, 1])

    def solve(target: torch.Tensor, seed) -> torch.Tensor | None:
        """One pose target (7,) from the seed joints -> (J,), or None where it found none in its time."""
        x, y, z, w, qx, qy, qz = target.double().tolist()
        answer = pytracik.ik(solver, seed, x, y, z, qx, qy, qz, w)  # its quaternion is (x, y, z, w)
        return None if answer[0] < 0 else torch.tensor(answer[1:], dtype=torch.float32)

    return solve


def trac_ik_one_target_row(arm, targets: torch.Tensor, config: LatencyConfig) -> dict | None:
    solve = trac_ik_solver(arm, config.trac_ik_timeout)
    if solve is None:
        return None
    middle = arm.joint_limits.double().mean(dim=-1).numpy()  # one fixed seed: the middle of the limits
    seconds, answers = [], []
    for target in targets:
        started = time.perf_counter()
        pose = solve(target, middle)
        seconds.append(time.perf_counter() - started)
        answers.append(torch.full((arm.num_joints,), math.nan) if pose is None else pose)
    ok = within(arm, torch.stack(answers)[:, None], targets)
    return timing_row(seconds, ok.any(-1), ok.sum(-1))


def smooth_path(arm, steps: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """A straight joint-space sweep over half the way between two uniform poses (a robot's; a planar arm's
    headings whole), its end effector at `steps` points: (start pose (J,), targets (steps, target_dim))."""
    first, second = arm.random_poses(2, generator=torch.Generator().manual_seed(seed + 5))
    if arm.kind == "chain":
        middle = (first + second) / 2
        first, second = middle - (second - first) / 4, middle + (second - first) / 4
    fractions = torch.linspace(0, 1, steps)[:, None]
    return first, arm.end_effector(first + fractions * (second - first))


def largest_jump(arm, start: torch.Tensor, angles: torch.Tensor) -> float:
    """The largest joint change between consecutive answers (P, J), the start first; headings the short way."""
    before = torch.cat([start[None], angles[:-1]])
    return float(joint_difference(arm, angles, before).abs().max())


def stream_rows(solver, config: LatencyConfig) -> dict:
    arm = solver.arm
    start, path = smooth_path(arm, config.stream_steps, config.seed)
    rows = {}
    for label, context in (("IKDP stream, fused", _nothing), ("IKDP stream, general kinematics", general_path)):
        with context():
            stream = solver.stream(start)
            seconds, poses = [], []
            for target in path:
                started = time.perf_counter()
                poses.append(stream(target))
                seconds.append(time.perf_counter() - started)
        angles = torch.stack(poses)
        rows[label] = {
            **timing_row(seconds, within(arm, angles[:, None], path).any(-1)),
            "largest_jump_rad": largest_jump(arm, start, angles),
            "fallbacks": stream.fallbacks,
        }
    options = MODELS.get(config_name(solver), {})
    options = {key: value for key, value in options.items() if key not in ("restart_steps", "stop_when_reached")}
    started = time.perf_counter()
    tracked = solver.track(path[: config.track_steps], start, num_samples=config.samples, **options)
    elapsed = time.perf_counter() - started
    rows[f"IKDP track, first {config.track_steps}"] = {
        "median_ms": elapsed * 1e3 / config.track_steps,
        "success_share": float(tracked.reached.double().mean()),
        "largest_jump_rad": tracked.largest_jump,
        "calls": 1,
    }
    if arm.kind == "chain" and arm.target_dim == 7:
        pk, pk_stream = pk_solver(arm, 1, config.pk_stream_iterations, config.seed)
        previous, seconds, poses = start.clone(), [], []
        for target in path:
            started = time.perf_counter()
            pk_stream.initial_config = previous[None]
            goal = pk.Transform3d(pos=target[None, :3], rot=target[None, 3:])
            previous = pk_stream.solve(goal).solutions.detach().float()[0, 0]
            seconds.append(time.perf_counter() - started)
            poses.append(previous)
        angles = torch.stack(poses)
        rows[f"PseudoInverseIK warm-started 1x{config.pk_stream_iterations}"] = {
            **timing_row(seconds, within(arm, angles[:, None], path).any(-1)),
            "largest_jump_rad": largest_jump(arm, start, angles),
        }
        solve = trac_ik_solver(arm, config.trac_ik_timeout)
        if solve is not None:
            previous, seconds, poses = start.clone(), [], []
            for target in path:
                started = time.perf_counter()
                pose = solve(target, previous.double().numpy())
                previous = previous if pose is None else pose  # none found: the arm stays
                seconds.append(time.perf_counter() - started)
                poses.append(previous)
            angles = torch.stack(poses)
            rows["TRAC-IK warm-started"] = {
                **timing_row(seconds, within(arm, angles[:, None], path).any(-1)),
                "largest_jump_rad": largest_jump(arm, start, angles),
            }
    return rows


def config_name(solver) -> str:
    return Path(solver.metadata["path"]).stem


def print_table(name: str, rows: dict) -> None:
    print(f"\n{name}")
    print(f"{'row':<42} {'median ms':>10} {'p10 ms':>8} {'p90 ms':>8} {'solved %':>9} {'valid':>6} {'jump rad':>9}")
    for label, row in rows.items():
        solved = row.get("success_share")
        print(
            f"{label:<42} {row['median_ms']:>10.3f} {row.get('p10_ms', math.nan):>8.3f} "
            f"{row.get('p90_ms', math.nan):>8.3f} "
            f"{'' if solved is None else f'{100 * solved:.1f}':>9} {row.get('valid_per_target', math.nan):>6.1f} "
            f"{row.get('largest_jump_rad', math.nan):>9.4f}"
        )


def main(config: LatencyConfig) -> dict:
    torch.set_num_threads(1)
    results: dict = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1)}
    for name in config.models:
        solver = ikdp.load(name)
        arm = solver.arm
        options = MODELS[name]
        targets = arm.end_effector(
            arm.random_poses(config.targets, generator=torch.Generator().manual_seed(config.seed))
        )
        solver.solve(targets[:2], num_samples=config.samples, **options)  # warm-up: constants built, code paged in
        rows = {"pipeline": options, **one_target_rows(solver, targets, options, config.samples)}
        if arm.kind == "chain" and arm.target_dim == 7:
            rows[f"PseudoInverseIK {config.pk_retries}x{config.pk_iterations}"] = pk_one_target_row(
                arm, targets, config
            )
            trac_ik = trac_ik_one_target_row(arm, targets, config)
            if trac_ik is not None:
                rows[f"TRAC-IK, {1000 * config.trac_ik_timeout:g} ms timeout"] = trac_ik
        rows.update(stream_rows(solver, config))
        results[name] = rows
        print_table(f"{name} {options}", {label: row for label, row in rows.items() if label != "pipeline"})
    results["machine"]["load_average_after"] = list(os_load())
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(results, indent=2))
    print(f"wrote {config.output}")
    return results


def os_load() -> tuple[float, ...]:
    import os

    return os.getloadavg()


if __name__ == "__main__":
    main(tyro.cli(LatencyConfig, description=__doc__.splitlines()[0]))
