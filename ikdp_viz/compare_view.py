"""Same noise, two samplers: the second sampler's denoising drawn beside the first, from the very same x_T.

With "compare with" set, each solve also runs that sampler (DDIM or DPM-Solver++, the
deterministic ODE; or DDPM) from the x_T the main sampler started from (solving.py,
`Solver.solve(initial_noise=)`). This draws it in a second workspace to the left of the
first, at the state nearest the same diffusion time t, in the main arms' style (the same sample
followed in full width with its joints, its trail faint to dark, the others thin, a ground grid under
both), so what differs between the two is the sampler alone, with a label naming each side; the chart
gets the followed sample's tip error under the second sampler (`compare_curve`). The scene
writer's thread alone calls `draw`.
"""

from __future__ import annotations

import numpy as np
import viser

from ikdp_viz.camera import Extent, camera_fit_3d
from ikdp_viz.chain_scene import skeleton_segments
from ikdp_viz.planar_scene import (
    arm_placement,
    circle_segments,
    follows_one,
    line_colors,
    nearest_state,
    trail_rows,
    trail_until,
)
from ikdp_viz.robot_view import SKELETON_PIXELS
from ikdp_viz.style import REACH_RING, TARGET_RED

GAP = 0.35  # between the two workspaces, in reach radii


def offset(reach: float) -> float:
    """x of the second workspace's centre: to the left of the first."""
    return -(2 + GAP) * reach


