"""Evaluate IKDP beside its baselines and regenerate the paper's tables and figures.

    python -m ikdp.evaluate --cache-dir .eval_cache            # full run, writes runs/evaluation/
    python -m ikdp.evaluate --quick --out-dir /tmp/eval        # small sizes, a smoke run
    python -m ikdp.evaluate --only fidelity                    # one stage; what it needs comes from the cache

A pipeline of named stages, run in order: `data` (load the shipped models, train once
into --cache-dir what is compared against: the paper-denoiser variants of Tables I and
II, the MLP and Neural IK baselines), `accuracy` (accuracy and diversity tables, Table
III's accuracy), `tables_1_2`, `runtime`, `fidelity` (MMD to rejection-sampled
references), `figure_data`, `figures` and `report` (RESULTS.md and results.json, every
number behind every table and figure, into --out-dir). Each stage's result is cached
under a key of everything that shapes it; `--only STAGE` runs that stage afresh and
takes what it needs from the cache where the key matches, computing it otherwise.
With --threads above 1 (and not --quick), what must be trained, and then the measuring
stages that time nothing, run in that many single-threaded processes (ikdp.evaluation.pool).
"""

from __future__ import annotations

import importlib.util
import json
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Literal

import torch
import tyro

import ikdp
from ikdp.evaluation import stages, tables
from ikdp.evaluation.cache import config_digest
from ikdp.evaluation.machine import machine_description
from ikdp.evaluation.mmd import KERNEL_DESCRIPTION
from ikdp.evaluation.models import FULL, QUICK, Models, Sizes, load_models
from ikdp.evaluation.pool import single_threaded_pool

StageName = Literal["data", "accuracy", "tables_1_2", "runtime", "fidelity", "figure_data", "figures", "report"]
PAPER = {  # the paper's tables as published (units not stated there)
    "table1": {2: (0.499, 1.982), 4: (0.32, 1.283), 8: (0.243, 8.03)},  # joints: (angle distance, target distance)
    "table2": {40: (1.382, 4.361), 80: (1.283, 3.611), 100: (1.37, 3.44)},  # T: (angle distance, target distance)
    "table3": {"MLP": (12.3, 0.04), "IKNet": (2.3, 0.007), "IKDP": (1.98, 0.065)},  # (target distance, runtime)
}


@dataclass(frozen=True)
class EvaluateConfig:
    quick: bool = False  # small sizes and stand-in models: a smoke run, used by the tests
    out_dir: str = "runs/evaluation"  # RESULTS.md, results.json and figures/; docs/paper.md renders its copy
    cache_dir: str = ".eval_cache"  # trained variants, baselines and stage results are cached here
    checkpoints: str = "checkpoints"  # folder of the shipped checkpoints (and their TensorBoard logs/)
    seed: int = 0  # seeds the targets, the samplers and every training run
    threads: int = 2  # torch CPU threads; a full run also trains and measures in this many one-thread processes
    only: StageName | None = None  # run this stage alone; what it needs comes from the cache where valid


@dataclass(frozen=True)
class FigureFiles(stages.StageResult):
    figures: dict[str, str]  # figure name -> PNG path


@dataclass(frozen=True)
class ReportFiles:
    results_json: Path  # every number behind every table and figure
    results_md: Path  # the tables and their discussion


