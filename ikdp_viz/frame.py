"""One picture as a plain value: the `Frame` the scene, the legend, the readouts and the chart are all written from.

The drawing loop (scene_writer.py) takes one snapshot (the solve on screen, the state
shown, the panel's view settings) and builds a `Frame` from it with `build_frame`; the arm
view draws its nodes from the frame, and the panel's texts and chart are the frame's own.
So the highlighted sample, the step, the colours and the words cannot disagree: they are
computed once, here. No viser here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ikdp_viz import readouts
from ikdp_viz.constraint_scene import holds, met_text, unmet_reasons
from ikdp_viz.planar_scene import TRAIL_CHOICES, compare_curve, error_curves
from ikdp_viz.style import Entry

# The animation's clock: how long each state of the denoising stays on screen.
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


HIGHLIGHT_CHOICES = "best"  # the highlight dropdown's first choice; the others are sample numbers from 1


@dataclass(frozen=True)
class ViewSettings:
    """How a solve is shown: the panel's view settings (a recording's too), read once per frame."""

    highlight: str = "best"  # the highlight dropdown: "best" or a sample's number from 1
    trail_of: str = TRAIL_CHOICES[0]  # highlighted (the paper's figure) or all samples
    show_trail: bool = True  # the trail up to the step shown
    show_estimate: bool = False  # ghost x̂0
    clock: str = CLOCK_CHOICES[0]  # spacing of the states in time: noise level or step
    seconds: float = 4.0  # from t = T to 0
    color_by_constraint: bool = True  # green / red by whether each sample's constraints hold
    followed: bool = False  # follow mode chose the highlighted sample (the Constraints folder)
    joint_space: bool = False  # the joint-space view is on (its colours join the legend)
    prior: bool = False  # poses drawn from the prior are on screen (until the next solve; their colour joins the
    # legend)
    obstacles: int = 0  # obstacles drawn (the Constraints folder's; their colour joins the legend)
    recording: bool = False  # a static page (record.py): the legend lists only what the page draws, and no
    # control to drag or click

    @classmethod
    def from_panel(cls, panel, *, color_by_constraint: bool = True, followed: bool = False,
                   prior: bool = False, obstacles: int = 0) -> ViewSettings:  # fmt: skip
        return cls(
            highlight=str(panel.highlight.value), trail_of=str(panel.learn.trail_of.value),
            show_trail=bool(panel.show_trail.value), show_estimate=bool(panel.show_estimate.value),
            clock=str(panel.learn.clock.value), seconds=float(panel.duration.value) or 4.0,
            color_by_constraint=color_by_constraint, followed=followed,
            joint_space=bool(panel.joint_space.show.value), prior=prior, obstacles=obstacles,
        )  # fmt: skip


def best_sample(solved) -> int:
    """The sample "best" names: the smallest error at t = 0 among those meeting the constraints there (else
    "best" highlighted a robot through an obstacle); of all samples when none meets them, or there are none."""
    view, violation = solved.view, getattr(solved, "state_violation", None)
    if violation is None or not holds(violation[-1]).any():
        return view.best_sample()
    return int(np.argmin(np.where(holds(violation[-1]), view.final_error, np.inf)))


def highlighted_sample(choice: str, solved) -> int:
    """The 0-based sample the highlight dropdown's `choice` names for `solved`: its best, or number - 1 (at most K)."""
    if choice == HIGHLIGHT_CHOICES:
        return best_sample(solved)
    return min(int(choice), solved.view.num_samples) - 1


def highlight_reason(settings: ViewSettings, highlight: int, solved) -> str:
    """Why this sample is the one followed, for the readouts: best, kept by follow mode, or chosen in the panel."""
    if settings.followed:
        return "kept by follow mode (the nearest that reaches)"
    violation = getattr(solved, "state_violation", None)
    meeting = 0 if violation is None else int(holds(violation[-1]).sum())
    best = "the best" if violation is None or meeting == 0 else f"the best of the {meeting} meeting the constraints"
    if settings.highlight == HIGHLIGHT_CHOICES:
        return best
    also = "" if highlight != best_sample(solved) else f"; it is also {best}"
    return f"chosen in the panel's highlight{also}"


