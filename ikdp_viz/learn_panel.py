"""The panel's controls that make the denoising readable: whose trail, the clock, the legend, sharing a solve."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from ikdp_viz.clock import CLOCK_CHOICES
from ikdp_viz.emphasis import TRAIL_CHOICES


@dataclass
class TargetInputs:
    """The target typed in the Target folder: x, y for a planar arm; a robot's position and rotation."""

    xy: viser.GuiVector2Handle  # planar arm only
    position_mm: viser.GuiVector3Handle  # a robot's hand position, millimetres
    rotation_deg: viser.GuiVector3Handle  # and its rotation, roll pitch yaw in degrees (pose models)
    go: viser.GuiButtonHandle  # solve the typed target

    def show_for(self, kind: str, target_dim: int) -> None:
        """Offer the fields of an arm of `kind` ("planar" or "chain"); rotation only for pose targets."""
        self.xy.visible = kind == "planar"
        self.position_mm.visible = kind != "planar"
        self.rotation_deg.visible = kind != "planar" and target_dim == 7


@dataclass
class LearnControls:
    trail_of: viser.GuiDropdownHandle  # the highlighted sample's trail (the paper's figure) or every sample's
    clock: viser.GuiDropdownHandle  # the animation's time spaced by noise level or by step
    clock_note: viser.GuiMarkdownHandle  # where the animation's time goes, said on screen
    legend: viser.GuiHtmlHandle  # what each colour means (legend.py; written by the scene writer)
    share: viser.GuiButtonHandle  # one self-contained HTML file of the solve on screen (record.py)
    target: TargetInputs  # the target typed in the panel
    compare: viser.GuiDropdownHandle  # "off" or a second sampler run from the same x_T, drawn beside (compare.py)


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
