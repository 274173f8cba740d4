"""The planar arm's scene nodes, drawn from a `Frame` (frame.py) by one method, `update`.

Owns the workspace (grid, boundary circles, base), the target's gizmo and red cross, and the
K arms of the state shown: the trail, links, joints, tips, x̂0, the refined poses and the
prior's draw. Only the drawing loop (scene_writer.py) calls it. What to draw is `planar_scene.py`'s
(plain numpy); this file copies those arrays into viser handles.
"""

from __future__ import annotations

import numpy as np
import viser

from ikdp_viz import robot_meshes
from ikdp_viz.camera import Extent, camera_fit, over_the_point
from ikdp_viz.frame import Frame
from ikdp_viz.planar_scene import (
    ARM_LIFT,
    HIGHLIGHT_LIFT,
    REFINED_LIFT,
    TARGET_LIFT,
    arm_placement,
    circle_segments,
    estimate_rows,
    follows_one,
    grid_segments,
    line_colors,
    polyline_segments,
    trail_rows,
    trail_until,
)
from ikdp_viz.style import (
    ARM_PIXELS,
    BASE,
    ESTIMATE,
    GRID_SECTION,
    LINE_PIXELS,
    REACH_RING,
    REFINED,
    TARGET_RED,
    prior_lines,
    removed,
    start_rebuild,
)

SAMPLE_NODES = ("trail", "estimate_lines", "refined_lines", "refined_tips", "links", "followed_links", "joints", "tips")
OTHER_PIXELS = 2.0  # the other samples' links while one is followed: thin and light, as the paper's figure draws them


