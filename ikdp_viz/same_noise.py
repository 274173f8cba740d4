"""Again from the same x_T: rerun the solve on screen from its very noise, and say how far the poses moved.

A solve's generator draws x_T first, then every stochastic step's noise. A rerun keeps x_T (the seed's
first draw) and reseeds what follows, so DDPM, which adds fresh noise at each of its T steps, lands
somewhere new each time, while DDIM, DPM-Solver++ and a distilled student, which draw nothing after x_T,
land on the very same poses. The readout compares each run with the one before it, sample by sample: how
far any joint of any final arm moved, in the arm's length unit. No viser here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RERUN_SEED_STRIDE = 1_000_003  # a prime: run r of seed s draws its step noise from s + r * stride, apart from s + 1
SAME_DISTANCE = 1e-5  # arms whose joints moved less than this (float32 rounding) landed on the same poses


def rerun_seed(seed: int, run: int) -> int:
    """The seed of run `run`'s step noise (run 0: the solve's own generator goes on; this is never asked)."""
    if run < 1:
        raise ValueError(f"run: expected a rerun numbered from 1, got {run}")
    return (int(seed) + int(run) * RERUN_SEED_STRIDE) % 2**63


def largest_move(previous: np.ndarray, current: np.ndarray) -> float:
    """The largest distance any joint moved between two runs' final arms (K, N+1, 2), in the arm's length unit."""
    previous, current = np.asarray(previous, dtype=np.float64), np.asarray(current, dtype=np.float64)
    if previous.shape != current.shape:
        raise ValueError(f"current: expected arms of shape {previous.shape} as the run before, got {current.shape}")
    return float(np.linalg.norm(current - previous, axis=-1).max()) if current.size else 0.0


@dataclass(frozen=True)
class Rerun:
    """One rerun's outcome, for the readout and its test."""

    run: int  # 1 for the first rerun
    sampler: str  # as the readouts name it
    moved: float  # the largest joint move from the run before
    compare_sampler: str | None = None  # the sampler drawn beside, rerun too
    compare_moved: float | None = None

    def text(self) -> str:
        lines = [f"**Again from the same x_T**, run {self.run + 1}: " + moved_words(self.sampler, self.moved)]
        if self.compare_sampler is not None and self.compare_moved is not None:
            lines.append("beside it, " + moved_words(self.compare_sampler, self.compare_moved))
        return "  \n".join(lines)


def moved_words(sampler: str, distance: float) -> str:
    if distance < SAME_DISTANCE:
        return f"{sampler} landed on the same poses as the run before"
    return f"{sampler} landed elsewhere: a joint moved {distance:.2f} from the run before"


class RerunReadout:
    """The runs of one solve from one x_T: each solve put on screen is compared with the run before when it is a
    rerun of it (the same request but for its step noise); any other solve starts a new series."""

    def __init__(self):
        self._last = None  # (request key, final arms (K, N+1, 2), compared arms or None)

    def after_solve(self, solved) -> str | None:
        """The readout's text for `solved` (a Rerun's, or None when it is no rerun), and remember its arms."""
        request = solved.request
        arms = getattr(solved.view, "final_joints", None)
        if arms is None:
            self._last = None
            return None
        compare = getattr(solved, "compare", None)
        compared = None if compare is None else compare.final_joints
        key = rerun_key(request)
        last, self._last = self._last, (key, arms, compared)
        if request.rerun < 1 or last is None or last[0] != key or last[1].shape != arms.shape:
            return None
        moved_beside = None
        if compared is not None and last[2] is not None and last[2].shape == compared.shape:
            moved_beside = largest_move(last[2], compared)
        rerun = Rerun(request.rerun, request.sampler_label, largest_move(last[1], arms),
                      request.compare_sampler if moved_beside is not None else None, moved_beside)  # fmt: skip
        return rerun.text()


def rerun_key(request) -> tuple:
    """What must match for two solves to be runs from one x_T: every setting but the step noise and the timing."""
    target = tuple(np.asarray(request.target).round(12))
    return (id(request.solver), target, request.num_samples, request.sampler, request.steps, request.seed,
            request.compare_sampler, request.compare_steps, request.refine_steps)  # fmt: skip
