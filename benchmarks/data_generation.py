"""How fast training data is made: 100,000 (theta, target) pairs, as the paper claims "at the millisecond level".

    python benchmarks/data_generation.py

Times `PosePrior.sample` + `tip_position` (what every training step does) for N = 2, 4, 8,
median of 21 runs after a warm-up, and writes benchmarks/results/data_generation.json.
"""

from __future__ import annotations

import json
import platform
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import torch
import tyro

from ikdp.kinematics import tip_position
from ikdp.priors import PosePrior


@dataclass(frozen=True)
class DataGenerationConfig:
    pairs: int = 100_000  # (theta, target) pairs per call
    repeats: int = 21  # timed calls per prior and N (median quoted)


def time_generation(prior: PosePrior, num_links: int, config: DataGenerationConfig) -> float:
    generator = torch.Generator().manual_seed(0)
    lengths = torch.ones(num_links)
    tip_position(prior.sample(config.pairs, num_links, generator=generator), lengths)  # warm-up
    seconds = []
    for _ in range(config.repeats):
        started = time.perf_counter()
        headings = prior.sample(config.pairs, num_links, generator=generator)
        tip_position(headings, lengths)
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds)


def main(config: DataGenerationConfig) -> None:
    rows = []
    print(
        f"{config.pairs:,} (theta, target) pairs, median of {config.repeats}, "
        f"torch threads = {torch.get_num_threads()}\n"
    )
    print("| prior | N | median ms |\n|---|---|---|")
    for kind in ("uniform", "relaxed"):
        for num_links in (2, 4, 8):
            milliseconds = 1000 * time_generation(PosePrior(kind=kind), num_links, config)
            rows.append({"prior": kind, "links": num_links, "median_ms": round(milliseconds, 2)})
            print(f"| {kind} | {num_links} | {milliseconds:.1f} |")
    output = Path("benchmarks/results/data_generation.json")
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(
        json.dumps(
            {
                "pairs": config.pairs,
                "repeats": config.repeats,
                "threads": torch.get_num_threads(),
                "torch": str(torch.__version__),
                "machine": platform.machine(),
                "date": time.strftime("%Y-%m-%d"),
                "rows": rows,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main(tyro.cli(DataGenerationConfig, description=__doc__.splitlines()[0]))
