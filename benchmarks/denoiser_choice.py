"""Which denoiser and training recipe: train each variant on the same budget, compare tip error.

    python benchmarks/denoiser_choice.py            # 2,000 steps of 256 poses each, N=4, 1 thread
    python benchmarks/denoiser_choice.py --steps 500  # a quick look

Every variant is trained by the project's own `ikdp.train.train` from the same seed,
then sampled with the raw 80-step DDPM, K=1, on 1,000 targets (FK of uniform poses,
fixed seed). Prints a markdown table and writes benchmarks/results/denoiser_choice.json.
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import torch

import ikdp
from ikdp.kinematics import tip_position
from ikdp.priors import PosePrior
from ikdp.train import TrainConfig, train

VARIANTS = {
    "film (default)": {},
    "film, raw-angle representation": {"representation": "angle"},
    "film, epsilon prediction": {"prediction": "epsilon"},
    "film, paper loss (no tip term, uniform t weights)": {"tip_loss_weight": 0.0, "snr_gamma": 0.0},
    "paper transformer, paper loss, raw angle": {
        "denoiser": "paper",
        "representation": "angle",
        "tip_loss_weight": 0.0,
        "snr_gamma": 0.0,
    },
    "paper transformer, our loss, cossin": {"denoiser": "paper"},
}


def tip_errors(checkpoint: Path, targets: torch.Tensor) -> torch.Tensor:
    solver = ikdp.load(checkpoint)
    out = solver.solve(targets, num_samples=1, generator=torch.Generator().manual_seed(0))
    return out.raw_tip_error[:, 0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results/denoiser_choice.json"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    truth = PosePrior().sample(args.targets, 4, generator=torch.Generator().manual_seed(2024))
    targets = tip_position(truth, torch.ones(4))
    base = TrainConfig(joints=4, steps=args.steps, batch=args.batch, eval_targets=0, threads=1, save_every=10**9)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name, changes in VARIANTS.items():
            config = replace(base, output=f"{folder}/model.pt", log_dir=f"{folder}/tb", **changes)
            started = time.perf_counter()
            checkpoint = train(config)
            seconds = time.perf_counter() - started
            error = tip_errors(checkpoint, targets)
            rows.append(
                {
                    "variant": name,
                    "changes": changes,
                    "train_seconds": round(seconds, 1),
                    "tip_error_median": float(error.median()),
                    "tip_error_mean": float(error.mean()),
                    "tip_error_p95": float(error.quantile(0.95)),
                }
            )
    print(f"\nN=4, {args.steps} steps x {args.batch} poses, raw DDPM-80, K=1, {args.targets} targets (bone lengths)\n")
    print("| variant | median | mean | p95 | train s |\n|---|---|---|---|---|")
    for row in rows:
        print(
            f"| {row['variant']} | {row['tip_error_median']:.4f} | {row['tip_error_mean']:.4f} "
            f"| {row['tip_error_p95']:.4f} | {row['train_seconds']:.0f} |"
        )
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(
        json.dumps(
            {
                "steps": args.steps,
                "batch": args.batch,
                "targets": args.targets,
                "threads": 1,
                "sampler": "ddpm-80 raw, K=1",
                "machine": platform.processor() or platform.machine(),
                "torch": str(torch.__version__),
                "date": time.strftime("%Y-%m-%d"),
                "rows": rows,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
