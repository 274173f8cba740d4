"""The Model dropdown's entries: the checkpoints in a folder that drive the kind of arm this viewer draws.

Each file's kind of arm is read once per version (student.py): re-listing on every new
tab costs a stat per file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import ikdp
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.session import initial_target
from ikdp_viz.student import STUDENT, checkpoint_header, model_and_student


def list_checkpoints(folder: Path, extra: Path | None = None) -> dict[str, Path]:
    """Dropdown label -> path for every `.pt` in `folder`, plus `extra` (labelled by its path) if elsewhere."""
    found = {path.name: path for path in sorted(Path(folder).glob("*.pt"))} if Path(folder).is_dir() else {}
    if extra is not None and Path(extra).resolve() not in {path.resolve() for path in found.values()}:
        found[str(extra)] = Path(extra)
    return found


def checkpoint_arm_kind(path: Path) -> str | None:
    """The kind of arm ("planar", "chain") a checkpoint file's model drives; None if ikdp cannot read the file."""
    header = checkpoint_header(path)
    return None if header is None else header.arm_kind


class ModelChoices:
    """Dropdown label -> checkpoint path, only the models of `solver`'s kind of arm; re-listed from `folder`."""

    def __init__(self, paths: dict[str, Path], solver, folder: Path | None):
        self.folder = folder
        self.paths = self.openable(paths, solver)

    def label_of(self, solver) -> str:
        """The entry of `solver`'s own checkpoint, added when the list lacks it."""
        path = Path(solver.metadata.get("path", ""))
        for label, candidate in self.paths.items():
            if candidate == path or (candidate.exists() and path.exists() and candidate.resolve() == path.resolve()):
                return label
        label = str(path)
        self.paths[label] = path
        return label

    def refresh(self, solver) -> bool:
        """Re-list the folder (new models appear as they are trained); False when there is no folder."""
        if self.folder is None:
            return False
        current = self.label_of(solver)
        found = self.openable(list_checkpoints(self.folder), solver)
        found.setdefault(current, self.paths[current])
        self.paths = found
        return True

    def openable(self, paths: dict[str, Path], solver) -> dict[str, Path]:
        """The entries of `paths` whose model drives `solver`'s kind of arm."""
        wanted = arm_kind(solver).name
        kept = {}
        for label, path in paths.items():
            if checkpoint_arm_kind(Path(path)) == wanted:
                kept[label] = path
        return kept


def switch_model(app, path: Path) -> bool:
    """Load `path` into `app` (a VizApp): its panel, its scene for the arm, a solve of the old target pulled into the
    new workspace. False, with the reason in the Model folder, when the file cannot be used or drives another kind
    of arm. The file is read on the calling thread; the switch itself runs on the drawing loop, the one writer of
    the panel and the scene (and of the Constraints folder it rebuilds)."""
    described = arm_kind(app.solver).model_text(app.solver)

    def refused(reason: str) -> bool:
        def say(writer) -> None:
            writer.panel.model_text.content = f"**Could not load** {reason}  \n\n" + described
            writer.panel.checkpoint.value = app._current_checkpoint_label()  # the dropdown back on the open model

        app.writer.run(say)
        return False

    try:
        solver = ikdp.load(path, device=app.solver.device)
    except (ikdp.CheckpointError, OSError, RuntimeError) as error:
        return refused(str(error))
    if arm_kind(solver) is not arm_kind(app.solver):  # the drawing loop draws one kind of arm
        return refused(f"{path}: a {arm_kind(solver).name} arm's model, this viewer draws a "
                       f"{arm_kind(app.solver).name} arm; start another with --ckpt {path}")  # fmt: skip
    opened = solver
    solver, student = model_and_student(solver, app.models.folder)  # read here, not on the drawing loop
    app.writer.run(lambda writer: adopt_model(app, writer, solver, student, on_student=student is opened))
    return True


def adopt_model(app, writer, solver, student=None, on_student: bool = False) -> None:
    """Drawing loop's thread: `solver` (with its few-step `student`, or None) becomes the app's model; the old
    target is asked again in its workspace. `on_student`: the student's file was the one picked, so its sampler
    is the one shown."""
    with app.session.lock:
        previous = app.session.target
        app.session.solver, app.session.student = solver, student
        app.sampling.offer_student()
        if on_student:
            writer.panel.sampler.value = STUDENT
        app.constraint_controls.rebuild(solver, writer)
        app.session.target = initial_target(solver, previous)
        writer.ask(model=(solver, app.session.target))  # the scene rebuilt at the loop's next pass
        writer.panel.model_text.content = arm_kind(solver).model_text(solver)
        writer.panel.checkpoint.value = app._current_checkpoint_label()
        writer.panel.steps.max = solver.timesteps  # here too, before the scene is rebuilt: show_steps reads it
        app.sampling.show_steps()
        app.sampling.show_switch()  # the new model's T, when its sampler takes all steps
        # the old target asked again: pulled into the new workspace, the panel says "clamped" if it was moved
        same_kind_of_target = np.shape(previous) == np.shape(app.session.target)
        app.move_target(previous if same_kind_of_target else app.session.target)
