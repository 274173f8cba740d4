"""Everything drawn in the scene, as components: the arm view and the side views beside it, and the one camera.

The arm view (planar_view.py or robot_view.py, picked by arm_kinds.py) owns the arm's nodes;
the side views of a planar arm (the joint-space square, the comparison's second workspace)
own theirs and report the part of the plane they cover. `frame_camera` frames the camera over
all that is shown, the only place that moves it (several camera writers each framing their own
view left one side view out of frame), and widens each tall tab's field of view.
"""

from __future__ import annotations

import numpy as np

from ikdp_viz.arm_kinds import arm_view_class, compare_view_class
from ikdp_viz.camera import camera_over, fit_fields_of_view, move_cameras
from ikdp_viz.joint_space_nodes import JointSpaceNodes


class Stage:
    """The arm view, the side views and the camera over them; written by the drawing loop only."""

    def __init__(self, server, panel, solver, target: np.ndarray, gizmo_update):
        self.server = server
        # No environment map: its reflections wash dark materials out to grey; the default lights stay.
        server.scene.configure_environment_map(hdri=None)
        # No shadow maps: nothing here casts one, and software WebGL drew the empty page at 16-26 frames/s with
        # them, 27-29 without
        server.scene.configure_default_lights(cast_shadow=False)
        self.view = arm_view_class(solver)(server, solver, target, gizmo_update)
        self.joint_space = JointSpaceNodes(server, panel.joint_space)  # the torus beside a planar arm
        self.joint_space.clear_of = getattr(self.view, "grid_half_width", None)  # beside the grid, not on it
        self.compare = compare_view_class(solver)(server)  # a second sampler from the same noise, beside the arm
        self._camera: tuple | None = None  # the camera last framed
        self.frame_camera()

    def draw(self, frame, solver) -> None:
        """The arm view, the side views and the camera over all that is shown, from one frame."""
        self.view.update(frame)
        self.joint_space.draw(solver, frame)
        self.compare.draw(solver, frame, sizes=getattr(self.view, "sizes", None))
        self.frame_camera()

    def extents(self) -> list:
        """The parts of the ground plane drawn in: the arm's, then each side view's that is shown."""
        side = [extent for extent in (self.joint_space.extent(), self.compare.extent()) if extent is not None]
        return [self.view.extent(), *side]

    def frame_camera(self) -> None:
        """One camera over everything shown (a robot's view has its own); moved only when it changes."""
        camera = self.view.camera()
        if camera is not None and self.compare.shown:  # a robot and its comparison: both in view
            camera = self.compare.camera(self.view.center, self.view.reach)
        if camera is None:
            camera = camera_over(self.extents())
        key = tuple(np.round(np.concatenate([np.ravel(camera[0]), np.ravel(camera[1])]), 9))
        if key != self._camera:
            move_cameras(self.server, camera)
            self._camera = key
            self.view.aim_cross(np.asarray(camera[0], dtype=np.float64))
        fit_fields_of_view(self.server)  # each tab's canvas shape, which the one camera cannot know

    def rebuild(self, solver, target: np.ndarray) -> None:
        """Another model: the side views go, the arm view is built for its arm, the camera framed again."""
        self.joint_space.reset()
        self.compare.remove()
        self.compare = compare_view_class(solver)(self.server)
        self.view.rebuild(solver, target)
        self.joint_space.clear_of = getattr(self.view, "grid_half_width", None)
        self._camera = None
        self.frame_camera()
