"""Which models the viewer opens: a checkpoint named on the command line, and the Model dropdown's entries.

`python -m ikdp_viz` (__main__.py) and `python -m ikdp_viz.record` (record.py) both find a checkpoint here, load it
and turn a bad one into a one-line error (exit status 2). The dropdown lists the checkpoints in a folder that drive
the kind of arm this viewer draws; each file's kind of arm is read once per version (student.py), so re-listing on
every new tab costs a stat per file.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

import ikdp
from ikdp.shipped import list_shipped, shipped_checkpoint
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.solving import initial_target
from ikdp_viz.student import STUDENT, checkpoint_header, model_and_student


def fail(program: str, message: str) -> None:
    """One line on stderr, `<program>: error: <message>`, and exit status 2: no traceback reaches a user."""
    print(f"{program}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


# What the [viz] extra installs, module -> package (tests/test_packaging.py holds them to pyproject.toml)
VIEWER_MODULES = {module: module for module in ("viser", "trimesh", "matplotlib", "imageio")} | {"collada": "pycollada"}


def installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a finder that refuses it, or a module set to None: not usable either
        return False


def check_viewer_packages(program: str) -> None:
    """Exit 2 with one line naming what the [viz] extra would have installed (a core install lacks it)."""
    missing = [package for module, package in VIEWER_MODULES.items() if not installed(module)]
    if missing:
        fail(program, f"the viewer needs {', '.join(missing)}: pip install 'ikdp[viz]'")


def checkpoint_path(ckpt: str) -> Path:
    """A shipped model's file when `ckpt` names one and is no file here, else `ckpt` as a path."""
    if not Path(ckpt).exists() and Path(ckpt).stem in {path.stem for path in list_shipped()} and "/" not in ckpt:
        return shipped_checkpoint(ckpt)
    return Path(ckpt)


def load_solver(program: str, path: Path, device: str = "cpu"):
    """`ikdp.load(path, device)`, or exit 2 with one line saying why the checkpoint or the device cannot be used."""
    import ikdp  # imported here: torch is slow to import and `--help` needs none of it

    try:
        return ikdp.load(path, device=device)
    except ikdp.CheckpointError as error:
        fail(program, str(error))
    except OSError as error:
        fail(program, f"{path}: cannot read it ({error.strerror or error})")
    except ValueError as error:  # ikdp.load's answer to an unknown or absent device: "device: ..."
        fail(program, f"--device {device}: {str(error).removeprefix('device: ')}")
    except (RuntimeError, AssertionError) as error:  # torch's, should the device fail later
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        fail(program, f"--device {device}: {reason}")


def command_target(solver, numbers):
    """The target `--target NUMBERS` asks for; ValueError when the numbers do not make one for this arm."""
    from ikdp_viz.solving import initial_target

    return arm_kind(solver).target_from_numbers(numbers, solver, initial_target(solver))


def target_flag_error(numbers, error: ValueError) -> str:
    return f"--target {' '.join(f'{value:g}' for value in numbers)}: {error}"


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
