"""Package a trained model for shipping: its weights, config, metrics and training record, no resume state.

    python -m ikdp.ship --model runs/panda.pt --student runs/student4.pt --output checkpoints/ikdp_panda.pt
    python -m ikdp.ship --model runs/z1.pt --output checkpoints/ikdp_z1.pt

A training run's file also holds what `--resume` needs (the optimizer's moments, the raw weights beside the EMA,
the data stream's generator states): two to three times the weights, and nothing a solve reads. The shipped file
keeps only what a user loads. `--student` folds a distilled few-step student (`python -m ikdp.distill`) into its
teacher's file, so one name gives both: `ikdp.load(name).solve(targets, sampler="student")` runs the student on
the grid it was distilled for. The weights are copied exactly, and checked against their models before writing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ikdp.checkpoint import CheckpointError, read_checkpoint, save_checkpoint
from ikdp.solver import STUDENT, folded_student, model_from_checkpoint

SHIPPED_KEYS = ("model", "prior", "train", "metrics", "history", "distill", "state_dict")  # nothing for --resume
STUDENT_KEYS = ("model", "train", "metrics", "distill", "state_dict")  # its prior and arm are its teacher's


def shipped_payload(teacher: dict, student: dict | None = None) -> dict:
    """The payload of a shipped file: `teacher`'s user-facing keys, with `student`'s nested under "student" (in
    place of any student the teacher's file held)."""
    payload = {key: teacher[key] for key in SHIPPED_KEYS if key in teacher}
    if student is not None:
        payload[STUDENT] = {key: student[key] for key in STUDENT_KEYS}
    return payload


def check_student(teacher: dict, student: dict) -> None:
    """ValueError unless `student` is a distilled student of `teacher` (its record holds the teacher's metrics at
    save, which a copy or a renamed file keeps)."""
    record = student.get("distill")
    if not isinstance(record, dict):
        raise ValueError("student: expected a student of python -m ikdp.distill (a file with a distill record)")
    if record.get("teacher_metrics") != teacher["metrics"]:
        raise ValueError(
            f"student: distilled from {record.get('teacher_path')!r}, whose metrics at save are not the teacher's"
        )


def ship(model_path: str | Path, output: str | Path, student_path: str | Path | None = None) -> Path:
    """Write the shipped file of `model_path` (and its student) to `output`; return `output`."""
    teacher = read_checkpoint(model_path)
    student = None
    if student_path is not None:
        student = read_checkpoint(student_path)
        check_student(teacher, student)
    payload = shipped_payload(teacher, student)
    model_from_checkpoint(payload, str(model_path))  # CheckpointError where weights do not fit, before writing
    if student is not None:
        model_from_checkpoint(folded_student(payload, Path(output)), str(student_path))
    save_checkpoint(output, payload)
    return Path(output)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Package a trained model (and its distilled student) to ship.")
    parser.add_argument("--model", required=True, help="the model's training file (ikdp.train's --output)")
    parser.add_argument("--student", help="its few-step student (ikdp.distill's --output), folded into the file")
    parser.add_argument("--output", required=True, help="the shipped file to write")
    args = parser.parse_args(argv)
    try:
        path = ship(args.model, args.output, args.student)
    except (CheckpointError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    print(f"{path}: {path.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
