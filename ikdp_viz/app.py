"""IKDP viewer: the reverse diffusion of a planar arm, live in the browser.

Drag the red cross. For each new target the app runs the reverse diffusion on a
worker thread (the newest target wins) and draws it as the paper's Fig. "vis":
every intermediate pose a thin line from faint (pure noise, t = T) to dark
(t = 0), the current pose solid; then it plays the denoising from t = T to 0.

Only handles and arrays live here: `scene.py` builds every array, `meshes.py`
the geometry, and the solving is `ikdp`'s public API.
"""

from __future__ import annotations

import collections
import contextlib
import random
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import viser

import ikdp
from ikdp_viz import meshes, readouts
from ikdp_viz.panel import SAMPLERS, build_panel, highlight_index, highlight_options, plot_scales
from ikdp_viz.player import Player
from ikdp_viz.scene import (
    HIGHLIGHT_LIFT,
    REFINED,
    REFINED_LIFT,
    TARGET_LIFT,
    TIP_DARK,
    TIP_FAINT,
    SolveView,
    arm_placement,
    build_view,
    circle_segments,
    clamp_to_workspace,
    error_curves,
    fade_colors,
    nearest_state,
    polyline_segments,
    sample_colors,
    trail_colors,
    trail_points,
    trail_until,
)
from ikdp_viz.solve_worker import Cancelled, LatestWorker

TARGET_RED = (220, 25, 25)
LINE_PIXELS = 1.5  # trail line thickness, screen pixels
STALE_GRACE = 0.1  # seconds without a new solve on screen after which no running solve is cancelled


