"""What the parts of benchmarks/constraints.py share: timing, the pose tolerance, a measured row, PseudoInverseIK."""

from __future__ import annotations

import functools
import time
from pathlib import Path

import torch


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
