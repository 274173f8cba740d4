"""IKDP viewer: the reverse diffusion of a planar arm or a robot from a URDF, live in the browser.

Drag the red cross (a robot: the 6-DoF gizmo at its hand). For each new target
the app runs the reverse diffusion on a worker thread (the newest target wins)
and draws it as the paper's Fig. "vis":
every intermediate pose a thin line from faint (pure noise, t = T) to dark
(t = 0), the current pose solid; then it plays the denoising from t = T to 0.

This file wires four parts: the session (model, target: `session.py`), the solve
worker (`solve_worker.py`, `solving.py`), the scene writer (`scene_writer.py`,
the one thread that draws; `chain_scene_writer.py` for a robot) and the panel
(`panel.py`). Callbacks only change the session and send messages; they never
write the scene. What differs per kind of arm is `arm_kinds.py`'s.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import viser

import ikdp
from ikdp.checkpoint import read_checkpoint
from ikdp.samplers import SAMPLERS, sampler_names
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.chain_scene_writer import scene_writer_class
from ikdp_viz.constraint_controls import ConstraintControls
from ikdp_viz.panel import DEFAULT_DURATION, build_panel, highlight_options
from ikdp_viz.scene_writer import (
    Call,
    NewModel,
    PlaceTarget,
    Redraw,
    ReplayWhenDrawn,
    ShowError,
    ShowPrior,
    ShowSolve,
    ShowState,
    TogglePlay,
    camera_fit,
)
from ikdp_viz.session import Session, initial_target
from ikdp_viz.solve_worker import LatestWorker
from ikdp_viz.solving import Solved, solve
from ikdp_viz.typed_target import target_from_numbers

STALE_GRACE = 0.1  # seconds without a new solve on screen after which no running solve is cancelled

__all__ = ["VizApp", "camera_fit", "list_checkpoints"]


def list_checkpoints(folder: Path, extra: Path | None = None) -> dict[str, Path]:
    """Dropdown label -> path for every `.pt` in `folder`, plus `extra` (labelled by its path) if elsewhere."""
    found = {path.name: path for path in sorted(Path(folder).glob("*.pt"))} if Path(folder).is_dir() else {}
    if extra is not None and Path(extra).resolve() not in {path.resolve() for path in found.values()}:
        found[str(extra)] = Path(extra)
    return found


def checkpoint_arm_kind(path: Path) -> str | None:
    """The kind of arm ("planar", "chain") a checkpoint file's model drives; None if ikdp cannot read the file."""
    try:
        payload = read_checkpoint(path)
    except ikdp.CheckpointError:
        return None
    arm = payload["model"].get("arm")  # absent or None: a planar arm described by its `lengths`
    return str(arm.get("kind", "planar")) if isinstance(arm, dict) else "planar"


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
    ):
        self.server = server
        self.session = Session(solver, target)
        self.checkpoint_folder = checkpoint_folder
        given = Path(solver.metadata.get("path", "model.pt"))
        self._checkpoint_kinds: dict[tuple[Path, float, int], str | None] = {}  # (path, mtime, size) -> arm kind
        # dropdown label -> path, only the models of the arm this viewer draws (issue 19: the Panda offered in a
        # planar session could not open)
        self.checkpoints = self._openable(dict(checkpoints or {given.name: given}), solver)
        self.worker = LatestWorker(stale_grace=STALE_GRACE)
        self._export_lock = threading.Lock()  # one export renders at a time
        self._export_notes: dict[int, viser.NotificationHandle] = {}  # client id -> its export's notification
        current = self._current_checkpoint_label()  # first: it lists the open model when the folder lacks it
        self.panel = build_panel(
            server.gui, num_timesteps=solver.timesteps, animation_seconds=animation_seconds,
            sampler_names=sampler_names(), checkpoint_labels=tuple(self.checkpoints),
            checkpoint_label=current, model_text=self._model_description(),
        )  # fmt: skip
        self.writer = scene_writer_class(solver)(server, self.panel, solver, self.session.target, self.on_gizmo_update)
        self._chosen_steps = int(self.panel.steps.value)  # the steps a sampler that can skip some takes
        self._showing_steps = False  # _show_steps is moving the slider
        self.constraint_controls = ConstraintControls(server, solver, self.writer.post, self.request_solve)
        self._wire_panel()
        self._show_steps()
        server.on_client_connect(lambda client: self.refresh_checkpoints())
        self.writer.post(PlaceTarget(self.session.target, False, move_gizmo=False, force=False))
        if solve_now:
            self.move_target(self.session.target)

    # ---------------------------------------------------------------- what tests and scripts read

    @property
    def solver(self) -> ikdp.Solver:
        return self.session.solver

    @property
    def target(self) -> np.ndarray:
        return self.session.target

    @property
    def solved(self) -> Solved | None:
        """The solve on screen."""
        return self.writer.solved

    @property
    def state(self) -> int:
        """Index of the state on screen, 0 (pure noise) .. S (final)."""
        return self.writer.state

    @property
    def playing(self) -> bool:
        return self.writer.playing

    @property
    def latencies(self):
        return self.writer.latencies

    def highlight_index(self) -> int:
        return self.writer.highlight_index()

    def __getattr__(self, name: str):
        # The scene's handles (gizmo, cross, trail, links, joints, tips, refined_lines, ...) are the writer's.
        if name in {"gizmo", "cross", "trail", "links", "joints", "tips", "refined_lines", "refined_tips",
                    "estimate_lines"}:  # fmt: skip
            return getattr(self.writer, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    # ---------------------------------------------------------------- requests

    def move_target(
        self, point, *, arrival: float | None = None, from_gizmo: bool = False, dragging: bool = False
    ) -> int | None:
        """Clamp `point` to the workspace, move the cross there and ask for its solve; returns the ticket.

        While `dragging`, each solve is drawn at once at its final pose (its trail from t = T
        to 0 included), so the arm follows the cross; the denoising plays when the drag ends.
        """
        arrival = time.perf_counter() if arrival is None else arrival
        with self.session.lock:  # the cross and the solve are posted in the order of the targets
            target, clamped, changed = self.session.move(point, from_gizmo=from_gizmo)
            released = from_gizmo and not dragging
            move_gizmo = clamped or not from_gizmo
            self.writer.post(PlaceTarget(target, clamped, move_gizmo=move_gizmo, force=released and move_gizmo))
            if not changed and from_gizmo:
                if released:
                    self.writer.post(ReplayWhenDrawn(target))
                return None
            return self.request_solve(arrival, animate=not dragging)

    def request_solve(self, arrival: float | None = None, *, animate: bool = True) -> int:
        """Solve the current target with the panel's settings, replacing any solve not yet started."""
        with self.session.lock:
            constraints = self.constraint_controls.constraints()
            request = self.session.request(
                self.panel,
                arrival=arrival,
                animate=animate,
                constraints=constraints,
                chosen_steps=self._chosen_steps,
            )
            return self.worker.submit(lambda cancel: solve(request, cancel), self._solved, self._failed)

    def _solved(self, ticket: int, solved: Solved) -> None:
        """Worker thread: hand the finished solve to the writer."""
        newest = self.worker.is_newest(ticket)
        self.writer.post(ShowSolve(solved, newest=newest))
        if newest:
            self.constraint_controls.after_solve(solved, self.panel)

    def _failed(self, ticket: int, error: BaseException) -> None:
        self.writer.post(ShowError(f"{type(error).__name__}: {error}"))

    async def on_gizmo_update(self, event: viser.TransformControlsEvent) -> None:
        """Gizmo callback. Async so viser runs it on its event loop in arrival order; it only queues work."""
        if event.phase == "start":
            return
        point = arm_kind(self.solver).gizmo_target(self.solver, event.target)
        self.move_target(point, arrival=time.perf_counter(), from_gizmo=True, dragging=event.phase == "update")

    def show_state(self, state: int) -> None:
        """Put state `state` (0 = pure noise .. S = final) on screen, and wait until it is written."""
        self.writer.post(ShowState(state=state))
        self.writer.flush()

    def toggle_play(self) -> None:
        """Pause a running animation, or play from the current step (from t = T when at the end)."""
        self.writer.post(TogglePlay())
        self.writer.flush()

    def wait_until_still(self, timeout: float = 30.0) -> bool:
        """Block until no solve is waiting or running and nothing is left to draw (for tests and scripts)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.worker.wait_idle(max(0.0, deadline - time.monotonic())):
                self.writer.flush(max(0.0, deadline - time.monotonic()))
                if self.worker.idle and self.writer.still:
                    return True
            time.sleep(0.005)
        return False

    def close(self) -> None:
        self.worker.close()
        self.writer.close()

    # ---------------------------------------------------------------- panel

    def _wire_panel(self) -> None:
        panel = self.panel
        panel.timestep.on_update(self._on_timestep)
        panel.previous_button.on_click(lambda event: self._post(event, ShowState(delta=-1)))
        panel.next_button.on_click(lambda event: self._post(event, ShowState(delta=+1)))
        panel.play_button.on_click(lambda event: self._post(event, TogglePlay()))
        joint_space = panel.joint_space
        for toggle in (panel.show_trail, panel.show_estimate, panel.highlight, joint_space.show, joint_space.first,
                       joint_space.second, joint_space.grid, panel.learn.trail_of,
                       panel.learn.clock, panel.duration):  # fmt: skip
            toggle.on_update(lambda event: self._post(event, Redraw()))
        panel.prior_button.on_click(lambda event: self.draw_prior(event.client is None))
        panel.export_button.on_click(self._on_export)
        panel.learn.share.on_click(self._on_share)
        panel.learn.target.go.on_click(lambda _: self.move_typed_target())
        panel.learn.compare.on_update(lambda _: self.request_solve())
        panel.samples.on_update(lambda _: self._on_samples())
        panel.sampler.on_update(lambda _: self._on_sampler())
        panel.steps.on_update(lambda _: self._on_steps())
        panel.refine_steps.on_update(lambda _: self.request_solve())
        panel.seed.on_update(lambda event: None if event.client is None else self.request_solve())
        panel.refine.on_update(lambda _: self._on_refine())
        panel.checkpoint.on_update(lambda _: self._on_checkpoint())

    def _post(self, event: viser.GuiEvent, message) -> None:
        """Send `message` to the writer; a value set from Python (a script, a test) waits until it is drawn."""
        if threading.current_thread() is self.writer._thread:
            return  # the writer itself moved a control while drawing
        self.writer.post(message)
        if event.client is None:
            self.writer.flush()

    def draw_prior(self, wait: bool = True) -> np.ndarray:
        """Draw K poses from the model's training prior and show them; returns their joints (K, N+1, 2 or 3)."""
        with self.session.lock:
            solver = self.session.solver
            headings = solver.prior.sample(int(self.panel.samples.value), solver.arm)  # (K, N)
            joints = solver.arm.forward_kinematics(headings.double()).numpy()  # (K, N+1, 2 or 3)
            self.writer.post(ShowPrior(joints))
        if wait:
            self.writer.flush()
        return joints

    def export(self, folder: Path, progress=None) -> tuple[Path, Path]:
        """Write the solve on screen as `<stem>.gif` (the denoising) and `<stem>_trail.png` into `folder`.

        `progress(done, total)` is called after each GIF frame (export.write_gif).
        """
        from ikdp_viz.export import write_gif, write_trail_png

        done: list = []
        self.writer.post(Call(lambda writer: done.append((writer.solved, writer.highlight_index()))))
        self.writer.flush()
        solved, highlight = done[0]  # read on the writer's thread: the pair belongs to one solve
        if solved is None:
            raise ValueError("export: nothing solved yet")
        if arm_kind(self.solver).name != "planar":
            raise ValueError("export: the GIF and PNG draw the planar arm; a robot's denoising is not exported")
        x, y = solved.view.target
        stem = f"ikdp_{solved.request.sampler}_K{solved.view.num_samples}_seed{solved.request.seed}_{x:+.3f}_{y:+.3f}"
        seconds = float(self.panel.duration.value) or 4.0
        gif = write_gif(solved.view, Path(folder) / f"{stem}.gif", highlight, seconds=seconds, progress=progress)
        png = write_trail_png(solved.view, Path(folder) / f"{stem}_trail.png", highlight)
        return gif, png

    def _on_export(self, event: viser.GuiEvent) -> None:
        """Export into a temporary folder and save both files in the downloads of the tab that asked.

        The tab sees one notification per export, replacing its last one: the GIF's frames as they
        render, then the two names. The files are saved at once (viser's `save_immediately`): without
        it viser shows a link per file to click, and the links pile up (issue 19).
        """
        import tempfile

        client = event.client
        if client is None:
            return
        previous = self._export_notes.pop(client.client_id, None)
        if previous is not None:  # popped, so never removed twice
            previous.remove()
        note = client.add_notification("Export", "starting", loading=True, with_close_button=False)
        self._export_notes[client.client_id] = note
        if not self._export_lock.acquire(blocking=False):
            note.title, note.body, note.loading = "Export", "another export is rendering; try again", False
            note.with_close_button, note.auto_close_seconds = True, 5.0
            return
        try:
            progress = lambda done, total: setattr(note, "body", f"rendering the GIF: frame {done} of {total}")
            with tempfile.TemporaryDirectory() as folder:
                paths = self.export(Path(folder), progress=progress)
                note.body = "sending the files"
                for path in paths:
                    client.send_file_download(path.name, path.read_bytes(), save_immediately=True)
            # a zero-width space after each "_" lets the long names wrap instead of being cut off with "..."
            names = [path.name.replace("_", "_\u200b") for path in paths]
            note.title, note.body = "Exported to your downloads", " and ".join(names)
        except ValueError as error:
            note.title, note.body, note.color = "Export failed", str(error), "red"
        finally:
            self._export_lock.release()
        note.loading, note.with_close_button, note.auto_close_seconds = False, True, 8.0

    def move_typed_target(self) -> int | None:
        """Solve the target typed in the panel's Target folder (pulled into the workspace as a drag would be)."""
        inputs, arm = self.panel.learn.target, self.solver.arm
        kind = arm_kind(self.solver).name
        if kind == "planar":
            values = tuple(inputs.xy.value)
        else:
            position = tuple(float(value) / 1000 for value in inputs.position_mm.value)
            values = position + (tuple(inputs.rotation_deg.value) if arm.target_dim == 7 else ())
        try:
            point = target_from_numbers(
                values, kind=kind, target_dim=getattr(arm, "target_dim", 2), current=self.target
            )
        except ValueError as error:
            self.panel.target_text.content = f"**Not a target** {error}"
            return None
        return self.move_target(point)

    def share(self) -> tuple[str, str]:
        """The solve on screen as one self-contained HTML page (record.py) with the panel's view: (file name, page)."""
        from ikdp_viz.record import RecordSettings, file_name, record_html

        done: list = []
        self.writer.post(Call(lambda writer: done.append(writer.solved)))
        self.writer.flush()
        solved = done[0]  # read on the writer's thread: the solve on screen
        if solved is None:
            raise ValueError("share: nothing solved yet")
        return file_name(solved), record_html(solved, RecordSettings.from_panel(self.panel))

    def _on_share(self, event: viser.GuiEvent) -> None:
        """Record the solve on screen and send the page to the tab that asked; the button says while it works."""
        if event.client is None or self.solved is None:
            return
        button = self.panel.learn.share
        label, button.label, button.disabled = button.label, "Recording the denoising...", True
        try:
            name, page = self.share()
            event.client.send_file_download(name, page.encode("utf-8"), save_immediately=True)
        finally:
            button.label, button.disabled = label, False

    def _on_timestep(self, event: viser.GuiEvent) -> None:
        self._post(event, ShowState(timestep=float(self.panel.timestep.value)))

    def _on_samples(self) -> None:
        options = highlight_options(int(self.panel.samples.value))
        current = self.panel.highlight.value
        self.panel.highlight.options = options
        if current not in options:
            self.panel.highlight.value = "best"
        self.request_solve()

    def _on_sampler(self) -> None:
        self._show_steps()
        self.request_solve()

    def _on_steps(self) -> None:
        steps = self.panel.steps
        if self._showing_steps or (steps.disabled and int(steps.value) == steps.max):
            return  # _show_steps, or the writer fitting the slider to a new model's T: no one's choice
        self._chosen_steps = int(steps.value)  # a script's or the command line's, for when a sampler can skip
        if steps.disabled:
            self._show_steps()  # this sampler takes all T: that is what the slider says
        else:
            self.request_solve()

    def _show_steps(self) -> None:
        """The steps slider: the user's choice for a sampler that can skip steps; else disabled at T, the steps
        it does take (issue 19: DDPM showed a stale number). The user's choice comes back with such a sampler."""
        steps = self.panel.steps
        takes_all = not SAMPLERS[str(self.panel.sampler.value)].supports_steps
        if takes_all and not steps.disabled:
            self._chosen_steps = int(steps.value)
        steps.disabled = takes_all
        shown = steps.max if takes_all else min(self._chosen_steps, steps.max)
        if steps.value != shown:
            self._showing_steps = True  # not a user's change: no solve of its own
            try:
                steps.value = shown
            finally:
                self._showing_steps = False

    def _on_refine(self) -> None:
        self.panel.refine_steps.disabled = not self.panel.refine.value
        self.request_solve()

    def _model_description(self) -> str:
        return arm_kind(self.solver).model_text(self.solver)

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
        found = self._openable(list_checkpoints(self.checkpoint_folder), self.solver)
        found.setdefault(current, self.checkpoints[current])
        self.checkpoints = found
        self.panel.checkpoint.options = tuple(found)

    def _openable(self, checkpoints: dict[str, Path], solver: ikdp.Solver) -> dict[str, Path]:
        """The entries of `checkpoints` whose model drives `solver`'s kind of arm; each file read once per version."""
        wanted = arm_kind(solver).name
        kept = {}
        for label, path in checkpoints.items():
            try:
                stat = Path(path).stat()
            except OSError:
                continue
            key = (Path(path), stat.st_mtime, stat.st_size)
            if key not in self._checkpoint_kinds:
                self._checkpoint_kinds[key] = checkpoint_arm_kind(Path(path))
            if self._checkpoint_kinds[key] == wanted:
                kept[label] = path
        return kept

    def _on_checkpoint(self) -> None:
        label = self.panel.checkpoint.value
        if label != self._current_checkpoint_label():
            self.load_checkpoint(self.checkpoints[label])

    def load_checkpoint(self, path: Path) -> bool:
        """Switch to another model: reload, redraw the scene for its arm, solve again."""
        try:
            solver = ikdp.load(path, device=self.solver.device)
        except (ikdp.CheckpointError, OSError, RuntimeError) as error:
            self.panel.model_text.content = f"**Could not load** {error}  \n\n" + self._model_description()
            self.panel.checkpoint.value = self._current_checkpoint_label()
            return False
        if arm_kind(solver) is not arm_kind(self.solver):  # the scene writer draws one kind of arm
            self.panel.model_text.content = (
                f"**Could not load** {path}: a {arm_kind(solver).name} arm's model, this viewer draws a "
                f"{arm_kind(self.solver).name} arm; start another with --ckpt {path}  \n\n" + self._model_description()
            )
            self.panel.checkpoint.value = self._current_checkpoint_label()
            return False
        with self.session.lock:
            previous = self.session.target
            self.session.solver = solver
            self.constraint_controls.rebuild(solver)
            self.session.target = initial_target(solver, previous)
            self.writer.post(NewModel(solver, self.session.target))
            self.panel.model_text.content = self._model_description()
            self.panel.checkpoint.value = self._current_checkpoint_label()
            self.panel.steps.max = solver.timesteps  # here too, not only on the writer's thread: _show_steps reads it
            self._show_steps()  # the new model's T, when its sampler takes all steps
            # the old target asked again: pulled into the new workspace, the panel says "clamped" (issue 19)
            same_kind_of_target = np.shape(previous) == np.shape(self.session.target)
            self.move_target(previous if same_kind_of_target else self.session.target)
        return True
