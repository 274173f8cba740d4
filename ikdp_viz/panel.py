"""The viewer's panel: every viser GUI control, created in one place and handed to the app as one object.

The app wires the callbacks; this file only lays the controls out, in the order
a user reads them: the target, the denoising (timestep, playback), the sampling
settings, the readouts and plot, the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import viser
import viser.uplot

from ikdp_viz.frame import CLOCK_CHOICES
from ikdp_viz.joint_space import JointSpaceControls, build_joint_space_controls
from ikdp_viz.planar_scene import TRAIL_CHOICES
from ikdp_viz.readouts import define
from ikdp_viz.style import CHART_HIGHLIGHTED, CHART_MEDIAN, CHART_NOW
from ikdp_viz.teaching import (
    TeachControls,
    build_rerun_controls,
    build_schedule_folder,
    build_tour_controls,
    build_words_folder,
    schedule_curves,
)

MAX_SAMPLES = 64
DEFAULT_SAMPLES = 16
DEFAULT_STEPS = 20  # for samplers that can skip steps (ikdp.samplers: supports_steps)
DEFAULT_DURATION = 4.0  # seconds from t = T to 0: at 80 steps, 20 states a second, each step seen
DEFAULT_REFINE_STEPS = 5


def highlight_options(num_samples: int) -> tuple[str, ...]:
    """The highlight dropdown: the sample with the smallest final tip error, or one by its number, 1 to K."""
    return ("best", *(str(number) for number in range(1, num_samples + 1)))


def highlight_index(choice: str, best: int, num_samples: int) -> int:
    """The 0-based sample a dropdown `choice` names: `best` for "best", else number - 1 (at most K - 1)."""
    if choice == "best":
        return best
    return min(int(choice), num_samples) - 1


def plot_scales(num_timesteps: int, low: int, high: int) -> dict:
    """log10 tip error (y, whole decades low..high) against diffusion time t = 0 .. T left to right, like the slider.

    Both ranges are fixed: an auto x range stuck at the placeholder data's 0..1.
    """
    return {
        "x": viser.uplot.Scale(time=False, auto=False, range=(0.0, float(max(num_timesteps, 1)))),
        "y": viser.uplot.Scale(auto=False, range=(float(low), float(high))),
    }


def plot_axes(low: int, high: int, unit: str) -> tuple:
    """The chart's axes: t along x; along y the error as plain numbers at each decade low..high, in `unit`.

    The y values are log10 of the error (see `plot_scales`); ticks say the errors themselves (0.01, 0.1, 1),
    and both axes name their units (a log10 of metres, unsaid, reads as metres).
    """
    decades = tuple(float(exponent) for exponent in range(int(low), int(high) + 1))
    return (
        viser.uplot.Axis(label="diffusion time t (T: noise)", labelSize=20, size=30),
        viser.uplot.Axis(
            label=f"{unit}, log scale", labelSize=20, size=52, splits=decades,
            values=tuple(f"{10.0**exponent:g}" for exponent in decades),
        ),
    )  # fmt: skip


@dataclass
class Panel:
    target_text: viser.GuiMarkdownHandle
    timestep: viser.GuiSliderHandle
    previous_button: viser.GuiButtonHandle
    play_button: viser.GuiButtonHandle
    next_button: viser.GuiButtonHandle
    duration: viser.GuiNumberHandle
    show_trail: viser.GuiCheckboxHandle
    show_estimate: viser.GuiCheckboxHandle
    prior_button: viser.GuiButtonHandle
    play_on_move: viser.GuiCheckboxHandle
    samples: viser.GuiSliderHandle
    highlight: viser.GuiDropdownHandle
    sampler: viser.GuiDropdownHandle
    teacher_student: viser.GuiButtonHandle  # the student's few steps <-> the teacher's full DDPM (student.py)
    steps: viser.GuiSliderHandle
    seed: viser.GuiNumberHandle
    new_seed: viser.GuiCheckboxHandle
    refine: viser.GuiCheckboxHandle
    refine_steps: viser.GuiSliderHandle
    readout_text: viser.GuiMarkdownHandle
    plot: viser.GuiUplotHandle
    export_button: viser.GuiButtonHandle
    checkpoint: viser.GuiDropdownHandle
    model_text: viser.GuiMarkdownHandle
    joint_space: JointSpaceControls
    learn: LearnControls  # what makes the denoising readable (panel.py)
    teach: TeachControls  # the tour, noise it, again from the same x_T, the schedule, the words (teaching.py)


def build_panel(
    gui: viser.GuiApi,
    *,
    num_timesteps: int,
    animation_seconds: float,
    sampler_names: tuple[str, ...],
    checkpoint_labels: tuple[str, ...],
    checkpoint_label: str,
    model_text: str,
    alphas_cumprod,
) -> Panel:
    """`alphas_cumprod` (T,): the model's schedule, which the Noise schedule folder plots."""
    # The panel in a column of its own beside the canvas, not floating over it: the canvas has a quarter fewer
    # pixels and the page stops compositing the panel over each frame (software WebGL, K = 16 animating:
    # 11.7 and 12.7 frames/s floating, 14.2 to 17.0 docked; docs/viewer.md, "Frames in the page").
    gui.main_panel.dock_right()
    tour = build_tour_controls(gui)
    with gui.add_folder("Target"):
        target_text = gui.add_markdown("")
        target_inputs = build_target_inputs(gui)
    with gui.add_folder("Denoising"):
        timestep = gui.add_slider(
            "timestep t", min=0, max=num_timesteps, step=1, initial_value=num_timesteps,
            hint="Diffusion time of the pose shown: T is pure noise, 0 the final pose",
        )  # fmt: skip
        previous_button = gui.add_button("Previous step (toward noise)", icon=viser.Icon.PLAYER_TRACK_PREV)
        play_button = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY)
        next_button = gui.add_button("Next step (toward t = 0)", icon=viser.Icon.PLAYER_TRACK_NEXT)
        duration = gui.add_number(
            "duration (s)", animation_seconds, min=0.0, max=30.0, step=0.1,
            hint="Time the animation takes from t = T to 0",
        )  # fmt: skip
        clock, clock_note = build_clock(gui)
        show_trail = gui.add_checkbox(
            "show trail", True, hint="Every pose from t = T to the current step, faint to dark"
        )
        trail_of = build_trail_of(gui)
        show_estimate = gui.add_checkbox("show x̂0", False, hint="Ghosted in purple at the step shown: " + define("x̂0"))
        prior_button = gui.add_button(
            "Draw from the prior", icon=viser.Icon.DICE,
            hint="K poses, in brown until the next solve, of the poses the model was trained on, before any target: "
            "p(pose), where the samples below are p(pose | target). " + define("prior"),
        )  # fmt: skip
        play_on_move = gui.add_checkbox("play on move", True, hint="Animate each new solve from t = T")
        noise_it, again, again_text = build_rerun_controls(gui)
        # in the folder open at the start, so the teacher's full denoising is one click away (a model with a student)
        teacher_student = gui.add_button(
            "Show the teacher", icon=viser.Icon.SCHOOL, visible=False,
            hint="The model's distilled few-step student, or the teacher's full DDPM it was distilled from",
        )  # fmt: skip
    schedule = build_schedule_folder(gui, schedule_curves(alphas_cumprod))
    legend = build_legend(gui)
    joint_space = build_joint_space_controls(gui)
    with gui.add_folder("Sampling"):
        samples = gui.add_slider("samples K", min=1, max=MAX_SAMPLES, step=1, initial_value=DEFAULT_SAMPLES)
        highlight = gui.add_dropdown(
            "highlight", highlight_options(DEFAULT_SAMPLES), initial_value="best",
            hint="best: the smallest tip error at t = 0 (of the refined pose when refine is on); samples count from 1",
        )  # fmt: skip
        sampler = gui.add_dropdown(
            "sampler", sampler_names, initial_value=sampler_names[0],
            hint="; ".join(define(term) for term in ("DDPM", "DDIM", "DPM-Solver++", "student"))
            + " (dpmpp2m is DPM-Solver++; ancestral: DDPM's noisy update on fewer steps)",
        )  # fmt: skip
        compare = build_compare(gui)
        steps = gui.add_slider(
            "steps", min=1, max=num_timesteps, step=1, initial_value=min(DEFAULT_STEPS, num_timesteps),
            disabled=True, hint="Reverse steps of a sampler that can skip some; DDPM always takes all T",
        )  # fmt: skip
        seed = gui.add_number("seed", 0, min=0, max=2**31 - 1, step=1)
        new_seed = gui.add_checkbox("new seed each move", False)
        refine = gui.add_checkbox("refine (DLS)", False, hint="Drawn in teal beside the raw pose: " + define("DLS"))
        refine_steps = gui.add_slider(
            "refine steps", min=1, max=50, step=1, initial_value=DEFAULT_REFINE_STEPS, disabled=True
        )
    with gui.add_folder("Readouts"):
        readout_text = gui.add_markdown("Waiting for the first solve...")
        plot = gui.add_uplot(
            data=(np.array([0.0, float(num_timesteps)]), np.zeros(2), np.zeros(2), np.full(2, np.nan)),
            series=(
                viser.uplot.Series(label="t"),
                viser.uplot.Series(label="median", stroke=CHART_MEDIAN, width=1.5),
                viser.uplot.Series(label="highlighted", stroke=CHART_HIGHLIGHTED, width=2),
                viser.uplot.Series(
                    label="now", stroke=CHART_NOW, width=0, points={"show": True, "size": 9, "fill": CHART_NOW}
                ),
            ),
            title="error against t",
            scales=plot_scales(num_timesteps, -3, 1),
            axes=plot_axes(-3, 1, "error"),
            # no hover values (the readouts above give them, with units) and no hover points: the "now" series
            # is NaN off the current state, which showed "now: NaN" and a stray dot; one legend line
            legend=viser.uplot.Legend(show=True, live=False),
            cursor=viser.uplot.Cursor(points={"show": False}),
            padding=(12, 24, 0, 0),  # room above the top decade's tick label
            aspect=1.2,
        )
        export_button = gui.add_button(
            "Export GIF + PNG", icon=viser.Icon.DOWNLOAD,
            hint="The denoising as a GIF and the trail figure as a PNG, downloaded by this tab",
        )  # fmt: skip
        share = build_share_button(gui)
    with gui.add_folder("Model"):
        checkpoint = gui.add_dropdown("checkpoint", checkpoint_labels, initial_value=checkpoint_label)
        model_markdown = gui.add_markdown(model_text)
    words = build_words_folder(gui)
    gui.add_html(PAGE_STYLE)
    teach = TeachControls(tour, noise_it, again, again_text, schedule, words)
    learn = LearnControls(trail_of, clock, clock_note, legend, share, target_inputs, compare)
    return Panel(
        target_text, timestep, previous_button, play_button, next_button, duration, show_trail, show_estimate,
        prior_button, play_on_move, samples, highlight, sampler, teacher_student, steps, seed, new_seed, refine,
        refine_steps, readout_text, plot, export_button, checkpoint, model_markdown, joint_space, learn, teach,
    )  # fmt: skip


