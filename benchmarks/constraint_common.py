"""What the parts of benchmarks/constraints.py share: the command line, timing, the pose tolerance, a measured row,
PseudoInverseIK. A leaf: the parts import it, it imports none of them."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch

RESULTS = Path(__file__).resolve().parent / "results" / "constraints.json"


@dataclass(frozen=True)
class ConstraintBenchmarkConfig:
    checkpoint: str = "ikdp_panda"  # the Panda pose model
    planar_checkpoint: str = "ikdp_n4"  # the planar model of part 4
    targets: int = 1000  # Panda targets of parts 1 and 2 (a 2-core CPU: fewer when time is short)
    planar_targets: int = 1000  # planar targets of part 4
    samples: int = 16  # K
    refine_steps: int = 5  # DLS steps after sampling
    sampler: str = "dpmpp2m:10"  # name[:steps] of IKDP's sampler
    planar_sampler: str = "dpmpp2m:10"
    obstacle_extra_samplers: tuple[str, ...] = ("ddpm",)  # more guided IKDP rows in the obstacle part
    random_start_steps: tuple[int, ...] = (5, 10, 20)  # constrained DLS steps from 16 uniform random starts
    restart_steps: int = 20  # parts 1, 2 and 3: one more IKDP row with solve's restart_steps (0: no such row)
    certified_placement: bool = True  # obstacles: only sphere pairs that leave a certified free solution
    pk_retries: int = 16
    pk_iterations: int = 30
    track_circles: int = 5  # circles certified reachable all the way round: the ready pose, then random starts
    track_points: int = 200  # targets per circle
    track_radius: float = 0.1  # metres
    track_weight: float = 0.6  # NearPose's pull while tracking
    parts: tuple[str, ...] = ("obstacles", "locked", "tracking", "partial", "planar")
    seed: int = 0
    output: Path = field(default=RESULTS)


def timed(run):
    started = time.perf_counter()
    result = run()
    return time.perf_counter() - started, result


def within_pose_tolerance(arm, joints: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """joints (B, K, J) -> (B, K) within the arm's tolerances of the pose targets (B, 7), 1 mm and 1 degree on a
    robot (what `track().reached` means too), and within the joint limits."""
    goals = targets[:, None].expand(-1, joints.shape[1], -1)
    limits = arm.joint_limits
    inside = ((joints >= limits[:, 0]) & (joints <= limits[:, 1])).all(dim=-1)
    close = arm.position_error(joints, goals) < arm.position_tolerance
    return inside & close & (arm.rotation_error(joints, goals) < arm.rotation_tolerance)


def row(valid: torch.Tensor, seconds: float, **extra) -> dict:
    """valid (B, K) -> the measured row: share of targets solved, valid solutions per target, ms per target."""
    return {
        "success_share": float(valid.any(dim=1).double().mean()),
        "valid_per_target": float(valid.sum(dim=1).double().mean()),
        "ms_per_target": 1000 * seconds / len(valid),
        **extra,
    }


@functools.cache
def pk_chain(arm):
    import pytorch_kinematics as pk

    return pk, pk.build_serial_chain_from_urdf(Path(arm.urdf_path).read_bytes(), arm.ee_link)


def run_pseudo_inverse(arm, targets: torch.Tensor, starts: torch.Tensor, iterations: int) -> tuple[float, torch.Tensor]:
    """PseudoInverseIK from the same `starts` (R, J) for every pose target (B, 7) -> seconds, (B, R, J)."""
    pk, chain = pk_chain(arm)
    solver = pk.PseudoInverseIK(
        chain,
        retry_configs=starts,
        joint_limits=arm.joint_limits,
        max_iterations=iterations,
        pos_tolerance=arm.position_tolerance,
        rot_tolerance=arm.rotation_tolerance,
        early_stopping_any_converged=True,
    )
    goal = pk.Transform3d(pos=targets[:, :3], rot=targets[:, 3:])
    seconds, solution = timed(lambda: solver.solve(goal))
    return seconds, solution.solutions.detach().float()
