"""The distillation's reference pool, kept on disk: the teacher's DDPM samples are drawn once per teacher and pool.

Drawing a Panda pool (4096 targets x 4 samples of the DDPM-100) takes six and a half minutes of one CPU thread; every
run of `ikdp.distill` with the same teacher file, pool size, samples per target, seed, reference (the teacher's DDPM or
the posterior by rejection) and refinement draws the same pool, so the first run writes it to `<output
folder>/reference_pools/` and the others read it. The file name carries the teacher file's hash: a retrained teacher
under the same name draws its own. A file that is unreadable, holds code, or does not hold the pool it is named for is
drawn again and replaced, never trusted.
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import torch

from ikdp.checkpoint import save_atomically

FORMAT = "ikdp-reference-pool"


def file_digest(path: str | Path) -> str:
    """The first 12 hex digits of the file's SHA-256."""
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:12]


def pool_key(
    teacher_path: str | Path, size: int, per_target: int, seed: int, refine_steps: int, reference: str = "teacher"
) -> dict:
    """What makes two runs' pools the same pool."""
    teacher = Path(teacher_path)
    return {
        "teacher": teacher.name,
        "teacher_sha256": file_digest(teacher),
        "size": size,
        "per_target": per_target,
        "seed": seed,
        "refine_steps": refine_steps,
        "reference": reference,
    }


def pool_path(folder: str | Path, key: dict) -> Path:
    name = f"{Path(key['teacher']).stem}-{key['teacher_sha256']}-{key['size']}x{key['per_target']}"
    source = "posterior" if key["reference"] == "posterior" else f"dls{key['refine_steps']}"
    return Path(folder) / f"{name}-seed{key['seed']}-{source}.pt"


def read_pool(path: Path, key: dict, joint_count: int, dim: int) -> tuple[torch.Tensor, torch.Tensor] | None:
    """The pool (joints (size, J), samples (size, per_target, D)) stored at `path` for `key`; None, with a line on
    stderr saying why, when there is none or it is not that pool."""
    if not path.is_file():
        return None
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        joints, samples = payload["joints"], payload["samples"]
        written = {"reference": "teacher", **payload["key"]}  # pools kept before --reference existed: the teacher's
        whole = payload["format"] == FORMAT and written == key
        whole = whole and tuple(joints.shape) == (key["size"], joint_count)
        whole = whole and tuple(samples.shape) == (key["size"], key["per_target"], dim)
        whole = whole and bool(torch.isfinite(joints).all() and torch.isfinite(samples).all())
    except Exception:  # noqa: BLE001 - any damage to a cache file means the same thing: draw the pool again
        whole = False
    if not whole:
        print(f"reference pool: {path} is not this pool or is damaged; drawing it again", file=sys.stderr)
        return None
    print(f"reference pool: read from {path}", file=sys.stderr)
    return joints, samples


def write_pool(path: Path, key: dict, joints: torch.Tensor, samples: torch.Tensor) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    save_atomically(path, {"format": FORMAT, "key": key, "joints": joints, "samples": samples})
