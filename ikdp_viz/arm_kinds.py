"""The one place that branches on the kind of arm: planar (x, y) targets, or a chain's pose targets.

The session, the solve, the drawing loop and the recording ask `arm_kind(solver)` (the arm's
maths, texts, colours and legend: planar_kind.py, chain_kind.py) and `arm_view_class(solver)`
(its scene nodes: planar_view.py, robot_view.py) instead of testing the arm's type.
"""

from __future__ import annotations

from ikdp_viz.chain_kind import ChainKind
from ikdp_viz.planar_kind import PlanarKind

ARM_KINDS = {"planar": PlanarKind(), "chain": ChainKind()}


def arm_kind(solver) -> PlanarKind | ChainKind:
    """The viewer's handling of `solver.arm` (by its `kind`: "planar" or "chain")."""
    kind = getattr(solver.arm, "kind", "planar")
    if kind not in ARM_KINDS:
        raise ValueError(f"solver: the viewer draws arms of kind {tuple(ARM_KINDS)}, got {kind!r}")
    return ARM_KINDS[kind]


def arm_view_class(solver):
    """The class whose object owns `solver`'s arm's scene nodes (imported here: the kinds need no viser)."""
    if arm_kind(solver).name == "planar":
        from ikdp_viz.planar_view import PlanarView

        return PlanarView
    from ikdp_viz.robot_view import RobotView

    return RobotView


def compare_view_class(solver):
    """The class of the side view that shows a second sampler from the same noise: a second planar workspace, or
    a robot's skeletons beside it."""
    if arm_kind(solver).name == "planar":
        from ikdp_viz.compare import CompareNodes

        return CompareNodes
    from ikdp_viz.compare import RobotCompareNodes

    return RobotCompareNodes
