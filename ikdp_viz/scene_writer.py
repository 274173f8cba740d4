"""The one thread that writes the viewer's scene and readouts; every other thread sends it messages.

Gizmo callbacks, panel callbacks and the solve worker never touch a scene node:
they `post()` a message, and this thread applies the messages one at a time, in
the order they were posted, and plays the animation between them. So nothing it
draws can be changed under it (the solve on screen, the model, the nodes), and
a solve of a replaced model or an older target cannot land over a newer one:
the races of a lock-per-method design are impossible by construction.

What to draw for a state is `scene.py`'s (plain numpy); this file only copies
those arrays into viser handles.
"""

from __future__ import annotations

import collections
import queue
import threading
import time
import traceback
from dataclasses import dataclass

import numpy as np
import viser

import ikdp
from ikdp_viz import meshes, readouts
from ikdp_viz.clock import CLOCK_CHOICES, clock_note, noise_levels, state_offsets
from ikdp_viz.compare import CompareNodes, compare_curve
from ikdp_viz.constraint_scene import (
    FREE_AXIS_COLOR,
    HOLDS,
    HOLDS_OTHERS,
    VIOLATES,
    VIOLATES_OTHERS,
    met_text,
    sample_tints,
)
from ikdp_viz.emphasis import OTHERS_FINAL, emphasis_colors, estimate_rows, follows_one, trail_rows
from ikdp_viz.joint_space_nodes import JointSpaceNodes
from ikdp_viz.legend import Entry, Swatch, legend_html
from ikdp_viz.panel import Panel, highlight_index, plot_axes, plot_scales
from ikdp_viz.scene import (
    ACCENT_DARK,
    ACCENT_FAINT,
    ARM_LIFT,
    DARK,
    FAINT,
    HIGHLIGHT_LIFT,
    REFINED,
    REFINED_LIFT,
    TARGET_LIFT,
    TIP_DARK,
    TIP_FAINT,
    arm_placement,
    circle_segments,
    error_curves,
    fade_colors,
    grid_segments,
    line_colors,
    nearest_state,
    polyline_segments,
    sample_colors,
    trail_colors,
    trail_until,
)
from ikdp_viz.solving import Solved

TARGET_RED = (220, 25, 25)
GRID_CELL = (236, 236, 236)  # grid lines every half bone length
GRID_SECTION = (212, 212, 212)  # grid lines every mean bone length
ESTIMATE = (150, 80, 200)  # the denoiser's x̂0, ghosted
PRIOR = (150, 100, 50)  # poses drawn from the training prior
LINE_PIXELS = 1.5  # trail line thickness, screen pixels
ARM_PIXELS = 5.0  # the K arms' links, screen pixels (the joints' spheres are about twice as wide at the default zoom)
FRAMES_PER_SECOND = 30.0  # the animation's clock ticks at most this often
PLAYING_TRAIL_STATES = 6  # the trail while an animation plays: every s-th state; all once it stops
PLAYING_FOLLOWED_STATES = 12  # the same for the one sample followed (the default picture)
COMPARE_STROKE = "#2a9d5c"  # the chart's line of the compared sampler
PLAYING_PANEL_WRITES = 6.0  # per second at most, the slider, chart and readouts while an animation plays


