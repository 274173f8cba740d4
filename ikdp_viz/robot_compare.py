"""Same noise, two samplers, for a robot: the second sampler's skeletons beside the robot.

The planar comparison (compare.py) draws a second workspace to the left; a robot's is its K
skeletons at the state nearest the same diffusion time, shifted along -y by the width of the
reach ball and a gap, coloured as the main skeletons, with the target's frame and a label
naming each side just above its own final skeletons. The drawing loop frames the camera over both (`camera`).
"""

from __future__ import annotations

import numpy as np

from ikdp_viz.camera import camera_fit_3d
from ikdp_viz.chain_scene import skeleton_segments
from ikdp_viz.robot_view import SKELETON_PIXELS
from ikdp_viz.scene import nearest_state
from ikdp_viz.style import TARGET_RED

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
        segments = skeleton_segments(compare.points[shown]) + self.shift
        self.nodes["skeletons"].points = segments.astype(np.float32)
        per_joint = np.repeat(lines, compare.num_joints, axis=0)[:, None]
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
        target = np.asarray(solved.view.target, dtype=np.float64)
        wxyz = target[3:7] if len(target) == 7 else (1.0, 0.0, 0.0, 0.0)
        base = np.asarray(solved.view.points[0, 0, 0], dtype=np.float64)
        self.nodes["skeletons"] = scene.add_line_segments(
            "/compare/skeletons", np.zeros((1, 2, 3)), colors=(0, 0, 0), thickness=SKELETON_PIXELS,
            thickness_units="screen",
        )  # fmt: skip
        self.nodes["target"] = scene.add_frame(
            "/compare/target", axes_length=0.1 * reach, axes_radius=0.006 * reach, origin_color=TARGET_RED,
            position=tuple(target[:3] + self.shift), wxyz=tuple(float(value) for value in wxyz),
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