class CompareNodes:
    """The second sampler's workspace: its circle, trail, arms, target cross and the two labels."""

    def __init__(self, server: viser.ViserServer):
        self.server = server
        self._reach: float | None = None  # the workspace radius while shown
        self.nodes: dict = {}
        self._titled: int | None = None  # the solve whose titles and cross are written

    @property
    def shown(self) -> bool:
        return bool(self.nodes)

    def extent(self) -> Extent | None:
        """The second workspace's part of the plane while it is shown (the drawing loop frames the camera)."""
        return None if not self.shown else Extent.disc(self._reach, x=offset(self._reach))

    def draw(self, solver, frame, *, sizes) -> None:
        """Write the second sampler's state nearest the main one's diffusion time, or remove the view."""
        solved, state, highlight = frame.solved, frame.state, frame.highlight
        trail_of, show_trail = frame.settings.trail_of, frame.settings.show_trail
        compare = getattr(solved, "compare", None)
        if compare is None or sizes is None:
            if self.shown:
                self.remove()
            return
        reach = float(solver.reach[1])
        if not self.shown:
            self._build(solver, solved, reach, sizes)
        arm_colors, segment_colors = frame.palette.compare_arms, frame.palette.compare_trail  # the frame's colours
        if self._titled != id(solved):
            self._titled = id(solved)
            request = solved.request
            self.nodes["title"].text = request.compare_title(compare.num_states - 1)
            main_steps = solved.view.num_states - 1
            self.nodes["main_title"].text = request.title(main_steps) + ": same x_T"
            target, cross = solved.view.target, self.nodes["cross"]
            cross.position = (float(target[0]) + offset(reach), float(target[1]), float(cross.position[2]))
        shown = nearest_state(compare.labels, float(solved.view.labels[state]))
        shift = np.array([offset(reach), 0.0, 0.0])
        rows = trail_rows(compare.num_samples, compare.num_links, highlight, trail_of)
        if show_trail:
            points, colors = trail_until(solved.compare_trail[:, rows], segment_colors[:, rows], shown)
            self.nodes["trail"].points, self.nodes["trail"].colors = points + shift.astype(np.float32), colors
        self.nodes["trail"].visible = show_trail
        placement = arm_placement(compare.joints[shown], height=0.25 * sizes.joint, raised=highlight,
                                  lift=2.0 * sizes.joint)  # fmt: skip
        self.nodes["links"].points = placement.link_segments + shift
        per_link = line_colors(np.repeat(arm_colors[shown], compare.num_links, axis=0))[:, None]
        self.nodes["links"].colors = np.broadcast_to(per_link, (compare.num_samples * compare.num_links, 2, 3))
        from ikdp_viz.planar_view import OTHER_PIXELS
        from ikdp_viz.style import ARM_PIXELS

        follows = follows_one(trail_of)
        self.nodes["links"].thickness = OTHER_PIXELS if follows else ARM_PIXELS  # as the main view draws them
        rows = slice(highlight * compare.num_links, (highlight + 1) * compare.num_links)
        self.nodes["followed"].points = placement.link_segments[rows] + shift
        self.nodes["followed"].colors = np.broadcast_to(per_link[rows], (compare.num_links, 2, 3))
        self.nodes["followed"].visible = follows
        joints = compare.num_links + 1
        followed_joints = placement.joint_positions[highlight * joints : (highlight + 1) * joints]
        self.nodes["joints"].batched_positions = followed_joints + shift
        self.nodes["joints"].batched_colors = np.broadcast_to(arm_colors[shown][highlight], (joints, 3))

    def _build(self, solver, solved, reach: float, sizes) -> None:
        from ikdp_viz import robot_meshes
        from ikdp_viz.planar_view import grid_under
        from ikdp_viz.style import ARM_PIXELS, LINE_PIXELS, TARGET_RED

        scene, x = self.server.scene, offset(reach)
        compare = solved.compare
        count = compare.num_samples * compare.num_links
        unit = float(np.mean(compare.lengths))
        self.nodes["grid"] = grid_under(scene, "/compare/grid", float(np.ceil((reach + unit) / unit)) * unit, unit, x)
        ring = circle_segments(reach, 96, z=-0.01 * reach) + (x, 0.0, 0.0)
        self.nodes["circle"] = scene.add_line_segments(
            "/compare/workspace", ring, colors=REACH_RING, thickness=LINE_PIXELS, thickness_units="screen"
        )
        self.nodes["trail"] = scene.add_line_segments(
            "/compare/trail", np.zeros((1, 2, 3)), colors=(255, 255, 255), thickness=LINE_PIXELS,
            thickness_units="screen",
        )  # fmt: skip
        self.nodes["links"] = scene.add_line_segments(
            "/compare/links", np.zeros((count, 2, 3)), colors=np.zeros((count, 2, 3), np.uint8), thickness=ARM_PIXELS,
            thickness_units="screen",
        )  # fmt: skip
        self.nodes["followed"] = scene.add_line_segments(
            "/compare/followed", np.zeros((compare.num_links, 2, 3)), colors=(0, 0, 0), thickness=ARM_PIXELS,
            thickness_units="screen",
        )  # fmt: skip
        sphere, joints = robot_meshes.sphere_mesh(sizes.joint), compare.num_links + 1
        self.nodes["joints"] = scene.add_batched_meshes_simple(
            "/compare/joints", sphere.vertices, sphere.faces, np.tile([1.0, 0.0, 0.0, 0.0], (joints, 1)),
            np.zeros((joints, 3)), batched_colors=np.zeros((joints, 3), np.uint8), lod="off", cast_shadow=False,
            receive_shadow=False,
        )  # fmt: skip
        cross = robot_meshes.cross_mesh(sizes.cross)
        target = solved.view.target
        self.nodes["cross"] = scene.add_mesh_simple(
            "/compare/target", cross.vertices, cross.faces, color=TARGET_RED, cast_shadow=False, receive_shadow=False,
            position=(float(target[0]) + x, float(target[1]), 4.0 * sizes.joint),
        )  # fmt: skip
        top = 1.08 * reach
        self.nodes["title"] = scene.add_label("/compare/title", "", position=(x, top, 0.0), anchor="bottom-center")
        self.nodes["main_title"] = scene.add_label("/compare/main_title", "", position=(0.0, top, 0.0),
                                                   anchor="bottom-center")  # fmt: skip
        self._reach = reach

    def remove(self) -> None:
        for node in self.nodes.values():
            node.remove()
        self.nodes, self._titled, self._reach = {}, None, None


# Same noise, two samplers, for a robot: the second sampler's skeletons beside the robot.
SHIFT = 2.4  # the second robot's base from the first, in reach radii along -y
TITLE_ABOVE = 0.08  # a title's gap over the highest joint of its side's final poses, in reach radii


