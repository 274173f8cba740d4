"""The joint-space view's scene nodes, written by the scene writer's thread only (scene_writer.py).

Five nodes beside the workspace, all batched: the square's frame and grid lines, the
denoiser's arrows at the step shown, the solution set (red crosses, or a red curve),
the K samples at the step shown (a point cloud coloured like the arms) and a white
backing that hides the ground grid under the square; and three text labels. They
exist only while the panel's toggle is on.
"""

from __future__ import annotations

import numpy as np
import viser

import ikdp
from ikdp_viz.camera import Extent
from ikdp_viz.joint_space import FieldCache, two_link_solutions
from ikdp_viz.joint_space_panel import JointSpaceControls
from ikdp_viz.joint_space_scene import (
    Square,
    arrow_segments,
    cross_segments,
    curve_segments,
    frame_segments,
    link_headings,
    model_timestep,
    square_beside,
)
from ikdp_viz.planar_kind import JOINT_SPACE_DOT
from ikdp_viz.words import branch_name, held_text, joint_space_title

FRAME_STRONG = (140, 140, 140)  # the border and the zero lines
FRAME_WEAK = (196, 196, 196)  # the lines at +-pi/2
ARROW = (185, 150, 215)  # the denoiser's arrows: a light shade of the x̂0 ghost's purple
SOLUTION = (220, 25, 25)  # the target's red: the exact solution set (N = 2)
FOUND = JOINT_SPACE_DOT  # the final samples' crosses (N > 2): not the target's red, which means the exact solutions
BACKING = (255, 255, 255)
# Heights above the square, in units of the reach, so that the top-down view draws samples over
# solutions over arrows over the frame.
ARROW_LIFT, SOLUTION_LIFT, SAMPLE_LIFT = 0.002, 0.004, 0.006


