"""A batch of Panda targets solved on a GPU as one CUDA graph: `solver.capture`.

On a GPU one solve is thousands of tiny kernel launches; `solver.capture(batch, ...)` records the whole
solve (sampling and refinement) for that batch size once, and each call replays it from one launch.
Without CUDA this prints one line saying so and exits 0.

    python docs/examples/06_gpu_batch_capture.py --batch 1000
"""

from __future__ import annotations

import statistics
import time

import torch
import tyro

import ikdp


def median_ms(run, repeats: int = 10) -> float:
    """The median wall time of `run()` in milliseconds, waiting for the GPU to finish each one."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        run()
        torch.cuda.synchronize()
        times.append(1000 * (time.perf_counter() - started))
    return statistics.median(times)


def main(batch: int = 1000, num_samples: int = 16, seed: int = 0) -> None:
    """Solve `batch` reachable Panda poses, `num_samples` each: the eager solve against its captured replay."""
    if not torch.cuda.is_available():
        print("skipped: no CUDA device here (torch.cuda.is_available() is False); this example needs a GPU")
        return
    solver = ikdp.load("ikdp_panda", device="cuda")
    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(batch, generator=torch.Generator().manual_seed(seed))).cuda()
    options = dict(num_samples=num_samples, sampler="dpmpp2m", steps=10, refine_steps=5)
    captured = solver.capture(batch, **options)  # records once per batch size and options: a few seconds
    result = captured(targets, seed=seed)  # its tensors are overwritten by the next replay
    reached = (result.tip_error < arm.position_tolerance) & (result.rotation_error < arm.rotation_tolerance)
    print(f"captured: {int(reached.any(dim=1).sum())} of {batch} targets reached within 1 mm and 1 degree")

    eager = median_ms(lambda: solver.solve(targets, generator=torch.Generator("cuda").manual_seed(seed), **options))
    replay = median_ms(lambda: captured(targets, seed=seed))
    print(f"{torch.cuda.get_device_name()}: eager solve {eager:.1f} ms, captured replay {replay:.1f} ms per batch")


if __name__ == "__main__":
    tyro.cli(main)