def camera_fit(reach: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera straight above the workspace of radius `reach`, all of it in view.

    +x to the right and +y up (a hair off the pole so "up" is defined), the workspace centred: the
    panel has a column of its own (panel.py).
    """
    distance = 1.55 * reach
    return (0.0, -1e-3 * distance, distance), (0.0, 0.0, 0.0)


def over_the_point(point, height: float, camera) -> np.ndarray:
    """(3,) where a marker `height` above the plane draws exactly over `point` (2,) on it, seen from `camera` (3,).

    On the ray from the camera to the point: straight above it, the perspective camera would draw the
    lifted target cross 15 to 25 px off where the tips meet (issue 19). Exact for the initial camera
    every tab starts with; orbiting the view shifts it by at most height / distance of the radius.
    """
    ground = np.array([float(point[0]), float(point[1]), 0.0])
    camera = np.asarray(camera, dtype=np.float64)
    return ground + (camera - ground) * (height / camera[2])


# ------------------------------------------------------------------ messages


@dataclass(frozen=True)
class ShowSolve:
    solved: Solved  # a finished solve, to draw in place of the one on screen
    newest: bool  # its target was still the newest when it finished (for the latency benchmark)


@dataclass(frozen=True)
class ShowState:
    state: int | None = None  # a state index (0 = pure noise .. S = final), or
    timestep: float | None = None  # the state nearest this diffusion time
    delta: int = 0  # added to the state on screen (previous / next buttons)


@dataclass(frozen=True)
class TogglePlay:
    pass


@dataclass(frozen=True)
class ReplayWhenDrawn:
    target: np.ndarray  # (2,) a drag ended here: play its solve from t = T, now if on screen, else once drawn


@dataclass(frozen=True)
class Redraw:
    pass  # the highlight, trail or x̂0 setting changed: draw the state on screen again


@dataclass(frozen=True)
class PlaceTarget:
    target: np.ndarray  # (2,) where the cross goes
    clamped: bool  # the asked point lay outside the workspace
    move_gizmo: bool  # write the gizmo's position (False: the page's drag already put it there)
    force: bool  # send the position even when the server's copy holds it already


@dataclass(frozen=True)
class NewModel:
    solver: ikdp.Solver  # rebuild the scene for this model; solves of any other are dropped
    target: np.ndarray  # (2,) the cross's place in the new workspace


@dataclass(frozen=True)
class ShowPrior:
    joints: np.ndarray  # (K, N+1, 2) poses drawn from the model's prior, shown until the next solve


@dataclass(frozen=True)
class ShowError:
    text: str  # why the newest solve failed


@dataclass(frozen=True)
class Call:
    function: object  # called on the writer's thread with the writer: for the panel's exports and tests


@dataclass(frozen=True)
class Barrier:
    done: threading.Event  # set once every message posted before it has been applied


@dataclass
class Animation:
    """The clock of one playing of the denoising: state first at `started_at`, one state per `seconds_per_state`."""

    first: int  # the state shown when it started
    last: int  # the state it ends on
    seconds_per_state: float  # 0: jump to the last state
    started_at: float  # time.monotonic() when `first` was shown
    offsets: np.ndarray | None = None  # (S+1,) when each state shows, seconds from state 0 (clock.py); None: evenly

    def state_at(self, now: float) -> int:
        """The state the clock has reached at `now`: a slow frame skips states, it never slows the animation."""
        if self.seconds_per_state <= 0:
            return self.last
        if self.offsets is not None:
            elapsed = now - self.started_at + self.offsets[self.first]
            reached = int(np.searchsorted(self.offsets, elapsed, side="right")) - 1
            return int(np.clip(reached, self.first, self.last))
        return min(self.last, self.first + int((now - self.started_at) / self.seconds_per_state))


# ------------------------------------------------------------------ the writer


class SceneWriter:
    """Owns the scene nodes, the solve on screen and the animation; applies posted messages on its own thread."""

    CHART_ERROR, CHART_UNIT = "tip error", "bone lengths"  # what the chart's y axis shows, in what unit
    CHART_SCALE = 1.0  # view.tip_error times this is in that unit
    # the legend's constraint colours: how the samples not highlighted show them
    HOLDS_TEXT = "constraints hold at the step shown (the others lighter)"
    VIOLATES_TEXT = "constraints fail at the step shown"

    def __init__(self, server: viser.ViserServer, panel: Panel, solver: ikdp.Solver, target: np.ndarray, gizmo_update):
        self.server, self.panel = server, panel
        self.solver = solver  # the model whose scene is drawn
        self.target, self.target_clamped = np.asarray(target, dtype=np.float64), False
        self._gizmo_update = gizmo_update  # the app's gizmo callback, wired to every gizmo this builds
        self.solved: Solved | None = None  # the solve on screen
        self.state = 0  # index of the state on screen
        self.error: str | None = None  # the newest solve's failure, shown in the readouts
        self.animation: Animation | None = None  # the playing animation, None when still
        self._panel_written = -np.inf  # time.monotonic() of the last state written to the panel
        self._replay_target: np.ndarray | None = None  # a drag ended here: animate its solve once drawn
        # (arrival, drawn, newest) of each solve put on screen: perf_counter times, and whether its target was
        # still the newest; for benchmarks/viz_latency.py
        self.latencies: collections.deque[tuple[float, float, bool]] = collections.deque(maxlen=100_000)
        self._queue: queue.Queue = queue.Queue()
        self._busy = False  # a message is being applied
        self._closed = False
        self._thread: threading.Thread | None = None  # started by the first post(), not at construction
        self._thread_lock = threading.Lock()
        self.nodes_shape: tuple[int, int] | None = None  # (K, N) of the arm nodes
        self._joint_scales_key: tuple | None = None  # what the joints' scales were written for
        self._colors: np.ndarray | None = None  # (S+1, K, 3) per-sample colour of each state
        self._trail_colors: np.ndarray | None = None  # (S+1, K*N, 2, 3)
        self._dot_colors: np.ndarray | None = None  # (S+1, K, 3) the joint-space dots, as "all samples" colours arms
        self.color_by_constraint = True  # the Constraints folder's "colour poses by constraint" (constraint_controls)
        self.trail = self.links = self.joints = self.tips = None
        self.refined_lines = self.refined_tips = self.estimate_lines = self.prior_lines = None
        self._static_nodes: list = []
        self.joint_space = JointSpaceNodes(server, panel.joint_space, camera_fit)  # the torus beside the arm
        self.compare = CompareNodes(server, camera_fit)  # a second sampler from the same noise, beside the arm
        self._chart_series = tuple(panel.plot.series)  # the chart's own series; a comparison adds one
        self._chart_compared: str | None = None  # the sampler whose curve the chart shows besides, if any
        # No environment map: its reflections wash dark materials out to grey; the default lights stay.
        server.scene.configure_environment_map(hdri=None)
        # No shadow maps: nothing here casts one, and software WebGL drew the empty page at 16-26 frames/s with
        # them, 27-29 without (docs/VIZ.md)
        server.scene.configure_default_lights(cast_shadow=False)
        self._build_static_scene()  # before any thread exists: the app's constructor is the only writer yet
        self._write_legend()
        self.write_target_inputs(self.target)

    # -------------------------------------------------------------- the queue

    def post(self, message) -> None:
        """Queue `message` for the writer's thread (any thread may post)."""
        with self._thread_lock:
            if self._closed:
                return
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="ikdp-viz-scene", daemon=True)
                self._thread.start()
        self._queue.put(message)

    def flush(self, timeout: float = 30.0) -> bool:
        """Block until every message posted so far has been applied (True), or `timeout` passes (False)."""
        if threading.current_thread() is self._thread:
            return True
        done = threading.Event()
        self.post(Barrier(done))
        return done.wait(timeout) or self._closed

    @property
    def playing(self) -> bool:
        return self.animation is not None

    @property
    def still(self) -> bool:
        """No message waiting or being applied, and no animation playing."""
        return self._queue.empty() and not self._busy and self.animation is None

    def close(self, timeout: float = 2.0) -> None:
        with self._thread_lock:
            self._closed, thread = True, self._thread
        self._queue.put(None)
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    def _run(self) -> None:
        while True:
            wait = None if self.animation is None else 1.0 / FRAMES_PER_SECOND
            try:
                message = self._queue.get(timeout=wait)
            except queue.Empty:
                message = ()  # the animation's clock ticked
            if message is None:
                return
            self._busy = True
            try:
                if message != ():
                    self._apply(message)
                self._tick()
            except Exception:
                traceback.print_exc()  # a failed frame is reported; the writer goes on
                self.animation = None
            finally:
                self._busy = False

    def _apply(self, message) -> None:
        if isinstance(message, ShowSolve):
            self._show_solve(message)
        elif isinstance(message, ShowState):
            self.animation = None  # a user's step pauses the animation
            if self.solved is not None:
                state = self.state + message.delta if message.state is None else message.state
                if message.timestep is not None:
                    state = nearest_state(self.solved.view.labels, message.timestep)
                self._draw_state(state)
        elif isinstance(message, TogglePlay):
            self._toggle_play()
        elif isinstance(message, ReplayWhenDrawn):
            self._replay_target = message.target
            if self.solved is not None and np.array_equal(self.solved.request.target, message.target):
                self._replay_target = None
                self._play_from_start(user=False)
        elif isinstance(message, Redraw):
            self._write_legend()
            if self.solved is not None:
                self._write_clock_note()
                self._recolor()
                self._draw_state(self.state)
        elif isinstance(message, PlaceTarget):
            self._place_target(message)
        elif isinstance(message, NewModel):
            self._new_model(message)
        elif isinstance(message, ShowPrior):
            self._show_prior(message.joints)
        elif isinstance(message, ShowError):
            self.error = message.text
            self._write_readouts()
        elif isinstance(message, Call):
            message.function(self)
        elif isinstance(message, Barrier):
            message.done.set()
        else:
            raise TypeError(f"message: expected one of the scene writer's messages, got {message!r}")

    # -------------------------------------------------------------- solves and the animation

    def _show_solve(self, message: ShowSolve) -> None:
        solved = message.solved
        if solved.request.solver is not self.solver:
            return  # a solve of the model that was replaced
        self.animation = None
        self.solved, self.error = solved, None
        if self.prior_lines is not None:  # the prior's draw was for the solve before
            self.prior_lines.remove()
            self.prior_lines = None
        self._recolor()
        self._ensure_arm_nodes()
        self._write_legend()  # the constraints' green and red come and go with the solve's constraints
        self._write_clock_note()
        self.write_target_inputs(solved.request.target)
        decades = readouts.error_range(solved.view.tip_error * self.CHART_SCALE)
        self.panel.plot.scales = plot_scales(self.solver.timesteps, *decades)
        self.panel.plot.axes = plot_axes(*decades, self.CHART_UNIT)
        self.panel.plot.title = f"{self.CHART_ERROR} against t"
        self._write_refined()
        last = solved.view.num_states - 1
        released = self._replay_target is not None and np.array_equal(solved.request.target, self._replay_target)
        if released:
            self._replay_target = None
        wanted = solved.request.animate or released
        animate = wanted and self.panel.play_on_move.value and self.panel.duration.value > 0 and last > 0
        if animate:
            self._start(0, last)
        else:
            self._draw_state(last)
        self.latencies.append((solved.request.arrival, time.perf_counter(), message.newest))

    def draw_recorded_state(self, solved: Solved, state: int) -> None:
        """Draw `state` of `solved` in full on the calling thread, without the panel: a frame of a recording.

        Only for a writer of its own, never started (record.py drives one on a private server):
        a started writer's thread must stay the only one that writes its scene.
        """
        if self._thread is not None:
            raise RuntimeError(
                "draw_recorded_state: this writer's thread draws its scene; record on a writer of its own"
            )
        if self.solved is not solved:
            self.solved, self.animation = solved, None
            self._recolor()
            self._ensure_arm_nodes()
            self._write_refined()
        self.state = int(np.clip(state, 0, solved.view.num_states - 1))
        self._draw_arms(solved, self.state, self.highlight_index())

    def _show_prior(self, joints: np.ndarray) -> None:
        if self.prior_lines is not None:
            self.prior_lines.remove()
        self.prior_lines = self.server.scene.add_line_segments(
            "/prior", polyline_segments(joints, z=0.5 * REFINED_LIFT * self.sizes.joint), colors=PRIOR,
            thickness=2 * LINE_PIXELS, thickness_units="screen",
        )  # fmt: skip

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
        self._write_play_label()

    def _start(self, first: int, last: int) -> None:
        """Play from state `first` to `last`: `first` is drawn now, as an animation's frame (the light scene)."""
        seconds = float(self.panel.duration.value)
        offsets = state_offsets(self.noise_levels(), str(self.panel.learn.clock.value), seconds)
        self.animation = Animation(first, last, seconds / max(last, 1), time.monotonic(), offsets)
        self._panel_written = -np.inf  # the panel shows where it starts
        self._draw_state(first)
        self._tick()

    def noise_levels(self) -> np.ndarray:
        """(S+1,) the noise level sigma of each state of the solve on screen."""
        schedule = self.solver.model.schedule
        return noise_levels(self.solved.view.labels, schedule.sqrt_one_minus_alphas_cumprod.cpu().numpy())

    def write_target_inputs(self, target: np.ndarray) -> None:
        """The typed-target fields show the target solved (so a small change is one edit away)."""
        inputs = self.panel.learn.target
        inputs.show_for("planar", 2)
        inputs.xy.value = tuple(round(float(value), 3) for value in target[:2])

    def legend_entries(self) -> list[Entry]:
        """What each colour of the planar scene means, for the panel's legend."""
        if follows_one(self.trail_of):
            trail = Entry(Swatch(ACCENT_DARK, faint=ACCENT_FAINT), "trail of the highlighted sample: t = T → 0")
            others = Entry(Swatch(OTHERS_FINAL, faint=FAINT), "the other samples (light)")
        else:
            trail = Entry(Swatch(DARK, faint=FAINT), "trails of all samples: t = T → 0")
            others = Entry(Swatch(DARK, faint=FAINT), "the other samples")
        return [
            trail,
            Entry(Swatch(ACCENT_DARK), "highlighted sample, at the step shown"),
            others,
            Entry(Swatch(TIP_DARK, "dot"), "tips"),
            Entry(Swatch(ESTIMATE), "x̂0: the denoiser's guess of the final pose"),
            Entry(Swatch(REFINED), "refined at t = 0 (DLS polish)"),
            Entry(Swatch(PRIOR), "poses drawn from the prior"),
            Entry(Swatch(TARGET_RED, "cross"), "target"),
        ]

    def _write_legend(self) -> None:
        self.panel.learn.legend.content = legend_html(self.legend_entries() + self.constraint_legend_entries())

    # -------------------------------------------------------------- colouring by constraint

    @property
    def constraint_colors_shown(self) -> bool:
        """Whether the samples are coloured by constraint now: asked for, and the solve on screen has a
        constraint that can hold or fail."""
        solved = self.solved
        return self.color_by_constraint and solved is not None and solved.state_violation is not None

    def constraint_tints(self) -> np.ndarray | None:
        """(S+1, K, 3) every sample's colour at every state by whether its constraints hold (constraint_scene),
        or None where `constraint_colors_shown` is False."""
        if not self.constraint_colors_shown:
            return None
        return sample_tints(self.solved.state_violation, self.highlight_index())

    def constraint_legend_entries(self) -> list[Entry]:
        """The Constraints folder's colours in the scene now: green and red, the free axis."""
        entries = []
        if self.constraint_colors_shown:
            entries += [
                Entry(Swatch(HOLDS, faint=HOLDS_OTHERS), self.HOLDS_TEXT),
                Entry(Swatch(VIOLATES, faint=VIOLATES_OTHERS), self.VIOLATES_TEXT),
            ]
        measure = getattr(self.solved.view, "rotation_measure", "rotation") if self.solved is not None else "rotation"
        if measure not in ("rotation", "none"):
            entries.append(Entry(Swatch(FREE_AXIS_COLOR), f"the hand's free {measure}: any turn about it counts"))
        return entries

    def set_constraint_colors(self, on: bool) -> None:
        """Colour the samples by constraint, or not; redraws the state on screen."""
        self.color_by_constraint = bool(on)
        self._write_legend()
        if self.solved is not None:
            self._recolor()
            self._draw_state(self.state)

    def _write_clock_note(self) -> None:
        """Say on screen where the animation's time goes (the clock's spacing)."""
        if self.solved is None:
            return
        sigmas = self.noise_levels()
        clock = str(self.panel.learn.clock.value)
        offsets = state_offsets(sigmas, clock, float(self.panel.duration.value))
        spacing = "by noise level σ = √(1 − ᾱ_t)" if clock == CLOCK_CHOICES[0] else "evenly by step"
        self.panel.learn.clock_note.content = (
            f"Time spaced {spacing}, {clock_note(self.solved.view.labels, offsets, sigmas)}"
        )

    def _tick(self) -> None:
        """Draw the state the animation's clock has reached, and end the animation on its last state."""
        animation = self.animation
        if animation is None or self.solved is None:
            self.animation = None
            return
        state = animation.state_at(time.monotonic())
        if state != self.state:
            self._draw_state(state)
        if state >= animation.last:
            self.animation = None
            self._write_play_label()

    # -------------------------------------------------------------- the target and the model

    def _place_target(self, message: PlaceTarget) -> None:
        self.target, self.target_clamped = message.target, message.clamped
        if message.move_gizmo:
            # viser skips a position equal to its copy, but while a drag goes past the boundary the page's
            # gizmo follows the pointer beyond the clamped point the server holds: on release, send it again.
            position = np.array([float(message.target[0]), float(message.target[1]), 0.0])
            if message.force:
                self.gizmo.position = position + (1e-3, 0.0, 0.0)
            self.gizmo.position = position
        # the cross is no child of the gizmo: during a drag past the boundary it stays on the clamped point
        self.cross.position = self._cross_position()
        self._write_target_text()

    def _cross_position(self) -> np.ndarray:
        """Over everything (lifted) yet drawn on the target, as the initial camera sees it."""
        return over_the_point(self.target, TARGET_LIFT * self.sizes.joint, self.server.initial_camera.position)

    def _write_target_text(self) -> None:
        self.panel.target_text.content = readouts.target_text(self.target, self.target_clamped, self.solver.reach)

    def _new_model(self, message: NewModel) -> None:
        self.animation = None
        self.solver, self.solved, self.target = message.solver, None, message.target
        self._remove_arm_nodes()
        self.joint_space.reset()
        self.compare.remove()
        self._build_static_scene()
        num_timesteps = message.solver.timesteps
        self.panel.timestep.max = num_timesteps
        self.panel.steps.max = num_timesteps
        self.panel.steps.value = min(self.panel.steps.value, num_timesteps)
        self._write_target_text()
        self._write_readouts()

    # -------------------------------------------------------------- drawing one state

    def _recolor(self) -> None:
        view = self.solved.view
        self._colors, ramp = emphasis_colors(view.num_states, view.num_samples, self.highlight_index(), self.trail_of)
        tints = self.constraint_tints()
        if tints is not None:  # every arm green where its constraints hold at that state, red where not
            self._colors = tints
        self._trail_colors = trail_colors(ramp, view.num_links)
        # the joint-space dots: every sample as dark as in "all samples", or light grey dots vanish on the square
        self._dot_colors = sample_colors(view.num_states, view.num_samples, self.highlight_index())

    @property
    def trail_of(self) -> str:
        """Whose trail is drawn and drawn dark: "highlighted" (the paper's figure) or "all samples"."""
        return str(self.panel.learn.trail_of.value)

    def highlight_index(self) -> int:
        """The 0-based sample the highlight dropdown names, for the solve on screen (0 before any)."""
        view = self.solved.view if self.solved is not None else None
        if view is None:
            return 0
        return highlight_index(self.panel.highlight.value, view.best_sample(), view.num_samples)

    def _draw_state(self, state: int) -> None:
        """Write one frame at `state` (clamped): the arms as `_draw_arms` draws them, the slider, chart, readouts."""
        solved = self.solved
        if solved is None:
            return
        view = solved.view
        state = int(np.clip(state, 0, view.num_states - 1))
        self.state = state
        highlight = self.highlight_index()
        now = time.monotonic()
        # Writing the panel with every state cost the playing page 5.4 ms a frame more in software WebGL
        # (benchmarks/viz_frame_costs.py): while playing it follows a few times a second; still frames write it.
        write_panel = not self.animating(state) or now - self._panel_written >= 1.0 / PLAYING_PANEL_WRITES
        with self.server.atomic():
            self._draw_arms(solved, state, highlight)
            if write_panel:
                self.write_panel_state(now)
            self._write_play_label()

    def write_panel_state(self, now: float) -> None:
        """The slider, the chart's dot and the readouts at the state on screen; `now` is when (time.monotonic())."""
        view, highlight = self.solved.view, self.highlight_index()
        self.panel.timestep.value = int(view.labels[self.state])  # the app ignores slider updates with no client
        data = error_curves(view, highlight, self.state, scale=self.CHART_SCALE)
        compared = self.solved.request.compare_sampler if self.solved.compare is not None else None
        if compared is not None:
            data = (*data, compare_curve(view, self.solved.compare, highlight))
        if compared != self._chart_compared:  # the series first: uPlot draws one column per series
            extra = () if compared is None else (viser.uplot.Series(label=compared, stroke=COMPARE_STROKE, width=2),)
            self.panel.plot.series = (*self._chart_series, *extra)
            self._chart_compared = compared
        self.panel.plot.data = data
        self._write_readouts()
        self._panel_written = now

    def _draw_arms(self, solved, state: int, highlight: int) -> None:
        """The planar frame: the trail up to `state`, the arms (and x̂0) at `state`, the joint space view."""
        view = solved.view
        num_samples, num_links = view.num_samples, view.num_links
        joint = self.sizes.joint
        placement = arm_placement(
            view.joints[state], height=ARM_LIFT * joint, raised=highlight, lift=HIGHLIGHT_LIFT * joint
        )
        colors = self._colors[state]  # (K, 3)
        tip_color = fade_colors(view.num_states, TIP_FAINT, TIP_DARK)[state]
        estimate = view.estimate_at(state) if self.panel.show_estimate.value else None
        if estimate is not None:
            estimate = estimate[estimate_rows(num_samples, highlight, self.trail_of)]
        if self.panel.show_trail.value:
            rows = trail_rows(num_samples, num_links, highlight, self.trail_of)
            points, segment_colors = trail_until(
                solved.trail_points[:, rows], self._trail_colors[:, rows], state,
                most_states=self.trail_states_limit(state),
            )  # fmt: skip
            self.trail.points = points
            self.trail.colors = segment_colors
            self.trail.visible = True
        else:
            self.trail.visible = False
        if estimate is not None:
            self.estimate_lines.points = polyline_segments(estimate, z=0.5 * REFINED_LIFT * self.sizes.joint)
            self.estimate_lines.visible = True
        else:
            self.estimate_lines.visible = False
        self.links.points = placement.link_segments
        link_colors = line_colors(np.repeat(colors, num_links, axis=0))[:, None]  # as dark as the joints
        self.links.colors = np.broadcast_to(link_colors, (num_samples * num_links, 2, 3))
        self.joints.batched_positions = placement.joint_positions
        joint_colors = colors
        if follows_one(self.trail_of):  # only the followed sample's joints show, in one colour: a constant array,
            joint_colors = np.broadcast_to(colors[highlight], colors.shape)  # which viser does not send again
        self.joints.batched_colors = np.repeat(joint_colors, num_links + 1, axis=0)
        self._write_joint_scales(num_samples, num_links, highlight)
        self.tips.batched_positions = placement.tip_positions
        self.tips.batched_colors = np.broadcast_to(tip_color, (num_samples, 3))
        for node in (self.links, self.joints, self.tips):
            node.visible = True
        final_shown = state == view.num_states - 1 and view.refined
        self.refined_lines.visible = final_shown
        self.refined_tips.visible = final_shown
        self.joint_space.draw(self.solver, solved, state, self._dot_colors[state], highlight)
        self.compare.draw(
            self.solver, solved, state, highlight, self.trail_of, show_trail=self.panel.show_trail.value,
            sizes=self.sizes,
        )  # fmt: skip
        self.cross.position = self._cross_position()  # the joint-space and compare views may have moved the camera
        # (viser skips a position it holds already)

    def _write_joint_scales(self, num_samples: int, num_links: int, highlight: int) -> None:
        """Following one sample, only its joints are drawn (the others are light lines): fewer spheres for the page
        to draw in every frame (docs/VIZ.md); written only when the followed sample or the setting changes."""
        key = (num_samples, num_links, highlight, follows_one(self.trail_of))
        if key == self._joint_scales_key:
            return
        per_sample = np.ones(num_samples, np.float32)
        if follows_one(self.trail_of):
            per_sample[:] = 0.0
            per_sample[highlight] = 1.0
        self.joints.batched_scales = np.repeat(per_sample, num_links + 1)
        self._joint_scales_key = key

    def animating(self, state: int) -> bool:
        """`state` is drawn as a frame of a playing animation, not its last: draw the light version of the scene.

        Software WebGL draws everything in every frame, and while an animation plays the page
        draws every frame: the full trail at K = 16 (5,184 segments) halves its frame rate, 16
        robot ghosts cost more than half of it (docs/VIZ.md). A pause, the last state and the
        slider draw it all.
        """
        animation = self.animation
        return animation is not None and state < animation.last

    def trail_states_limit(self, state: int) -> int | None:
        """How many states the trail may show at `state`: few while an animation plays, all (None) at its end.

        Following one sample, 12 of its states: its whole trail (81 states of N links, 324 segments at
        N = 4) cost the playing page about 10 ms a frame here (15.1 against 17.9 frames/s with 6 states,
        benchmarks/viz_frames_ab.py under load 5).
        """
        if not self.animating(state):
            return None
        return PLAYING_FOLLOWED_STATES if follows_one(self.trail_of) else PLAYING_TRAIL_STATES

    def _write_play_label(self) -> None:
        playing = self.animation is not None
        self.panel.play_button.label = "Pause" if playing else "Play"
        self.panel.play_button.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def _write_readouts(self) -> None:
        solved = self.solved
        if solved is None:
            failed = f"**Solve failed** {self.error}" if self.error else "Waiting for the first solve..."
            self.panel.readout_text.content = failed
            return
        text = self._solve_text(solved)
        if solved.state_violation is not None:
            text += "  \n" + met_text(solved.state_violation, self.state, colored=self.constraint_colors_shown)
        self.panel.readout_text.content = text

    def _solve_text(self, solved) -> str:
        """The readouts of the solve on screen at the state shown (markdown)."""
        request = solved.request
        return readouts.solve_text(
            solved.view, self.state, self.highlight_index(), sampler=request.sampler, seed=request.seed,
            refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds, error=self.error,
        )  # fmt: skip

    # -------------------------------------------------------------- nodes

    def _build_static_scene(self) -> None:
        """Grid, workspace boundary, base and the target's gizmo, sized to the current arm; the camera fitted."""
        scene = self.server.scene
        for handle in self._static_nodes:
            handle.remove()
        lengths = self.solver.lengths
        self.sizes = meshes.ArmSizes.for_lengths(lengths)
        inner, outer = self.solver.reach
        unit = float(np.mean(lengths))
        extent = 2 * float(np.ceil((outer + unit) / unit)) * unit
        # half-length cells: software WebGL pays for every pixel of line, and the quarter-length grid's
        # 82 lines cost the page as much as the 16 arms (docs/VIZ.md)
        grid, sections = grid_segments(extent / 2, unit / 2, unit, z=-0.02 * unit)
        grid_colors = np.where(sections[:, None, None], GRID_SECTION, GRID_CELL).astype(np.uint8)
        grid_colors = np.broadcast_to(grid_colors, grid.shape).copy()
        nodes = [scene.add_line_segments("/grid", grid, colors=grid_colors, thickness=1.0, thickness_units="screen")]
        for name, radius in (("outer", outer), ("inner", inner)):
            if radius > 0:
                nodes.append(
                    scene.add_line_segments(
                        f"/workspace/{name}",
                        circle_segments(radius, 96, z=-0.01 * unit),  # 96 look round; each costs the page
                        colors=(150, 150, 150),
                        thickness=LINE_PIXELS,
                        thickness_units="screen",
                    )  # fmt: skip
                )
        base = meshes.base_mesh(self.sizes.base)
        nodes.append(
            scene.add_mesh_simple(
                "/base", base.vertices, base.faces, color=(90, 90, 90), cast_shadow=False, receive_shadow=False
            )
        )
        self.gizmo = scene.add_transform_controls(
            "/target", scale=0.7 * unit, active_axes=(True, True, False), disable_rotations=True,
            translation_limits=((-outer, outer), (-outer, outer), (0.0, 0.0)), depth_test=False,
            position=(float(self.target[0]), float(self.target[1]), 0.0),
        )  # fmt: skip
        self.gizmo.on_update(self._gizmo_update)
        position, look_at = camera_fit(outer)
        self.server.initial_camera.position, self.server.initial_camera.look_at = position, look_at
        cross = meshes.cross_mesh(self.sizes.cross)
        self.cross = scene.add_mesh_simple(
            "/target_cross", cross.vertices, cross.faces, color=TARGET_RED, cast_shadow=False, receive_shadow=False,
            position=self._cross_position(),
        )  # fmt: skip
        self._static_nodes = [*nodes, self.gizmo, self.cross]
        for client in self.server.get_clients().values():  # open tabs too: the new arm may reach farther
            with client.atomic():
                client.camera.position, client.camera.look_at = position, look_at

    def _ensure_arm_nodes(self) -> None:
        """(Re)create the arm's nodes when K or N changed: a batched node keeps its instance count."""
        view = self.solved.view
        shape = (view.num_samples, view.num_links)
        if shape == self.nodes_shape:
            return
        self._remove_arm_nodes()
        scene = self.server.scene
        num_samples, num_links = shape
        links, joints = num_samples * num_links, num_samples * (num_links + 1)
        lines = dict(thickness_units="screen", visible=False)
        # the joints and tips as instanced spheres: viser's point clouds, tried first, cost the page
        # more per update than 80 small spheres (K = 1 animated at 7 frames/s with them, 14 without)
        spheres = dict(lod="off", cast_shadow=False, receive_shadow=False, visible=False)
        identity = lambda count: np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))  # noqa: E731
        origin = lambda count: np.zeros((count, 3))  # noqa: E731
        joint, tip = meshes.sphere_mesh(self.sizes.joint), meshes.sphere_mesh(self.sizes.tip)
        self.trail = scene.add_line_segments(
            "/arm/trail", np.zeros((1, 2, 3)), colors=(255, 255, 255), thickness=LINE_PIXELS, **lines
        )
        self.estimate_lines = scene.add_line_segments(
            "/arm/estimate", np.zeros((1, 2, 3)), colors=ESTIMATE, thickness=2 * LINE_PIXELS, **lines
        )
        self.refined_lines = scene.add_line_segments(
            "/arm/refined", np.zeros((1, 2, 3)), colors=REFINED, thickness=3 * LINE_PIXELS, **lines
        )
        self.refined_tips = scene.add_batched_meshes_simple(
            "/arm/refined_tips", tip.vertices, tip.faces, identity(num_samples), origin(num_samples),
            batched_colors=np.broadcast_to(np.array(REFINED, np.uint8), (num_samples, 3)), **spheres,
        )  # fmt: skip
        self.links = scene.add_line_segments(
            "/arm/links", np.zeros((links, 2, 3)), colors=np.zeros((links, 2, 3), np.uint8), thickness=ARM_PIXELS,
            **lines,
        )  # fmt: skip
        self.joints = scene.add_batched_meshes_simple(
            "/arm/joints", joint.vertices, joint.faces, identity(joints), origin(joints),
            batched_colors=np.zeros((joints, 3), np.uint8), **spheres,
        )  # fmt: skip
        self.tips = scene.add_batched_meshes_simple(
            "/arm/tips", tip.vertices, tip.faces, identity(num_samples), origin(num_samples),
            batched_colors=np.zeros((num_samples, 3), np.uint8), **spheres,
        )  # fmt: skip
        self.nodes_shape = shape
        self._joint_scales_key = None  # a new node: all its joints drawn

    def _write_refined(self) -> None:
        view = self.solved.view
        lift = REFINED_LIFT * self.sizes.joint  # above the other arms, under the highlighted one
        self.refined_lines.points = polyline_segments(view.final_joints, z=lift)
        self.refined_lines.colors = np.broadcast_to(
            np.array(REFINED, np.uint8), (view.num_samples * view.num_links, 2, 3)
        )
        tips = np.concatenate((view.final_joints[:, -1], np.full((view.num_samples, 1), lift)), axis=-1)
        self.refined_tips.batched_positions = tips

    def _remove_arm_nodes(self) -> None:
        for name in (
            "trail",
            "estimate_lines",
            "prior_lines",
            "links",
            "joints",
            "tips",
            "refined_lines",
            "refined_tips",
        ):
            handle = getattr(self, name, None)
            if handle is not None:
                handle.remove()
                setattr(self, name, None)
        self.nodes_shape = None
