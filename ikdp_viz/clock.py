"""The animation's clock: how long each state of the denoising stays on screen.

Spaced by step, a DDPM animation is mostly noise: with the linear schedule of the shipped
planar models (T = 80), the noise level sigma_t = sqrt(1 - alphabar_t) is still above 0.9
for the first 48 steps, the median tip error falls from 2.9 to 1.0 only by t = 20, and the
arms settle in the last fifth of the time. Spaced by noise level, each step lasts in
proportion to how much it lowers sigma_t: the noisy steps pass in a few tenths of a second
and the steps where the poses form fill most of the animation. No viser here.
"""

from __future__ import annotations

import numpy as np

CLOCK_CHOICES = ("noise level", "step")  # the panel's "clock" dropdown, the default first


def noise_levels(labels: np.ndarray, sqrt_one_minus_alphas_cumprod) -> np.ndarray:
    """(S+1,) the noise level sigma of each state: sqrt(1 - alphabar_t) at diffusion time t >= 1, 0 for the final pose.

    `labels` are the states' diffusion times, T .. 0 (scene.state_labels); the schedule's
    table is 0-based, so time t reads entry t - 1.
    """
    labels = np.asarray(labels, dtype=np.int64)
    table = np.asarray(sqrt_one_minus_alphas_cumprod, dtype=np.float64)
    if labels.ndim != 1 or labels.min() < 0 or labels.max() > len(table):
        raise ValueError(f"labels: expected diffusion times 0 .. {len(table)}, got {labels.tolist()}")
    return np.where(labels > 0, table[np.maximum(labels - 1, 0)], 0.0)


def state_offsets(sigmas: np.ndarray, clock: str, seconds: float) -> np.ndarray:
    """(S+1,) seconds after the start at which each state is shown; the last state at `seconds`.

    "step": every state the same time. "noise level": state s stays on screen in proportion to
    sigma_s - sigma_(s+1), the drop in noise level of the step that follows it.
    """
    if clock not in CLOCK_CHOICES:
        raise ValueError(f"clock: expected one of {CLOCK_CHOICES}, got {clock!r}")
    sigmas = np.asarray(sigmas, dtype=np.float64)
    count = len(sigmas)
    if count < 2:
        return np.zeros(count)
    drop = sigmas[0] - sigmas[-1]
    if clock == "step" or drop <= 0:
        return seconds * np.arange(count) / (count - 1)
    fallen = np.maximum.accumulate(sigmas[0] - sigmas)  # monotone even if a schedule wobbled
    return seconds * fallen / drop


def clock_note(labels: np.ndarray, offsets: np.ndarray, sigmas: np.ndarray) -> str:
    """One line for the panel: where the time goes, e.g. "t = 80 .. 33 (sigma > 0.9): 0.4 s of 4.0 s; ..."."""
    total = float(offsets[-1])
    if total <= 0 or len(labels) < 2:
        return "No animation: the final pose is shown at once."
    noisy = np.flatnonzero(sigmas > 0.9)
    settled = np.flatnonzero(labels <= max(1, int(round(0.25 * labels[0]))))  # the last quarter of diffusion time
    parts = []
    if len(noisy) > 1:
        seconds = offsets[min(noisy[-1] + 1, len(offsets) - 1)] - offsets[noisy[0]]  # until the next state shows
        parts.append(f"t = {labels[noisy[0]]} .. {labels[noisy[-1]]} (σ > 0.9) take {seconds:.1f} s")
    if len(settled):
        parts.append(f"t = {labels[settled[0]]} .. 0 take {total - offsets[settled[0]]:.1f} s")
    return f"of {total:.1f} s: " + "; ".join(parts) if parts else f"{total:.1f} s in all"


def solve_noise_levels(solver, view) -> np.ndarray:
    """(S+1,) the noise level sigma of each state of a solve's `view`, from `solver`'s schedule."""
    return noise_levels(view.labels, solver.model.schedule.sqrt_one_minus_alphas_cumprod.cpu().numpy())