class Run:
    """One evaluation in progress: its settings, the models (loaded once, on demand) and the stage results."""

    def __init__(self, config: EvaluateConfig, sizes: Sizes, command: str):
        self.config, self.sizes, self.command = config, sizes, command
        self.out_dir, self.cache_dir = Path(config.out_dir), Path(config.cache_dir)
        self.results: dict[str, stages.StageResult] = {}
        self.seconds: dict[str, float] = {}  # compute time of each stage, when and wherever it ran
        self.started = time.perf_counter()
        # worker processes for the independent runs; none in a quick run, whose jobs are so small that starting a
        # worker (a fresh interpreter importing torch) costs more than it shares: its trainings took 64 s in two
        # workers and 42 s in this process on the shared 2-core machine
        self.workers = 1 if config.quick else config.threads
        self._models: Models | None = None

    def models(self) -> Models:
        if self._models is None:
            started = time.perf_counter()
            self._models = load_models(
                self.sizes,
                checkpoints=Path(self.config.checkpoints),
                cache_dir=self.cache_dir,
                seed=self.config.seed,
                workers=self.workers,
            )
            self.seconds["data"] = round(time.perf_counter() - started, 1)
        return self._models

    def cache_path(self, stage: str) -> Path:
        """Where a stage's result is cached: keyed by the sizes, the seed and the models, and by what else shapes it:
        the threads of the timings, the folder the figures were drawn into."""
        extra = {"runtime": self.config.threads, "figures": str(self.out_dir.resolve())}.get(stage, "")
        key = config_digest(stage, self.sizes, self.config.seed, self.models().fingerprint, extra)
        return self.cache_dir / "stages" / f"{stage}_{key}.json"


@dataclass(frozen=True)
class Stage:
    name: StageName  # as given to --only
    needs: tuple[StageName, ...]  # stages whose results it reads
    result: type[stages.StageResult] | None  # its cached result type; None: not cached (data, report)
    run: Callable[[Run], object]  # computes it from the run's models and earlier results


def draw_figures(run: Run) -> FigureFiles:
    """The figures, from the accuracy results and the figure data."""
    from ikdp.evaluation import figures  # matplotlib: only this stage needs it (checked before any work)

    data = {**run.results["accuracy"].to_json(), **run.results["figure_data"].to_json()}
    return FigureFiles(figures=figures.draw_all(data, run.out_dir / "figures"))


def collect_results(run: Run) -> dict:
    """results.json: the settings, the machine, the paper's numbers and every stage's result."""
    models = run.models()
    results = {
        "command": run.command,
        "config": asdict(run.config),
        "sizes": asdict(run.sizes),
        "machine": machine_description(torch.get_num_threads()),
        "kernel": KERNEL_DESCRIPTION,
        "paper": {name: {str(key): value for key, value in table.items()} for name, table in PAPER.items()},
        "checkpoints": models.descriptions,
        "variant_training": models.variant_training,
        "baseline_training": models.baseline_training,
        "stage_seconds": dict(run.seconds),
    }
    for result in run.results.values():
        results.update(result.to_json())
    results["wall_seconds"] = time.perf_counter() - run.started
    return results


def write_report(run: Run) -> ReportFiles:
    """RESULTS.md and results.json into the out dir."""
    results = collect_results(run)
    files = ReportFiles(results_json=run.out_dir / "results.json", results_md=run.out_dir / "RESULTS.md")
    run.out_dir.mkdir(parents=True, exist_ok=True)
    files.results_json.write_text(json.dumps(results, indent=1))
    files.results_md.write_text(tables.render(results))
    return files


def _measure(function) -> Callable[[Run], stages.StageResult]:
    return lambda run: function(run.models(), run.sizes, run.config.seed)


STAGES: dict[str, Stage] = {
    stage.name: stage
    for stage in (
        Stage("data", (), None, lambda run: run.models()),
        Stage("accuracy", (), stages.AccuracyResult, _measure(stages.measure_accuracy)),
        Stage("tables_1_2", (), stages.VariantResult, _measure(stages.measure_variants)),
        Stage("runtime", (), stages.RuntimeResult, _measure(stages.measure_runtime)),
        Stage("fidelity", (), stages.FidelityResult, _measure(stages.measure_fidelity)),
        Stage("figure_data", (), stages.FigureData, _measure(stages.figure_data)),
        Stage("figures", ("accuracy", "figure_data"), FigureFiles, draw_figures),
        Stage(
            "report",
            ("accuracy", "tables_1_2", "runtime", "fidelity", "figure_data", "figures"),
            None,
            write_report,
        ),
    )
}