# The panel's controls that make the denoising readable: whose trail, the clock, the legend, sharing a solve.
@dataclass
class TargetInputs:
    """The target typed in the Target folder: x, y for a planar arm; a robot's position and rotation."""

    xy: viser.GuiVector2Handle  # planar arm only
    position_mm: viser.GuiVector3Handle  # a robot's hand position, millimetres
    rotation_deg: viser.GuiVector3Handle  # and its rotation, roll pitch yaw in degrees (pose models)
    go: viser.GuiButtonHandle  # solve the typed target

    def show_fields(self, *, point: bool, rotation: bool) -> None:
        """Offer a planar point's x, y (`point`), else a hand's position, with its rotation for pose targets."""
        self.xy.visible = point
        self.position_mm.visible = not point
        self.rotation_deg.visible = not point and rotation


@dataclass
class LearnControls:
    trail_of: viser.GuiDropdownHandle  # the highlighted sample's trail (the paper's figure) or every sample's
    clock: viser.GuiDropdownHandle  # the animation's time spaced by noise level or by step
    clock_note: viser.GuiMarkdownHandle  # where the animation's time goes, said on screen
    legend: viser.GuiHtmlHandle  # what each colour means (style.py; written by the scene writer)
    share: viser.GuiButtonHandle  # one self-contained HTML file of the solve on screen (record.py)
    target: TargetInputs  # the target typed in the panel
    compare: viser.GuiDropdownHandle  # "off" or a second sampler run from the same x_T, drawn beside (compare_view.py)


