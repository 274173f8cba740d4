"""Follow a circle with one continuous solution: `solver.track`.

Each target of the path is solved with a pull toward the pose before it, and of the samples that
reach it the nearest to that pose is kept, so the arm moves smoothly instead of jumping between
the many poses that reach each point.

    python docs/examples/03_track_path.py --points 40 --radius 0.8
"""

from __future__ import annotations

import math

import torch
import tyro

import ikdp


def main(center: tuple[float, float] = (1.5, 1.0), radius: float = 0.8, points: int = 40, seed: int = 0) -> None:
    """Track a circle of `radius` (bone lengths) around `center` with ikdp_n4, `points` targets once round."""
    solver = ikdp.load("ikdp_n4")
    angles = torch.linspace(0.0, 2 * math.pi, points + 1)[:-1]
    path = torch.stack([center[0] + radius * angles.cos(), center[1] + radius * angles.sin()], dim=-1)
    options = dict(num_samples=16, sampler="dpmpp2m", steps=10, refine_steps=5)
    generator = torch.Generator().manual_seed(seed)
    first = solver.solve(path[:1], generator=generator, **options)
    start = first.angles[0, first.tip_error[0].argmin()]  # the best pose at the first target
    track = solver.track(path, start, generator=generator, **options)

    for index, (error, jump) in enumerate(zip(track.position_error.tolist(), track.joint_jumps.tolist(), strict=True)):
        print(f"step {index:3d}: tip error {error:.1e}, largest joint step {jump:.3f} rad")
    reached = int(track.reached.sum())
    print(f"reached {reached} of {points} targets; largest joint step {track.largest_jump:.3f} rad")
    print(f"branch switches: {track.switch_indices or 'none'}")


if __name__ == "__main__":
    tyro.cli(main)
