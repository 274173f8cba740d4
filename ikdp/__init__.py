"""IKDP: inverse kinematics of a planar N-link arm by a conditional diffusion model."""

from ikdp.checkpoint import CheckpointError
from ikdp.kinematics import (
    absolute_to_relative,
    forward_kinematics,
    relative_to_absolute,
    tip_jacobian,
    tip_position,
    wrap_angle,
)
from ikdp.solver import Solver, SolveResult, load

__all__ = [
    "CheckpointError",
    "SolveResult",
    "Solver",
    "absolute_to_relative",
    "forward_kinematics",
    "load",
    "relative_to_absolute",
    "tip_jacobian",
    "tip_position",
    "wrap_angle",
]
__version__ = "0.1.0"  # the one place the version is written; pyproject.toml reads it
