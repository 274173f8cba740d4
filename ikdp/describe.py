"""Describe IKDP checkpoints: how each was trained and what it measured at save.

    python -m ikdp.describe checkpoints/*.pt          # a markdown table and the commands

Reads the checkpoint's own record (it never runs code from the file), and rebuilds
the training command from the saved training config: every option that differs
from today's default is spelled out, so the command stays true as defaults move.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import fields
from pathlib import PurePath

from ikdp.checkpoint import CheckpointError, read_checkpoint
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
        elif isinstance(value, tuple):
            parts.append(flag + " " + " ".join(str(v) for v in value))
        else:
            parts.append(f"{flag} {value}")
    return " ".join(parts)


def arm_text(model: dict, train: dict) -> str:
    """'planar, 4 links', 'panda (panda_hand), 7 joints, pose targets' or 'z1.urdf (gripperStator), ...' for --urdf."""
    arm = model.get("arm") or {"kind": "planar"}  # a planar model may store only its lengths
    if arm["kind"] == "planar":
        return f"planar, {len(model['lengths'])} links"
    name = train.get("robot") or (train.get("urdf") and PurePath(train["urdf"]).name) or "chain"  # not a long path
    return f"{name} ({arm.get('ee_link', '?')}), {len(arm['joint_names'])} joints, {arm.get('target', 'pose')} targets"


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


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Describe IKDP checkpoints as markdown.")
    parser.add_argument("paths", nargs="+", help="checkpoint files")
    args = parser.parse_args(argv)
    try:
        print(describe(args.paths))
    except CheckpointError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
