"""The drawing loop: the one thread that writes the viewer's scene, cameras and panel outputs.

Gizmo callbacks, panel callbacks and the solve worker never touch a scene node: they set
fields of one intent (`ask`, intent.py); this thread takes the intent, submits the newest
solve, adopts the newest result and plays the animation; the loop is the clock.
Each picture is first a plain `Frame` (frame.py) built from one snapshot (the solve on
screen, the state, the panel's view settings); the arm view (planar_view.py or
robot_view.py, its nodes), the side views and the panel's outputs (scene_writer.py) are
all written from that frame inside one `server.atomic()`, so they cannot disagree.
"""

from __future__ import annotations

import collections
import time

import numpy as np
import viser
import viser.uplot

import ikdp
from ikdp_viz import readouts
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.camera import fit_fields_of_view
from ikdp_viz.frame import (
    CLOCK_CHOICES,
    Frame,
    Palettes,
    ViewSettings,
    build_frame,
    clock_note,
    highlighted_sample,
    solve_noise_levels,
    state_offsets,
)
from ikdp_viz.intent import Animation, Asked, Intent, StateAsked, TargetMove
from ikdp_viz.joint_space_view import Stage
from ikdp_viz.panel import Panel, plot_axes, plot_scales
from ikdp_viz.planar_scene import nearest_state
from ikdp_viz.style import COMPARE_STROKE, Entry, legend_html
from ikdp_viz.teaching import schedule_curves, schedule_plot_data

FRAMES_PER_SECOND = 30.0  # the animation's clock ticks at most this often
NOISE_HOLD = 0.6  # seconds pure noise (t = T) shows before a played denoising moves (the noisy steps pass fast)
SOFTWARE_WEBGL_TOAST = "webgl-software-rendering"  # viser's own notification id (its BrowserWarning.tsx)


