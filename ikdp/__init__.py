"""IKDP: inverse kinematics by a conditional diffusion model, for a planar N-link arm or a robot from a URDF."""

from ikdp.arm import PlanarArm
from ikdp.chain_arm import ChainArm
from ikdp.checkpoint import CheckpointError
from ikdp.constraints import (
    FreeAxis,
    LockedJoints,
    NearPose,
    Obstacles,
    PositionOnly,
    SelfCollision,
    constraint_names,
    make_constraint,
)
from ikdp.kinematics import (
    absolute_to_relative,
    forward_kinematics,
    relative_to_absolute,
    tip_jacobian,
    tip_position,
    wrap_angle,
)
from ikdp.robots import load_robot, robot_names
from ikdp.samplers import sampler_names
from ikdp.solver import Solver, SolveResult, load

__all__ = [
    "ChainArm",
    "CheckpointError",
    "FreeAxis",
    "LockedJoints",
    "NearPose",
    "Obstacles",
    "PositionOnly",
    "PlanarArm",
    "SelfCollision",
    "SolveResult",
    "Solver",
    "absolute_to_relative",
    "constraint_names",
    "forward_kinematics",
    "load",
    "load_robot",
    "make_constraint",
    "relative_to_absolute",
    "robot_names",
    "sampler_names",
    "tip_jacobian",
    "tip_position",
    "wrap_angle",
]
__version__ = "0.1.0"  # the one place the version is written; pyproject.toml reads it