class JointSpaceNodes:
    """Draws the joint-space view of the state on screen, or removes it when the panel's toggle is off."""

    def __init__(self, server: viser.ViserServer, controls: JointSpaceControls):
        self.server, self.controls = server, controls
        self.clear_of: float | None = None  # x the square stays right of (the arm view's ground grid edge)
        self.fields = FieldCache()
        self.frame = self.arrows = self.solutions = self.samples = self.backing = None
        self.labels: list = []
        self.held = None  # the label under the title: what the other joints are held at (N > 2)
        self.branches: list = []  # the 2-link arm's "elbow up" and "elbow down", beside their crosses
        self.square: Square | None = None
        self._solutions_key: tuple | None = None  # what the solutions node shows: (solve, joints)
        self._labels_key: tuple[int, int] | None = None  # the joints the labels name
        self.last_field = None  # the field drawn last, for tests and scripts

    @property
    def shown(self) -> bool:
        return self.frame is not None

    def reset(self) -> None:
        """The model changed: its view goes (the next draw builds the new arm's), its fields are stale."""
        self._remove()
        self.fields.clear()

    def extent(self) -> Extent | None:
        """The square's part of the plane while it is shown (the drawing loop frames the camera over it)."""
        if self.square is None:
            return None
        (cx, cy), half = self.square.centre, self.square.side / 2
        return Extent(cx - half, cx + half, cy - 1.1 * half, cy + 1.1 * half)  # its labels above and below

    def draw(self, solver: ikdp.Solver, frame) -> None:
        """Write the view for the frame's state (frame.py); the dots take its joint-space colours. In an atomic."""
        solved, state, highlight = frame.solved, frame.state, frame.highlight
        if solver.arm.kind != "planar":
            return
        num_joints = solver.num_links
        self.controls.fit(num_joints)
        wanted = self.controls.show.value and num_joints >= 2
        if not wanted:
            if self.shown:
                self._remove()
            return
        if not self.shown:
            self._build(solver.reach[1])
        view = solved.view
        square, reach = self.square, solver.reach[1]
        joints = self.controls.joints()
        headings = link_headings(view.joints[state])  # (K, N)
        count = int(self.controls.grid.value)
        timestep = model_timestep(view.labels, state)
        field = self.fields.field(solver, view.target, timestep, joints, headings[highlight], count)
        self.last_field = field
        self.arrows.points = arrow_segments(square, field.starts, field.arrows, count, ARROW_LIFT * reach)
        self.samples.points = square.place(headings[:, list(joints)], SAMPLE_LIFT * reach).astype(np.float32)
        self.samples.colors = np.asarray(frame.palette.dots, dtype=np.uint8)
        if self._solutions_key != (id(solved), joints):
            self.solutions.points = self._solution_segments(view, joints, SOLUTION_LIFT * reach)
            self.solutions.colors = np.broadcast_to(np.array(self._solution_color(view), np.uint8),
                                                    self.solutions.points.shape).copy()  # fmt: skip
            self._solutions_key = (id(solved), joints)
            self._write_branches(view, joints)
        if self._labels_key != joints:
            self._write_labels(joints)
        held = held_text(tuple(self.controls.first.options), joints, headings[highlight]) if num_joints > 2 else ""
        if self.held is not None and self.held.text != held:
            self.held.text = held

    # -------------------------------------------------------------- building and removing

    def _solution_segments(self, view, joints: tuple[int, int], lift: float) -> np.ndarray:
        """N = 2: the exact solution set (points as crosses, or a curve); N > 2: the final samples' crosses."""
        square = self.square
        if view.num_links == 2:
            solutions = two_link_solutions(view.lengths, view.target)
            parts = [cross_segments(square, solutions.points[:, list(joints)], lift)]
            if solutions.curve is not None:
                parts.append(curve_segments(square, solutions.curve[:, list(joints)], lift))
            return np.concatenate(parts).astype(np.float32)
        finals = link_headings(view.final_joints)[:, list(joints)]  # (K, 2): the solutions found
        return cross_segments(square, finals, lift).astype(np.float32)

    def _solution_color(self, view) -> tuple[int, int, int]:
        return SOLUTION if view.num_links == 2 else FOUND

    def _build(self, reach: float) -> None:
        scene = self.server.scene
        square = self.square = square_beside(reach, self.clear_of)
        (cx, cy), half = square.centre, square.side / 2
        corners = np.array([[cx - half, cy - half, 0], [cx + half, cy - half, 0], [cx + half, cy + half, 0],
                            [cx - half, cy + half, 0]]) + (0.0, 0.0, square.z - 0.004 * reach)  # fmt: skip
        self.backing = scene.add_mesh_simple(
            "/joint_space/backing", corners, np.array([[0, 1, 2], [0, 2, 3]]), color=BACKING,
            flat_shading=True, cast_shadow=False, receive_shadow=False,
        )  # fmt: skip
        segments, strong = frame_segments(square)
        frame_colors = np.where(strong[:, None, None], FRAME_STRONG, FRAME_WEAK).astype(np.uint8)
        lines = dict(thickness_units="screen")
        self.frame = scene.add_line_segments(
            "/joint_space/frame", segments, colors=np.broadcast_to(frame_colors, segments.shape).copy(), thickness=1.0,
            **lines,
        )  # fmt: skip
        self.arrows = scene.add_line_segments(
            "/joint_space/field", np.zeros((1, 2, 3)), colors=ARROW, thickness=1.2, **lines
        )
        self.solutions = scene.add_line_segments(
            "/joint_space/solutions", np.zeros((1, 2, 3)), colors=SOLUTION, thickness=2.5, **lines
        )
        self.samples = scene.add_point_cloud(
            "/joint_space/samples", np.zeros((1, 3), np.float32), colors=(0, 0, 0), point_size=square.side / 60,
            point_shape="circle", precision="float32",
        )  # fmt: skip
        self._solutions_key = None

    def _write_labels(self, joints: tuple[int, int]) -> None:
        """The axes' names and the title, re-created only when the joints change (not edited every frame).

        In headless chromium (software WebGL) these labels were drawn in some screenshots and not in
        others; the cause is not established, the rest of the view does not depend on them."""
        for handle in self.labels:
            handle.remove()
        first, second = (self.controls.first.options[index] for index in joints)
        (cx, cy), half = self.square.centre, self.square.side / 2
        add = self.server.scene.add_label
        self.labels = [
            add("/joint_space/x_label", first, position=(cx, cy - 1.06 * half, 0.0), anchor="top-center"),
            add("/joint_space/y_label", second, position=(cx - 1.04 * half, cy, 0.0), anchor="center-right"),
            add("/joint_space/title", joint_space_title(first, second), position=(cx, cy + 1.04 * half, 0.0),
                anchor="bottom-center"),
            # the ends of each axis, so the reader sees the range: -π and π are the same heading, the torus's seam
            add("/joint_space/x_low", "−π", position=(cx - half, cy - 1.01 * half, 0.0), anchor="top-center"),
            add("/joint_space/x_high", "π", position=(cx + half, cy - 1.01 * half, 0.0), anchor="top-center"),
            add("/joint_space/y_low", "−π", position=(cx - 1.01 * half, cy - half, 0.0), anchor="center-right"),
            add("/joint_space/y_high", "π", position=(cx - 1.01 * half, cy + half, 0.0), anchor="center-right"),
        ]  # fmt: skip
        self.held = add("/joint_space/held", "", position=(cx, cy - 1.12 * half, 0.0), anchor="top-center")
        self.labels.append(self.held)
        self._labels_key = joints

    def _write_branches(self, view, joints: tuple[int, int]) -> None:
        """A 2-link arm: each exact solution's branch named beside its cross (no names for more links, whose
        crosses are the samples found)."""
        for handle in self.branches:
            handle.remove()
        self.branches = []
        if view.num_links != 2:
            return
        half = self.square.side / 2
        for number, pose in enumerate(two_link_solutions(view.lengths, view.target).points):
            (x, y) = self.square.place(pose[None, list(joints)])[0, :2]
            self.branches.append(self.server.scene.add_label(
                f"/joint_space/branch_{number}", branch_name(view.lengths, pose),
                position=(float(x), float(y) + 0.06 * half, 0.0), anchor="bottom-center",
            ))  # fmt: skip

    def _remove(self) -> None:
        for handle in (self.frame, self.arrows, self.solutions, self.samples, self.backing, *self.labels,
                       *self.branches):  # fmt: skip
            if handle is not None:
                handle.remove()
        self.frame = self.arrows = self.solutions = self.samples = self.backing = self.held = None
        self.labels, self.branches, self.square, self._solutions_key, self._labels_key = [], [], None, None, None
