"""The panel's controls that teach: the tour's folder, noise it, again from the same x_T, the schedule, the words.

Laid out here, wired in app.py, written (texts and the schedule plot) by the drawing loop alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import viser

from ikdp_viz.schedule_plot import SCHEDULE_NOTE, ScheduleCurves, build_schedule_plot
from ikdp_viz.words import define, glossary_markdown


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
    noise_it: viser.GuiButtonHandle  # the forward process of the poses on screen (noise_it.py)
    again: viser.GuiButtonHandle  # rerun the solve on screen from its x_T (same_noise.py)
    again_text: viser.GuiMarkdownHandle  # how far the rerun's poses moved
    schedule: viser.GuiUplotHandle  # sigma(t) and alphabar_t, the step shown, the sampler's steps (schedule_plot.py)
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
