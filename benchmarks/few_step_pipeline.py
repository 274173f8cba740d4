"""K = 16 + refinement on a robot, one CPU thread: IKDP's fastest pipeline at a success share beside
pytorch_kinematics' PseudoInverseIK tuned to the same share, in the same run.

    OMP_NUM_THREADS=1 python benchmarks/few_step_pipeline.py --checkpoints ikdp_panda ikdp_panda_fast

On robot_benchmark's 1000 held-out pose targets, every IKDP pipeline `name:steps:spacing+refine` (K = 16
samples, then `refine` limit-aware DLS steps; `+refineRrestart`, e.g. `+8r20`, then gives the targets still
unreached K fresh random starts and `restart` DLS steps, solve's `restart_steps`; a `/int8` suffix samples
with the model's int8 weights, `ikdp.load(..., precision="int8")`) and every PseudoInverseIK setting
`retriesxiterations` is timed once per round, round-robin (so the machine's load hits all alike), `rounds`
rounds, median quoted; a target is solved when one of its poses is within 1 mm and 1 degree. For each, the
fastest row at a share of at least `success` is picked, and the ratio IKDP / PseudoInverseIK printed. Rows of
DLS from uniform random starts (`random_start_steps`, `steps` or `stepsRrestart` as above) are timed in the
same rounds: the moonshot line names the IKDP rows faster than the fastest of them with at least twice its
valid solutions. Writes benchmarks/results/few_step_pipeline.json.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import NamedTuple

import torch
import tyro

import ikdp
from benchmarks.robot_benchmark import dls_from_random_starts, parse_sampler, pseudo_inverse, verdict, write
from ikdp.evaluation.machine import machine_description

RESULTS = Path(__file__).resolve().parent / "results" / "few_step_pipeline.json"


@dataclass(frozen=True)
class PipelineConfig:
    checkpoints: tuple[str, ...] = ("ikdp_panda", "ikdp_panda_fast")  # paths or shipped names
    pipelines: tuple[str, ...] = (  # name:steps:spacing+refine[rRESTART][/int8]
        "dpmpp2m:3:uniform+10",
        "dpmpp2m:3:quadratic+10",
        "ddim:3:uniform+5",
        "ddim:3:quadratic+5",
        "ddim:2:uniform+5",
        "ddim:4:quadratic+5",
        "dpmpp2m:4:quadratic+5",
        "ddim:2:uniform+10",
    )
    pk_settings: tuple[str, ...] = ("8x20", "8x30", "16x20", "16x30")  # PseudoInverseIK retries x iterations
    # DLS steps from `samples` uniform random starts within the limits (our own numerical baseline; the moonshot's)
    random_start_steps: tuple[str, ...] = ("20",)  # DLS steps[rRESTART]
    success: float = 0.995  # the share a pipeline must reach to be picked
    targets: int = 1000
    samples: int = 16
    rounds: int = 3
    seed: int = 0
    output: Path = field(default=RESULTS)


class Pipeline(NamedTuple):
    sampler: str
    steps: int | None
    spacing: str
    refine: int  # DLS steps after sampling
    restart: int  # DLS steps from random starts for the targets still unreached (0: none)
    precision: str


class Answer(NamedTuple):
    """What a row's run returns: its poses (B, K, J), and which targets took random restarts (None: no fallback)."""

    angles: torch.Tensor
    restarted: torch.Tensor | None

    @classmethod
    def of_solve(cls, result: ikdp.SolveResult) -> Answer:
        return cls(result.angles, result.restarted)

    def restarted_share(self) -> float | None:
        return None if self.restarted is None else float(self.restarted.double().mean())


def parse_refinement(text: str) -> tuple[int, int]:
    """'8' -> (8, 0); '8r20' -> (8, 20): DLS steps, then restart steps for the targets unreached; ValueError else."""
    refine, marker, restart = text.partition("r")
    if not refine.isdigit() or (marker and not restart.isdigit()):
        raise ValueError(f"refinement {text!r}: expected DLS steps, then optionally r and restart steps (8, 8r20)")
    return int(refine), int(restart or 0)


def parse_pipeline(text: str) -> Pipeline:
    """'ddim:3:quadratic+5' -> Pipeline('ddim', 3, 'quadratic', 5, 0, 'float32'); '...+8r20/int8': 8, 20, 'int8'.
    ValueError naming the row when it is not name:steps:spacing+refine[rRESTART][/precision]."""
    body, _, precision = text.partition("/")
    sampler, plus, refinement = body.partition("+")
    head, _, spacing = sampler.rpartition(":")
    try:
        name, steps = parse_sampler(head)
    except ValueError:
        name = ""  # steps that are not a number
    if not plus or not name or not spacing:
        raise ValueError(f"pipeline {text!r}: expected name:steps:spacing+refine[rRESTART][/int8]")
    return Pipeline(name, steps, spacing, *parse_refinement(refinement), precision or "float32")


