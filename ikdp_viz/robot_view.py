"""A robot's scene nodes (a chain from a URDF), drawn from a `Frame` (frame.py) by one method, `update`.

For K samples at one state it draws:
- the K robots' meshes (the URDF's collision meshes): the highlighted sample opaque, one
  node per mesh; the others translucent ghosts with light hulls of the meshes, one batched
  node per mesh with K instances (the highlighted one scaled to nothing: a translucent
  instance drawn before an opaque one in the same node hides it). While an animation plays,
  the ghosts are hidden and the skeletons stand in for them: software WebGL animated K = 16
  at 6 frames/s with them, 15 without (docs/viewer.md); a pause, the last state and the slider
  show them;
- the K skeletons (joint origins to the hand) as one line-segment node, and as the trail the
  path of each hand through the states before, as another;
- the highlighted sample's hand frame, and the target as a 6-DoF gizmo that sets the pose; a robot of
  several end effectors (a tree) has one hand frame and one labelled gizmo per end effector, its
  skeletons one polyline per chain and its trail one path per hand.
Every part of one frame is drawn from the same state: otherwise the skeletons could show the
returned, refined pose at the end while the meshes did not, or the other way round.
"""

from __future__ import annotations

import numpy as np
import viser

from ikdp_viz.camera import camera_fit_3d
from ikdp_viz.chain_kind import VIOLATING_GHOST_OPACITY, ghost_opacities
from ikdp_viz.chain_scene import mesh_poses, skeleton_segments
from ikdp_viz.frame import Frame
from ikdp_viz.planar_scene import estimate_rows, grid_segments, trail_rows, trail_until
from ikdp_viz.robot_meshes import light_mesh, robot_meshes
from ikdp_viz.style import ESTIMATE, GRID_CELL, GRID_SECTION, LINE_PIXELS, REFINED, prior_lines, removed, start_rebuild

SKELETON_PIXELS = 2.5  # the current state's skeletons, over the thinner trail
HAND_AXES = 0.08  # hand frame's axes, in reach radii


def grid_cell(reach: float) -> float:
    """The first round spacing (1, 2 or 5 times a power of ten) at least a tenth of the reach: 0.1 m for the Panda."""
    tenth = reach / 10
    power = 10 ** np.floor(np.log10(tenth))
    return float(next(step * power for step in (1, 2, 5, 10) if step * power >= tenth * (1 - 1e-9)))


