"""The models shipped with IKDP, found by name: `ikdp.load("ikdp_n4")`.

The `.pt` files live in the repository's top-level `checkpoints/` folder; this
module is the one place that knows where that folder is at run time.
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_MODEL = "ikdp_n4"  # the visualizer's model when no --ckpt is given


def shipped_dir() -> Path:
    """The folder holding the shipped checkpoints."""
    return Path(__file__).resolve().parent.parent / "checkpoints"


def list_shipped() -> list[Path]:
    """Every shipped checkpoint, sorted by name."""
    folder = shipped_dir()
    return sorted(folder.glob("*.pt")) if folder.is_dir() else []


def shipped_checkpoint(name: str) -> Path:
    """The path of a shipped model by name (`ikdp_n4` or `ikdp_n4.pt`); ValueError listing the names otherwise."""
    stem = name[:-3] if name.endswith(".pt") else name
    for path in list_shipped():
        if path.stem == stem:
            return path
    names = ", ".join(path.stem for path in list_shipped()) or "none found"
    raise ValueError(f"model {name!r}: not a shipped model (shipped: {names})")
