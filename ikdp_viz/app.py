"""IKDP viewer: the reverse diffusion of a planar arm or a robot from a URDF, live in the browser.

Drag the red cross (a robot: the 6-DoF gizmo at its hand). For each new target
the app runs the reverse diffusion on a worker thread (the newest target wins)
and draws it as the paper's Fig. "vis":
every intermediate pose a thin line from faint (pure noise, t = T) to dark
(t = 0), the current pose solid; then it plays the denoising from t = T to 0.

This file wires four parts: the session (model, target: `solving.py`), the solve
worker (`solve_worker.py`, `solving.py`: it only hands results back), the drawing
loop (`scene_writer.py`, the one thread that writes the scene, cameras and panel
outputs, from one `Frame` per picture: `frame.py`) and the panel (`panel.py`).
Callbacks only set fields of one intent (intent.py: the newest target, a solve wanted, a state, a control that
changed); the drawing loop takes it, submits the solve (the newest wins), adopts finished solves and draws each
picture. A control whose handler writes other controls (K and the highlight's options, the sampler and its steps)
is named in the intent, and its handler runs on the loop, the one writer of every panel output.
What differs per kind of arm is an arm kind (`planar_kind.py`, `chain_kind.py`) and
an arm view (`planar_view.py`, `robot_view.py`), picked in `arm_kinds.py` alone.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path

import numpy as np
import viser

import ikdp
from ikdp.samplers import sampler_names
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.camera import camera_fit, fit_fields_of_view
from ikdp_viz.constraint_controls import ConstraintControls
from ikdp_viz.downloads import Downloads
from ikdp_viz.intent import StateAsked, TargetMove
from ikdp_viz.joint_space import solve_fields
from ikdp_viz.models import ModelChoices, checkpoint_arm_kind, list_checkpoints, switch_model
from ikdp_viz.panel import DEFAULT_DURATION, build_panel
from ikdp_viz.sampling_controls import SamplingControls
from ikdp_viz.scene_writer import SceneWriter
from ikdp_viz.solve_worker import LatestWorker
from ikdp_viz.solving import Session, Solved, solve
from ikdp_viz.student import model_and_student
from ikdp_viz.teaching import RerunReadout, forward_solved, is_forward
from ikdp_viz.tour import TourRunner

PAGE_DRAW_TIMEOUT = 20.0  # seconds a new tab gets to draw its first frame before the denoising plays anyway
STALE_GRACE = 0.1  # seconds without a new solve on screen after which no running solve is cancelled

__all__ = ["VizApp", "camera_fit", "checkpoint_arm_kind", "list_checkpoints"]


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
        animation_seconds: float = DEFAULT_DURATION,
        wait_for_tab: bool = False,
        previews: bool = True,
        student: ikdp.Solver | None = None,
        tour: bool = False,
    ):
        """`student`: the model's few-step student (student.py); None: looked for in `checkpoint_folder`.
        `tour`: open on the guided first visit (tour.py; a planar arm's), as the command line does; scripts and
        tests start without it."""
        self.server = server
        if student is None:  # a student's file opens with its teacher beside it when the folder holds that
            opened = solver
            solver, student = model_and_student(solver, checkpoint_folder)
            self.asked_for_student = student is opened
        else:
            self.asked_for_student = False
        self.session = Session(solver, target, student)
        given = Path(solver.metadata.get("path", "model.pt"))
        # dropdown label -> path, only the models of the arm this viewer draws (the Panda offered in a
        # planar session could not open)
        self.models = ModelChoices(dict(checkpoints or {given.name: given}), solver, checkpoint_folder)
        self.worker = LatestWorker(stale_grace=STALE_GRACE)
        self.previews = previews  # a robot's drag shows a fast solve first (benchmarks turn it off to compare)
        current = self._current_checkpoint_label()  # first: it lists the open model when the folder lacks it
        self.panel = build_panel(
            server.gui, num_timesteps=solver.timesteps, animation_seconds=animation_seconds,
            sampler_names=sampler_names(), checkpoint_labels=tuple(self.checkpoints),
            checkpoint_label=current, model_text=arm_kind(solver).model_text(solver),
            alphas_cumprod=solver.model.schedule.alphas_cumprod,
        )  # fmt: skip
        self.writer = SceneWriter(server, self.panel, solver, self.session.target, self.on_gizmo_update)
        self.writer.wait_for_tab = wait_for_tab  # the page opens on pure noise and plays once a tab is there
        self.writer.submit_solve = self._submit
        self.writer.stage.joint_space.ask_fields = self._submit_fields
        self._solve_ticket = self._solve_answered = 0  # the newest solve submitted, and the newest delivered or failed
        self._fields_job: tuple | None = None  # (solved, joints, highlight, count, ticket) of the newest field job
        self.writer.on_changed = self._on_changed
        self.sampling = SamplingControls(self.panel, lambda: self.request_solve(), self.session)
        self.constraint_controls = ConstraintControls(
            server, solver, self.writer.run, self.request_solve, self.writer.on_loop_thread
        )
        self.reruns = RerunReadout()  # again from the same x_T: how far each run's poses moved from the one before
        self.writer.after_solve = self._after_solve
        self.writer.draw_overlay = lambda frame: self.constraint_controls.draw_overlay(frame)
        self.downloads = Downloads(self.writer, self.panel)
        self._wire_panel()
        self.sampling.offer_student()
        self.sampling.show_steps()
        server.on_client_connect(self._on_connect)
        self.writer.ask(target=TargetMove(self.session.target, False, move_gizmo=False, force=False))
        self.tour = TourRunner(self)
        if solve_now:
            self.move_target(self.session.target)
        if tour:
            self.tour.start()

    # ---------------------------------------------------------------- what tests and scripts read

    solver = property(lambda self: self.session.solver)  # the model the newest requests use
    target = property(lambda self: self.session.target)  # the newest target, inside the workspace
    solved = property(lambda self: self.writer.solved)  # the solve on screen
    state = property(lambda self: self.writer.state)  # index of the state on screen, 0 (pure noise) .. S (final)
    playing = property(lambda self: self.writer.playing)

    latencies = property(lambda self: self.writer.latencies)  # (arrival, drawn, newest) per solve drawn

    def highlight_index(self) -> int:
        return self.writer.highlight_index()

    def __getattr__(self, name: str):
        # The scene's handles (gizmo, cross, trail, links, joints, tips, refined_lines, ...) are the arm view's.
        if name in {"gizmo", "cross", "trail", "links", "joints", "tips", "refined_lines", "refined_tips",
                    "estimate_lines"}:  # fmt: skip
            return getattr(self.writer.view, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _on_connect(self, client) -> None:
        """A tab connected (viser's pool thread): play the solve no one saw once the page draws."""
        self.refresh_checkpoints()
        # viser calls this on the page's first camera message, before its first frame: on a CPU the page then drew
        # its first frame at t = 54 of 80. A tiny render comes back once the page has drawn the scene (its shaders
        # built), so the denoising plays from a frame the page can draw.
        try:
            client.get_render(height=8, width=8, timeout=PAGE_DRAW_TIMEOUT)
        except (TimeoutError, RuntimeError):  # a page that never draws (or closed): play anyway, as before
            pass
        self.writer.ask(tabs=[client])  # the loop plays a solve no one saw, and hides viser's WebGL toast
        shape = [None]  # the canvas size last seen: a resized window gets its field of view on the drawing loop

        def resized(camera) -> None:
            size = (camera.image_width, camera.image_height)
            if size != shape[0]:
                shape[0] = size
                self.writer.run(lambda writer: fit_fields_of_view(writer.server), wait=False)

        client.camera.on_update(resized)

    # ---------------------------------------------------------------- requests

    def move_target(
        self, point, *, arrival: float | None = None, from_gizmo: bool = False, dragging: bool = False
    ) -> None:
        """Clamp `point` to the workspace, move the cross there and ask for its solve.

        While `dragging`, each solve is drawn at once at its final pose (its trail from t = T
        to 0 included), so the arm follows the cross; the denoising plays when the drag ends.
        """
        arrival = time.perf_counter() if arrival is None else arrival
        with self.session.lock:  # the cross and the solve are posted in the order of the targets
            target, clamped, changed = self.session.move(point, from_gizmo=from_gizmo)
            released = from_gizmo and not dragging
            move_gizmo = clamped or not from_gizmo
            move = TargetMove(target, clamped, move_gizmo=move_gizmo, force=released and move_gizmo)
            if not changed and from_gizmo:
                self.writer.ask(target=move, **({"replay": target} if released else {}))
                return
            self.writer.ask(target=move, solve=(arrival, not dragging))

    def request_solve(self, arrival: float | None = None, *, animate: bool = True) -> None:
        """Ask for a solve of the current target with the panel's settings (the loop submits it; the newest wins)."""
        self.writer.ask(solve=(time.perf_counter() if arrival is None else arrival, animate))

    def _submit(self, arrival: float, animate: bool) -> int:
        """Drawing loop: the solve of the newest target with the panel's settings now, replacing any not started."""
        with self.session.lock:
            constraints = self.constraint_controls.constraints()
            request = self.session.request(self.panel, arrival=arrival, animate=animate, constraints=constraints,
                                           chosen_steps=self.sampling.chosen_steps,
                                           follow_from=self.constraint_controls.follow_from())  # fmt: skip
        if self.panel.new_seed.value:  # the new seed shown, so a good draw can be kept
            self.panel.seed.value = request.seed
        return self._submit_request(request)

    def _field_ask(self):
        """The joint-space fields a solve asked now should bring with it (None: the view is off)."""
        return self.writer.stage.joint_space.field_ask(self.solver, str(self.panel.highlight.value))

    def _submit_request(self, request) -> int:
        request = dataclasses.replace(request, joint_space=self._field_ask())
        self._solve_ticket = self.worker.submit(self._job(request), self._solved, self._failed)
        return self._solve_ticket

    def _submit_fields(self, solved, joints: tuple[int, int], highlight: int, count: int) -> None:
        """Drawing loop, which lacks the joint-space fields of the solve on screen for this pair, highlight and grid:
        compute them on the solve worker (the newest job wins) and hand them back through the intent. Not while
        a newer solve is under way: it brings its own, and a job here would replace it unstarted."""
        wanted = (tuple(joints), highlight, count)
        if self._solve_answered < self._solve_ticket:
            return
        asked = self._fields_job  # a solve is compared by identity: `==` on its arrays has no single truth
        if asked is not None and asked[0] is solved and asked[1:4] == wanted and self.worker.is_newest(asked[4]):
            return  # asked already, and no job since has replaced it
        model = solved.request.model

        def job(cancel):
            return solve_fields(model, solved.view, joints, highlight, count, cancel)

        # no on_error: a failed field job is printed, the square stays without arrows (no solve failed)
        ticket = self.worker.submit(job, lambda _, fields: self.writer.ask(fields=(solved, fields)))
        self._fields_job = (solved, *wanted, ticket)

    def again(self) -> int | None:
        """Solve the solve on screen again from its very x_T with new step noise (teaching.py); the worker's ticket,
        or None when nothing is on screen to rerun."""
        solved = self.writer.solved
        if solved is None or is_forward(solved) or solved.preview_of is not None:
            return None
        request = dataclasses.replace(
            solved.request, rerun=solved.request.rerun + 1, arrival=time.perf_counter(), animate=True
        )
        return self._submit_request(request)

    def noise_it(self, play: bool = True):
        """Show the forward process of the final poses on screen (teaching.py) and play it from t = 0 toward T;
        returns its Solved, or None when there is nothing to noise (no solve, a robot's)."""
        solved = self.writer.solved
        if solved is None or is_forward(solved) or not arm_kind(solved.request.solver).teaches:
            return None
        forward = forward_solved(solved, seed=solved.request.seed)
        self.writer.ask(solved=(forward, True))  # drawn at its last state: t = 0, the poses themselves
        self.writer.flush()
        if play:
            self.forward_player = threading.Thread(target=self._play_forward, args=(forward,), daemon=True)
            self.forward_player.start()
        return forward

    def _play_forward(self, forward) -> None:
        """Step the forward process from t = 0 to T over the animation's duration; a newer solve on screen stops it.
        Each step is a state asked of the drawing loop, the one writer."""
        last = forward.view.num_states - 1
        seconds = float(self.panel.duration.value) or 4.0
        started = time.monotonic()
        for state in range(last, -1, -1):
            time.sleep(max(0.0, started + seconds * (last - state) / last - time.monotonic()))
            if self.writer.solved is not forward:
                return
            self.writer.ask(state=StateAsked(state=state))

    def _after_solve(self, solved) -> None:
        """The drawing loop's thread, before the frame that shows `solved`: follow mode picks the highlighted
        sample; a rerun's readout says how far its poses moved."""
        self.constraint_controls.after_solve(solved, self.panel, self.writer)
        self.panel.teach.again_text.content = self.reruns.after_solve(solved) or ""

    def _job(self, request):
        """The worker's job for `request`: its solve, and for a robot's drag a fast preview first, handed back as a
        result like any other (solving.preview_request)."""
        if not self.previews:
            return lambda cancel: solve(request, cancel)
        show = lambda cancel: lambda solved: self.writer.ask(solved=(solved, not cancel.is_set()))  # noqa
        return lambda cancel: solve(request, cancel, show(cancel))

    def _solved(self, ticket: int, solved: Solved) -> None:
        """Worker thread: hand the finished solve to the drawing loop, nothing else."""
        self._solve_answered = max(self._solve_answered, ticket)  # before the loop draws it and asks for fields
        self.writer.ask(solved=(solved, self.worker.is_newest(ticket)))

    def _failed(self, ticket: int, error: BaseException) -> None:
        self._solve_answered = max(self._solve_answered, ticket)
        self.writer.ask(error=f"{type(error).__name__}: {error}")

    async def on_gizmo_update(self, event: viser.TransformControlsEvent) -> None:
        """Gizmo callback. Async so viser runs it on its event loop in arrival order; it only queues work."""
        if event.phase == "start":
            return
        point = arm_kind(self.solver).gizmo_target(self.solver, event.target, self.target)
        self.move_target(point, arrival=time.perf_counter(), from_gizmo=True, dragging=event.phase == "update")

    def show_state(self, state: int) -> None:
        """Put state `state` (0 = pure noise .. S = final) on screen, and wait until it is written."""
        self.writer.ask(state=StateAsked(state=state))
        self.writer.flush()

    def toggle_play(self) -> None:
        """Pause a running animation, or play from the current step (from t = T when at the end)."""
        self.writer.ask(toggle_play=True)
        self.writer.flush()

    def wait_until_still(self, timeout: float = 30.0) -> bool:
        """Block until no solve is waiting or running and nothing is left to draw (for tests and scripts)."""
        return self.wait_until_drawn(timeout, playing=False)

    def wait_until_drawn(self, timeout: float = 30.0, *, playing: bool = True) -> bool:
        """Block until no solve is asked, waiting or running and the newest is on screen; `playing`: its animation
        may still be playing."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.worker.wait_idle(max(0.0, deadline - time.monotonic())):
                self.writer.flush(max(0.0, deadline - time.monotonic()))
                if self.worker.idle and self.writer.asked.idle and (playing or self.writer.still):
                    return True
            time.sleep(0.005)
        return False

    def close(self) -> None:
        self.worker.close()
        self.writer.close()

    # ---------------------------------------------------------------- panel

    def _wire_panel(self) -> None:
        panel = self.panel
        panel.timestep.on_update(lambda event: self._ask(event, state=StateAsked(timestep=float(panel.timestep.value))))
        panel.previous_button.on_click(lambda event: self._ask(event, state=StateAsked(delta=-1)))
        panel.next_button.on_click(lambda event: self._ask(event, state=StateAsked(delta=+1)))
        panel.play_button.on_click(lambda event: self._ask(event, toggle_play=True))
        joint_space = panel.joint_space
        for toggle in (panel.show_trail, panel.show_estimate, panel.highlight, joint_space.show, joint_space.grid,
                       panel.learn.trail_of, panel.learn.clock, panel.duration):  # fmt: skip
            toggle.on_update(lambda event: self._ask(event, redraw=True))
        for name, dropdown in (("joint x", joint_space.first), ("joint y", joint_space.second)):
            dropdown.on_update(lambda event, name=name: self._ask(event, changed=[name], redraw=True))
        panel.prior_button.on_click(lambda event: self.draw_prior(event.client is None))
        panel.export_button.on_click(self.downloads.on_export)
        panel.learn.share.on_click(self.downloads.on_share)
        panel.learn.target.go.on_click(lambda _: self.move_typed_target())
        for name, control in (("samples", panel.samples), ("sampler", panel.sampler), ("steps", panel.steps),
                              ("refine", panel.refine)):  # fmt: skip
            control.on_update(lambda event, name=name: self._ask(event, changed=[name]))
        panel.teacher_student.on_click(lambda event: self._ask(event, changed=["switch"]))
        for control in (panel.learn.compare, panel.refine_steps):
            control.on_update(lambda event: self._ask(event, solve=(time.perf_counter(), True)))
        panel.seed.on_update(lambda event: None if event.client is None else self.request_solve())
        panel.checkpoint.on_update(lambda _: self._on_checkpoint())
        panel.teach.again.on_click(lambda _: self.again())
        panel.teach.noise_it.on_click(lambda _: self.noise_it())

    def _on_changed(self, name: str) -> None:
        """Drawing loop: the handler of a control that writes other controls (sampling_controls.py)."""
        sampling = self.sampling
        joint_space = self.panel.joint_space  # a pair of one joint twice is a line: the other dropdown moves on
        handler = {"samples": sampling.on_samples, "sampler": sampling.on_sampler, "steps": sampling.on_steps,
                   "refine": sampling.on_refine, "switch": sampling.on_switch,
                   "joint x": lambda: joint_space.keep_apart(joint_space.first),
                   "joint y": lambda: joint_space.keep_apart(joint_space.second)}[name]  # fmt: skip
        handler()

    def _ask(self, event: viser.GuiEvent, **fields) -> None:
        """A callback's whole work: set fields of the intent. A control the drawing loop itself wrote is its own
        doing and asks nothing; a value set from Python (a script, a test) waits until it is drawn."""
        if self.writer.on_loop_thread():
            return
        self.writer.ask(**fields)
        if event.client is None:
            asked = self._fields_job
            self.writer.flush()
            if self._fields_job is not asked:  # the picture asked for joint-space arrows: they are part of it
                self.wait_until_drawn()

    def draw_prior(self, wait: bool = True) -> np.ndarray:
        """Draw K poses from the model's training prior and show them; returns their joints (K, N+1, 2 or 3)."""
        with self.session.lock:
            solver = self.session.solver
            headings = solver.prior.sample(int(self.panel.samples.value), solver.arm)  # (K, N)
            joints = solver.arm.forward_kinematics(headings.double()).numpy()  # (K, N+1, 2 or 3)
            self.writer.ask(prior=joints)
        if wait:
            self.writer.flush()
        return joints

    def export(self, folder: Path, progress=None) -> tuple[Path, Path]:
        """Write the solve on screen as `<stem>.gif` and `<stem>_trail.png` into `folder` (downloads.py)."""
        return self.downloads.export(folder, progress)

    def move_typed_target(self) -> int | None:
        """Solve the target typed in the panel's Target folder (pulled into the workspace as a drag would be)."""
        kind = arm_kind(self.solver)
        values = kind.typed_numbers(self.panel.learn.target, self.solver.arm)
        try:
            point = kind.target_from_numbers(values, self.solver, self.target)
        except ValueError as error:
            text = f"**Not a target** {error}"  # written by the drawing loop, like every panel output
            self.writer.run(lambda writer: setattr(writer.panel.target_text, "content", text))
            return None
        return self.move_target(point)

    def share(self) -> tuple[str, str]:
        """The solve on screen as one self-contained HTML page (record.py): (file name, page)."""
        return self.downloads.share()

    # ---------------------------------------------------------------- checkpoints

    @property
    def checkpoints(self) -> dict[str, Path]:
        """The model dropdown's label -> path (models.py)."""
        return self.models.paths

    @checkpoints.setter
    def checkpoints(self, paths: dict[str, Path]) -> None:
        self.models.paths = dict(paths)

    def _current_checkpoint_label(self) -> str:
        return self.models.label_of(self.solver)

    def refresh_checkpoints(self) -> None:
        """Re-list the checkpoint folder (new models appear as they are trained)."""
        if self.models.refresh(self.solver):
            options = tuple(self.models.paths)
            self.writer.run(lambda writer: setattr(writer.panel.checkpoint, "options", options))

    def _on_checkpoint(self) -> None:
        label = self.panel.checkpoint.value
        if label != self._current_checkpoint_label():
            self.load_checkpoint(self.checkpoints[label])

    def load_checkpoint(self, path: Path) -> bool:
        """Switch to another model: reload, redraw the scene for its arm, solve again (models.py)."""
        return switch_model(self, path)