def measure(checkpoint: str, config: PipelineConfig) -> dict:
    solvers = {"float32": ikdp.load(checkpoint)}
    arm = solvers["float32"].arm
    targets = arm.end_effector(arm.random_poses(config.targets, generator=torch.Generator().manual_seed(config.seed)))
    runs = {}
    for text in config.pipelines:
        pipeline = parse_pipeline(text)
        if pipeline.precision not in solvers:
            solvers[pipeline.precision] = ikdp.load(checkpoint, precision=pipeline.precision)
        runs[f"IKDP {text}"] = lambda pipeline=pipeline, solver=solvers[pipeline.precision]: Answer.of_solve(
            solver.solve(
                targets,
                num_samples=config.samples,
                sampler=pipeline.sampler,
                steps=pipeline.steps,
                spacing=pipeline.spacing,
                refine_steps=pipeline.refine,
                restart_steps=pipeline.restart,
                generator=torch.Generator().manual_seed(2),
            )
        )
    for text in config.pk_settings:
        retries, iterations = (int(part) for part in text.split("x"))
        solve = pseudo_inverse(arm, targets, retries, iterations, config.seed)
        runs[f"PseudoInverseIK {text}"] = lambda solve=solve: Answer(solve(), None)
    goals = targets[:, None].expand(-1, config.samples, -1)
    for text in config.random_start_steps:
        dls_steps, restart = parse_refinement(text)
        label = f"random starts + {dls_steps} DLS" + (f", restarts + {restart}" if restart else "")
        runs[label] = lambda steps=dls_steps, restart=restart: Answer(
            *dls_from_random_starts(arm, goals, steps, restart, with_restarted=True)
        )
    seconds: dict[str, list[float]] = {label: [] for label in runs}
    answers = {}
    for label, run in runs.items():  # warm-up, and the answers judged
        answers[label] = run()
    for _ in range(config.rounds):
        for label, run in runs.items():
            started = time.perf_counter()
            run()
            seconds[label].append(time.perf_counter() - started)
    rows = {}
    for label in runs:
        rows[label] = {
            "ms_per_target": 1000 * statistics.median(seconds[label]) / len(targets),
            "repeats_ms_per_target": [1000 * s / len(targets) for s in seconds[label]],
            **verdict(arm, answers[label].angles, targets),
            "restarted_share": answers[label].restarted_share(),
        }

    def fastest(prefix: str):
        eligible = [(row["ms_per_target"], label) for label, row in rows.items() if label.startswith(prefix)]
        eligible = [(ms, label) for ms, label in eligible if rows[label]["success_share"] >= config.success]
        return min(eligible)[1] if eligible else None

    ours, theirs, random = fastest("IKDP"), fastest("PseudoInverseIK"), fastest("random starts")
    ratio = rows[ours]["ms_per_target"] / rows[theirs]["ms_per_target"] if ours and theirs else None
    return {
        "path": solvers["float32"].metadata["path"],
        "rows": rows,
        "fastest_ikdp": ours,
        "fastest_pk": theirs,
        "ratio": ratio,
        "fastest_random_starts": random,
        "moonshot": moonshot(rows, random, config.success),
    }


def moonshot(rows: dict, random: str | None, success: float) -> dict | None:
    """The CPU moonshot, against the fastest random-start row at the success share: the IKDP rows that are faster
    than it with at least twice its valid solutions per target, i.e. a learned seed that beats plain random restarts
    on both time and diversity (None without such a baseline row)."""
    if random is None:
        return None
    baseline = rows[random]
    met = [
        label
        for label, row in rows.items()
        if label.startswith("IKDP")
        and row["success_share"] >= success
        and row["ms_per_target"] < baseline["ms_per_target"]
        and row["valid_per_target"] >= 2 * baseline["valid_per_target"]
    ]
    return {"baseline": random, "met_by": met}


def main(config: PipelineConfig) -> dict:
    torch.set_num_threads(1)
    results = {"config": {**asdict(config), "output": str(config.output)}, "machine": machine_description(1)}
    models = {}
    for checkpoint in config.checkpoints:
        models[checkpoint] = measure(checkpoint, config)
        model = models[checkpoint]
        print(f"\n{checkpoint}: K = {config.samples} + refinement, {config.targets} targets, within 1 mm and 1 deg")
        print("| pipeline | solved | valid of 16 | diversity (rad) | restarted | ms per target (median of rounds) |")
        print("|---|---|---|---|---|---|")
        for label, row in model["rows"].items():
            restarted = "" if row["restarted_share"] is None else f"{100 * row['restarted_share']:.1f} %"
            print(
                f"| {label} | {100 * row['success_share']:.1f} % | {row['valid_per_target']:.1f} "
                f"| {row['diversity_rad']:.2f} | {restarted} | {row['ms_per_target']:.3f} |"
            )
        ratio = f"{model['ratio']:.2f}" if model["ratio"] is not None else "n/a"
        print(f"fastest at >= {100 * config.success:.1f} %: {model['fastest_ikdp']} / {model['fastest_pk']} = {ratio}")
        if model["moonshot"] is not None:
            met = ", ".join(model["moonshot"]["met_by"]) or "no IKDP row"
            print(f"faster than {model['moonshot']['baseline']} with twice its valid solutions: {met}")
    results["models"] = models
    write(results, config.output)
    return results


if __name__ == "__main__":
    config = tyro.cli(PipelineConfig, description=__doc__.splitlines()[0])
    try:  # before any work: one line for a row it cannot read
        [parse_pipeline(text) for text in config.pipelines] + [parse_refinement(t) for t in config.random_start_steps]
    except ValueError as error:
        raise SystemExit(f"few_step_pipeline: error: {error}") from None
    main(config)