class SceneWriter:
    """Owns what the browser shows, the solve on screen and the animation; takes what is asked on its thread."""

    def __init__(self, server: viser.ViserServer, panel: Panel, solver: ikdp.Solver, target: np.ndarray, gizmo_update):
        self.server, self.panel = server, panel
        self.solver, self.kind = solver, arm_kind(solver)  # the model whose scene is drawn, and its arm's kind
        self.target, self.target_clamped = np.asarray(target, dtype=np.float64), False
        self.solved = None  # solving.Solved on screen
        self.state = 0  # index of the state on screen
        self.frame: Frame | None = None  # the last frame drawn
        self.error: str | None = None  # the newest solve's failure, shown in the readouts
        self.animation: Animation | None = None  # the playing animation, None when still
        self.color_by_constraint = True  # the Constraints folder's "colour poses by constraint"
        self.obstacles = 0  # obstacles the Constraints folder draws (the legend lists them)
        self.followed = False  # follow mode keeps the highlighted sample (the Constraints folder says)
        self.after_solve = None  # called here with each solve put on screen (the Constraints folder's follow mode)
        self._unseen = False  # the solve on screen waits at pure noise for a tab to open, to play then
        self.wait_for_tab = False  # with no tab open, a solve to animate waits at pure noise (the command line's)
        self._replay_target: np.ndarray | None = None  # a drag ended here: animate its solve once drawn
        self.snap_note: str | None = None  # a t asked for that the sampler does not visit, said in the readouts
        # (arrival, drawn, newest) of each solve put on screen: perf_counter times, and whether its target was
        # still the newest; for benchmarks/viz_latency.py
        self.latencies: collections.deque[tuple[float, float, bool]] = collections.deque(maxlen=100_000)
        self.submit_solve = None  # submit_solve(arrival, animate): the app's solve of the newest target
        self.on_changed = None  # on_changed(name): the handler of a control that writes other controls
        self.draw_overlay = None  # draw_overlay(frame): the Constraints folder's coloured states, in the frame's atomic
        self.asked = Asked(
            self._apply,
            wait=lambda: None if self.animation is None else 1.0 / FRAMES_PER_SECOND,  # the next frame, or none
            failed=lambda: setattr(self, "animation", None),  # a failed frame is reported; the loop goes on, still
        )  # fmt: skip
        # any thread: set fields of the intent; wait until all asked is applied; stop the loop (intent.py)
        self.ask, self.flush, self.close, self.on_loop_thread = (
            self.asked.ask, self.asked.flush, self.asked.close, self.asked.on_thread
        )  # fmt: skip
        self._palettes = Palettes()
        self.output = PanelOutput(panel)
        # before any thread exists: the app's constructor is the only writer yet
        self.stage = Stage(server, panel, solver, self.target, gizmo_update)
        self.kind.configure_panel(panel)
        self.output.legend(self.kind.legend_entries(self.settings(), constraint_colors=False, view=None, solved=None))
        self.kind.write_typed_fields(panel.learn.target, self.target)

    # -------------------------------------------------------------- what others read

    view = property(lambda self: self.stage.view)  # the arm view (planar_view.py or robot_view.py): its nodes
    playing = property(lambda self: self.animation is not None)
    still = property(lambda self: self.asked.idle and self.animation is None)  # nothing to apply, nothing playing

    def settings(self) -> ViewSettings:
        """The panel's view settings now (read on this thread, once per frame)."""
        return ViewSettings.from_panel(self.panel, color_by_constraint=self.color_by_constraint,
                                       followed=self.followed, prior=self.view.prior_lines is not None,
                                       obstacles=self.obstacles)  # fmt: skip

    def highlight_index(self) -> int:
        """The 0-based sample the highlight dropdown names, for the solve on screen (0 before any)."""
        if self.solved is None:
            return 0
        return highlighted_sample(str(self.panel.highlight.value), self.solved)

    def run(self, function, wait: bool = True) -> None:
        """Have the loop call `function(writer)` (any thread but the loop's own): long work's panel writes, such as
        an export's progress, and scripts'."""
        if self.on_loop_thread():
            raise RuntimeError("run: already on the drawing loop; call the function directly")
        self.ask(chores=[function])
        if wait:
            self.flush()

    def _apply(self, intent: Intent) -> None:
        """One pass of the loop: everything asked, in the order a picture depends on it, then the clock."""
        if intent.model is not None:
            self._new_model(*intent.model)
        for client in intent.tabs:
            self._tab_opened(client)
        for name in intent.changed:
            self.on_changed(name)
        for chore in intent.chores:
            chore(self)
        if intent.target is not None:
            self._place_target(intent.target)
        if intent.solve is not None:
            self.submit_solve(*intent.solve)
        if intent.prior is not None:
            self.view.show_prior(intent.prior)
            intent.redraw = True  # the legend lists the prior's draw now
        if intent.error is not None:
            self.error, intent.redraw = intent.error, True
        if intent.solved is not None:
            self._show_solve(*intent.solved)
        if intent.fields is not None and intent.fields[0] is self.solved:  # else for a solve no longer on screen
            self.stage.joint_space.adopt(*intent.fields)
            intent.redraw = True
        if intent.replay is not None:
            self._replay(intent.replay)
        if intent.state is not None:
            self._show_asked_state(intent.state)
        if intent.toggle_play:
            self._toggle_play()
        elif intent.redraw:
            self._redraw()
        self._tick()

    def _show_asked_state(self, asked: StateAsked) -> None:
        self.animation = None  # a user's step pauses the animation
        if self.solved is None:
            return
        state = self.state + asked.delta if asked.state is None else asked.state
        self.snap_note = None
        if asked.timestep is not None:
            state = nearest_state(self.solved.view.labels, asked.timestep)
            self.snap_note = snap_note(self.solved.view.labels, asked.timestep, state)
        self._draw_state(state)

    def _replay(self, target: np.ndarray) -> None:
        """A drag ended at `target`: play its solve from t = T, now if on screen, else once drawn."""
        self._replay_target = target
        shown = self.solved is not None and self.solved.preview_of is None  # a preview's full solve follows
        if shown and np.array_equal(self.solved.request.target, target):
            self._replay_target = None
            self._play_from_start(user=False)

    # -------------------------------------------------------------- solves and the animation

    def _show_solve(self, solved, newest: bool) -> None:
        if solved.request.model is not self.solver:
            return  # a solve of the model that was replaced
        self.animation, self._unseen = None, False
        self.solved, self.error, self.snap_note = solved, None, None
        self.view.clear_prior()  # the prior's draw was for the solve before
        preview = solved.preview_of is not None
        if self.after_solve is not None and newest and not preview:
            self.after_solve(solved)  # follow mode picks the sample kept: before the frame that shows it
        self.output.clock(solved.view, self.noise_levels())
        self.kind.write_typed_fields(self.panel.learn.target, solved.request.target)
        last = solved.view.num_states - 1
        released = (
            not preview
            and self._replay_target is not None
            and np.array_equal(solved.request.target, self._replay_target)
        )
        if released:
            self._replay_target = None
        wanted = solved.request.animate or released
        if wanted and self.panel.play_on_move.value and self.panel.duration.value > 0 and last > 0:
            if not self.wait_for_tab or self.server.get_clients():
                self._start(0, last)
            else:  # no one would see it play: show pure noise, and play when a tab opens
                self._unseen = True
                self._draw_state(0)
        else:
            self._draw_state(last)
        self.latencies.append((solved.request.arrival, time.perf_counter(), newest))

    def _redraw(self) -> None:
        """A view setting changed (or a solve failed): the state on screen again, with its legend and readouts."""
        if self.solved is None:
            self.output.waiting(self.error)
            self.output.legend(self.kind.legend_entries(self.settings(), constraint_colors=False, view=None,
                                                        solved=None))  # fmt: skip
            return
        self.output.clock(self.solved.view, self.noise_levels())
        self._draw_state(self.state)

    def set_constraint_colors(self, on: bool) -> None:
        """Colour the samples by constraint, or not; redraws the state on screen (this thread only)."""
        self.color_by_constraint = bool(on)
        self._redraw()

    def show_obstacles(self, count: int) -> None:
        """`count` obstacles are drawn now: the legend says so with the picture on screen (this thread only)."""
        if count != self.obstacles:
            self.obstacles = int(count)
            self._redraw()

    def _play_from_start(self, *, user: bool) -> None:
        """Play the solve on screen from t = T: on a user's Play, or (if "play on move" is on) after a drag."""
        if self.solved is None or self.panel.duration.value <= 0:
            return
        if not user and not self.panel.play_on_move.value:
            return
        self._start(0, self.solved.view.num_states - 1)

    def _toggle_play(self) -> None:
        """Pause a running animation, or play from the current step (from t = T when at the end)."""
        if self.animation is not None:
            self.animation = None
            self._draw_state(self.state)  # paused: now a still frame, drawn in full (the whole trail)
        elif self.solved is not None:
            last = self.solved.view.num_states - 1
            if self.state >= last:
                self._play_from_start(user=True)
            else:
                self._start(self.state, last)
        self.output.playing(self.playing)

    def _start(self, first: int, last: int) -> None:
        """Play from state `first` to `last`: `first` is drawn now, as an animation's frame (the light scene)."""
        seconds = float(self.panel.duration.value)
        offsets = state_offsets(self.noise_levels(), str(self.panel.learn.clock.value), seconds)
        hold = NOISE_HOLD if first == 0 else 0.0  # pure noise stays a moment: the learner sees where it starts
        self.animation = Animation(first, last, seconds / max(last, 1), time.monotonic() + hold, offsets)
        self._draw_state(first)
        self._tick()

    def noise_levels(self) -> np.ndarray:
        """(S+1,) the noise level sigma of each state of the solve on screen."""
        return solve_noise_levels(self.solver, self.solved.view)

    def _tick(self) -> None:
        """Draw the state the animation's clock has reached, and end the animation on its last state."""
        animation = self.animation
        if animation is None or self.solved is None:
            self.animation = None
            return
        state = animation.state_at(time.monotonic())
        if state != self.state or self.frame is None or self.frame.light != (state < animation.last):
            self._draw_state(state)
        if state >= animation.last:
            self.animation = None
            self.output.playing(False)

    # -------------------------------------------------------------- one frame

    def make_frame(self, state: int) -> Frame:
        """The frame of `state` of the solve on screen, as the panel's settings show it now."""
        return build_frame(
            self.kind, self.solved, state, self.settings(), palettes=self._palettes,
            animating_to=None if self.animation is None else self.animation.last, error=self.error,
            note=self.snap_note,
        )  # fmt: skip

    def _draw_state(self, state: int) -> None:
        """Write one frame at `state` (clamped): the scene, the side views, the camera, the panel's outputs."""
        if self.solved is None:
            return
        frame = self.make_frame(state)
        self.state, self.frame = frame.state, frame
        # The slider and the readout go with every state drawn, in the scene's atomic: written a few times a second
        # instead, they named a state up to 17 steps away from the arms on screen while playing.
        with self.server.atomic():
            self.draw_scene(frame)
            if self.draw_overlay is not None:
                self.draw_overlay(frame)
            self.output.frame(frame, self.kind, self.solver)
            self.output.playing(self.playing)

    def draw_scene(self, frame: Frame) -> None:
        """The arm view, the side views and the camera over all that is shown, from one frame."""
        self.stage.draw(frame, self.solver)

    def _tab_opened(self, client) -> None:
        """A tab connected: hide viser's software-WebGL toast, which covered the scene's top left,
        and play the solve on screen if no one has seen it play (the page opened on pure noise)."""
        hide_toast(client)
        fit_fields_of_view(self.server)
        if self._unseen and self.solved is not None:
            self._unseen = False
            self._play_from_start(user=False)

    # -------------------------------------------------------------- the target and the model

    def _place_target(self, move: TargetMove) -> None:
        self.target, self.target_clamped = move.target, move.clamped
        self.view.place_target(move.target, move_gizmo=move.move_gizmo, force=move.force,
                               camera_position=np.asarray(self.server.initial_camera.position))  # fmt: skip
        self.panel.target_text.content = self.kind.target_text(self.solver, self.target, self.target_clamped)

    def _new_model(self, solver, target) -> None:
        self.animation = None
        self.solver, self.solved, self.target, self.frame = solver, None, target, None
        self.stage.rebuild(solver, target)
        self.output.new_model(solver.timesteps)
        self.panel.target_text.content = self.kind.target_text(self.solver, self.target, self.target_clamped)
        self.output.waiting(self.error)


