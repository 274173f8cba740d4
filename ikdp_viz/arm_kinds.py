"""The one place that branches on the kind of arm: planar (x, y) targets, or a robot's pose targets (a chain's one
hand, or a tree's several: one pose per end effector).

The session, the solve, the drawing loop and the recording ask `arm_kind(solver)` (the arm's
maths, texts, colours and legend: planar_kind.py, chain_kind.py's ChainKind and TreeKind) and `arm_view(...)`
(its scene nodes: planar_view.py, robot_view.py) instead of testing the arm's type.

A new kind of arm (its solver's `arm.kind` a new word) is one entry in `ARM_KINDS` and one branch in each
`*_class` function below; nothing outside this file asks which kind it is. Its kind object (plain maths and
texts, no viser) provides what PlanarKind and ChainKind both provide:

- attributes: `name`; `default_sampler` (sampler, steps); `opens_on_student`, `opens_with_trail` (how the
  viewer opens); `chart_error`, `chart_unit`, `chart_scale` (the error chart's y); `holds_text`, `violates_text`
  (the constraint colours' legend words); `partial_target_note` (the Constraints folder's line where no partial
  target is offered, or None);
- the target: `initial_target`, `clamp` (into the reach, and whether it moved), `gizmo_target` (the target a
  dragged gizmo asks for, the other hands' kept from the current one), `typed_numbers`,
  `write_typed_fields`, `target_text`, `target_words`;
- the panel and texts: `configure_panel`, `model_text`, `solve_text`;
- the picture: `drawable` (a solve's arrays to draw), `palette`, `arm_colors`, `light_trail_states`,
  `legend_entries` (one entry per colour drawn at the state shown), `flat_picture` (the exported PNG/GIF),
  `sample_path` (one sample's points at every state and their polylines, for the constraint overlay).

Its view class owns the scene nodes and draws a Frame (planar_view.PlanarView, robot_view.RobotView show the
methods: rebuild, update(frame), place_target, show_prior and clear_prior, remove_samples, extent); its compare class
draws a second sampler beside it.
tests/test_viz_frame.py runs the legend and frame checks over the kinds; add a new kind to their parameters.
"""

from __future__ import annotations

from ikdp_viz.chain_kind import ChainKind, TreeKind
from ikdp_viz.planar_kind import PlanarKind

ARM_KINDS = {"planar": PlanarKind(), "chain": ChainKind(), "tree": TreeKind()}


def arm_kind(solver) -> PlanarKind | ChainKind:
    """The viewer's handling of `solver.arm` (by its `kind`: "planar", "chain" or "tree")."""
    kind = getattr(solver.arm, "kind", "planar")
    if kind not in ARM_KINDS:
        raise ValueError(f"solver: the viewer draws arms of kind {tuple(ARM_KINDS)}, got {kind!r}")
    return ARM_KINDS[kind]


def arm_view(server, solver, target, gizmo_update):
    """The object that owns `solver`'s arm's scene nodes (its class imported here: the kinds need no viser)."""
    kind = arm_kind(solver)
    if kind.name == "planar":
        from ikdp_viz.planar_view import PlanarView

        return PlanarView(server, solver, target, gizmo_update)
    from ikdp_viz.robot_view import RobotView

    return RobotView(server, solver, target, gizmo_update, kind)


def compare_view_class(solver):
    """The class of the side view that shows a second sampler from the same noise: a second planar workspace, or
    a robot's skeletons beside it."""
    if arm_kind(solver).name == "planar":
        from ikdp_viz.compare_view import CompareNodes

        return CompareNodes
    from ikdp_viz.compare_view import RobotCompareNodes

    return RobotCompareNodes
