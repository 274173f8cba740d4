"""How long a training runs, and its learning rate along the way: a step count, a wall-clock budget, or both.

With `minutes` the run ends at whichever of the two comes first, and the cosine decay follows the budget's
progress (the larger of the step and the time fraction), so a run cut by its clock still ends on a low rate
instead of stopping at the peak. Time is the training's own (seconds saved in the checkpoint carry over a
`--resume`), not counting start-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

FINAL_FRACTION = 0.1  # the cosine ends at a tenth of the peak rate


@dataclass(frozen=True)
class TrainingBudget:
    """Steps and minutes a training may take, and the learning-rate factor at any point of it."""

    steps: int  # optimizer steps at most (> 0)
    minutes: float = 0.0  # wall-clock minutes at most; 0: steps alone
    warmup: int = 0  # linear warm-up, in steps

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
        """The rate of the next step over the peak: (step + 1) / warmup, then cosine down to a tenth.

        The cosine runs over what is left after the warm-up: by steps, (step - warmup) / (steps - warmup);
        by the clock, the time fraction itself (the warm-up's few seconds are not worth a second clock).
        """
        if step < self.warmup:
            return (step + 1) / self.warmup
        by_steps = (step - self.warmup) / max(1, self.steps - self.warmup)
        after_warmup = min(1.0, max(by_steps, self.clock_fraction(seconds)))
        return FINAL_FRACTION + (1 - FINAL_FRACTION) * 0.5 * (1 + math.cos(math.pi * after_warmup))