def build_trail_of(gui: viser.GuiApi) -> viser.GuiDropdownHandle:
    return gui.add_dropdown(
        "trail of", TRAIL_CHOICES, initial_value=TRAIL_CHOICES[0],
        hint="highlighted: the paper's figure, one sample's denoising from faint to dark, the others light; "
        "all samples: every sample's trail and arm dark",
    )  # fmt: skip


def build_clock(gui: viser.GuiApi) -> tuple[viser.GuiDropdownHandle, viser.GuiMarkdownHandle]:
    clock = gui.add_dropdown(
        "clock", CLOCK_CHOICES, initial_value=CLOCK_CHOICES[0],
        hint="noise level: each step lasts in proportion to how much it lowers the noise level σ = √(1 − ᾱ_t), so "
        "the animation dwells where the poses form; step: every step the same time",
    )  # fmt: skip
    return clock, gui.add_markdown("")


# The timestep slider and its number box move with every state a played denoising draws. Each on a compositing layer
# of its own, the browser re-rasters those two small layers, not the panel's tile around them: with software WebGL
# (no GPU) the playing page drew about 8 % more frames a second (docs/viewer.md).
PAGE_STYLE = "<style>.mantine-Slider-root, .mantine-NumberInput-root { will-change: transform; }</style>"


