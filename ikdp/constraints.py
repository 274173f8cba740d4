"""Constraints at sampling time, without retraining: one small registry, like the samplers'.

    solver.solve(targets, constraints=[ikdp.LockedJoints({"panda_joint1": 0.3}), ikdp.Obstacles(centers, radii)])

Kinds: locked joints and a pose to stay near (ikdp/joint_constraints.py), obstacles
(ikdp/obstacles.py), partial targets for pose models: position only, or rotation free about
an axis (ikdp/partial_targets.py; a tree's per end effector), a tree's self-collision
(ikdp/self_collision.py, on by default where its links can meet). Each is guided during the
reverse process or inpainted, kept by the refinement, and checked (ikdp/guidance.py runs them).
"""

from __future__ import annotations

from ikdp.constraint_base import Constraint
from ikdp.joint_constraints import LockedJoints, NearPose
from ikdp.obstacles import Obstacles
from ikdp.partial_targets import FreeAxis, PositionOnly
from ikdp.self_collision import SelfCollision

CONSTRAINTS: dict[str, type[Constraint]] = {
    cls.name: cls for cls in (LockedJoints, NearPose, Obstacles, PositionOnly, FreeAxis, SelfCollision)
}


def constraint_names() -> tuple[str, ...]:
    return tuple(CONSTRAINTS)


def make_constraint(name: str, **options) -> Constraint:
    """The constraint called `name` built from its options; ValueError naming the choices otherwise."""
    if name not in CONSTRAINTS:
        raise ValueError(f"constraint: expected one of {constraint_names()}, got {name!r}")
    return CONSTRAINTS[name](**options)
