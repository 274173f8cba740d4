"""The training's progress bar: steps, or seconds of a --minutes budget; the loss; the held-out accuracy at saves."""

from __future__ import annotations

import math

from tqdm import tqdm

from ikdp.train_budget import TrainingBudget


def accuracy_text(metrics: dict) -> str:
    """The accuracy measured at a save, in the arm's units: mm and degrees for a robot, bone lengths for a planar."""
    median = metrics.get("tip_error_median")
    if median is None:
        return ""
    if metrics.get("tip_error_units") != "m":
        return f"{median:.4f}"  # bone lengths
    text = f"{1000 * median:.1f} mm"
    if "rotation_error_median" in metrics:
        text += f" {math.degrees(metrics['rotation_error_median']):.1f}°"
    return text


class TrainingProgress:
    """A tqdm bar over the budget: steps when it is a step count, seconds when --minutes sets a clock."""

    def __init__(self, budget: TrainingBudget, *, step: int, seconds: float, name: str, enabled: bool):
        self.by_clock = budget.minutes > 0
        total = round(60 * budget.minutes) if self.by_clock else budget.steps
        unit = "s" if self.by_clock else "it"
        initial = self.position(step, seconds)
        self.bar = tqdm(total=total, initial=initial, desc=name, unit=unit, dynamic_ncols=True, disable=not enabled)
        self.held_out = ""
        self.losses: dict[str, str] = {}

    def position(self, step: int, seconds: float) -> int:
        return int(seconds) if self.by_clock else step

    def advance(self, step: int, seconds: float) -> None:
        self.bar.update(min(self.bar.total, self.position(step, seconds)) - self.bar.n)

    def show_losses(self, step: int, theta_loss: float, tip_distance: float) -> None:
        self.losses = {"step": str(step), "loss": f"{theta_loss:.4f}", "tip": f"{tip_distance:.4f}"}
        self._show(refresh=False)

    def show_accuracy(self, metrics: dict) -> None:
        """The held-out accuracy of the last save, kept beside the loss until the next one."""
        self.held_out = accuracy_text(metrics)
        self._show(refresh=True)

    def _show(self, *, refresh: bool) -> None:
        self.bar.set_postfix(self.losses | ({"held-out": self.held_out} if self.held_out else {}), refresh=refresh)

    def close(self) -> None:
        self.bar.close()