class RobotView:
    """A robot's nodes: the floor grid and the target's gizmo, the K robots, skeletons and hand of the frame shown."""

    def __init__(self, server: viser.ViserServer, solver, target: np.ndarray, gizmo_update, kind):
        """`kind`: the arm kind (chain_kind.ChainKind or TreeKind) whose hands, polylines and meshes it draws; the
        same for every model this view rebuilds for (a viewer keeps its kind of arm)."""
        self.server, self._gizmo_update, self.kind = server, gizmo_update, kind
        self.ghosts: list = []  # one batched mesh node per robot mesh, K instances
        self.robot: list = []  # the highlighted sample: one opaque mesh node per robot mesh
        self.trail = self.skeletons = self.estimate_lines = self.refined_lines = None
        self.hands: list = []  # the highlighted sample's hand frames, one per end effector
        self.prior_lines = None
        self.nodes_shape: tuple[int, int] | None = None
        self._refined_of = None
        self._static_nodes: list = []
        self.rebuild(solver, target)

    # -------------------------------------------------------------- the floor and the target

    def rebuild(self, solver, target: np.ndarray) -> None:
        """Floor grid, the target's 6-DoF gizmo at the target pose, the robot's meshes read once."""
        start_rebuild(self, solver, target)
        scene = self.server.scene
        arm = solver.arm
        kind = self.kind
        self.polylines = kind.polylines(arm)
        self.robot_meshes = robot_meshes(arm, chains=kind.mesh_chains(arm))
        self.mesh_links = np.array([mesh.link_index for mesh in self.robot_meshes], dtype=np.int64)
        self.mesh_offsets = np.array([mesh.offset for mesh in self.robot_meshes]).reshape(-1, 4, 4)
        self.center, self.reach = kind.reach_center(arm), float(arm.reach[1])
        cell = grid_cell(self.reach)
        extent = 2 * cell * np.ceil(1.2 * self.reach / cell)
        scene.set_up_direction("+z")
        # Line segments, not viser's shader grid: that alone took headless chromium from 40 to 2 frames/s.
        segments, sections = grid_segments(extent / 2, cell, 5 * cell)
        grid_colors = np.where(sections[:, None, None], GRID_SECTION, GRID_CELL).astype(np.uint8)
        grid = scene.add_line_segments(
            "/grid", segments, colors=np.broadcast_to(grid_colors, segments.shape).copy(), thickness=1.0,
            thickness_units="screen", position=(self.center[0], self.center[1], 0.0),
        )  # fmt: skip
        names, rows = kind.effector_names(arm), kind.pose_rows(arm, self.target)
        self.gizmos, self._static_nodes = [], [grid]
        for name, node_name, pose in zip(names, kind.gizmo_names(arm), rows, strict=True):
            wxyz = pose[3:7] if len(pose) == 7 else (1.0, 0.0, 0.0, 0.0)
            gizmo = scene.add_transform_controls(
                node_name, scale=0.25 * self.reach / np.sqrt(len(names)), depth_test=False,
                disable_rotations=len(pose) != 7, position=tuple(pose[:3]), wxyz=tuple(wxyz),
            )  # fmt: skip
            gizmo.on_update(self._gizmo_update)
            self.gizmos.append(gizmo)
            if len(names) > 1:  # which hand each gizmo sets, written beside it
                self._static_nodes.append(scene.add_label(f"{node_name}/name", name, position=(0.0, 0.0, 0.02)))
        self.gizmo = self.gizmos[0]  # the one gizmo of a chain (the Constraints folder's target kind sets its rings)
        self._static_nodes += self.gizmos

    @property
    def hand(self):
        """The first end effector's hand frame (a chain's one)."""
        return self.hands[0] if self.hands else None

    def extent(self):
        """None: a 3-D view has no side views on its ground plane; it has a camera of its own (`camera`)."""
        return None

    def camera(self):
        return camera_fit_3d(self.center, self.reach)

    def place_target(self, target: np.ndarray, *, move_gizmo: bool, force: bool, camera_position=None) -> None:
        self.target = np.asarray(target, dtype=np.float64)
        if not move_gizmo:
            return
        for gizmo, pose in zip(self.gizmos, self.kind.pose_rows(self.solver.arm, self.target), strict=True):
            position = pose[:3]
            if len(pose) == 7:
                gizmo.wxyz = pose[3:7]
            if force:  # as the planar view: the page's gizmo may be past the clamped point
                gizmo.position = position + (1e-3, 0.0, 0.0)
            gizmo.position = position

    def aim_cross(self, camera_position) -> None:
        """No cross: the gizmo is the target."""

    def hide_target_controls(self) -> None:
        """A recording: the gizmo's rings and arrows go, a frame marks the target pose instead."""
        rows = self.kind.pose_rows(self.solver.arm, self.target)
        for number, (gizmo, pose) in enumerate(zip(self.gizmos, rows, strict=True)):
            gizmo.visible = False
            wxyz = pose[3:7] if len(pose) == 7 else (1.0, 0.0, 0.0, 0.0)
            self._static_nodes.append(
                self.server.scene.add_frame(
                    "/target_frame" if number == 0 else f"/target_frame_{number}",
                    axes_length=0.1 * self.reach,
                    axes_radius=0.006 * self.reach,
                    position=tuple(float(value) for value in pose[:3]),
                    wxyz=tuple(float(value) for value in wxyz),
                )  # fmt: skip
            )

    # -------------------------------------------------------------- one frame

    def update(self, frame: Frame) -> None:
        """The 3-D frame: the trail before its state, the K skeletons and robots at its state, the hand."""
        solved, state, highlight, palette = frame.solved, frame.state, frame.highlight, frame.palette
        view = solved.view
        self._ensure_nodes(view.num_samples, view.num_joints)
        if self._refined_of is not solved:
            self._write_refined(view)
            self._refined_of = solved
        arm = self.solver.arm
        poses = view.joint_values[state]  # (K, J): the state shown, for the meshes and the skeletons alike
        points = view.points[state]  # (K, J+1, 3) their joint origins
        mesh_positions, mesh_wxyzs = mesh_poses(arm, poses, self.mesh_links, self.mesh_offsets)  # (K, M, 3|4)
        scales = np.ones(view.num_samples)
        scales[highlight] = 0.0  # drawn opaque by its own nodes
        colors = palette.ghosts[state]  # (K, 3)
        hand_positions, hand_wxyzs = self.kind.hand_poses(arm, poses[highlight])  # (E, 3), (E, 4)
        trail_of = frame.settings.trail_of
        shown = frame.settings.show_trail and state > 0
        if shown:
            rows = trail_rows(view.num_samples, view.num_effectors, highlight, trail_of)
            trail_points, segment_colors = trail_until(
                solved.trail_points[:, rows], palette.trail[:, rows], state, most_states=frame.trail_states
            )
            self.trail.points, self.trail.colors = trail_points, segment_colors
        self.trail.visible = shown
        self.skeletons.points = skeleton_segments(points, view.polylines).astype(np.float32)
        self.skeletons.colors = palette.skeletons[state]
        self.skeletons.visible = True
        estimate = view.estimate_at(state) if frame.settings.show_estimate else None
        if estimate is not None:
            self.estimate_lines.points = skeleton_segments(
                estimate[estimate_rows(view.num_samples, highlight, trail_of)], view.polylines
            )
        self.estimate_lines.visible = estimate is not None
        ghosts_shown = not frame.light  # the skeletons stand in while it plays
        for index, node in enumerate(self.ghosts):
            if ghosts_shown:
                node.batched_positions = mesh_positions[:, index]
                node.batched_wxyzs = mesh_wxyzs[:, index]
                node.batched_colors = colors
                node.batched_scales = scales
                node.batched_opacities = palette.ghost_opacities[state]
            node.visible = ghosts_shown
        for index, node in enumerate(self.robot):
            node.position, node.wxyz = mesh_positions[highlight, index], mesh_wxyzs[highlight, index]
            node.color = tuple(int(channel) for channel in colors[highlight])
            node.visible = True
        for hand, position, wxyz in zip(self.hands, hand_positions, hand_wxyzs, strict=True):
            hand.position, hand.wxyz, hand.visible = position, wxyz, True
        self.refined_lines.visible = frame.final and view.refined

    def _write_refined(self, view) -> None:
        self.refined_lines.points = skeleton_segments(view.final_points, view.polylines)
        count = view.num_samples * view.num_segments
        self.refined_lines.colors = np.broadcast_to(np.array(REFINED, np.uint8), (count, 2, 3))

    def show_prior(self, joints: np.ndarray) -> None:
        """Poses from the prior as brown skeletons; `joints` (K, J+1, 3) are their joint origins and hands."""
        self.prior_lines = prior_lines(self.server, skeleton_segments(joints, self.polylines), self.prior_lines)

    def clear_prior(self) -> None:
        self.prior_lines = removed(self.prior_lines)

    # -------------------------------------------------------------- nodes

    def _ensure_nodes(self, num_samples: int, num_joints: int) -> None:
        """(Re)create the sample nodes when K or J changed: a batched node keeps its instance count."""
        if (num_samples, num_joints) == self.nodes_shape:
            return
        self.remove_samples()
        scene = self.server.scene
        lines = dict(thickness_units="screen", visible=False)
        empty = np.zeros((1, 2, 3))
        self.trail = scene.add_line_segments("/samples/trail", empty, colors=(255, 255, 255), thickness=LINE_PIXELS,
                                             **lines)  # fmt: skip
        self.skeletons = scene.add_line_segments(
            "/samples/skeletons", empty, colors=(0, 0, 0), thickness=SKELETON_PIXELS, **lines
        )
        self.estimate_lines = scene.add_line_segments(
            "/samples/estimate", empty, colors=ESTIMATE, thickness=2 * LINE_PIXELS, **lines
        )
        self.refined_lines = scene.add_line_segments(
            "/samples/refined", empty, colors=REFINED, thickness=2 * LINE_PIXELS, **lines
        )
        identity = np.tile([1.0, 0.0, 0.0, 0.0], (num_samples, 1))
        self.ghosts = [
            scene.add_batched_meshes_simple(
                f"/samples/robot/{mesh.name}",
                *light_mesh(mesh.vertices),
                identity,
                np.zeros((num_samples, 3)),
                batched_colors=np.zeros((num_samples, 3), np.uint8),
                batched_scales=np.ones(num_samples),
                batched_opacities=ghost_opacities(np.ones(num_samples, bool)),
                opacity=VIOLATING_GHOST_OPACITY,
                lod="off",
                cast_shadow=False,
                receive_shadow=False,
                visible=False,
            )  # fmt: skip
            for mesh in self.robot_meshes
        ]
        self.robot = [
            scene.add_mesh_simple(
                f"/samples/highlighted/{mesh.name}",
                mesh.vertices,
                mesh.faces,
                cast_shadow=False,
                receive_shadow=False,
                visible=False,
            )  # fmt: skip
            for mesh in self.robot_meshes
        ]
        self.hands = [
            scene.add_frame(
                "/samples/hand" if number == 0 else f"/samples/hand_{number}",
                axes_length=HAND_AXES * self.reach,
                axes_radius=0.06 * HAND_AXES * self.reach,
                origin_radius=0.1 * HAND_AXES * self.reach,
                visible=False,
            )  # fmt: skip
            for number in range(len(self.gizmos))
        ]
        self.nodes_shape = (num_samples, num_joints)
        self._refined_of = None

    def remove_samples(self) -> None:
        """Remove the nodes of the samples (not the floor, the target or the prior's draw)."""
        for handle in (*self.ghosts, *self.robot, *self.hands):
            handle.remove()
        self.ghosts, self.robot, self.hands = [], [], []
        for name in ("trail", "skeletons", "estimate_lines", "refined_lines"):
            handle = getattr(self, name, None)
            if handle is not None:
                handle.remove()
                setattr(self, name, None)
        self.nodes_shape = self._refined_of = None
