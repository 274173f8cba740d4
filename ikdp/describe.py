"""Describe IKDP checkpoints: what ships, how each was trained and what it measured at save.

    python -m ikdp.describe                           # the shipped models, one line each
    python -m ikdp.describe checkpoints/*.pt          # a markdown table and the commands

Reads the checkpoint's own record (it never runs code from the file), and rebuilds
the training command from the saved training config: every option that differs
from today's default is spelled out, so the command stays true as defaults move.
"""

from __future__ import annotations

import argparse
import math
import sys
import typing
from dataclasses import fields
from pathlib import PurePath

import tyro.conf

from ikdp.checkpoint import CheckpointError, read_checkpoint
from ikdp.shipped import PURPOSES, list_shipped
from ikdp.solver import STUDENT
from ikdp.train import TrainConfig

NOT_OPTIONS = {"step", "seconds", "finished", "torch_version"}
MACHINE_OPTIONS = {"resume"}  # how a run was continued, not what it trained


def training_command(train: dict) -> str:
    """The `python -m ikdp.train ...` command that reproduces a saved training config (a student: its own)."""
    if train.get("command"):  # ikdp.distill records the command it ran
        return train["command"]
    parts = ["python -m ikdp.train"]
    for field in fields(TrainConfig):
        if field.name in NOT_OPTIONS or field.name in MACHINE_OPTIONS or field.name not in train:
            continue
        value = train[field.name]
        default = field.default
        if isinstance(value, list):
            value = tuple(value)
        if value == default:
            continue
        flag = "--" + field.name.replace("_", "-")
        if isinstance(value, bool) and default is None:  # a recipe's option: tyro takes --flag True / False
            parts.append(f"{flag} {value}")
        elif isinstance(value, bool):
            parts.append(flag if value else "--no-" + field.name.replace("_", "-"))
        elif isinstance(value, tuple) and repeated_flag(field.name):  # --ee-link a --ee-link b
            parts += [f"{flag} {v}" for v in value]
        elif isinstance(value, tuple):
            parts.append(flag + " " + " ".join(str(v) for v in value))
        else:
            parts.append(f"{flag} {value}")
    return " ".join(parts)


def repeated_flag(name: str) -> bool:
    """Whether TrainConfig's option `name` is given once per value on the command line (tyro's append action)."""
    hint = typing.get_type_hints(TrainConfig, include_extras=True)[name]
    return tyro.conf.UseAppendAction in getattr(hint, "__metadata__", ())


def arm_text(model: dict, train: dict) -> str:
    """'planar, 4 links', 'panda (panda_hand), 7 joints, pose targets' or 'z1.urdf (gripperStator), ...' for --urdf."""
    arm = model.get("arm") or {"kind": "planar"}  # a planar model may store only its lengths
    if arm["kind"] == "planar":
        return f"planar, {len(model['lengths'])} links"
    name = train.get("robot") or (train.get("urdf") and PurePath(train["urdf"]).name) or "chain"  # not a long path
    ends = arm.get("ee_link") or ", ".join(arm.get("ee_links", ["?"]))  # a tree names several
    return f"{name} ({ends}), {len(arm['joint_names'])} joints, {arm.get('target', 'pose')} targets"


def accuracy_text(model: dict, metrics: dict) -> str:
    """The median error at save: in bone lengths for a planar arm, mm (and degrees) for a chain."""
    median = metrics.get("tip_error_median")
    if median is None:
        return "..."
    where = f"({metrics.get('eval_targets')} targets, {metrics.get('sampler')})"
    if (model.get("arm") or {"kind": "planar"})["kind"] == "planar":
        return f"{median:.4f} {where}"
    rotation = metrics.get("rotation_error_median")
    rotation_text = f" / {math.degrees(rotation):.1f}°" if rotation is not None else ""
    return f"{median * 1000:.1f} mm{rotation_text} {where}"


def describe(paths: list[str]) -> str:
    rows = [
        "| checkpoint | arm | T | denoiser | representation | prior | steps | train time | median error at save |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    commands = []
    for path in paths:
        payload = read_checkpoint(path)
        model, train, metrics = payload["model"], payload["train"], payload["metrics"]
        teacher_train = (payload.get("distill") or {}).get("teacher_train")  # a student's robot is its teacher's
        arm = arm_text(model, teacher_train or train)
        minutes = float(train.get("seconds", 0)) / 60
        rows.append(
            f"| `{path}` | {arm} | {model['schedule']['timesteps']} | {model['denoiser']['kind']} "
            f"| {model['representation']} | {payload['prior']['kind']} | {train.get('step')} "
            f"| {minutes:.1f} min ({train.get('threads')} thread) | {accuracy_text(model, metrics)} |"
        )
        commands.append(f"- `{path}`: `{training_command(train)}`")
    return "\n".join(rows) + "\n\nCommands:\n\n" + "\n".join(commands) + "\n"


def short_accuracy(model: dict, metrics: dict) -> str:
    """The raw median at save, short: '0.0072' (bone lengths) or '2.7 mm / 0.5°'."""
    return accuracy_text(model, metrics).split(" (")[0]


def fast_sampler_text(payload: dict) -> str:
    """'student: ddim 4 steps, 3.7 mm / 0.7°' for a model with a folded student (its own grid for a student's
    file), '-' for none."""
    student = payload.get(STUDENT) or (payload if payload.get("distill") else None)
    if student is None:
        return "-"
    record, accuracy = student["distill"], short_accuracy(student["model"], student["metrics"])
    steps = f"{record['steps']} step" + ("s" if record["steps"] != 1 else "")
    return f"{STUDENT}: {record['sampler']} {steps}, {accuracy}"


def describe_shipped() -> str:
    """One line per shipped model: name, arm, what it is for, its fast sampler, its raw median at save (K = 1)."""
    lines = ["name | arm | for | fast sampler | raw median at save (DDPM, K=1)"]
    for path in list_shipped():
        payload = read_checkpoint(path)
        model, train = payload["model"], payload["train"]
        arm = arm_text(model, (payload.get("distill") or {}).get("teacher_train") or train)
        accuracy = "-" if payload.get("distill") else short_accuracy(model, payload["metrics"])
        purpose = PURPOSES.get(path.stem, "")
        lines.append(f"{path.stem} | {arm} | {purpose} | {fast_sampler_text(payload)} | {accuracy}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Describe IKDP checkpoints as markdown (none named: what ships).")
    parser.add_argument("paths", nargs="*", help="checkpoint files (none: the shipped models, one line each)")
    args = parser.parse_args(argv)
    try:
        print(describe(args.paths) if args.paths else describe_shipped())
    except CheckpointError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