def build_legend(gui: viser.GuiApi) -> viser.GuiHtmlHandle:
    with gui.add_folder("Legend"):
        return gui.add_html("")


def build_share_button(gui: viser.GuiApi) -> viser.GuiButtonHandle:
    return gui.add_button(
        "Share this denoising (HTML)", icon=viser.Icon.SHARE,
        hint="One HTML file of the solve on screen, playable and scrubbable in any browser with no server: "
        "for a web page or a lecture",
    )  # fmt: skip


def build_target_inputs(gui: viser.GuiApi) -> TargetInputs:
    xy = gui.add_vector2("x, y", (0.0, 0.0), step=0.01, hint="Type a target and press 'Solve this target'")
    position = gui.add_vector3("x, y, z (mm)", (0.0, 0.0, 0.0), step=1.0, visible=False, hint="The hand's position")
    rotation = gui.add_vector3(
        "roll, pitch, yaw (°)", (0.0, 0.0, 0.0), step=1.0, visible=False,
        hint="The hand's rotation: about x, then y, then z, in degrees",
    )  # fmt: skip
    go = gui.add_button("Solve this target", icon=viser.Icon.TARGET)
    return TargetInputs(xy, position, rotation, go)


COMPARE_CHOICES = ("off", "ddim", "dpmpp2m", "ddpm")  # the "compare with" dropdown: off, or a sampler


def build_compare(gui: viser.GuiApi) -> viser.GuiDropdownHandle:
    return gui.add_dropdown(
        "compare with", COMPARE_CHOICES, initial_value="off",
        hint="Same noise, two samplers: this sampler too, from the very same x_T, drawn beside with its own "
        "trail, in the same colours; the chart adds its tip error. DDPM is stochastic; DDIM and DPM-Solver++ "
        "follow the deterministic ODE (ordinary differential equation: a noise-free path from x_T to a pose); "
        "teacher: the teacher's deterministic run a distilled student is trained to match; "
        "student: the student's few steps",
    )  # fmt: skip
