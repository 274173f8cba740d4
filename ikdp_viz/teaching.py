"""What the viewer shows a learner beyond the denoising itself, and the panel's controls for it: the tour's folder,
noise it, again from the same x_T, the schedule, the words.

Noise it: training noises a pose and the network learns to undo it; "noise it" shows that direction. The K
final poses of the solve on screen are mixed with one held noise eps at every t (ikdp.forward_process), and
the result is handed to the drawing loop as a solve like any other, its states ordered as a reverse run's
(t = T first, t = 0 last): the slider, the trail, the chart and the readouts all read it as they read a
denoising, and playing it from t = 0 toward T takes the pose to pure noise. Planar arms only: a robot's pose
error also has a rotation, which this view does not rank.

Again from the same x_T: a rerun keeps x_T (the seed's first draw) and reseeds what follows (solving.rerun_seed),
so DDPM, which adds fresh noise at each of its T steps, lands somewhere new each time, while DDIM, DPM-Solver++ and a
distilled student, which draw nothing after x_T, land on the very same poses. The readout compares each run with the
one before it, sample by sample: how far any joint of any final arm moved, in the arm's length unit.

The schedule beside the slider: x_t = sqrt(alphabar_t) x_0 + sqrt(1 - alphabar_t) eps, so sigma_t =
sqrt(1 - alphabar_t) is the share of noise in the state drawn at t and alphabar_t what is left of the pose.
The dots on sigma are the diffusion times the chosen sampler visits: DDPM stops at every t, DDIM and the
student at a few, jumping along the curve because each step lands on x̂0's prediction at the next noise
level, not on a small random move.

The controls are laid out here (`build_*`), wired in app.py, and written (texts, the schedule plot) by the drawing
loop alone.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch
import viser
import viser.uplot

from ikdp.forward_process import forward_trajectory
from ikdp.solve_result import SolveResult
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.readouts import define, glossary_markdown
from ikdp_viz.solving import Solved

FORWARD = "forward process (noise it)"  # the readouts' sampler name for a noised solve


def forward_solved(solved: Solved, seed: int) -> Solved:
    """The forward process of `solved`'s returned poses with noise eps drawn from `seed`, as a Solved of T+1 states.

    Its state s is x at t = T - s: state 0 the noisiest, the last the poses themselves.
    """
    request = solved.request
    solver = request.solver
    if not arm_kind(solver).teaches:
        raise ValueError(f"solved: expected a planar arm's solve to noise, got a {arm_kind(solver).name} arm's")
    if solved.final_angles is None:
        raise ValueError("solved: expected a solve with its returned poses (final_angles), got None")
    model = solver.model
    clean = torch.as_tensor(np.asarray(solved.final_angles), dtype=torch.float32)  # (K, J)
    generator = torch.Generator().manual_seed(int(seed))
    noise = torch.randn((clean.shape[0], model.representation.dim), generator=generator)  # (K, D) one eps per sample
    states = forward_trajectory(model.schedule, model.representation, clean, noise).flip(0)  # (T+1, K, J) t = T first
    tip_error = torch.as_tensor(np.asarray(solved.view.final_tip_error), dtype=torch.float32)[None]  # (1, K)
    result = SolveResult(
        angles=clean[None], tip_error=tip_error, trajectory=states[:, None], reachable=None,
        timesteps=list(range(solver.timesteps - 1, -1, -1)), raw_angles=clean[None], raw_tip_error=tip_error,
    )  # fmt: skip
    view, trail = arm_kind(solver).drawable(result, solver, request.target)
    forward_request = dataclasses.replace(request, sampler=FORWARD, steps=None, animate=False, compare_sampler=None)
    return Solved(forward_request, view, trail, 0.0, final_angles=solved.final_angles, forward=True)


def is_forward(solved: Solved | None) -> bool:
    """`solved` is a forward process made by `forward_solved`, not a denoising."""
    return solved is not None and solved.forward


SAME_DISTANCE = 1e-5  # arms whose joints moved less than this (float32 rounding) landed on the same poses


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


def schedule_plot_data(curves: ScheduleCurves, now: float | None, visited) -> tuple[np.ndarray, ...]:
    """The uPlot's data: (t, sigma, alphabar, the sampler's visited times on sigma, the step shown on sigma).

    `visited`: the diffusion times of the states the sampler lands on (scene.state_labels); `now` the slider's t
    (None: no step marked, as while the denoising plays).
    Off those times the two marker series are NaN, so they draw as dots only.
    """
    t = curves.t
    last = int(t[-1])
    if now is not None and not 0 <= now <= last:
        raise ValueError(f"now: expected a diffusion time in [0, {last}] or None, got {now}")
    steps = np.full(t.shape, np.nan)
    chosen = np.clip(np.asarray(list(visited), dtype=np.int64), 0, last)
    steps[chosen] = curves.sigma[chosen]
    marker = np.full(t.shape, np.nan)
    if now is not None:
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


@dataclass
class TourControls:
    folder: viser.GuiFolderHandle  # first in the panel; hidden for a robot, whose tour this is not
    text: viser.GuiMarkdownHandle  # the step's number, title and sentence
    back: viser.GuiButtonHandle
    next: viser.GuiButtonHandle
    leave: viser.GuiButtonHandle  # leave the tour for the default view
    take: viser.GuiButtonHandle  # shown once the tour is left: open it again at its first step


@dataclass
class TeachControls:
    tour: TourControls
    noise_it: viser.GuiButtonHandle  # the forward process of the poses on screen (teaching.py)
    again: viser.GuiButtonHandle  # rerun the solve on screen from its x_T (teaching.py)
    again_text: viser.GuiMarkdownHandle  # how far the rerun's poses moved
    schedule: viser.GuiUplotHandle  # sigma(t) and alphabar_t, the step shown, the sampler's steps (teaching.py)
    words: viser.GuiMarkdownHandle  # the glossary


def build_tour_controls(gui: viser.GuiApi) -> TourControls:
    """The Tour folder, built before any other so it opens the panel."""
    with gui.add_folder("Tour: diffusion in six steps") as folder:
        text = gui.add_markdown("")
        back = gui.add_button("Back", icon=viser.Icon.ARROW_LEFT, visible=False)
        next_button = gui.add_button("Next", icon=viser.Icon.ARROW_RIGHT, visible=False)
        leave = gui.add_button("Leave the tour", icon=viser.Icon.X, visible=False)
        take = gui.add_button(
            "Take the tour", icon=viser.Icon.SCHOOL, hint="Six short steps, each a view and a sentence"
        )
    return TourControls(folder, text, back, next_button, leave, take)


def build_rerun_controls(
    gui: viser.GuiApi,
) -> tuple[viser.GuiButtonHandle, viser.GuiButtonHandle, viser.GuiMarkdownHandle]:
    """In the Denoising folder: noise it, and again from the same x_T with its readout."""
    noise_it = gui.add_button(
        "Noise it (forward process)", icon=viser.Icon.WAVE_SINE,
        hint="The final poses on screen taken toward pure noise on the same t slider, as training noises a pose: "
        "play it and t runs from 0 to T. " + define("forward process"),
    )  # fmt: skip
    again = gui.add_button(
        "Again from the same x_T", icon=viser.Icon.REPEAT,
        hint="Solve again from the very same pure noise x_T with new noise for the steps after it: "
        + define("stochastic") + "; " + define("deterministic"),
    )  # fmt: skip
    return noise_it, again, gui.add_markdown("")


def build_schedule_folder(gui: viser.GuiApi, curves: ScheduleCurves) -> viser.GuiUplotHandle:
    with gui.add_folder("Noise schedule"):
        plot = build_schedule_plot(gui, curves)
        gui.add_markdown(SCHEDULE_NOTE)
    return plot


def build_words_folder(gui: viser.GuiApi) -> viser.GuiMarkdownHandle:
    with gui.add_folder("Words", expand_by_default=False):
        return gui.add_markdown(glossary_markdown())
