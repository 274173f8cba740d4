"""IKDP checkpoints: written atomically, read without ever running code from the file.

A checkpoint is a plain dict of tensors and plain values (nanoGPT style):
format tag, version, the model config (arm, representation, schedule, denoiser),
the prior, the training config, the metrics measured at save, and the weights.
It loads with `torch.load(..., weights_only=True)`, which refuses pickled code.
"""

from __future__ import annotations

import os
import pickle
import re
import tempfile
import zipfile
from pathlib import Path

import torch

FORMAT = "ikdp-checkpoint"
VERSION = 1
REQUIRED_KEYS = ("format", "version", "model", "prior", "train", "metrics", "state_dict")


class CheckpointError(ValueError):
    """A file that is not a loadable IKDP checkpoint; the message is one line naming the file and why."""


def remove_stale_temporaries(path: str | Path) -> list[Path]:
    """Delete the temp files a killed save of `path` left beside it (ours only, by name); return what was removed.

    A SIGKILL during `save_checkpoint` cannot run its cleanup, so the half-written
    `.NAME.xxxxxxxx.tmp` stays. Call it only where no other save of `path` is running.
    """
    path = Path(path)
    if not path.parent.is_dir():
        return []
    pattern = re.compile(rf"\.{re.escape(path.name)}\.[a-z0-9_]{{8}}\.tmp")  # save_checkpoint's mkstemp names
    stale = [entry for entry in path.parent.iterdir() if pattern.fullmatch(entry.name) and entry.is_file()]
    for entry in stale:
        entry.unlink(missing_ok=True)
    return stale


def save_checkpoint(path: str | Path, payload: dict) -> None:
    """Write `payload` (without format/version, which are added) to `path` atomically: temp file, fsync, rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    save_atomically(path, {"format": FORMAT, "version": VERSION, **payload})


def save_atomically(path: str | Path, payload: dict) -> None:
    """`torch.save(payload)` to `path` (its folder must exist) so that a reader sees the old file or the new one,
    never half of one; two writers of one path each leave a whole file, the later one."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as file:
            torch.save(payload, file)
            file.flush()
            os.fsync(file.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # mkstemp makes it private; a checkpoint is an ordinary file
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def read_checkpoint(path: str | Path) -> dict:
    """Read and validate a checkpoint; raise CheckpointError with a one-line reason otherwise."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no such file")
    if not path.is_file():
        raise CheckpointError(f"{path}: not a file")
    if not zipfile.is_zipfile(path):
        raise CheckpointError(f"{path}: not an IKDP checkpoint (not a torch zip archive; truncated or another format)")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        # torch's message advises re-loading with weights_only=False, i.e. running the file's code: never pass it on.
        culprit = re.search(r"GLOBAL (\S+)", str(error))
        what = f"pickled code ({culprit.group(1)})" if culprit else "pickled objects"
        raise CheckpointError(
            f"{path}: refused, it holds {what}, not plain data; IKDP does not run code from a checkpoint"
        ) from None
    except (RuntimeError, EOFError, OSError, zipfile.BadZipFile, KeyError):
        # torch's own message (a paragraph on miniz and how files get corrupted) says no more than this
        raise CheckpointError(
            f"{path}: unreadable or truncated checkpoint (its archive is damaged: written only in part, or changed "
            f"after saving)"
        ) from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise CheckpointError(f"{path}: not an IKDP checkpoint (no '{FORMAT}' format tag)")
    if payload.get("version") != VERSION:
        raise CheckpointError(
            f"{path}: checkpoint version {payload.get('version')!r}, this ikdp reads version {VERSION}"
        )
    missing = [key for key in REQUIRED_KEYS if key not in payload]
    if missing:
        raise CheckpointError(f"{path}: incomplete checkpoint, missing {', '.join(missing)}")
    return payload
