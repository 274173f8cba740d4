"""Solve one target for a planar 4-link arm and draw the K poses the model samples.

The diffusion model gives K different poses that all reach the target (the arm is redundant);
`refine_steps` polishes each one by damped least squares.

    python docs/examples/01_solve_planar.py --output planar_poses.png --target 1.5 2.0
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # write a file; no window needed
import matplotlib.pyplot as plt
import torch
import tyro

import ikdp


def main(
    output: Path = Path("planar_poses.png"),
    target: tuple[float, float] = (1.5, 2.0),
    num_samples: int = 16,
    seed: int = 0,
) -> None:
    """Solve `target` (x, y, in bone lengths) with ikdp_n4 and save a plot of its poses to `output`."""
    solver = ikdp.load("ikdp_n4")
    result = solver.solve(
        [target], num_samples=num_samples, refine_steps=5, generator=torch.Generator().manual_seed(seed)
    )
    errors = result.tip_error[0]
    print(f"{num_samples} poses, tip error median {errors.median():.2e}, largest {errors.max():.2e} (bone lengths)")

    points = solver.arm.forward_kinematics(result.angles[0])  # (K, links + 1, 2): base, joints, tip
    figure, axes = plt.subplots(figsize=(5, 5))
    for pose in points:
        axes.plot(pose[:, 0], pose[:, 1], "-o", markersize=3, alpha=0.6)
    axes.plot(*target, "kx", markersize=12, markeredgewidth=2, label="target")
    axes.add_patch(plt.Circle((0, 0), solver.reach[1], fill=False, linestyle=":", color="gray"))
    axes.set_aspect("equal")
    axes.set_title(f"ikdp_n4: {num_samples} poses reaching {target}")
    axes.legend(loc="lower left")
    figure.savefig(output, dpi=100)
    print(f"wrote {output}")


if __name__ == "__main__":
    tyro.cli(main)
