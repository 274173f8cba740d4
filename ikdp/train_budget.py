"""How long a training runs, and its learning rate along the way: a step count, a wall-clock budget, or both.

With `minutes` the run ends at whichever of the two comes first, and the cosine decay follows the budget's
progress (the larger of the step and the time fraction), so a run cut by its clock still ends on a low rate
instead of stopping at the peak. Time is the training's own (seconds saved in the checkpoint carry over a
`--resume`), not counting start-up.

A `--resume` with more steps or minutes than the run had (`resumed`) goes on down from the rate it had reached,
over what the new budget leaves: fitting the cosine to the longer budget afresh had lifted the rate back up
(a distilled student lost a fifth of its fidelity gain that way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

FINAL_FRACTION = 0.1  # the cosine ends at a tenth of the peak rate


@dataclass(frozen=True)
class TrainingBudget:
    """Steps and minutes a training may take, and the learning-rate factor at any point of it."""

    steps: int  # optimizer steps at most (> 0)
    minutes: float = 0.0  # wall-clock minutes at most; 0: steps alone
    warmup: int = 0  # linear warm-up, in steps
    # where this budget took over from a shorter one on a resume: the cosine's progress then, the step, the seconds
    decay_from: float = 0.0
    from_step: int = 0
    from_seconds: float = 0.0

    def __post_init__(self):
        if not self.steps > 0:
            raise ValueError(f"steps: got {self.steps}, expected a positive number")
        if not (self.minutes >= 0 and math.isfinite(self.minutes)):
            raise ValueError(f"minutes: got {self.minutes}, expected 0 (no clock) or a positive number")
        if self.warmup < 0:
            raise ValueError(f"warmup: got {self.warmup}, expected 0 or more")

    def progress(self, step: int, seconds: float) -> float:
        """The fraction of the budget used, in [0, 1]: the larger of the step and the clock fractions."""
        return min(1.0, max(step / self.steps, self.clock_fraction(seconds)))

    def clock_fraction(self, seconds: float) -> float:
        """The fraction of the minutes used; 0 without a clock."""
        return seconds / (60.0 * self.minutes) if self.minutes > 0 else 0.0

    def finished(self, step: int, seconds: float) -> bool:
        return self.progress(step, seconds) >= 1.0

    def lr_factor(self, step: int, seconds: float) -> float:
        """The rate of the next step over the peak: (step + 1) / warmup, then cosine down to a tenth."""
        if step < self.warmup:
            return (step + 1) / self.warmup
        return FINAL_FRACTION + (1 - FINAL_FRACTION) * 0.5 * (
            1 + math.cos(math.pi * self.decay_progress(step, seconds))
        )

    def decay_progress(self, step: int, seconds: float) -> float:
        """How far down the cosine the rate is, in [0, 1].

        It runs over what is left after the warm-up (or after the resume that extended the budget): by steps,
        (step - start) / (steps - start); by the clock, the time fraction of what was left (the warm-up's few
        seconds are not worth a second clock).
        """
        start = max(self.warmup, self.from_step)
        by_steps = max(0, step - start) / max(1, self.steps - start)
        by_clock = 0.0
        if self.minutes > 0:
            by_clock = (seconds - self.from_seconds) / max(1e-9, 60.0 * self.minutes - self.from_seconds)
        rest = min(1.0, max(by_steps, by_clock, 0.0))
        return self.decay_from + (1 - self.decay_from) * rest

    def record(self) -> dict:
        """What a checkpoint keeps of this budget beyond the training config, for `resumed`."""
        return {"decay_from": self.decay_from, "from_step": self.from_step, "from_seconds": self.from_seconds}

    def resumed(self, saved: dict, step: int, seconds: float) -> TrainingBudget:
        """This budget continuing a run whose checkpoint record is `saved`, at `step` and `seconds`.

        The same steps and minutes: the saved run's budget as it was. Others: the cosine goes on from the progress
        the saved run had reached, down to a tenth at the end of this budget (never back up).
        """
        try:
            decay = saved.get("lr_decay") or {}
            previous = TrainingBudget(
                int(saved["steps"]), float(saved.get("minutes", 0.0)), int(saved.get("warmup", 0)),
                decay_from=float(decay.get("decay_from", 0.0)), from_step=int(decay.get("from_step", 0)),
                from_seconds=float(decay.get("from_seconds", 0.0)),
            )  # fmt: skip
        except (AttributeError, KeyError, TypeError, ValueError):
            return self  # a record from before budgets were saved, or unreadable: the budget as given
        if (previous.steps, previous.minutes, previous.warmup) == (self.steps, self.minutes, self.warmup):
            return previous
        if step < previous.warmup:
            return self  # still warming up: the new budget from its start
        return replace(self, decay_from=previous.decay_progress(step, seconds), from_step=step, from_seconds=seconds)