def camera_fit(reach: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera straight above the workspace of radius `reach`, all of it in view.

    +x to the right and +y up (a hair off the pole so "up" is defined), the workspace a little
    left of centre, clear of the panel on the right.
    """
    distance, shift = 1.55 * reach, 0.25 * reach
    return (shift, -1e-3 * distance, distance), (shift, 0.0, 0.0)


def list_checkpoints(folder: Path, extra: Path | None = None) -> dict[str, Path]:
    """Dropdown label -> path for every `.pt` in `folder`, plus `extra` (labelled by its path) if elsewhere."""
    found = {path.name: path for path in sorted(Path(folder).glob("*.pt"))} if Path(folder).is_dir() else {}
    if extra is not None and Path(extra).resolve() not in {path.resolve() for path in found.values()}:
        found[str(extra)] = Path(extra)
    return found


@dataclass(frozen=True)
class SolveRequest:
    """One solve, with the panel's settings as they were when it was asked for."""

    solver: ikdp.Solver
    target: np.ndarray  # (2,) inside the workspace
    num_samples: int
    sampler: str  # "ddpm" or "ddim"
    steps: int | None  # DDIM steps; None for DDPM
    refine_steps: int  # 0: no damped-least-squares polish
    seed: int
    arrival: float  # time.perf_counter() when the move (or settings change) arrived
    animate: bool  # play the denoising once drawn; False while the gizmo is being dragged


@dataclass(frozen=True)
class Solved:
    request: SolveRequest
    view: SolveView
    trail_points: np.ndarray  # (S+1, K*N, 2, 3) every state's polylines, see scene.trail_points
    solve_seconds: float  # solver.solve alone


@contextlib.contextmanager
def stop_when(cancel: threading.Event, model: torch.nn.Module):
    """Inside the block, the next call of one of `model`'s modules raises Cancelled once `cancel` is set.

    `solver.solve` takes no cancellation hook, but every denoising step calls the
    model's modules: a forward pre-hook on each stops a stale solve within one
    step. Only this thread's calls are stopped.
    """
    thread = threading.get_ident()

    def check(module, inputs):
        if cancel.is_set() and threading.get_ident() == thread:
            raise Cancelled

    handles = [module.register_forward_pre_hook(check) for module in model.modules()]
    try:
        yield
    finally:
        for handle in handles:
            handle.remove()


def solve(request: SolveRequest, cancel: threading.Event | None = None) -> Solved:
    """Run the reverse diffusion for one request and build its drawable arrays (worker thread).

    Raises Cancelled, part-way, once `cancel` is set: a newer request has arrived.
    """
    cancel = cancel if cancel is not None else threading.Event()
    if cancel.is_set():
        raise Cancelled
    generator = torch.Generator(device=request.solver.device).manual_seed(request.seed)
    started = time.perf_counter()
    with stop_when(cancel, request.solver.model):
        result = request.solver.solve(
            request.target,
            num_samples=request.num_samples,
            sampler=request.sampler,
            steps=request.steps,
            refine_steps=request.refine_steps,
            generator=generator,
            return_trajectory=True,
        )
    solve_seconds = time.perf_counter() - started
    view = build_view(result, request.solver.lengths, request.target)
    return Solved(request, view, trail_points(view.joints), solve_seconds)


class VizApp:
    """The scene and panel of one viser server; every browser tab sees the same."""

    def __init__(
        self,
        server: viser.ViserServer,
        solver: ikdp.Solver,
        *,
        checkpoints: dict[str, Path] | None = None,
        checkpoint_folder: Path | None = None,
        target: tuple[float, float] | None = None,
        solve_now: bool = True,
        animation_seconds: float = 1.0,
    ):
        self.server = server
        self.solver = solver
        self.checkpoint_folder = checkpoint_folder
        given = Path(solver.metadata.get("path", "model.pt"))
        self.checkpoints = dict(checkpoints or {given.name: given})  # dropdown label -> path
        self.worker = LatestWorker(stale_grace=STALE_GRACE)
        self.player = Player(self._draw_from_player)
        self._lock = threading.RLock()  # guards what is drawn; held while a frame is written
        self._syncing = False  # True while the app itself moves the timestep slider
        self.solved: Solved | None = None  # the solve on screen
        self._animate_target: np.ndarray | None = None  # a drag ended here: animate its solve once drawn
        self._replay_pending = False  # a replay thread is about to start the animation
        self.state = 0  # index of the state on screen
        self.target, self.target_clamped = self._initial_target(target), False
        self.error: str | None = None  # the last solve's failure, shown in the panel
        # (arrival, drawn, newest) of each solve put on screen: perf_counter times, and whether its target was
        # still the newest (False: a newer one arrived too late in its solve to cancel it); for benchmarks
        self.latencies: collections.deque[tuple[float, float, bool]] = collections.deque(maxlen=100_000)
        self._arm_shape: tuple[int, int] | None = None  # (K, N) of the arm nodes
        self._colors: np.ndarray | None = None  # (S+1, K, 3) per-sample colour of each state
        self._trail_colors: np.ndarray | None = None  # (S+1, K*N, 2, 3)
        self.panel = build_panel(
            server.gui, num_timesteps=solver.timesteps, animation_seconds=animation_seconds,
            checkpoint_labels=tuple(self.checkpoints), checkpoint_label=self._current_checkpoint_label(),
            model_text=self._model_description(),
        )  # fmt: skip
        self._wire_panel()
        # No environment map: its reflections wash dark materials out to grey; the default lights stay.
        server.scene.configure_environment_map(hdri=None)
        self._build_scene()
        server.on_client_connect(lambda client: self.refresh_checkpoints())
        if solve_now:
            self.move_target(self.target)

    # ---------------------------------------------------------------- requests

    def move_target(
        self, point, *, arrival: float | None = None, from_gizmo: bool = False, dragging: bool = False
    ) -> int | None:
        """Clamp `point` to the workspace, move the cross there and ask for its solve; returns the ticket.

        While `dragging`, each solve is drawn at once at its final pose (its trail from t = T
        to 0 included), so the arm follows the cross; the denoising plays when the drag ends.
        """
        arrival = time.perf_counter() if arrival is None else arrival
        inner, outer = self.solver.reach
        target, clamped = clamp_to_workspace(point, inner, outer)
        unchanged = np.array_equal(target, self.target)
        # A drag past the boundary ends on the boundary point the app put the gizmo at: still the clamped request.
        clamped = clamped or (unchanged and from_gizmo and self.target_clamped)
        self.target, self.target_clamped = target, clamped
        released = from_gizmo and not dragging
        if clamped or not from_gizmo:
            self._place_gizmo(target, force=released)
        self._write_target_text()
        if unchanged and from_gizmo:
            if not dragging:
                self._animate_after_drag()
            return None
        return self.request_solve(arrival, animate=not dragging)

    def _place_gizmo(self, target: np.ndarray, *, force: bool = False) -> None:
        """Move the cross to `target`; `force`: send it even if the server's copy is there already.

        viser skips a position equal to its copy, but while a drag goes past the boundary the page's
        gizmo follows the pointer beyond the clamped point the server holds: on release it must be sent again.
        """
        position = np.array([float(target[0]), float(target[1]), 0.0])
        if force:
            self.gizmo.position = position + (1e-3, 0.0, 0.0)  # differs from the server's copy
        self.gizmo.position = position

    def request_solve(self, arrival: float | None = None, *, animate: bool = True) -> int:
        """Solve the current target with the panel's settings, replacing any solve not yet started."""
        if self.panel.new_seed.value:
            self.panel.seed.value = random.randrange(2**31)  # shown, so a good draw can be kept
        sampler = self.panel.sampler.value.lower()
        assert sampler.upper() in SAMPLERS, f"sampler: expected one of {SAMPLERS}, got {sampler!r}"
        request = SolveRequest(
            solver=self.solver,
            target=self.target.copy(),
            num_samples=int(self.panel.samples.value),
            sampler=sampler,
            steps=int(self.panel.ddim_steps.value) if sampler == "ddim" else None,
            refine_steps=int(self.panel.refine_steps.value) if self.panel.refine.value else 0,
            seed=int(self.panel.seed.value),
            arrival=time.perf_counter() if arrival is None else arrival,
            animate=animate,
        )
        # The animation on screen is of a stale target now: stopping it leaves the CPU to the new solve.
        self.player.interrupt()
        return self.worker.submit(lambda cancel: solve(request, cancel), self._show_solved, self._show_error)

    async def on_gizmo_update(self, event: viser.TransformControlsEvent) -> None:
        """Gizmo callback. Async so viser runs it on its event loop in arrival order; it only queues work."""
        if event.phase == "start":
            return
        x, y = event.target.position[:2]
        self.move_target((x, y), arrival=time.perf_counter(), from_gizmo=True, dragging=event.phase == "update")

    def _animate_after_drag(self) -> None:
        """The drag ended where its last update put the target: animate that solve, now or once it is drawn."""
        with self._lock:
            self._animate_target = self.target.copy()  # _show_solved animates a solve for it
            drawn = self.solved is not None and np.array_equal(self.solved.request.target, self.target)
        if drawn and self.worker.idle:
            self._replay_pending = True
            threading.Thread(target=self.replay, name="ikdp-viz-replay", daemon=True).start()  # off the event loop

    def replay(self) -> None:
        """Play the denoising of the solve on screen from t = T (if "play on move" is on)."""
        try:
            with self._lock:
                self._animate_target = None
                if self.solved is None or not self.panel.play_on_move.value or self.panel.duration.value <= 0:
                    return
            self.player.pause()
            self.show_state(0)
            last = self.solved.view.num_states - 1
            self.player.play(0, last, self.panel.duration.value / max(last, 1), first_shown=True)
            self._write_play_label()
        finally:
            self._replay_pending = False

    def wait_until_still(self, timeout: float = 30.0) -> bool:
        """Block until no solve is waiting or running and the animation has stopped (for tests and scripts)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.worker.wait_idle(max(0.0, deadline - time.monotonic())) and not self.player.playing:
                with self._lock:  # a frame in progress finishes first
                    if self.worker.idle and not self.player.playing and not self._replay_pending:
                        return True
            time.sleep(0.005)
        return False

    def close(self) -> None:
        self.player.close()
        self.worker.close()

    # ---------------------------------------------------------------- drawing

    def _show_solved(self, ticket: int, solved: Solved) -> None:
        """Worker thread: put a finished solve on screen and start its animation."""
        self.player.pause()  # returns between frames: no frame of the old solve follows
        with self._lock:
            self.solved, self.error = solved, None
            self._recolor()
            self._ensure_arm_nodes()
            self.panel.plot.scales = plot_scales(self.solver.timesteps, *readouts.error_range(solved.view.tip_error))
            self._write_refined()
            last = solved.view.num_states - 1
            released = self._animate_target is not None and np.array_equal(solved.request.target, self._animate_target)
            if released:
                self._animate_target = None
            wanted = solved.request.animate or released
            animate = wanted and self.panel.play_on_move.value and self.panel.duration.value > 0 and last > 0
            self._draw_state(0 if animate else last)
            self.latencies.append((solved.request.arrival, time.perf_counter(), self.worker.is_newest(ticket)))
        if animate:
            self.player.play(0, last, self.panel.duration.value / last, first_shown=True)
            self._write_play_label()

    def _show_error(self, ticket: int, error: BaseException) -> None:
        self.error = f"{type(error).__name__}: {error}"
        self._write_readouts()

    def _draw_from_player(self, state: int) -> None:
        with self._lock:
            self._draw_state(state)

    def show_state(self, state: int) -> None:
        """Put state `state` (0 = pure noise .. S = final) on screen."""
        with self._lock:
            self._draw_state(state)

    def _draw_state(self, state: int) -> None:
        """Write one frame: the trail up to `state`, the arms at `state`, the readouts. Caller holds the lock."""
        solved = self.solved
        if solved is None:
            return
        view = solved.view
        last = view.num_states - 1
        state = int(np.clip(state, 0, last))
        self.state = state
        highlight = self.highlight_index()
        num_samples, num_links = view.num_samples, view.num_links
        lift = HIGHLIGHT_LIFT * self.sizes.joint
        placement = arm_placement(view.joints[state], view.lengths, raised=highlight, lift=lift)
        colors = self._colors[state]  # (K, 3)
        tip_color = fade_colors(view.num_states, TIP_FAINT, TIP_DARK)[state]
        with self.server.atomic():
            if self.panel.show_trail.value:
                points, segment_colors = trail_until(solved.trail_points, self._trail_colors, state)
                self.trail.points = points
                self.trail.colors = segment_colors
                self.trail.visible = True
            else:
                self.trail.visible = False
            self.links.batched_positions = placement.link_positions
            self.links.batched_wxyzs = placement.link_wxyzs
            self.links.batched_scales = placement.link_scales
            self.links.batched_colors = np.repeat(colors, num_links, axis=0)
            self.joints.batched_positions = placement.joint_positions
            self.joints.batched_colors = np.repeat(colors, num_links + 1, axis=0)
            self.tips.batched_positions = placement.tip_positions
            self.tips.batched_colors = np.broadcast_to(tip_color, (num_samples, 3))
            for node in (self.links, self.joints, self.tips):
                node.visible = True
            final_shown = state == last and view.refined
            self.refined_lines.visible = final_shown
            self.refined_tips.visible = final_shown
            self._syncing = True
            try:
                self.panel.timestep.value = int(view.labels[state])
            finally:
                self._syncing = False
            self.panel.plot.data = error_curves(view, highlight, state)
            self._write_readouts()
            self._write_play_label()

    def _recolor(self) -> None:
        view = self.solved.view
        self._colors = sample_colors(view.num_states, view.num_samples, self.highlight_index())
        self._trail_colors = trail_colors(self._colors, view.num_links)

    def highlight_index(self) -> int:
        view = self.solved.view if self.solved is not None else None
        if view is None:
            return 0
        return highlight_index(self.panel.highlight.value, view.best_sample(), view.num_samples)

    # ---------------------------------------------------------------- scene

    def _initial_target(self, target) -> np.ndarray:
        inner, outer = self.solver.reach
        point = np.array(target if target is not None else (0.55 * outer, 0.3 * outer), dtype=np.float64)
        return clamp_to_workspace(point, inner, outer)[0]

    def _build_scene(self) -> None:
        """Grid, workspace boundary, base and the target's gizmo, sized to the current arm."""
        scene = self.server.scene
        for handle in getattr(self, "_static_nodes", ()):
            handle.remove()
        lengths = self.solver.lengths
        self.sizes = meshes.ArmSizes.for_lengths(lengths)
        inner, outer = self.solver.reach
        unit = float(np.mean(lengths))
        extent = 2 * float(np.ceil((outer + unit) / unit)) * unit
        nodes = [
            scene.add_grid(
                "/grid",
                width=extent,
                height=extent,
                plane="xy",
                cell_size=unit / 4,
                section_size=unit,
                cell_color=(236, 236, 236),
                section_color=(212, 212, 212),
                position=(0.0, 0.0, -0.02 * unit),
                shadow_opacity=0.0,
            )
        ]
        for name, radius in (("outer", outer), ("inner", inner)):
            if radius > 0:
                nodes.append(
                    scene.add_line_segments(
                        f"/workspace/{name}",
                        circle_segments(radius, z=-0.01 * unit),
                        colors=(150, 150, 150),
                        thickness=LINE_PIXELS,
                        thickness_units="screen",
                    )
                )
        base = meshes.base_mesh(self.sizes.base)
        nodes.append(
            scene.add_mesh_simple(
                "/base", base.vertices, base.faces, color=(90, 90, 90), cast_shadow=False, receive_shadow=False
            )
        )
        self.gizmo = scene.add_transform_controls(
            "/target",
            scale=0.7 * unit,
            active_axes=(True, True, False),
            disable_rotations=True,
            translation_limits=((-outer, outer), (-outer, outer), (0.0, 0.0)),
            depth_test=False,
            position=(float(self.target[0]), float(self.target[1]), 0.0),
        )
        self.gizmo.on_update(self.on_gizmo_update)
        cross = meshes.cross_mesh(self.sizes.cross)
        self.cross = scene.add_mesh_simple(
            "/target/cross", cross.vertices, cross.faces, color=TARGET_RED, cast_shadow=False, receive_shadow=False,
            position=(0.0, 0.0, TARGET_LIFT * self.sizes.joint),
        )  # fmt: skip
        self._static_nodes = [*nodes, self.gizmo]
        position, look_at = camera_fit(outer)
        self.server.initial_camera.position, self.server.initial_camera.look_at = position, look_at
        for client in self.server.get_clients().values():  # open tabs too: the new arm may reach farther
            with client.atomic():
                client.camera.position, client.camera.look_at = position, look_at

    def _ensure_arm_nodes(self) -> None:
        """(Re)create the arm's nodes when K or N changed: a batched node keeps its instance count."""
        view = self.solved.view
        shape = (view.num_samples, view.num_links)
        if shape == self._arm_shape:
            return
        scene = self.server.scene
        num_samples, num_links = shape
        links, joints, tips = (instances * num_samples for instances in (num_links, num_links + 1, 1))
        identity = lambda count: np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))  # noqa: E731
        origin = lambda count: np.zeros((count, 3))  # noqa: E731
        options = dict(lod="off", cast_shadow=False, receive_shadow=False, visible=False)
        link, joint, tip = (
            meshes.link_mesh(self.sizes.link),
            meshes.sphere_mesh(self.sizes.joint),
            meshes.sphere_mesh(self.sizes.tip, 1),
        )
        self.trail = scene.add_line_segments(
            "/arm/trail",
            np.zeros((1, 2, 3)),
            colors=(255, 255, 255),
            thickness=LINE_PIXELS,
            thickness_units="screen",
            visible=False,
        )
        self.links = scene.add_batched_meshes_simple(
            "/arm/links",
            link.vertices,
            link.faces,
            identity(links),
            origin(links),
            batched_scales=np.ones((links, 3)),
            batched_colors=np.zeros((links, 3), np.uint8),
            **options,
        )
        self.joints = scene.add_batched_meshes_simple(
            "/arm/joints",
            joint.vertices,
            joint.faces,
            identity(joints),
            origin(joints),
            batched_colors=np.zeros((joints, 3), np.uint8),
            **options,
        )
        self.tips = scene.add_batched_meshes_simple(
            "/arm/tips",
            tip.vertices,
            tip.faces,
            identity(tips),
            origin(tips),
            batched_colors=np.zeros((tips, 3), np.uint8),
            **options,
        )
        self.refined_lines = scene.add_line_segments(
            "/arm/refined",
            np.zeros((1, 2, 3)),
            colors=REFINED,
            thickness=3 * LINE_PIXELS,
            thickness_units="screen",
            visible=False,
        )
        self.refined_tips = scene.add_batched_meshes_simple(
            "/arm/refined_tips",
            tip.vertices,
            tip.faces,
            identity(num_samples),
            origin(num_samples),
            batched_colors=np.broadcast_to(np.array(REFINED, np.uint8), (num_samples, 3)),
            **options,
        )
        self._arm_shape = shape

    def _write_refined(self) -> None:
        view = self.solved.view
        lift = REFINED_LIFT * self.sizes.joint  # above the other arms, under the highlighted one
        self.refined_lines.points = polyline_segments(view.final_joints, z=lift)
        self.refined_lines.colors = np.broadcast_to(
            np.array(REFINED, np.uint8), (view.num_samples * view.num_links, 2, 3)
        )
        tips = np.concatenate((view.final_joints[:, -1], np.full((view.num_samples, 1), lift)), axis=-1)
        self.refined_tips.batched_positions = tips

    # ---------------------------------------------------------------- panel

    def _wire_panel(self) -> None:
        panel = self.panel
        panel.timestep.on_update(self._on_timestep)
        panel.previous_button.on_click(lambda _: self._step_by(-1))
        panel.next_button.on_click(lambda _: self._step_by(+1))
        panel.play_button.on_click(lambda _: self.toggle_play())
        panel.show_trail.on_update(lambda _: self.show_state(self.state))
        panel.highlight.on_update(lambda _: self._on_highlight())
        panel.samples.on_update(lambda _: self._on_samples())
        panel.sampler.on_update(lambda _: self._on_sampler())
        for handle in (panel.ddim_steps, panel.refine_steps):
            handle.on_update(lambda _: self.request_solve())
        panel.seed.on_update(lambda event: None if event.client is None else self.request_solve())
        panel.refine.on_update(lambda _: self._on_refine())
        panel.checkpoint.on_update(lambda _: self._on_checkpoint())

    def _on_timestep(self, event: viser.GuiEvent) -> None:
        if event.client is None and self._syncing:
            return  # the app moved the slider while drawing
        if event.client is not None:
            self.player.pause()
        with self._lock:
            if self.solved is not None:
                self._draw_state(nearest_state(self.solved.view.labels, self.panel.timestep.value))

    def _step_by(self, delta: int) -> None:
        self.player.pause()
        with self._lock:
            self._draw_state(self.state + delta)

    def toggle_play(self) -> None:
        """Pause a running animation, or play from the current step (from t = T when at the end)."""
        if self.player.playing:
            self.player.pause()
        elif self.solved is not None:
            last = self.solved.view.num_states - 1
            first = 0 if self.state >= last else self.state
            if first == 0:
                self.show_state(0)
            self.player.play(first, last, self.panel.duration.value / max(last, 1), first_shown=True)
        self._write_play_label()

    def _on_highlight(self) -> None:
        with self._lock:
            if self.solved is not None:
                self._recolor()
                self._draw_state(self.state)

    def _on_samples(self) -> None:
        options = highlight_options(int(self.panel.samples.value))
        current = self.panel.highlight.value
        self.panel.highlight.options = options
        if current not in options:
            self.panel.highlight.value = "best"
        self.request_solve()

    def _on_sampler(self) -> None:
        self.panel.ddim_steps.disabled = self.panel.sampler.value != "DDIM"
        self.request_solve()

    def _on_refine(self) -> None:
        self.panel.refine_steps.disabled = not self.panel.refine.value
        self.request_solve()

    def _write_play_label(self) -> None:
        at_end = self.solved is None or self.state >= self.solved.view.num_states - 1
        playing = self.player.playing and not at_end  # the last frame is drawn while the player still runs
        self.panel.play_button.label = "Pause" if playing else "Play"
        self.panel.play_button.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def _write_target_text(self) -> None:
        self.panel.target_text.content = readouts.target_text(self.target, self.target_clamped, self.solver.reach)

    def _write_readouts(self) -> None:
        solved = self.solved
        if solved is None:
            failed = f"**Solve failed** {self.error}" if self.error else "Waiting for the first solve..."
            self.panel.readout_text.content = failed
            return
        request = solved.request
        self.panel.readout_text.content = readouts.solve_text(
            solved.view, self.state, self.highlight_index(), sampler=request.sampler, steps=request.steps,
            seed=request.seed, refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds, error=self.error,
        )  # fmt: skip

    def _model_description(self) -> str:
        solver = self.solver
        return readouts.model_text(solver.num_links, solver.lengths, solver.timesteps, solver.metadata)

    # ---------------------------------------------------------------- checkpoints

    def _current_checkpoint_label(self) -> str:
        path = Path(self.solver.metadata.get("path", ""))
        for label, candidate in self.checkpoints.items():
            if candidate == path or (candidate.exists() and path.exists() and candidate.resolve() == path.resolve()):
                return label
        label = str(path)
        self.checkpoints[label] = path
        return label

    def refresh_checkpoints(self) -> None:
        """Re-list the checkpoint folder (new models appear as they are trained)."""
        if self.checkpoint_folder is None:
            return
        current = self._current_checkpoint_label()
        found = list_checkpoints(self.checkpoint_folder)
        found.setdefault(current, self.checkpoints[current])
        self.checkpoints = found
        self.panel.checkpoint.options = tuple(found)

    def _on_checkpoint(self) -> None:
        label = self.panel.checkpoint.value
        current = self._current_checkpoint_label()
        if label == current:
            return
        self.load_checkpoint(self.checkpoints[label])

    def load_checkpoint(self, path: Path) -> bool:
        """Switch to another model: reload, redraw the arm with its number of links, solve again."""
        try:
            solver = ikdp.load(path, device=self.solver.device)
        except (ikdp.CheckpointError, OSError, RuntimeError) as error:
            self.panel.model_text.content = f"**Could not load** {error}  \n\n" + self._model_description()
            self.panel.checkpoint.value = self._current_checkpoint_label()
            return False
        self.player.pause()
        with self._lock:
            self.solver = solver
            self.solved = None
            self._remove_arm_nodes()
            self.target = self._initial_target(self.target)
            self._build_scene()
            num_timesteps = solver.timesteps
            self.panel.timestep.max = num_timesteps
            self.panel.ddim_steps.max = num_timesteps
            self.panel.ddim_steps.value = min(self.panel.ddim_steps.value, num_timesteps)
            self.panel.model_text.content = self._model_description()
            self.panel.checkpoint.value = self._current_checkpoint_label()
        self.move_target(self.target)
        return True

    def _remove_arm_nodes(self) -> None:
        for name in ("trail", "links", "joints", "tips", "refined_lines", "refined_tips"):
            handle = getattr(self, name, None)
            if handle is not None:
                handle.remove()
                setattr(self, name, None)
        self._arm_shape = None
