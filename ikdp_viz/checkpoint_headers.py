"""What the viewer reads of a checkpoint file without building its model: the kind of arm it drives and its
`distill` record (a few-step student names its teacher there).

Read once per version of a file (its path, mtime and size): the Model dropdown re-lists its folder on every new tab
and the search for a model's student or teacher walks the same files; each read loads the whole file (a Panda
model is 20-30 MB), so without this start-up read the folder twice.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ikdp.checkpoint import CheckpointError, read_checkpoint


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
