"""What every kind of arm does alike with what it is given: target rows read and checked, and the device a
random draw is made on.

A leaf: ikdp/arm.py (the planar arm, and the factory that builds any arm) and ikdp/chain_arm.py (a URDF
chain) both import it and it imports neither, so neither imports the other back.
"""

from __future__ import annotations

import numpy as np
import torch


def drawing_device(generator: torch.Generator | None) -> torch.device:
    """Where a draw from `generator` is made: its own device (a training's data on its GPU), else the CPU."""
    return generator.device if generator is not None else torch.device("cpu")


FEW_ROWS = 16  # targets at most that a check reads through NumPy on a CPU, where torch's per-operation cost dominates


def few_rows_on_cpu(targets: torch.Tensor) -> bool:
    """Whether targets (B, target_dim) are few enough, on the CPU and without gradients, to be read through NumPy."""
    return (
        targets.device.type == "cpu" and targets.dim() == 2 and len(targets) <= FEW_ROWS and not targets.requires_grad
    )


def validate_target_rows(targets, target_dim: int) -> torch.Tensor:
    """Array-like (B, target_dim) -> float32 tensor; ValueError naming the problem otherwise.

    A 1-D input is refused like any other wrong shape: `[1.0, 2.0]` is ambiguous between one
    target and two numbers, and silently guessing hides bugs in the caller.
    """
    try:
        if not isinstance(targets, torch.Tensor):
            targets = np.asarray(targets, dtype=np.float32)  # a list of arrays converts fast this way
        tensor = torch.as_tensor(targets, dtype=torch.float32)
    except (TypeError, ValueError, RuntimeError) as error:
        expected = f"targets: expected numbers of shape (B, {target_dim})"
        raise ValueError(f"{expected}, could not read them ({error})") from None
    if tensor.ndim != 2 or tensor.shape[1] != target_dim or tensor.shape[0] == 0:
        hint = "; wrap one target as [[...]]" if tensor.ndim == 1 else ""
        raise ValueError(f"targets: expected shape (B, {target_dim}) with B >= 1, got {tuple(tensor.shape)}{hint}")
    # a few rows on a CPU (one target's solve): NumPy's check, a fifth of torch's fixed cost
    small = tensor.device.type == "cpu" and tensor.shape[0] <= FEW_ROWS
    finite = np.isfinite(tensor.detach().numpy()).all(axis=1) if small else torch.isfinite(tensor).all(dim=1)
    if not bool(finite.all()):  # the rows named only then: nonzero costs more than the check
        row = int(np.flatnonzero(~finite)[0]) if small else int(torch.nonzero(~finite)[0, 0])
        raise ValueError(f"targets: row {row} is {tensor[row].tolist()}, NaN or inf is not a target")
    return tensor