def title_position(points: np.ndarray, reach: float) -> tuple[float, float, float]:
    """Where a side's title goes: over the middle of its final poses' joints `points` (K, J, 3), just above the
    highest (a title at a fixed height over the base floated far above poses that stay low)."""
    joints = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    low, high = joints.min(axis=0), joints.max(axis=0)
    return (float((low[0] + high[0]) / 2), float((low[1] + high[1]) / 2), float(high[2] + TITLE_ABOVE * reach))


class RobotCompareNodes:
    """The second sampler's skeletons, target and labels beside a robot; removed when the comparison goes."""

    def __init__(self, server):
        self.server = server
        self.nodes: dict = {}
        self.shift: np.ndarray | None = None  # (3,) while shown
        self._titled = None  # the solve whose final poses the titles were placed over

    @property
    def shown(self) -> bool:
        return bool(self.nodes)

    def extent(self):
        return None  # a 3-D view: `camera` frames it

    def camera(self, center: np.ndarray, reach: float):
        """A camera over the robot and its comparison together: the robot's own look, from farther away."""
        middle = center + self.shift / 2
        return camera_fit_3d(middle, 1.6 * reach)

    def draw(self, solver, frame, *, sizes=None) -> None:
        solved, compare = frame.solved, getattr(frame.solved, "compare", None)
        if compare is None:
            self.remove()
            return
        reach = float(solver.arm.reach[1])
        if not self.shown:
            self._build(solved, reach)
        shown = nearest_state(compare.labels, float(solved.view.labels[frame.state]))
        lines = frame.palette.lines[min(frame.state, len(frame.palette.lines) - 1)]  # (K, 3) the main colours
        segments = skeleton_segments(compare.points[shown], compare.polylines) + self.shift
        self.nodes["skeletons"].points = segments.astype(np.float32)
        per_joint = np.repeat(lines, compare.num_segments, axis=0)[:, None]
        self.nodes["skeletons"].colors = np.broadcast_to(per_joint, (len(segments), 2, 3))
        request = solved.request
        self.nodes["title"].text = request.compare_title(compare.num_states - 1)
        self.nodes["main_title"].text = request.title(solved.view.num_states - 1) + ": same x_T"
        if self._titled is not solved:  # once a solve: each title over its own side's final poses
            self.nodes["title"].position = title_position(compare.points[-1] + self.shift, reach)
            self.nodes["main_title"].position = title_position(solved.view.points[-1], reach)
            self._titled = solved

    def _build(self, solved, reach: float) -> None:
        scene = self.server.scene
        self.shift = np.array([0.0, -SHIFT * reach, 0.0])
        base = np.asarray(solved.view.points[0, 0, 0], dtype=np.float64)
        self.nodes["skeletons"] = scene.add_line_segments(
            "/compare/skeletons", np.zeros((1, 2, 3)), colors=(0, 0, 0), thickness=SKELETON_PIXELS,
            thickness_units="screen",
        )  # fmt: skip
        for number, target in enumerate(np.asarray(solved.view.target_poses, dtype=np.float64)):  # one per hand
            wxyz = target[3:7] if len(target) == 7 else (1.0, 0.0, 0.0, 0.0)
            self.nodes["target" if number == 0 else f"target_{number}"] = scene.add_frame(
                "/compare/target" if number == 0 else f"/compare/target_{number}", axes_length=0.1 * reach,
                axes_radius=0.006 * reach, origin_color=TARGET_RED, position=tuple(target[:3] + self.shift),
                wxyz=tuple(float(value) for value in wxyz),
            )  # fmt: skip
        top = base + (0.0, 0.0, 1.2 * reach)
        self.nodes["title"] = scene.add_label("/compare/title", "", position=tuple(top + self.shift),
                                              anchor="bottom-center")  # fmt: skip
        self.nodes["main_title"] = scene.add_label("/compare/main_title", "", position=tuple(top),
                                                   anchor="bottom-center")  # fmt: skip

    def remove(self) -> None:
        for node in self.nodes.values():
            node.remove()
        self.nodes, self.shift, self._titled = {}, None, None