@dataclass(frozen=True)
class Frame:
    """Everything one picture shows: a state of one solve, the sample followed, the colours and the words."""

    solved: object  # solving.Solved on screen
    state: int  # 0 (pure noise) .. S (final)
    highlight: int  # the sample followed, 0-based
    settings: ViewSettings
    palette: object  # the arm kind's colours of this solve and highlight (arm_kinds: PlanarPalette, ChainPalette)
    light: bool  # a frame of a playing animation, not its last: the light scene (fewer trail states, no ghosts)
    trail_states: int | None  # the most trail states shown; None: all up to the state
    constraint_colors: bool  # the samples are coloured green / red by constraint
    readout: str  # the Readouts folder's markdown
    legend: tuple[Entry, ...]  # what each colour drawn means
    chart: tuple[np.ndarray, ...]  # the chart's columns: t, median, highlighted, now (and a compared sampler's)
    chart_compared: str | None  # the sampler of the chart's extra column, if any
    step_label: str  # "step s of S (t = ...)", for a recording's label

    @property
    def view(self):
        return self.solved.view

    @property
    def final(self) -> bool:
        return self.state == self.view.num_states - 1


def build_frame(kind, solved, state: int, settings: ViewSettings, *, palettes, animating_to: int | None,
                error: str | None = None, note: str | None = None) -> Frame:  # fmt: skip
    """The frame of `state` of `solved` as `settings` show it; `animating_to` is the playing animation's last state
    (None when still); `palettes` caches the kind's colours per (solve, highlight, settings); `note`: a line for
    the readouts (the t asked for and the step shown instead)."""
    view = solved.view
    state = int(np.clip(state, 0, view.num_states - 1))
    forward = getattr(solved, "forward", False)  # the forward process of teaching.py (a test's stand-in may lack it)
    if forward:  # a trail up to the step shown would run ahead of the noising, to t = T
        settings = dataclasses.replace(settings, show_trail=False)
    highlight = highlighted_sample(settings.highlight, solved)
    constraint_colors = settings.color_by_constraint and solved.state_violation is not None
    palette = palettes.get(kind, solved, highlight, settings.trail_of, constraint_colors)
    light = animating_to is not None and state < animating_to
    text = kind.solve_text(solved, state, highlight, highlight_reason(settings, highlight, solved), error)
    if solved.preview_of is not None:  # say which is shown
        text = (f"**Fast preview** ({solved.request.sampler_label}, {view.num_states - 1} steps) while the "
                f"{solved.preview_of} solve runs  \n" + text)  # fmt: skip
    if forward:
        text = readouts.FORWARD_NOTE + "  \n" + text
    if solved.state_violation is not None:
        text += "  \n" + met_text(solved.state_violation, state, colored=constraint_colors)
    text += "".join("  \n" + line for line in unmet_reasons(solved))  # why, here too: the folder starts closed
    if solved.request.compare_note is not None:
        text += "  \n" + solved.request.compare_note
    if note is not None:
        text += "  \n" + note
    # a playing frame's chart has no marker of the state: redrawing the chart with every state cost the page more
    # than the arms did (benchmarks/viz_frame_costs.py); the slider and the readout name the state
    chart = error_curves(view, highlight, None if light else state, scale=kind.chart_scale)
    compared = solved.request.compare_sampler if solved.compare is not None else None
    if compared is not None:
        chart = (*chart, compare_curve(view, solved.compare, highlight, scale=kind.chart_scale))
    shown = None if settings.recording else state  # a recording's one legend stands for every state it plays
    legend = kind.legend_entries(settings, constraint_colors=constraint_colors, view=view, solved=solved, state=shown)
    last = view.num_states - 1
    return Frame(
        solved=solved, state=state, highlight=highlight, settings=settings, palette=palette, light=light,
        trail_states=kind.light_trail_states(settings.trail_of) if light else None,
        constraint_colors=constraint_colors, readout=text, legend=tuple(legend), chart=chart,
        chart_compared=compared, step_label=f"step {state} of {last} (t = {int(view.labels[state])})",
    )  # fmt: skip


class Palettes:
    """The arm kind's colours of the solve on screen, once per (solve, highlight, trail, constraint colours)."""

    def __init__(self):
        self._solved = None  # held, so that the key's solve is never another object at the same address
        self._key: tuple | None = None
        self._palette = None

    def get(self, kind, solved, highlight: int, trail_of: str, constraint_colors: bool):
        key = (kind.name, highlight, trail_of, constraint_colors)
        if solved is not self._solved or key != self._key:
            self._solved = solved
            self._palette = kind.palette(solved, highlight, trail_of, constraint_colors)
            self._key = key
        return self._palette
