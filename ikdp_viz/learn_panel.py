"""The panel's controls that make the denoising readable: whose trail is drawn (more in later commits)."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from ikdp_viz.emphasis import TRAIL_CHOICES


@dataclass
class LearnControls:
    trail_of: viser.GuiDropdownHandle  # the highlighted sample's trail (the paper's figure) or every sample's


def build_trail_of(gui: viser.GuiApi) -> viser.GuiDropdownHandle:
    return gui.add_dropdown(
        "trail of", TRAIL_CHOICES, initial_value=TRAIL_CHOICES[0],
        hint="highlighted: the paper's figure, one sample's denoising from faint to dark, the others light; "
        "all samples: every sample's trail and arm dark",
    )  # fmt: skip