def run_stage(run: Run, name: str, *, fresh: bool) -> object:
    """Run one stage after what it needs; a stage not `fresh` is read from the cache when its key matches."""
    stage = STAGES[name]
    if name in run.results:
        return run.results[name]
    for need in stage.needs:
        run_stage(run, need, fresh=False)
    if stage.result is not None and not fresh:
        path = run.cache_path(name)
        if path.exists():
            cached = json.loads(path.read_text())
            run.results[name] = stage.result.from_json(cached["result"])
            run.seconds[name] = cached["seconds"]
            return run.results[name]
    run.models()  # the data stage's time is its own, not the first measuring stage's
    started = time.perf_counter()
    output = stage.run(run)
    if stage.result is None:
        return output
    run.seconds[name] = round(time.perf_counter() - started, 1)
    run.results[name] = output
    path = run.cache_path(name)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"seconds": run.seconds[name], "result": output.to_json()}))
    return output


# the measuring stages that need nothing of each other, longest first; not runtime, whose timings want the machine
INDEPENDENT_STAGES: tuple[StageName, ...] = ("accuracy", "tables_1_2", "fidelity", "figure_data")


def _stage_in_worker(config: EvaluateConfig, sizes: Sizes, command: str, name: StageName) -> None:
    run_stage(Run(replace(config, threads=1), sizes, command), name, fresh=True)


def measure_in_parallel(run: Run) -> None:
    """The independent measuring stages at once, in single-threaded processes; their results come back
    through the stage cache, where each worker writes its own."""
    run.models()  # trains what is missing first, in its own pool: the workers only load
    with single_threaded_pool(run.workers) as pool:
        arguments = (run.config, run.sizes, run.command)
        futures = [pool.submit(_stage_in_worker, *arguments, name) for name in INDEPENDENT_STAGES]
        for future in futures:
            future.result()
    for name in INDEPENDENT_STAGES:
        run_stage(run, name, fresh=False)


def check_packages(config: EvaluateConfig) -> None:
    """ValueError naming the extra to install, before any work: the stages that compute may train variants
    (TensorBoard logs), the figures need matplotlib."""
    needed = {"matplotlib": config.only in (None, "figures"), "tensorboard": config.only not in ("figures", "report")}
    missing = [name for name, needs in needed.items() if needs and importlib.util.find_spec(name) is None]
    if missing:
        raise ValueError(f"{' and '.join(missing)} not installed: pip install 'ikdp[eval]'")


def evaluate(config: EvaluateConfig, argv: list[str] | None = None, sizes: Sizes | None = None) -> dict:
    """Run every stage (or `config.only` and what it needs); returns the results dict of the run.

    `sizes` overrides the quick/full sizes (for tests).
    """
    check_packages(config)
    torch.set_num_threads(config.threads)
    arguments = argv if argv is not None else sys.argv[1:]
    command = " ".join(["python -m ikdp.evaluate", *map(shlex.quote, arguments)])
    run = Run(config, sizes or (QUICK if config.quick else FULL), command)
    if config.only is None and run.workers > 1:
        measure_in_parallel(run)
    for name in [config.only] if config.only else STAGES:
        run_stage(run, name, fresh=True)
    return collect_results(run)


def main(argv: list[str] | None = None) -> None:
    config = tyro.cli(
        EvaluateConfig,
        args=argv,
        description="Evaluate IKDP beside its baselines; regenerate the paper's tables and figures.",
        config=(tyro.conf.FlagCreatePairsOff,),
    )
    try:
        results = evaluate(config, argv)
    except (ValueError, FileNotFoundError, ikdp.CheckpointError) as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    done = config.only or "every stage"
    print(f"ran {done} in {results['wall_seconds']:.0f} s; out dir {config.out_dir}", file=sys.stderr)


if __name__ == "__main__":
    main()
