"""Again from the same x_T: rerun the solve on screen from its very noise, and say how far the poses moved.

A solve's generator draws x_T first, then every stochastic step's noise. A rerun keeps x_T (the seed's
first draw) and reseeds what follows, so DDPM, which adds fresh noise at each of its T steps, lands
somewhere new each time, while DDIM, DPM-Solver++ and a distilled student, which draw nothing after x_T,
land on the very same poses. The readout compares each run with the one before it, sample by sample,
in the pose's own joint angles. No viser here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RERUN_SEED_STRIDE = 1_000_003  # a prime: run r of seed s draws its step noise from s + r * stride, apart from s + 1
SAME_DEGREES = 1e-3  # poses that moved less than this (degrees, float32 rounding) landed on the same poses


def rerun_seed(seed: int, run: int) -> int:
    """The seed of run `run`'s step noise (run 0: the solve's own generator goes on; this is never asked)."""
    if run < 1:
        raise ValueError(f"run: expected a rerun numbered from 1, got {run}")
    return (int(seed) + int(run) * RERUN_SEED_STRIDE) % 2**63


def largest_move_degrees(previous: np.ndarray, current: np.ndarray) -> float:
    """The largest change of any joint of any sample between two runs' poses (K, J), in degrees, wrapped at ±180°."""
    previous, current = np.asarray(previous, dtype=np.float64), np.asarray(current, dtype=np.float64)
    if previous.shape != current.shape:
        raise ValueError(f"current: expected poses of shape {previous.shape} as the run before, got {current.shape}")
    change = np.remainder(current - previous + math.pi, 2 * math.pi) - math.pi
    return float(np.degrees(np.abs(change).max())) if change.size else 0.0


@dataclass(frozen=True)
class Rerun:
    """One rerun's outcome, for the readout and its test."""

    run: int  # 1 for the first rerun
    sampler: str  # as the readouts name it
    moved_degrees: float  # the largest joint change from the run before
    compare_sampler: str | None = None  # the sampler drawn beside, rerun too
    compare_moved_degrees: float | None = None

    def text(self) -> str:
        lines = [f"**Again from the same x_T**, run {self.run + 1}: " + moved_words(self.sampler, self.moved_degrees)]
        if self.compare_sampler is not None and self.compare_moved_degrees is not None:
            lines.append("beside it, " + moved_words(self.compare_sampler, self.compare_moved_degrees))
        return "  \n".join(lines)


def moved_words(sampler: str, degrees: float) -> str:
    if degrees < SAME_DEGREES:
        return f"{sampler} landed on the same poses as the run before (no joint moved by {SAME_DEGREES}°)"
    return f"{sampler} landed elsewhere: a joint moved by {degrees:.1f}° from the run before"
