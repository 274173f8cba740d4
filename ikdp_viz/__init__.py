"""ikdp_viz: the interactive browser viewer of IKDP's reverse diffusion (viser).

    python -m ikdp_viz --ckpt checkpoints/ikdp_n4.pt      # or: ikdp-viz

`scene` turns a solve into drawable arrays and never imports viser; `app` is the
viser layer; `__main__` the command line. Importing the package does nothing.
"""

from pathlib import Path

DEFAULT_CHECKPOINT_DIR = Path(__file__).resolve().parent.parent / "checkpoints"  # the repo's shipped models
DEFAULT_CHECKPOINT = DEFAULT_CHECKPOINT_DIR / "ikdp_n4.pt"

__all__ = ["DEFAULT_CHECKPOINT", "DEFAULT_CHECKPOINT_DIR"]
