"""The panel's texts (markdown) and the plot's range, from plain values: no viser here."""

from __future__ import annotations

import numpy as np

from ikdp_viz.scene import SolveView


def target_text(target: np.ndarray, clamped: bool, reach: tuple[float, float]) -> str:
    x, y = target
    text = f"**Target** x = {x:+.3f}, y = {y:+.3f}"
    if clamped:
        inner, outer = reach
        boundary = outer if np.hypot(x, y) >= outer - 1e-9 else inner
        text += f"  \n*Clamped to the workspace boundary* (r = {boundary:.2f}): the arm reaches no farther."
    return text


def sample_note(view, highlight: int, reason: str | None, error_name: str, raw_best: int) -> tuple[str, str]:
    """(" (why this sample, ranked by what)", a line naming the best raw sample or "") for the error line.

    The note sits in parentheses before the numbers, which are the highlighted sample's: with
    refinement, "best" ranks the refined poses, and the sample whose raw pose ranks first is named
    on a line of its own (named before the numbers, it would read as their owner).
    `reason` says why this sample is followed ("the best", "kept by follow mode", "chosen in the panel");
    None: "the best" when it is, else nothing.
    """
    if reason is None:
        reason = "the best" if highlight == view.best_sample() else ""
    best = reason.startswith("the best")
    if best:
        reason += f" by refined {error_name}" if view.refined else f" by {error_name} at t = 0"
    note = f" ({reason})" if reason else ""
    raw_line = ""
    if view.refined and best and raw_best != highlight:
        raw_line = f"by raw {error_name} at t = 0 the best is sample {raw_best + 1}"
    return note, raw_line


FORWARD_NOTE = (  # the readouts' first line while noise_it.py's forward process is on screen
    "**Noise it**: the final poses mixed with one noise ε as training does, x_t = √ᾱ_t · x_0 + √(1 − ᾱ_t) · ε; "
    "t = 0 is the poses themselves, t = T pure noise (no trail: the path goes on to t = T)"
)


def solve_text(
    view: SolveView,
    state: int,
    highlight: int,
    *,
    sampler: str,
    seed: int,
    refine_steps: int,
    solve_seconds: float,
    error: str | None = None,
    reason: str | None = None,
) -> str:
    """The step shown, the highlighted sample's tip error now and at t = 0, the K samples' median, the solve.

    `highlight` is 0-based; the text numbers samples as people count, from 1. `reason`: see `sample_note`.
    """
    last = view.num_states - 1
    note, raw_line = sample_note(view, highlight, reason, "tip error", int(np.argmin(view.tip_error[-1])))
    lines = [
        f"**Step** {state} of {last} (t = {int(view.labels[state])})",
        f"**Tip error**, sample {highlight + 1} of {view.num_samples}{note}: "
        f"{view.tip_error[state, highlight]:.4f} now, {view.tip_error[last, highlight]:.4f} at t = 0",
        f"median of K = {view.num_samples}: {np.median(view.tip_error[state]):.4f} now, "
        f"{np.median(view.tip_error[last]):.4f} at t = 0",
    ]
    if view.refined:
        lines.append(f"refined ({refine_steps} DLS steps): {view.final_tip_error[highlight]:.2e}")
    if raw_line:
        lines.append(raw_line)
    lines.append(f"**Solve** {1000 * solve_seconds:.1f} ms ({sampler}, {last} steps, seed {seed})")
    if error:
        lines.append(f"**Last solve failed** {error}")
    return "  \n".join(lines)


def error_range(tip_error: np.ndarray) -> tuple[int, int]:
    """Whole decades (low, high), as log10 exponents, holding every positive tip error; at least one apart."""
    positive = tip_error[tip_error > 0]
    if not positive.size:
        return -3, -2
    low = int(np.floor(np.log10(max(float(positive.min()), 1e-6))))
    high = int(np.ceil(np.log10(float(positive.max()))))
    return low, max(high, low + 1)
