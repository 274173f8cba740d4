"""Devices and memory: a device name checked before any work, and how much memory it has free.

`torch.device("nope")` raises a RuntimeError listing every backend torch knows, and `.to("cuda")`
on a machine without CUDA an AssertionError from deep inside torch; a user gets one line instead,
naming the argument. `available_bytes` is what a solve may count on: the GPU's free memory, or
Linux's MemAvailable on a CPU (None where neither can be read, and then nothing is refused).
"""

from __future__ import annotations

from pathlib import Path

import torch


def checked_device(device, what: str = "device") -> torch.device:
    """`device` (a name, or a torch.device) -> torch.device; ValueError naming `what` when it cannot be used here."""
    try:
        resolved = torch.device(device)
    except (RuntimeError, TypeError, ValueError):
        raise ValueError(f"{what}: expected 'cpu', 'cuda' or 'cuda:N', got {device!r}") from None
    if resolved.type == "cuda":
        if not torch.cuda.is_available():
            raise ValueError(f"{what}: got {device!r}, but torch finds no CUDA GPU here; use 'cpu'")
        count = torch.cuda.device_count()
        if resolved.index is not None and resolved.index >= count:
            raise ValueError(f"{what}: got {device!r}, but torch finds {count} CUDA GPU(s): cuda:0 to cuda:{count - 1}")
    elif resolved.type == "mps" and not torch.backends.mps.is_available():
        raise ValueError(f"{what}: got {device!r}, but torch finds no MPS device here; use 'cpu'")
    elif resolved.type not in ("cpu", "cuda", "mps"):
        raise ValueError(f"{what}: expected 'cpu', 'cuda' or 'cuda:N', got {device!r}")
    return resolved


def available_bytes(device: torch.device) -> int | None:
    """Free memory a computation on `device` can count on, in bytes; None when it cannot be read."""
    if device.type == "cuda":
        return int(torch.cuda.mem_get_info(device)[0])
    if device.type != "cpu":
        return None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024  # reported in kB
    except (OSError, ValueError, IndexError):
        return None
    return None