def snap_note(labels: np.ndarray, asked: float, state: int) -> str | None:
    """The readouts' line when the slider asked for a t the sampler never visits (a few-step sampler's gaps)."""
    shown = int(labels[state])
    if round(float(asked)) == shown:
        return None
    times = [int(label) for label in labels]
    visits = ", ".join(map(str, times)) if len(times) <= 12 else f"{len(times)} of them"
    return (
        f"t = {float(asked):g} is no step of this sampler (it visits t = {visits}): the nearest, t = {shown}, is shown"
    )


def same_columns(shown, columns) -> bool:
    """A plot's data already holds `columns` (NaN equal to NaN): writing it again would redraw the plot."""
    return len(shown) == len(columns) and all(
        np.shape(a) == np.shape(b) and np.array_equal(a, b, equal_nan=True) for a, b in zip(shown, columns, strict=True)
    )


def hide_toast(client) -> None:
    """Ask `client`'s page to close viser's "Software WebGL rendering detected" notification (viser's own message:
    the notification has a fixed id; a page with a GPU never shows it, and the message then does nothing)."""
    from viser._messages import RemoveNotificationMessage

    client._websock_connection.queue_message(RemoveNotificationMessage(SOFTWARE_WEBGL_TOAST))


# The panel's outputs, written from a `Frame`: slider, readouts, legend, chart, clock note, play button, target.
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
        """The slider, the chart and the readouts at the frame's state, and the legend of its colours; only what
        changed is sent (a playing frame's chart and schedule plot have no marker of the state, so they stand)."""
        panel, view = self.panel, frame.view
        timestep = int(view.labels[frame.state])
        if panel.timestep.value != timestep:
            panel.timestep.value = timestep  # the app ignores slider updates with no client
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
        if not same_columns(panel.plot.data, frame.chart):
            panel.plot.data = frame.chart
        if panel.readout_text.content != frame.readout:
            panel.readout_text.content = frame.readout
        self.schedule(frame, solver)
        self.legend(frame.legend)

    def schedule(self, frame: Frame, solver) -> None:
        """The schedule plot: the model's sigma and alphabar, the step shown (none while playing), the times its
        sampler visits."""
        if self._schedule is None or self._schedule[0] is not solver:
            self._schedule = (solver, schedule_curves(solver.model.schedule.alphas_cumprod))
        view = frame.view
        now = None if frame.light else float(view.labels[frame.state])
        data = schedule_plot_data(self._schedule[1], now, view.labels)
        if not same_columns(self.panel.teach.schedule.data, data):
            self.panel.teach.schedule.data = data

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
