"""A model's few-step student in the viewer: folded into its teacher's file, offered as a sampler.

A student of `python -m ikdp.distill` is its teacher's network trained so that a few DDIM steps
land where the teacher's long sampler lands from the same noise. When the model the viewer opens
holds a student (`python -m ikdp.ship --student`), the Sampling folder offers it as the sampler "student"
(a robot's default: a new target's first frame comes after a few network evaluations, not a
hundred); one button switches to the teacher's full DDPM and back; "compare with" draws the other
from the very same x_T; and a robot's drag shows the student while the teacher's solve runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import ikdp
from ikdp.checkpoint import CheckpointError, read_checkpoint

STUDENT = "student"  # the sampler dropdown's and "compare with"'s name for the student
TEACHER = "teacher"  # "compare with": the teacher's sampler the student was trained to match, from the same x_T
DETERMINISTIC = {"ddim": "DDIM (deterministic ODE)", "dpmpp2m": "DPM-Solver++(2M) (deterministic ODE)"}


def sampler_title(name: str, steps: int) -> str:
    return f"{DETERMINISTIC.get(name, name.upper() + ' (stochastic)')}, {steps} steps"


def is_student_of(record: dict | None, teacher: ikdp.Solver) -> bool:
    """A checkpoint's `distill` record names `teacher`: the same file name and the same recorded metrics (a copy of
    the teacher elsewhere still finds its student; another model of the same name does not)."""
    if not isinstance(record, dict):
        return False
    teacher_file = Path(str(teacher.metadata.get("path", ""))).name
    same_file = Path(str(record.get("teacher_path", ""))).name == teacher_file
    return same_file and record.get("teacher_metrics") == teacher.metadata.get("metrics")


def find_teacher(student: ikdp.Solver, folder: Path | None) -> ikdp.Solver | None:
    """The teacher of `student` in `folder` (the file its record names, with the recorded metrics), loaded; None if
    `student` is no student or its teacher is not there."""
    record = student.metadata.get("distill")
    if folder is None or not isinstance(record, dict):
        return None
    path = Path(folder) / Path(str(record.get("teacher_path", ""))).name
    if not path.is_file() or checkpoint_header(path) is None:
        return None
    try:
        teacher = ikdp.load(path, device=student.device)
    except (ikdp.CheckpointError, OSError, RuntimeError):
        return None
    return teacher if is_student_of(record, teacher) else None


def model_and_student(solver: ikdp.Solver, folder: Path | None) -> tuple[ikdp.Solver, ikdp.Solver | None]:
    """The (model, student) a viewer opens for `solver`: a teacher with the student folded into its file (ikdp.ship);
    a student opened itself comes with its teacher when the folder holds that (its own network then serves the
    student's sampler, and the teacher's full denoising stays one click away); otherwise (solver, None)."""
    teacher = find_teacher(solver, folder)
    if teacher is not None:
        return teacher, solver
    return solver, solver.student


def student_sampling(student: ikdp.Solver) -> tuple[str, int]:
    """The (sampler, steps) the student was distilled for: its few steps, on its own grid (Solver.default_spacing)."""
    record = student.metadata["distill"]
    return str(record["sampler"]), int(record["steps"])


def distillation_target(student: ikdp.Solver) -> tuple[str, int, str]:
    """(sampler, steps, spacing) of the teacher's run the student learnt to land on from the same noise: what
    distillation does, seen, when the two are drawn side by side."""
    record = student.metadata["distill"]
    return str(record["teacher_sampler"]), int(record["teacher_steps"]), str(record["teacher_spacing"])


def role(solver: ikdp.Solver, student: ikdp.Solver | None) -> str:
    """ "student", "teacher" (a model that has a student here) or "" (no student in sight)."""
    if solver.metadata.get("distill"):
        return STUDENT
    return "teacher" if student is not None else ""


def solve_title(solver: ikdp.Solver, student: ikdp.Solver | None, sampler: str, steps: int) -> str:
    """The label over a solve: its sampler, and whose network ran it when a student is in sight."""
    who = role(solver, student)
    return (f"{who.capitalize()}: " if who else "") + sampler_title(sampler, steps)


def matched_its_teacher(student: ikdp.Solver) -> bool:
    """Whether the student's (last) distillation matched the teacher's run from the same noise: a run with
    `--match-weight 0` learnt from the FK miss and the teacher's DDPM samples instead (records before the option
    have no weight: they matched)."""
    return float(student.metadata.get("train", {}).get("match_weight", 1.0)) > 0


def target_title(sampler: str, steps: int, matched: bool = True) -> str:
    """The label over the teacher's run from the student's x_T (short: it sits over a narrow view); "what the student
    learnt to match" only where its distillation did."""
    short = {"dpmpp2m": "DPM-Solver++"}.get(sampler, sampler.upper())
    return f"Teacher: {short}, {steps} steps, " + ("what the student learnt to match" if matched else "same x_T")


def sampler_label(solver: ikdp.Solver, student: ikdp.Solver | None, sampler: str) -> str:
    """The sampler as the readouts name it: "student's ddim", "teacher's ddpm", or the sampler alone."""
    who = role(solver, student)
    return f"{who}'s {sampler}" if who else sampler


def switch_label(on_student: bool, teacher: ikdp.Solver, student: ikdp.Solver) -> str:
    """The Denoising folder's teacher/student button: what one click shows."""
    if on_student:  # short: the panel's column cuts a longer label
        return f"Show the teacher (DDPM, {teacher.timesteps} steps)"
    sampler, steps = student_sampling(student)
    return f"Show the student ({sampler.upper()}, {steps} steps)"


def opening_sampler(kind, student: ikdp.Solver | None, asked_for_student: bool = False) -> tuple[str, int]:
    """The (sampler, steps) a viewer opens on for an arm of `kind` (arm_kinds): the student where there is one and
    the kind opens on it (a robot's) or the student's file was the one asked for, else the kind's own (the paper's
    DDPM); the steps apply to a sampler that can skip some."""
    sampler, steps = kind.default_sampler
    first = student is not None and (kind.opens_on_student or asked_for_student)
    return (STUDENT if first else sampler), steps


# What the viewer reads of a checkpoint file without building its model: the kind of arm it drives and its
@dataclass(frozen=True)
class CheckpointHeader:
    arm_kind: str  # "planar" or "chain" (ikdp_viz.arm_kinds)
    distill: dict | None  # the student's record of its teacher; None for a model trained from scratch


_headers: dict[tuple[Path, float, int], CheckpointHeader | None] = {}


def checkpoint_header(path: Path) -> CheckpointHeader | None:
    """The header of the checkpoint at `path`; None when the file is missing or ikdp cannot read it."""
    try:
        stat = Path(path).stat()
    except OSError:
        return None
    key = (Path(path).resolve(), stat.st_mtime, stat.st_size)
    if key not in _headers:
        _headers[key] = read_header(Path(path))
    return _headers[key]


def read_header(path: Path) -> CheckpointHeader | None:
    try:
        payload = read_checkpoint(path)
    except (CheckpointError, OSError):
        return None
    arm = payload["model"].get("arm")  # absent or None: a planar arm described by its `lengths`
    kind = str(arm.get("kind", "planar")) if isinstance(arm, dict) else "planar"
    distill = payload.get("distill")
    return CheckpointHeader(kind, distill if isinstance(distill, dict) else None)
