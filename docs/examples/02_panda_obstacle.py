"""The Panda reaching a pose around a sphere that no link may touch.

`ikdp.Obstacles` guides every step of the reverse diffusion away from the sphere and the refinement
keeps it clear; `constraints_met` says which poses hold it. No retraining: the constraint acts at
sampling time only.

    python docs/examples/02_panda_obstacle.py --center 0.25 0.0 0.55 --radius 0.08
"""

from __future__ import annotations

import torch
import tyro

import ikdp


def main(
    target: tuple[float, float, float, float, float, float, float] = (0.5, 0.0, 0.4, 0.0, 1.0, 0.0, 0.0),
    center: tuple[float, float, float] = (0.25, 0.0, 0.55),
    radius: float = 0.08,
    num_samples: int = 16,
    seed: int = 0,
) -> None:
    """Solve `target` (x y z in metres, then a unit quaternion w x y z: here the hand pointing down)
    with a sphere of `radius` metres at `center` in the way."""
    solver = ikdp.load("ikdp_panda")
    obstacle = ikdp.Obstacles(centers=[center], radii=[radius])
    result = solver.solve(
        [target],
        num_samples=num_samples,
        sampler="dpmpp2m",
        steps=10,
        refine_steps=5,
        constraints=[obstacle],
        generator=torch.Generator().manual_seed(seed),
    )
    arm = solver.arm
    reached = (result.tip_error[0] < arm.position_tolerance) & (result.rotation_error[0] < arm.rotation_tolerance)
    clear = result.constraints_met[0]
    print(f"{int(reached.sum())} of {num_samples} poses reach the target within 1 mm and 1 degree")
    print(f"{int(clear.sum())} of {num_samples} poses clear the sphere")
    print(f"{int((reached & clear).sum())} of {num_samples} poses reach the target and clear the sphere")
    if (reached & clear).any():
        best = int(torch.where(reached & clear, result.tip_error[0], torch.inf).argmin())
        joints = ", ".join(f"{value:+.3f}" for value in result.angles[0, best].tolist())
        print(f"one of them (radians): [{joints}]")


if __name__ == "__main__":
    tyro.cli(main)
