"""The panel's outputs, written from a `Frame`: slider, readouts, legend, chart, clock note, play button, target.

Only the drawing loop (scene_writer.py) calls these, so a text, the chart and the scene are
always the same frame's. Everything written here is skipped when it holds its value already
(viser sends every assignment), which matters while an animation plays.
"""

from __future__ import annotations

import numpy as np
import viser
import viser.uplot

from ikdp_viz import readouts
from ikdp_viz.clock import CLOCK_CHOICES, clock_note, state_offsets
from ikdp_viz.frame import Frame
from ikdp_viz.legend import Entry, legend_html
from ikdp_viz.panel import Panel, plot_axes, plot_scales
from ikdp_viz.schedule_plot import schedule_curves, schedule_plot_data
from ikdp_viz.style import COMPARE_STROKE


class PanelOutput:
    """Writes the parts of the panel that show the frame on screen."""

    def __init__(self, panel: Panel):
        self.panel = panel
        self._chart_series = tuple(panel.plot.series)  # the chart's own series; a comparison adds one
        self._chart_compared: str | None = None  # the sampler whose curve the chart shows besides, if any
        self._legend: tuple[Entry, ...] | None = None
        self._chart_solve = None  # the solve the chart's scales were written for
        self._schedule = None  # (solver, its ScheduleCurves) the schedule plot draws

    def frame(self, frame: Frame, kind, solver) -> None:
        """The slider, the chart and the readouts at the frame's state, and the legend of its colours."""
        panel, view = self.panel, frame.view
        panel.timestep.value = int(view.labels[frame.state])  # the app ignores slider updates with no client
        if self._chart_solve is not frame.solved:
            decades = readouts.error_range(view.tip_error * kind.chart_scale)
            panel.plot.scales = plot_scales(solver.timesteps, *decades)
            panel.plot.axes = plot_axes(*decades, kind.chart_unit)
            panel.plot.title = f"{kind.chart_error} against t"
            self._chart_solve = frame.solved
        if frame.chart_compared != self._chart_compared:  # the series first: uPlot draws one column per series
            compared = frame.chart_compared
            extra = () if compared is None else (viser.uplot.Series(label=compared, stroke=COMPARE_STROKE, width=2),)
            panel.plot.series = (*self._chart_series, *extra)
            self._chart_compared = compared
        panel.plot.data = frame.chart
        panel.readout_text.content = frame.readout
        self.legend(frame.legend)
        self.schedule(frame, solver)

    def schedule(self, frame: Frame, solver) -> None:
        """The schedule plot: the model's sigma and alphabar, the step shown, the times its sampler visits."""
        if self._schedule is None or self._schedule[0] is not solver:
            self._schedule = (solver, schedule_curves(solver.model.schedule.alphas_cumprod))
        view = frame.view
        now = float(view.labels[frame.state])
        self.panel.teach.schedule.data = schedule_plot_data(self._schedule[1], now, view.labels)

    def legend(self, entries) -> None:
        entries = tuple(entries)
        if entries != self._legend:
            self.panel.learn.legend.content = legend_html(list(entries))
            self._legend = entries

    def waiting(self, error: str | None) -> None:
        """No solve on screen: say why."""
        self.panel.readout_text.content = f"**Solve failed** {error}" if error else "Waiting for the first solve..."

    def clock(self, view, sigmas: np.ndarray) -> None:
        """Say on screen where the animation's time goes (the clock's spacing)."""
        clock = str(self.panel.learn.clock.value)
        offsets = state_offsets(sigmas, clock, float(self.panel.duration.value))
        spacing = "by noise level σ = √(1 − ᾱ_t)" if clock == CLOCK_CHOICES[0] else "evenly by step"
        self.panel.learn.clock_note.content = f"Time spaced {spacing}, {clock_note(view.labels, offsets, sigmas)}"

    def playing(self, playing: bool) -> None:
        button = self.panel.play_button
        label, icon = ("Pause", viser.Icon.PLAYER_PAUSE) if playing else ("Play", viser.Icon.PLAYER_PLAY)
        if button.label != label:
            button.label, button.icon = label, icon

    def new_model(self, num_timesteps: int) -> None:
        panel = self.panel
        panel.timestep.max = num_timesteps
        panel.steps.max = num_timesteps
        panel.steps.value = min(panel.steps.value, num_timesteps)
        self._chart_solve = None
