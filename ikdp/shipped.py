"""The models shipped with IKDP, found by name: `ikdp.load("ikdp_n4")`.

The `.pt` files live in the repository's top-level `checkpoints/` folder. A wheel
carries that folder as `ikdp/checkpoints/` (pyproject.toml maps it there), so this
module is the one place that knows where it is at run time: inside the installed
package for a wheel, beside the package for a clone or an editable install.
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_MODEL = "ikdp_n4"  # the visualizer's model when no --ckpt is given

# What each shipped model is for, in a few words (`python -m ikdp.describe`); the files say the rest themselves
PURPOSES = {
    "ikdp_n2": "2 links: the elbow-up / elbow-down pair",
    "ikdp_n4": "the default planar arm",
    "ikdp_n8": "a redundant planar arm",
    "ikdp_paper_n4": "the paper's transformer and loss, for comparison",
    "ikdp_n4_relaxed": "natural poses (a relaxed joint prior)",
    "ikdp_panda": "the most precise Panda",
    "ikdp_panda_fast": "Panda: seed of the fastest CPU pipeline (+ DLS)",
    "ikdp_z1": "the Unitree Z1, trained from its URDF",
    "ikdp_g1": "the Unitree G1's two hands (waist and arms): a tree",
}


def shipped_dir() -> Path:
    """The folder holding the shipped checkpoints (it may not exist, e.g. in a sparse checkout)."""
    package = Path(__file__).resolve().parent
    in_wheel = package / "checkpoints"
    return in_wheel if in_wheel.is_dir() else package.parent / "checkpoints"


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
