"""Fidelity over several seeds, paired: is a few-step sampler as faithful as the DDPM, beyond one seed's luck?

    OMP_NUM_THREADS=1 python -m benchmarks.fidelity_seeds --rows ikdp_n4_relaxed@ddpm \
        ikdp_n4_relaxed@student ikdp_n4_relaxed@dpmpp2m:16:quadratic --seeds 5

One seed of benchmarks/fidelity.py draws its targets, reference sets and samples once; the DDPM-80 of
ikdp_n4_relaxed read 0.00010 to 0.00135 excess MMD^2 over five seeds, as wide as the gaps
between samplers it was meant to rank. Here every row runs on the same seeds (the same targets and
references), and each row's excess is set beside the first row's seed by seed: the mean, the
ratio of the means, and the mean and spread of the paired differences. Prints a table and writes
benchmarks/results/fidelity_seeds.json.
"""

from __future__ import annotations

import json
import statistics
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import tyro

from benchmarks.fidelity import FidelityConfig
from benchmarks.fidelity import main as fidelity

RESULTS = Path(__file__).resolve().parent / "results" / "fidelity_seeds.json"


@dataclass(frozen=True)
class SeedsConfig:
    # checkpoint@sampler[:steps[:spacing]]; the first row is the baseline of the paired differences
    rows: tuple[str, ...] = ("ikdp_n4_relaxed@ddpm", "ikdp_n4_relaxed@student")
    seeds: int = 5  # seeds 0 .. seeds - 1
    output: Path = field(default=RESULTS)


def parse_row(row: str) -> tuple[str, str, int | None, str | None]:
    """ "name@sampler:steps:spacing" -> (name, sampler, steps or None, spacing or None); ValueError naming the row."""
    name, _, spec = row.partition("@")
    parts = spec.split(":") if spec else ["ddpm"]
    if not name or len(parts) > 3 or (len(parts) > 1 and not parts[1].isdigit()):
        raise ValueError(f"row {row!r}: expected checkpoint@sampler[:steps[:spacing]]")
    return name, parts[0], int(parts[1]) if len(parts) > 1 else None, parts[2] if len(parts) > 2 else None


def main(config: SeedsConfig) -> dict:
    rows = [parse_row(row) for row in config.rows]
    excess: dict[str, list[float]] = {row: [] for row in config.rows}
    median: dict[str, list[float]] = {row: [] for row in config.rows}
    with tempfile.TemporaryDirectory() as scratch:
        for seed in range(config.seeds):
            for row, (name, sampler, steps, spacing) in zip(config.rows, rows, strict=True):
                one = FidelityConfig(
                    checkpoints=(name,), sampler=sampler, steps=steps, spacing=spacing, seed=seed,
                    output=Path(scratch) / "one.json",
                )  # fmt: skip
                measured = next(iter(fidelity(one)["models"].values()))
                excess[row].append(measured["mmd2_excess"])
                median[row].append(measured["raw_median_tip_error"])
    baseline = excess[config.rows[0]]
    table = {}
    for row in config.rows:
        differences = [value - base for value, base in zip(excess[row], baseline, strict=True)]
        table[row] = {
            "excess_mmd2_per_seed": excess[row],
            "excess_mmd2_mean": statistics.fmean(excess[row]),
            "ratio_of_means_to_first_row": statistics.fmean(excess[row]) / statistics.fmean(baseline),
            "paired_difference_mean": statistics.fmean(differences),
            "paired_difference_stdev": statistics.stdev(differences) if len(differences) > 1 else 0.0,
            "raw_median_tip_error_mean": statistics.fmean(median[row]),
        }
    print(f"\nexcess MMD^2 over seeds 0-{config.seeds - 1}, paired with {config.rows[0]}")
    print("| row | per seed | mean | x first row | paired difference (mean, sd) | raw median |")
    print("|---|---|---|---|---|---|")
    for row, line in table.items():
        seeds = " ".join(f"{value:.5f}" for value in line["excess_mmd2_per_seed"])
        print(
            f"| {row} | {seeds} | {line['excess_mmd2_mean']:.5f} | {line['ratio_of_means_to_first_row']:.2f} | "
            f"{line['paired_difference_mean']:+.5f} ({line['paired_difference_stdev']:.5f}) | "
            f"{line['raw_median_tip_error_mean']:.4f} |"
        )
    result = {"rows": list(config.rows), "seeds": config.seeds, "table": table}
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    config = tyro.cli(SeedsConfig, description=__doc__.splitlines()[0])
    try:
        [parse_row(row) for row in config.rows]  # before any work: one line for a row it cannot read
    except ValueError as error:
        raise SystemExit(f"fidelity_seeds: error: {error}") from None
    main(config)
