"""What the joint-space view adds to a viewer's solve: its field at every state, computed with the solve.

    OMP_NUM_THREADS=1 python benchmarks/viz_joint_space_solve.py            # the shipped ikdp_n4, its DDPM

For `targets` targets in the workspace (fixed seed), the viewer's solve (`ikdp_viz/solving.py`:
K = 16, the planar viewer's sampler, trajectory and x̂0 kept) with the joint-space view off
and on (20 x 20 grid, the first two joints, held at the best sample), interleaved in the same
run, `repeats` times each, for a solve to animate (every state's field: one denoiser call a
state sharing its condition, joint_space.clean_estimates_of_states) and a drag's solve (drawn
at its final state: that state's field); and, for the same poses, every state's field as one
network call of all the grids, and as one `clean_estimates` call a state with a condition per
row. Medians on one torch thread. Prints a table and writes
benchmarks/results/viz_joint_space_solve.json.
"""

from __future__ import annotations

import json
import statistics
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
import tyro

import ikdp
from ikdp.evaluation.machine import machine_description
from ikdp_viz.joint_space import FieldAsk, clean_estimates, grid_poses, link_headings, model_timestep, torus_grid
from ikdp_viz.planar_kind import PlanarKind
from ikdp_viz.solving import SolveRequest, solve

RESULTS = Path(__file__).resolve().parent / "results" / "viz_joint_space_solve.json"
NAMES = {
    "off": "solve to animate, view off",
    "on": "solve to animate, view on (every state's field)",
    "drag_off": "drag's solve (drawn at its end), view off",
    "drag_on": "drag's solve, view on (the final state's field)",
    "one_call": "every state's field: one network call of all grids",
    "per_state": "every state's field: one clean_estimates call a state",
}


@dataclass(frozen=True)
class JointSpaceSolveConfig:
    checkpoint: str = "ikdp_n4"  # a path or a shipped model's name (a planar arm)
    targets: int = 10
    repeats: int = 5  # solves per target and setting
    samples: int = 16  # K, the viewer's default
    grid: int = 20  # arrows per side, the view's default
    seed: int = 0
    output: Path = field(default=RESULTS)


@dataclass(frozen=True)
class Row:
    what: str
    ms: float  # median
    low_ms: float  # 10th percentile
    high_ms: float  # 90th percentile


def timed(function) -> float:
    started = time.perf_counter()
    function()
    return 1000 * (time.perf_counter() - started)


def row(what: str, times: list[float]) -> Row:
    low, high = np.percentile(times, [10, 90])
    return Row(what, statistics.median(times), float(low), float(high))


def all_in_one_call(solver, poses: np.ndarray, timesteps: list[int], target: np.ndarray) -> None:
    """Every state's grid (S+1, M, N) as one batch through the network, a timestep per row."""
    with torch.inference_mode():
        x = solver.model.representation.encode(torch.as_tensor(poses.reshape(-1, poses.shape[-1]), dtype=torch.float32))
        t = torch.as_tensor(np.repeat(timesteps, poses.shape[1]))
        targets = solver.arm.clamp_to_workspace(torch.as_tensor(target[None], dtype=torch.float32))
        solver.model.denoiser(x, t, targets.expand(len(x), -1))


def one_call_a_state(solver, poses: np.ndarray, timesteps: list[int], target: np.ndarray) -> None:
    for state_poses, timestep in zip(poses, timesteps, strict=True):
        clean_estimates(solver, state_poses, timestep, target)


def measure(config: JointSpaceSolveConfig) -> tuple[list[Row], dict]:
    torch.set_num_threads(1)
    solver = ikdp.load(config.checkpoint)
    sampler, _ = PlanarKind.default_sampler  # the DDPM of all T steps (it takes no step count)
    generator = np.random.default_rng(config.seed)
    inner, outer = solver.reach
    radii = generator.uniform(inner + 0.1 * (outer - inner), 0.95 * outer, config.targets)
    angles = generator.uniform(-np.pi, np.pi, config.targets)
    targets = np.stack((radii * np.cos(angles), radii * np.sin(angles)), axis=-1)
    ask = FieldAsk((0, 1), config.grid, "best")
    times: dict[str, list[float]] = {name: [] for name in NAMES}
    states = 0
    for index, target in enumerate(targets):
        request = SolveRequest(
            solver=solver, target=target, num_samples=config.samples, sampler=sampler, steps=None, refine_steps=0,
            seed=config.seed + index, arrival=0.0, animate=True,
        )  # fmt: skip
        settings = {
            "off": request,
            "on": replace(request, joint_space=ask),
            "drag_off": replace(request, animate=False),
            "drag_on": replace(request, animate=False, joint_space=ask),
        }
        solve(request)  # warm
        for _ in range(config.repeats):
            for name, setting in settings.items():  # interleaved: the same load on each
                times[name].append(timed(lambda setting=setting: solve(setting)))
        solved = solve(settings["on"])
        view, highlight = solved.view, solved.fields.held_by or 0
        states = view.num_states
        grid = torus_grid(config.grid)
        poses = np.stack([grid_poses(grid, ask.joints, pose) for pose in link_headings(view.joints)[:, highlight]])
        timesteps = [model_timestep(view.labels, state) for state in range(states)]
        times["one_call"].append(timed(lambda: all_in_one_call(solver, poses, timesteps, target)))  # noqa: B023
        times["per_state"].append(timed(lambda: one_call_a_state(solver, poses, timesteps, target)))  # noqa: B023
    rows = [row(NAMES[name], values) for name, values in times.items()]
    facts = {"states": states, "grid_poses": config.grid**2}
    for kind in ("", "drag_"):
        off, on = times[kind + "off"], times[kind + "on"]
        extra = [b - a for a, b in zip(off, on, strict=True)]
        facts[kind + "extra_ms_median"] = statistics.median(extra)
        facts[kind + "on_over_off"] = statistics.median(on) / statistics.median(off)
    return rows, facts


def main() -> None:
    config = tyro.cli(JointSpaceSolveConfig)
    rows, facts = measure(config)
    print(f"{config.checkpoint}, K = {config.samples}, {facts['states']} states, {config.grid} x {config.grid} grid, "
          f"{config.targets} targets x {config.repeats}, one torch thread")  # fmt: skip
    print("| | median ms | p10 | p90 |")
    print("|---|---|---|---|")
    for line in rows:
        print(f"| {line.what} | {line.ms:.1f} | {line.low_ms:.1f} | {line.high_ms:.1f} |")
    print(f"extra with the view on: {facts['extra_ms_median']:.1f} ms median (on / off {facts['on_over_off']:.1f}x); "
          f"a drag's solve: {facts['drag_extra_ms_median']:.1f} ms ({facts['drag_on_over_off']:.2f}x)")  # fmt: skip
    config.output.parent.mkdir(parents=True, exist_ok=True)
    payload = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1),
               "facts": facts, "rows": [asdict(line) for line in rows]}  # fmt: skip
    config.output.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {config.output}")


if __name__ == "__main__":
    main()
