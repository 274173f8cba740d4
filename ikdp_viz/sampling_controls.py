"""The Sampling folder's controls that depend on each other: K and the highlight, the sampler and its steps.

A sampler that takes all T steps (DDPM) shows T on a disabled slider; the steps the user chose
for one that can skip some come back with it (issue 19). Each change asks for a solve.
"""

from __future__ import annotations

from ikdp.samplers import SAMPLERS
from ikdp_viz.panel import Panel, highlight_options


class SamplingControls:
    """K, the sampler, its steps and the refinement of one panel; `request_solve()` after each change."""

    def __init__(self, panel: Panel, request_solve):
        self.panel, self.request_solve = panel, request_solve
        self.chosen_steps = int(panel.steps.value)  # the steps a sampler that can skip some takes
        self._showing = False  # show_steps is moving the slider

    def on_samples(self) -> None:
        options = highlight_options(int(self.panel.samples.value))
        current = self.panel.highlight.value
        self.panel.highlight.options = options
        if current not in options:
            self.panel.highlight.value = "best"
        self.request_solve()

    def on_sampler(self) -> None:
        self.show_steps()
        self.request_solve()

    def on_steps(self) -> None:
        steps = self.panel.steps
        if self._showing or (steps.disabled and int(steps.value) == steps.max):
            return  # show_steps, or the loop fitting the slider to a new model's T: no one's choice
        self.chosen_steps = int(steps.value)  # a script's or the command line's, for when a sampler can skip
        if steps.disabled:
            self.show_steps()  # this sampler takes all T: that is what the slider says
        else:
            self.request_solve()

    def show_steps(self) -> None:
        """The steps slider: the user's choice for a sampler that can skip steps; else disabled at T, the steps
        it does take (issue 19: DDPM showed a stale number). The user's choice comes back with such a sampler."""
        steps = self.panel.steps
        takes_all = not SAMPLERS[str(self.panel.sampler.value)].supports_steps
        if takes_all and not steps.disabled:
            self.chosen_steps = int(steps.value)
        steps.disabled = takes_all
        shown = steps.max if takes_all else min(self.chosen_steps, steps.max)
        if steps.value != shown:
            self._showing = True  # not a user's change: no solve of its own
            try:
                steps.value = shown
            finally:
                self._showing = False

    def on_refine(self) -> None:
        self.panel.refine_steps.disabled = not self.panel.refine.value
        self.request_solve()
