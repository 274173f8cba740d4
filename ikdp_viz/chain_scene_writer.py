"""The scene writer of a robot from a URDF: the planar writer's thread, messages and clock, 3-D drawing.

`SceneWriter` owns the queue, the solve on screen and the animation; this subclass
replaces only what a frame looks like. For K samples at one state it draws:
- the K robots' meshes (the URDF's collision meshes): the highlighted sample opaque, one
  node per mesh; the others translucent ghosts with light hulls of the meshes, one batched
  node per mesh with K instances (the highlighted one scaled to nothing: a translucent
  instance drawn before an opaque one in the same node hides it). Coloured from faint
  (t = T) to dark (t = 0) as the planar arms are. While an animation plays, the ghosts
  are hidden and the skeletons stand in for them: software WebGL animated K = 16 at 6
  frames/s with them, 15 without (docs/VIZ.md); a pause, the last state and the slider
  show them;
- the K skeletons (joint origins to the hand) as one line-segment node, and as the trail
  the path of each hand through the states before, as another;
- the highlighted sample's hand frame, and the target as a 6-DoF gizmo that sets the pose.
What to draw is `chain_scene.py`'s (plain numpy); this file copies it into viser handles.
"""

from __future__ import annotations

import numpy as np
import viser

import ikdp
from ikdp_viz import chain_readouts
from ikdp_viz.chain_scene import GHOST_DARK, GHOST_FAINT, ghost_colors, gizmo_pose, mesh_poses, skeleton_segments
from ikdp_viz.constraint_scene import holds, sample_tints
from ikdp_viz.emphasis import OTHERS_FINAL, emphasis_colors, estimate_rows, follows_one, trail_rows
from ikdp_viz.legend import Entry, Swatch
from ikdp_viz.panel import Panel
from ikdp_viz.robot_meshes import light_mesh, robot_meshes
from ikdp_viz.scene import (
    ACCENT_DARK,
    ACCENT_FAINT,
    DARK,
    FAINT,
    REFINED,
    grid_segments,
    trail_colors,
    trail_until,
)
from ikdp_viz.scene_writer import ESTIMATE, GRID_CELL, GRID_SECTION, LINE_PIXELS, PRIOR, SceneWriter
from ikdp_viz.typed_target import roll_pitch_yaw_degrees

HIGHLIGHTED_ROBOT = (40, 110, 235)  # the followed sample's opaque robot: a lighter blue than the lines, as shading
# darkens a mesh and the Panda's links are near black in their own shadows
GHOST_OPACITY = 0.15  # the samples not highlighted: seen through, so the highlighted robot stays readable
# a see-through robot that breaks a constraint at the step shown: at 0.15 its red read as a pale pink beside the
# greens, so the ones in collision are drawn denser (viser multiplies each robot's factor into the node's opacity)
VIOLATING_GHOST_OPACITY = 0.45
SKELETON_PIXELS = 2.5  # the current state's skeletons, over the thinner trail
HAND_AXES = 0.08  # hand frame's axes, in reach radii


def ghost_opacities(holding: np.ndarray) -> np.ndarray:
    """(..., K) whether each see-through robot meets the constraints -> (..., K) float32 factors of the ghosts'
    node opacity (VIOLATING_GHOST_OPACITY): the usual GHOST_OPACITY where it holds, the full node opacity where not."""
    return np.where(holding, GHOST_OPACITY / VIOLATING_GHOST_OPACITY, 1.0).astype(np.float32)


def grid_cell(reach: float) -> float:
    """The first round spacing (1, 2 or 5 times a power of ten) at least a tenth of the reach: 0.1 m for the Panda."""
    tenth = reach / 10
    power = 10 ** np.floor(np.log10(tenth))
    return float(next(step * power for step in (1, 2, 5, 10) if step * power >= tenth * (1 - 1e-9)))


