"""The schedule beside the slider: sigma(t) and alphabar_t on the same t axis, the step shown and the sampler's steps.

A learner sees where the noise goes: x_t = sqrt(alphabar_t) x_0 + sqrt(1 - alphabar_t) eps, so
sigma_t = sqrt(1 - alphabar_t) is the share of noise in the state drawn at t and alphabar_t what is
left of the pose. The dots on sigma are the diffusion times the chosen sampler visits: DDPM stops at
every t, DDIM and the student at a few, jumping along the curve because each step lands on x̂0's
prediction at the next noise level, not on a small random move. The data are plain arrays; the
builder is the panel's uPlot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import viser
import viser.uplot

SIGMA_STROKE = "#1f5ad2"  # the noise share, blue as the highlighted sample's error on the chart above it
ALPHA_BAR_STROKE = "#999999"  # what is left of the pose
NOW_FILL = "#eb780a"  # the step shown, orange as the chart's "now" dot
STEPS_FILL = "#1f5ad2"

SCHEDULE_NOTE = (
    "x_t = √ᾱ_t · pose + σ(t) · noise: ᾱ_t falls from 1 (all pose) to near 0 (all noise) and σ(t) = √(1 − ᾱ_t) "
    "rises from 0 to 1. "
    "Blue dots: the times the sampler visits. DDPM stops at every t and adds fresh noise each time, so each "
    "step must be small. DDIM reuses the noise the denoiser predicted instead of drawing new noise: its path "
    "is smooth (an ODE), and a few big steps along it land where DDPM's many small ones do. A distilled "
    "student was trained to land in its few steps where its teacher lands."
)


@dataclass(frozen=True)
class ScheduleCurves:
    """The schedule on the slider's axis t = 0 .. T (t = 0: the clean pose, T: pure noise)."""

    t: np.ndarray  # (T+1,) diffusion time, 0 .. T
    sigma: np.ndarray  # (T+1,) sqrt(1 - alphabar_t), 0 at t = 0
    alpha_bar: np.ndarray  # (T+1,) alphabar_t, 1 at t = 0


def schedule_curves(alphas_cumprod) -> ScheduleCurves:
    """The curves of a schedule's alphas_cumprod (T,), 0-based: slider time t reads entry t - 1, as the clock does."""
    table = np.asarray(alphas_cumprod, dtype=np.float64)
    if table.ndim != 1 or table.size < 1 or not np.all((table > 0) & (table <= 1)):
        raise ValueError(f"alphas_cumprod: expected a (T,) array of values in (0, 1], got shape {table.shape}")
    alpha_bar = np.concatenate(([1.0], table))
    t = np.arange(table.size + 1, dtype=np.float64)
    return ScheduleCurves(t=t, sigma=np.sqrt(1 - alpha_bar), alpha_bar=alpha_bar)


def schedule_plot_data(curves: ScheduleCurves, now: float, visited) -> tuple[np.ndarray, ...]:
    """The uPlot's data: (t, sigma, alphabar, the sampler's visited times on sigma, the step shown on sigma).

    `visited`: the diffusion times of the states the sampler lands on (scene.state_labels); `now` the slider's t.
    Off those times the two marker series are NaN, so they draw as dots only.
    """
    t = curves.t
    last = int(t[-1])
    if not 0 <= now <= last:
        raise ValueError(f"now: expected a diffusion time in [0, {last}], got {now}")
    steps = np.full(t.shape, np.nan)
    chosen = np.clip(np.asarray(list(visited), dtype=np.int64), 0, last)
    steps[chosen] = curves.sigma[chosen]
    marker = np.full(t.shape, np.nan)
    at = int(round(now))
    marker[at] = curves.sigma[at]
    return t, curves.sigma, curves.alpha_bar, steps, marker


def visited_count(data: tuple[np.ndarray, ...]) -> int:
    """How many sampler steps a plot's data marks (what a test compares with the readout's step count)."""
    return int(np.isfinite(data[3]).sum())


def dots(label: str, fill: str, size: int) -> viser.uplot.Series:
    """A series drawn as dots alone (its values NaN off the marked times)."""
    return viser.uplot.Series(label=label, stroke=fill, width=0, points={"show": True, "size": size, "fill": fill})


def build_schedule_plot(gui: viser.GuiApi, curves: ScheduleCurves) -> viser.GuiUplotHandle:
    """The small plot: sigma and alphabar against t, t = 0 at the left as on the slider and the error chart."""
    return gui.add_uplot(
        data=schedule_plot_data(curves, float(curves.t[-1]), curves.t.astype(np.int64)),
        series=(
            viser.uplot.Series(label="t"),
            viser.uplot.Series(label="σ(t) noise", stroke=SIGMA_STROKE, width=2),
            viser.uplot.Series(label="ᾱ_t", stroke=ALPHA_BAR_STROKE, width=1.5),
            dots("sampler's steps", STEPS_FILL, 5),
            dots("now", NOW_FILL, 9),
        ),
        title="the noise schedule",
        scales={
            "x": viser.uplot.Scale(time=False, auto=False, range=(0.0, float(curves.t[-1]))),
            "y": viser.uplot.Scale(auto=False, range=(0.0, 1.0)),
        },
        axes=(
            viser.uplot.Axis(label="diffusion time t (T: noise)", labelSize=20, size=30),
            viser.uplot.Axis(label="share", labelSize=20, size=40),
        ),
        legend=viser.uplot.Legend(show=True, live=False),
        cursor=viser.uplot.Cursor(points={"show": False}),
        aspect=1.6,
    )
