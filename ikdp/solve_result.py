"""What every way of solving shares: the result it returns, and the check of a count among its options.

A leaf: ikdp/solver.py (the eager solve) and ikdp/cuda_graph.py (the same solve captured as a CUDA graph,
which the solver builds when asked) both import it and it imports neither, so neither imports the other back.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class SolveResult:
    angles: torch.Tensor  # (B, K, J) joint values (planar: absolute link headings in (-pi, pi]); refined if asked
    tip_error: torch.Tensor  # (B, K) distance from the end effector of `angles` to the target (arm's length unit)
    trajectory: torch.Tensor | None  # (S+1, B, K, J) raw sampler states from noise to final, when asked
    timesteps: list[int]  # the S diffusion timesteps of the sampler, noisiest first
    reachable: torch.Tensor | None  # (B,) False where the target lies outside the arm's reach; None if unknown
    raw_angles: torch.Tensor  # (B, K, J) the sampler's output before refinement
    raw_tip_error: torch.Tensor  # (B, K) tip error of `raw_angles`
    estimates: torch.Tensor | None = None  # (S, B, K, J) the denoiser's x̂0 at each step, when asked
    stopped: bool = False  # True when the callback stopped the solve; the poses are the state reached then
    rotation_error: torch.Tensor | None = None  # (B, K) radians, for pose targets (free axis: the axis's miss)
    constraint_violation: torch.Tensor | None = None  # (B, K) summed violation of `angles`, 0 where all hold
    network_evaluations: int = 0  # denoiser calls each sample went through, one after another (the refinement: none)
    restarted: torch.Tensor | None = None  # (B,) True where a target, unreached, restarted from random starts
    # several end effectors (a tree): each one's errors, (B, K, E), of which tip_error and rotation_error are the worst;
    # NaN where a partial target did not ask that part (a free hand's position, a position-only hand's rotation)
    tip_error_by_effector: torch.Tensor | None = None
    rotation_error_by_effector: torch.Tensor | None = None

    @property
    def constraints_met(self) -> torch.Tensor | None:
        """(B, K) True where every constraint holds (locked joints exactly, no link inside an obstacle)."""
        return None if self.constraint_violation is None else self.constraint_violation == 0

    @property
    def position_error(self) -> torch.Tensor:
        """(B, K) the end effector's distance to the target position (= tip_error)."""
        return self.tip_error


def is_integer(value) -> bool:
    """An int, and not a bool (True is an int to Python, never a count to a caller)."""
    return isinstance(value, int) and not isinstance(value, bool)