def camera_fit_3d(center: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(position, look_at) of a camera in front of, beside and above the reach ball, seen along (-1, 1, -0.6)."""
    return center + reach * np.array([1.0, -1.0, 0.6]), center.copy()


class ChainSceneWriter(SceneWriter):
    """SceneWriter for a ChainArm: same messages and animation, robots in 3-D."""

    # the readouts' unit; the rotation error is in the readouts, in degrees
    CHART_ERROR, CHART_UNIT = "hand position error", "mm"
    CHART_SCALE = 1000.0  # view.tip_error is in metres
    HOLDS_TEXT = "constraints hold at the step shown"
    VIOLATES_TEXT = "constraints fail at the step shown (those see-through robots denser)"

    def __init__(self, server: viser.ViserServer, panel: Panel, solver: ikdp.Solver, target: np.ndarray, gizmo_update):
        self.ghosts: list = []  # one batched mesh node per robot mesh, K instances
        self.robot: list = []  # the highlighted sample: one opaque mesh node per robot mesh
        self.skeletons = self.hand = None
        super().__init__(server, panel, solver, target, gizmo_update)
        # Off at start: near t = T the hands jump across the whole reach ball, and their paths cage the robots.
        panel.show_trail.value = False
        panel.joint_space.folder.visible = False  # the joint space view draws planar arms only
        panel.learn.compare.visible = False  # and so does the comparison of two samplers (compare.py)

    # -------------------------------------------------------------- static scene

    def _build_static_scene(self) -> None:
        """Floor grid, the target's 6-DoF gizmo at the target pose, the robot's meshes read once; camera fitted."""
        scene = self.server.scene
        for handle in self._static_nodes:
            handle.remove()
        arm = self.solver.arm
        self.robot_meshes = robot_meshes(arm)
        self.mesh_links = np.array([mesh.link_index for mesh in self.robot_meshes], dtype=np.int64)
        self.mesh_offsets = np.array([mesh.offset for mesh in self.robot_meshes]).reshape(-1, 4, 4)
        center, reach = arm.reach_center.double().numpy(), float(arm.reach[1])
        self.reach = reach
        cell = grid_cell(reach)
        extent = 2 * cell * np.ceil(1.2 * reach / cell)
        scene.set_up_direction("+z")
        # Line segments, not viser's shader grid: that alone took headless chromium from 40 to 2 frames/s.
        segments, sections = grid_segments(extent / 2, cell, 5 * cell)
        grid_colors = np.where(sections[:, None, None], GRID_SECTION, GRID_CELL).astype(np.uint8)
        grid = scene.add_line_segments(
            "/grid", segments, colors=np.broadcast_to(grid_colors, segments.shape).copy(), thickness=1.0,
            thickness_units="screen", position=(center[0], center[1], 0.0),
        )  # fmt: skip
        pose = self.target
        wxyz = pose[3:7] if len(pose) == 7 else (1.0, 0.0, 0.0, 0.0)
        self.gizmo = scene.add_transform_controls(
            "/target", scale=0.25 * reach, depth_test=False, disable_rotations=len(pose) != 7,
            position=tuple(pose[:3]), wxyz=tuple(wxyz),
        )  # fmt: skip
        self.gizmo.on_update(self._gizmo_update)
        self._static_nodes = [grid, self.gizmo]
        self.panel.export_button.disabled = True  # the GIF / PNG export draws the planar arm only
        position, look_at = camera_fit_3d(center, reach)
        self.server.initial_camera.position, self.server.initial_camera.look_at = position, look_at
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.position, client.camera.look_at = position, look_at

    def _write_target_text(self) -> None:
        note = "  \n(moved inside the reach ball)" if self.target_clamped else ""
        self.panel.target_text.content = chain_readouts.pose_text(self.target) + note

    def _place_target(self, message) -> None:
        self.target, self.target_clamped = message.target, message.clamped
        if message.move_gizmo:
            position = np.asarray(message.target[:3], dtype=np.float64)
            if len(message.target) == 7:
                self.gizmo.wxyz = np.asarray(message.target[3:7], dtype=np.float64)
            if message.force:  # see SceneWriter._place_target: the page's gizmo may be past the clamped point
                self.gizmo.position = position + (1e-3, 0.0, 0.0)
            self.gizmo.position = position
        self._write_target_text()

    # -------------------------------------------------------------- nodes

    def _ensure_arm_nodes(self) -> None:
        """(Re)create the sample nodes when K or J changed: a batched node keeps its instance count."""
        view = self.solved.view
        shape = (view.num_samples, view.num_joints)
        if shape == self.nodes_shape:
            return
        self._remove_arm_nodes()
        scene = self.server.scene
        num_samples = view.num_samples
        lines = dict(thickness_units="screen", visible=False)
        empty = np.zeros((1, 2, 3))
        self.trail = scene.add_line_segments(
            "/samples/trail", empty, colors=(255, 255, 255), thickness=LINE_PIXELS, **lines
        )
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
            )
            for mesh in self.robot_meshes
        ]
        self.hand = scene.add_frame(
            "/samples/hand", axes_length=HAND_AXES * self.reach, axes_radius=0.06 * HAND_AXES * self.reach,
            origin_radius=0.1 * HAND_AXES * self.reach, visible=False,
        )  # fmt: skip
        self.nodes_shape = shape

    def _remove_arm_nodes(self) -> None:
        for handle in (*self.ghosts, *self.robot):
            handle.remove()
        self.ghosts, self.robot = [], []
        for name in ("skeletons", "hand"):
            handle = getattr(self, name, None)
            if handle is not None:
                handle.remove()
                setattr(self, name, None)
        super()._remove_arm_nodes()

    def _show_prior(self, joints: np.ndarray) -> None:
        """Poses from the prior as brown skeletons; `joints` (K, J+1, 3) are their joint origins and hands."""
        if self.prior_lines is not None:
            self.prior_lines.remove()
        self.prior_lines = self.server.scene.add_line_segments(
            "/prior", skeleton_segments(joints), colors=PRIOR, thickness=2 * LINE_PIXELS, thickness_units="screen"
        )

    # -------------------------------------------------------------- one state

    def _recolor(self) -> None:
        view = self.solved.view
        highlight = self.highlight_index()
        # (S+1, K, 3) each: following one sample (the default), its skeleton blue and the others' light grey
        self._colors, ramp = emphasis_colors(view.num_states, view.num_samples, highlight, self.trail_of)
        self._trail_colors = trail_colors(ramp, 1)  # (S+1, K, 2, 3): one hand step per sample
        self._ghost_colors = ghost_colors(view.num_states, view.num_samples, highlight)  # (S+1, K, 3)
        if follows_one(self.trail_of):
            self._ghost_colors[:, highlight] = HIGHLIGHTED_ROBOT  # the followed robot stands out at every step
        self._ghost_opacities = ghost_opacities(np.ones((view.num_states, view.num_samples), bool))
        if self.constraint_colors_shown:  # every robot and skeleton green where its constraints hold, red where not,
            # in full colour: at the ghosts' opacity, and as thin lines sent as is (lighter on the page), the lighter
            # tints of the planar arms read as grey; the highlighted robot is the opaque one
            self._colors = self._ghost_colors = sample_tints(self.solved.state_violation, highlight, others_full=True)
            self._ghost_opacities = ghost_opacities(holds(self.solved.state_violation))
        self._skeleton_colors = trail_colors(self._colors, view.num_joints)  # (S+1, K*J, 2, 3)

    def _write_refined(self) -> None:
        view = self.solved.view
        self.refined_lines.points = skeleton_segments(view.final_points)
        count = view.num_samples * view.num_joints
        self.refined_lines.colors = np.broadcast_to(np.array(REFINED, np.uint8), (count, 2, 3))

    def _draw_arms(self, solved, state: int, highlight: int) -> None:
        """The 3-D frame: trail before `state`, the K skeletons and robots at `state`, the hand."""
        view = solved.view
        arm = self.solver.arm
        poses = np.stack([view.pose_at(state, sample) for sample in range(view.num_samples)])  # (K, J)
        mesh_positions, mesh_wxyzs = mesh_poses(arm, poses, self.mesh_links, self.mesh_offsets)  # (K, M, 3|4)
        scales = np.ones(view.num_samples)
        scales[highlight] = 0.0  # drawn opaque by its own nodes
        colors = self._ghost_colors[state]  # (K, 3)
        hand_position, hand_wxyz = gizmo_pose(arm, poses[highlight])
        estimate = view.estimate_at(state) if self.panel.show_estimate.value else None
        if self.panel.show_trail.value and state > 0:
            rows = trail_rows(view.num_samples, 1, highlight, self.trail_of)
            points, segment_colors = trail_until(
                solved.trail_points[:, rows], self._trail_colors[:, rows], state,
                most_states=self.trail_states_limit(state),
            )  # fmt: skip
            self.trail.points, self.trail.colors, self.trail.visible = points, segment_colors, True
        else:
            self.trail.visible = False
        self.skeletons.points = skeleton_segments(view.points[state]).astype(np.float32)
        self.skeletons.colors = self._skeleton_colors[state]
        self.skeletons.visible = True
        if estimate is not None:
            self.estimate_lines.points = skeleton_segments(
                estimate[estimate_rows(view.num_samples, highlight, self.trail_of)]
            )
            self.estimate_lines.visible = True
        else:
            self.estimate_lines.visible = False
        ghosts_shown = not self.animating(state)  # the skeletons stand in while it plays
        for index, node in enumerate(self.ghosts):
            if ghosts_shown:
                node.batched_positions = mesh_positions[:, index]
                node.batched_wxyzs = mesh_wxyzs[:, index]
                node.batched_colors = colors
                node.batched_scales = scales
                node.batched_opacities = self._ghost_opacities[state]
            node.visible = ghosts_shown
        for index, node in enumerate(self.robot):
            node.position, node.wxyz = mesh_positions[highlight, index], mesh_wxyzs[highlight, index]
            node.color = tuple(int(channel) for channel in colors[highlight])
            node.visible = True
        self.hand.position, self.hand.wxyz, self.hand.visible = hand_position, hand_wxyz, True
        self.refined_lines.visible = state == view.num_states - 1 and view.refined

    def write_target_inputs(self, target: np.ndarray) -> None:
        """The typed-target fields show the target solved: position in mm, rotation as roll pitch yaw in degrees."""
        inputs = self.panel.learn.target
        inputs.show_for("chain", len(target))
        inputs.position_mm.value = tuple(round(1000 * float(value), 1) for value in target[:3])
        if len(target) == 7:
            inputs.rotation_deg.value = tuple(round(float(value), 1) for value in roll_pitch_yaw_degrees(target[3:7]))

    def legend_entries(self) -> list[Entry]:
        """What each colour of the 3-D scene means, for the panel's legend."""
        follows = follows_one(self.trail_of)
        return [
            Entry(
                Swatch(HIGHLIGHTED_ROBOT if follows else ACCENT_DARK), "highlighted robot (opaque), at the step shown"
            ),
            Entry(Swatch(GHOST_DARK, faint=GHOST_FAINT), "the other robots (see-through), t = T → 0"),
            Entry(Swatch(OTHERS_FINAL if follows else DARK, faint=FAINT), "skeletons: joint origins to the hand"),
            Entry(
                Swatch(ACCENT_DARK, faint=ACCENT_FAINT) if follows else Swatch(DARK, faint=FAINT),
                "trail (show trail): the highlighted hand's path"
                if follows
                else "trail (show trail): the hands' paths",
            ),
            Entry(Swatch((220, 40, 40)), "hand frame of the highlighted robot: x red, y green, z blue"),
            Entry(Swatch(ESTIMATE), "x̂0: the denoiser's guess of the final pose"),
            Entry(Swatch(REFINED), "refined at t = 0 (DLS polish)"),
            Entry(Swatch(PRIOR), "poses drawn from the prior"),
            Entry(Swatch((220, 25, 25), "cross"), "target: the gizmo's pose"),
        ]

    def _solve_text(self, solved) -> str:
        request = solved.request
        text = chain_readouts.chain_solve_text(
            solved.view, self.state, self.highlight_index(), sampler=request.sampler, seed=request.seed,
            refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds,
        )  # fmt: skip
        return text + (f"  \n**Newest solve failed** {self.error}" if self.error else "")


def scene_writer_class(solver) -> type[SceneWriter]:
    """The scene writer that draws `solver`'s kind of arm."""
    from ikdp_viz.arm_kinds import arm_kind

    return {"planar": SceneWriter, "chain": ChainSceneWriter}[arm_kind(solver).name]
