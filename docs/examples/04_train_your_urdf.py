"""Bring your own arm: train a model from its URDF in minutes, then solve with it.

Training runs the command a user types, `python -m ikdp.train --urdf ARM.urdf --ee-link LINK --minutes M`
(data is drawn on the fly from the joint limits; nothing to download). Without `--urdf`, this uses the
UR5 of example-robot-data (`pip install "ikdp[robots]"`). After 2 minutes on one CPU the raw samples still
miss by centimetres and the refinement finishes the job; longer runs sample closer (docs/robots.md).

    python docs/examples/04_train_your_urdf.py --minutes 2 --output runs/ur5.pt
    python docs/examples/04_train_your_urdf.py --urdf my_arm.urdf --ee-link tool0 --minutes 8
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import torch
import tyro

import ikdp


def main(urdf: Path | None = None, ee_link: str = "tool0", minutes: float = 2.0, output: Path = Path("ur5.pt")) -> None:
    """Train on `urdf` (None: example-robot-data's UR5) for `minutes`, save to `output`, solve one target."""
    urdf = Path(ikdp.load_robot("ur5").urdf_path) if urdf is None else urdf
    command = [sys.executable, "-m", "ikdp.train", "--urdf", str(urdf), "--ee-link", ee_link]
    command += ["--minutes", str(minutes), "--output", str(output)]
    print("python", " ".join(command[1:]), flush=True)
    trained = subprocess.run(command)
    if trained.returncode:
        sys.exit(trained.returncode)  # the trainer said why, in one line

    solver = ikdp.load(output)
    arm = solver.arm
    target = arm.end_effector(arm.random_poses(1, generator=torch.Generator().manual_seed(0)))  # a reachable pose
    result = solver.solve(target, num_samples=16, refine_steps=5, generator=torch.Generator().manual_seed(1))
    reached = (result.tip_error[0] < arm.position_tolerance) & (result.rotation_error[0] < arm.rotation_tolerance)
    best = int(result.tip_error[0].argmin())
    print(f"{arm}: raw samples' median miss {result.raw_tip_error[0].median() * 1000:.1f} mm")
    print(
        f"after 5 refinement steps {int(reached.sum())} of 16 poses within 1 mm and 1 degree "
        f"(best {result.tip_error[0, best] * 1000:.3f} mm, {torch.rad2deg(result.rotation_error[0, best]):.3f} deg)"
    )


if __name__ == "__main__":
    tyro.cli(main)