class PlanarView:
    """A planar arm's nodes: the static workspace and target, the K arms of the frame shown."""

    def __init__(self, server: viser.ViserServer, solver, target: np.ndarray, gizmo_update):
        self.server, self._gizmo_update = server, gizmo_update
        self.trail = self.links = self.followed_links = self.joints = self.tips = None
        self.refined_lines = self.refined_tips = self.estimate_lines = self.prior_lines = None
        self.nodes_shape: tuple[int, int] | None = None  # (K, N) of the arm nodes
        self._joint_scales_key: tuple | None = None  # what the joints' scales were written for
        self._refined_of = None  # the solve whose refined poses the refined nodes hold
        self._static_nodes: list = []
        self.rebuild(solver, target)

    # -------------------------------------------------------------- the workspace and the target

    def rebuild(self, solver, target: np.ndarray) -> None:
        """Grid, workspace boundary, base and the target's gizmo and cross, sized to `solver`'s arm."""
        start_rebuild(self, solver, target)
        scene = self.server.scene
        lengths = solver.lengths
        self.sizes = robot_meshes.ArmSizes.for_lengths(lengths)
        inner, outer = solver.reach
        self.reach = float(outer)
        unit = float(np.mean(lengths))
        self.unit, self.grid_half_width = unit, float(np.ceil((outer + unit) / unit)) * unit
        nodes = [self._grid(self.grid_half_width)]
        for name, radius in (("outer", outer), ("inner", inner)):
            if radius > 0:
                nodes.append(
                    scene.add_line_segments(
                        f"/workspace/{name}",
                        circle_segments(radius, 96, z=-0.01 * unit),  # 96 look round; each costs the page
                        colors=REACH_RING,
                        thickness=LINE_PIXELS,
                        thickness_units="screen",
                    )  # fmt: skip
                )
        base = robot_meshes.base_mesh(self.sizes.base)
        nodes.append(
            scene.add_mesh_simple(
                "/base", base.vertices, base.faces, color=BASE, cast_shadow=False, receive_shadow=False
            )
        )
        # The page's control (drei's PivotControls) limits the sum of the drags since it was drawn, not the
        # position: limits of +-reach would be +-reach around the first target. So the limits are the reach
        # around the base less where the control was first drawn and every move of the server's that stuck
        # (`_translation_limits`); the corners of that square beyond the circle are clamped and said so.
        self._drag_origin = np.array([float(self.target[0]), float(self.target[1])])
        self._dragging = False  # a move the server makes mid-drag is overwritten by the page's next pointer move
        self.gizmo = scene.add_transform_controls(
            "/target", scale=0.7 * unit, active_axes=(True, True, False), disable_rotations=True,
            translation_limits=self._translation_limits(), depth_test=False,
            position=(float(self.target[0]), float(self.target[1]), 0.0),
        )  # fmt: skip
        self.gizmo.on_update(self._track_drag)  # first: viser awaits async callbacks in the order given
        self.gizmo.on_update(self._gizmo_update)
        cross = robot_meshes.cross_mesh(self.sizes.cross)
        self.cross = scene.add_mesh_simple(
            "/target_cross", cross.vertices, cross.faces, color=TARGET_RED, cast_shadow=False, receive_shadow=False,
            position=self.cross_position(camera_fit(self.reach)[0]),
        )  # fmt: skip
        self._static_nodes = [*nodes, self.gizmo, self.cross]

    def _grid(self, half_width: float):
        return grid_under(self.server.scene, "/grid", half_width, self.unit)

    def extent(self) -> Extent:
        """The part of the plane this view draws in: the workspace disc (the grid around it is background)."""
        return Extent.disc(self.reach)

    def camera(self):
        """None: a planar view is framed from above over the extents shown (camera.camera_over)."""
        return None

    def place_target(self, target: np.ndarray, *, move_gizmo: bool, force: bool, camera_position) -> None:
        self.target = np.asarray(target, dtype=np.float64)
        if move_gizmo:
            # viser skips a position equal to its copy, but while a drag goes past the boundary the page's
            # gizmo follows the pointer beyond the clamped point the server holds: on release, send it again.
            position = np.array([float(target[0]), float(target[1]), 0.0])
            if not self._dragging:
                self._drag_origin += position[:2] - np.asarray(self.gizmo.position, dtype=np.float64)[:2]
            if force:
                self.gizmo.position = position + (1e-3, 0.0, 0.0)
            self.gizmo.position = position
            self.gizmo.translation_limits = self._translation_limits()
        # the cross is no child of the gizmo: during a drag past the boundary it stays on the clamped point
        self.aim_cross(camera_position)

    async def _track_drag(self, event: viser.TransformControlsEvent) -> None:
        self._dragging = event.phase != "end"

    def _translation_limits(self) -> tuple:
        """The page control's limits on its summed drags that keep the target in the square of the reach about
        the base: the drags start from `_drag_origin`, where it was drawn plus the server's moves since."""
        (x, y), outer = self._drag_origin, self.reach
        return ((-outer - x, outer - x), (-outer - y, outer - y), (0.0, 0.0))

    def aim_cross(self, camera_position) -> None:
        """Put the cross where the camera at `camera_position` sees it on the target (viser skips an equal one)."""
        self.cross.position = self.cross_position(camera_position)

    def cross_position(self, camera_position) -> np.ndarray:
        """Over everything (lifted) yet drawn on the target, as the initial camera sees it."""
        return over_the_point(self.target, TARGET_LIFT * self.sizes.joint, camera_position)

    def hide_target_controls(self) -> None:
        """A recording: the gizmo cannot be dragged there, the cross alone marks the target; the grid
        reaches past the sides of a page without a panel (a narrower one ended in a visible rectangle)."""
        self.gizmo.visible = False
        self._static_nodes[0].remove()
        self._static_nodes[0] = self._grid(float(np.ceil(2.5 * self.reach / self.unit)) * self.unit)

    # -------------------------------------------------------------- one frame

    def update(self, frame: Frame) -> None:
        """Write the frame: the trail up to its state, the arms (and x̂0) at its state, the refined poses at the end."""
        solved, state, highlight, palette = frame.solved, frame.state, frame.highlight, frame.palette
        view = solved.view
        self._ensure_nodes(view.num_samples, view.num_links)
        if self._refined_of is not solved:
            self._write_refined(view)
            self._refined_of = solved
        trail_of = frame.settings.trail_of
        num_samples, num_links = view.num_samples, view.num_links
        joint = self.sizes.joint
        placement = arm_placement(view.joints[state], height=ARM_LIFT * joint, raised=highlight,
                                  lift=HIGHLIGHT_LIFT * joint)  # fmt: skip
        colors = palette.arms[state]  # (K, 3)
        if frame.settings.show_trail:
            rows = trail_rows(num_samples, num_links, highlight, trail_of)
            points, segment_colors = trail_until(
                solved.trail_points[:, rows], palette.trail[:, rows], state, most_states=frame.trail_states
            )
            self.trail.points, self.trail.colors = points, segment_colors
        self.trail.visible = frame.settings.show_trail
        estimate = view.estimate_at(state) if frame.settings.show_estimate else None
        if estimate is not None:
            estimate = estimate[estimate_rows(num_samples, highlight, trail_of)]
            self.estimate_lines.points = polyline_segments(estimate, z=0.5 * REFINED_LIFT * joint)
        self.estimate_lines.visible = estimate is not None
        self.links.points = placement.link_segments
        link_colors = line_colors(np.repeat(colors, num_links, axis=0))[:, None]  # as dark as the joints
        self.links.colors = np.broadcast_to(link_colors, (num_samples * num_links, 2, 3))
        follows = follows_one(trail_of)
        self.links.thickness = OTHER_PIXELS if follows else ARM_PIXELS
        if follows:  # the followed arm in full width over the thin others
            rows = slice(highlight * num_links, (highlight + 1) * num_links)
            self.followed_links.points = placement.link_segments[rows]
            self.followed_links.colors = np.broadcast_to(link_colors[rows], (num_links, 2, 3))
        self.followed_links.visible = follows
        self.joints.batched_positions = placement.joint_positions
        joint_colors = colors
        if follows_one(trail_of):  # only the followed sample's joints show, in one colour: a constant array,
            joint_colors = np.broadcast_to(colors[highlight], colors.shape)  # which viser does not send again
        self.joints.batched_colors = np.repeat(joint_colors, num_links + 1, axis=0)
        self._write_joint_scales(num_samples, num_links, highlight, follows_one(trail_of))
        self.tips.batched_positions = placement.tip_positions
        if follows_one(trail_of):  # the other samples' tips too would cover the picture with K dots
            self.tips.batched_scales = (np.arange(num_samples) == highlight).astype(np.float32)
        else:
            self.tips.batched_scales = np.ones(num_samples, np.float32)
        self.tips.batched_colors = np.broadcast_to(palette.tips[state], (num_samples, 3))
        for node in (self.links, self.joints, self.tips):
            node.visible = True
        final_shown = frame.final and view.refined
        self.refined_lines.visible = final_shown
        self.refined_tips.visible = final_shown

    def _write_joint_scales(self, num_samples: int, num_links: int, highlight: int, follows: bool) -> None:
        """Following one sample, only its joints are drawn (the others are light lines): fewer spheres for the page
        to draw in every frame (docs/viewer.md); written only when the followed sample or the setting changes."""
        key = (num_samples, num_links, highlight, follows)
        if key == self._joint_scales_key:
            return
        per_sample = np.ones(num_samples, np.float32)
        if follows:
            per_sample[:] = 0.0
            per_sample[highlight] = 1.0
        self.joints.batched_scales = np.repeat(per_sample, num_links + 1)
        self._joint_scales_key = key

    def _write_refined(self, view) -> None:
        lift = REFINED_LIFT * self.sizes.joint  # above the other arms, under the highlighted one
        self.refined_lines.points = polyline_segments(view.final_joints, z=lift)
        self.refined_lines.colors = np.broadcast_to(
            np.array(REFINED, np.uint8), (view.num_samples * view.num_links, 2, 3)
        )
        tips = np.concatenate((view.final_joints[:, -1], np.full((view.num_samples, 1), lift)), axis=-1)
        self.refined_tips.batched_positions = tips

    def show_prior(self, joints: np.ndarray) -> None:
        """K poses from the model's prior, (K, N+1, 2), in brown until the next solve."""
        segments = polyline_segments(joints, z=0.5 * REFINED_LIFT * self.sizes.joint)
        self.prior_lines = prior_lines(self.server, segments, self.prior_lines)

    def clear_prior(self) -> None:
        self.prior_lines = removed(self.prior_lines)

    # -------------------------------------------------------------- nodes

    def _ensure_nodes(self, num_samples: int, num_links: int) -> None:
        """(Re)create the arm's nodes when K or N changed: a batched node keeps its instance count."""
        if (num_samples, num_links) == self.nodes_shape:
            return
        self.remove_samples()
        scene = self.server.scene
        links, joints = num_samples * num_links, num_samples * (num_links + 1)
        lines = dict(thickness_units="screen", visible=False)
        # the joints and tips as instanced spheres: viser's point clouds, tried first, cost the page
        # more per update than 80 small spheres (K = 1 animated at 7 frames/s with them, 14 without)
        spheres = dict(lod="off", cast_shadow=False, receive_shadow=False, visible=False)
        identity = lambda count: np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))  # noqa: E731
        origin = lambda count: np.zeros((count, 3))  # noqa: E731
        joint, tip = robot_meshes.sphere_mesh(self.sizes.joint), robot_meshes.sphere_mesh(self.sizes.tip)
        self.trail = scene.add_line_segments(
            "/arm/trail", np.zeros((1, 2, 3)), colors=(255, 255, 255), thickness=LINE_PIXELS, **lines
        )
        self.estimate_lines = scene.add_line_segments(
            "/arm/estimate", np.zeros((1, 2, 3)), colors=ESTIMATE, thickness=2 * LINE_PIXELS, **lines
        )
        self.refined_lines = scene.add_line_segments(
            "/arm/refined", np.zeros((1, 2, 3)), colors=REFINED, thickness=3 * LINE_PIXELS, **lines
        )
        self.refined_tips = scene.add_batched_meshes_simple(
            "/arm/refined_tips", tip.vertices, tip.faces, identity(num_samples), origin(num_samples),
            batched_colors=np.broadcast_to(np.array(REFINED, np.uint8), (num_samples, 3)), **spheres,
        )  # fmt: skip
        self.links = scene.add_line_segments(
            "/arm/links", np.zeros((links, 2, 3)), colors=np.zeros((links, 2, 3), np.uint8), thickness=ARM_PIXELS,
            **lines,
        )  # fmt: skip
        self.followed_links = scene.add_line_segments(
            "/arm/followed_links", np.zeros((num_links, 2, 3)), colors=np.zeros((num_links, 2, 3), np.uint8),
            thickness=ARM_PIXELS, **lines,
        )  # fmt: skip
        self.joints = scene.add_batched_meshes_simple(
            "/arm/joints", joint.vertices, joint.faces, identity(joints), origin(joints),
            batched_colors=np.zeros((joints, 3), np.uint8), **spheres,
        )  # fmt: skip
        self.tips = scene.add_batched_meshes_simple(
            "/arm/tips", tip.vertices, tip.faces, identity(num_samples), origin(num_samples),
            batched_colors=np.zeros((num_samples, 3), np.uint8), **spheres,
        )  # fmt: skip
        self.nodes_shape = (num_samples, num_links)
        self._joint_scales_key = self._refined_of = None  # new nodes: all their joints drawn, no refined poses

    def remove_samples(self) -> None:
        """Remove the nodes of the samples (not the workspace, the target or the prior's draw)."""
        for name in SAMPLE_NODES:
            handle = getattr(self, name, None)
            if handle is not None:
                handle.remove()
                setattr(self, name, None)
        self.nodes_shape = self._refined_of = None


def grid_under(scene, name: str, half_width: float, unit: float, x: float = 0.0):
    """The ground grid out to `half_width` about (x, 0): a line every bone length."""
    # software WebGL pays for every row a line crosses: lines every half bone length cost every frame more
    # (benchmarks/viz_frame_costs.py, "half-length grid"), and the quarter-length grid's as much as the 16 arms
    grid, _ = grid_segments(half_width, unit, unit, z=-0.02 * unit)
    return scene.add_line_segments(name, grid + np.array([x, 0.0, 0.0], dtype=grid.dtype), colors=GRID_SECTION,
                                   thickness=1.0, thickness_units="screen")  # fmt: skip
