"""The joint-space view's scene nodes, written by the scene writer's thread only (scene_writer.py).

Five nodes beside the workspace, all batched: the square's frame and grid lines, the
denoiser's arrows at the step shown, the solution set (red crosses, or a red curve),
the K samples at the step shown (a point cloud coloured like the arms) and a white
backing that hides the ground grid under the square; and three text labels. They
exist only while the panel's toggle is on. The arrows are computed on the solve
worker's thread, with the solve or later for the solve on screen (joint_space.SolveFields);
this thread draws them only where they are the pair, grid and held pose shown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import viser

import ikdp
from ikdp_viz.arm_kinds import arm_kind, arm_view, compare_view_class
from ikdp_viz.camera import Extent, camera_over, fit_fields_of_view, move_cameras
from ikdp_viz.joint_space import (
    Field,
    FieldAsk,
    JointSpaceControls,
    SolveFields,
    link_headings,
    two_link_solutions,
    wrap_to_square,
)
from ikdp_viz.readouts import branch_name, held_text, joint_space_title
from ikdp_viz.style import ARROW, BACKING, FRAME_STRONG, FRAME_WEAK, JOINT_SPACE_DOT, SOLUTION

FOUND = JOINT_SPACE_DOT  # the final samples' crosses (N > 2): not the target's red, which means the exact solutions
# Heights above the square, in units of the reach, so that the top-down view draws samples over
# solutions over arrows over the frame.
ARROW_LIFT, SOLUTION_LIFT, SAMPLE_LIFT = 0.002, 0.004, 0.006


class JointSpaceNodes:
    """Draws the joint-space view of the state on screen, or removes it when the panel's toggle is off."""

    def __init__(self, server: viser.ViserServer, controls: JointSpaceControls):
        self.server, self.controls = server, controls
        self.clear_of: float | None = None  # x the square stays right of (the arm view's ground grid edge)
        # ask_fields(solved, joints, highlight, count): the app's job for fields the solve on screen lacks, on the
        # solve worker (this thread never runs the network); None: none asked (the arrows wait for the solve's own)
        self.ask_fields = None
        self._adopted: tuple | None = None  # (Solved, SolveFields) computed for a solve after it came on screen
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
        self._adopted = None

    def wanted(self, solver: ikdp.Solver) -> bool:
        """The view is drawn for this model now: a planar arm, the panel's toggle on."""
        return arm_kind(solver).draws_joint_space and bool(self.controls.show.value) and solver.num_links >= 2

    def field_ask(self, solver: ikdp.Solver, highlight: str) -> FieldAsk | None:
        """The fields a solve asked now should bring (the highlight dropdown's `highlight`); None: the view is off."""
        if not self.wanted(solver):
            return None
        return FieldAsk(self.controls.joints(), int(self.controls.grid.value), highlight)

    def adopt(self, solved, fields: SolveFields) -> None:
        """Fields computed for `solved` after it came on screen (the drawing loop's thread, from the intent)."""
        self._adopted = (solved, fields)

    def field_at(self, solved, state: int, joints: tuple[int, int], highlight: int, count: int) -> Field | None:
        """The field of `solved` at `state` for this pair, held pose and grid, from its own fields or those adopted
        since; None: not computed."""
        adopted = self._adopted[1] if self._adopted is not None and self._adopted[0] is solved else None
        for fields in (solved.fields, adopted):
            if fields is not None and fields.fits(joints, highlight, count) and fields.computed[state]:
                return fields.at(state)
        return None

    def extent(self) -> Extent | None:
        """The square's part of the plane while it is shown (the drawing loop frames the camera over it)."""
        if self.square is None:
            return None
        (cx, cy), half = self.square.centre, self.square.side / 2
        return Extent(cx - half, cx + half, cy - 1.1 * half, cy + 1.1 * half)  # its labels above and below

    def draw(self, solver: ikdp.Solver, frame) -> None:
        """Write the view for the frame's state (frame.py); the dots take its joint-space colours. In an atomic."""
        solved, state, highlight = frame.solved, frame.state, frame.highlight
        if not arm_kind(solver).draws_joint_space:
            return
        num_joints = solver.num_links
        self.controls.fit(num_joints)
        if not self.wanted(solver):
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
        field = self.last_field = self.field_at(solved, state, joints, highlight, count)
        if field is None:  # no arrows until they are computed: never another pair's or held pose's
            if self.arrows.visible:
                self.arrows.visible = False
            if self.ask_fields is not None:
                self.ask_fields(solved, joints, highlight, count)
        else:
            self.arrows.points = arrow_segments(square, field.starts, field.arrows, count, ARROW_LIFT * reach)
            if not self.arrows.visible:
                self.arrows.visible = True
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


# Drawable arrays of the joint-space view: a flat square beside the workspace that shows two joints' torus.
GAP = 0.2  # between the workspace's outer circle and the square, in units of the reach
SIDE = 1.8  # the square's side, in units of the reach
ARROW_CELL_FILL = 0.9  # an arrow of length pi (the farthest x̂0 can be on one joint) spans this much of a cell
ARROW_HEAD = 0.3  # head length as a share of the drawn arrow
ARROW_HEAD_ANGLE = math.radians(25.0)
ARROW_MIN_HEAD = 0.08  # head length floor, in cells, so that short arrows still show their direction
CROSS_CELLS = 0.035  # half the arms of a solution's cross, as a share of the side


@dataclass(frozen=True)
class Square:
    """Where the joint-space square lies in the scene: centre (x, y), side, and the height it is drawn at."""

    centre: tuple[float, float]
    side: float
    z: float

    def place(self, angles, lift: float = 0.0) -> np.ndarray:
        """Angles (..., 2) in radians -> scene points (..., 3); wrapped first, so any angle lands in the square."""
        unit = (wrap_to_square(angles) + math.pi) / (2 * math.pi) - 0.5  # (..., 2) in [-0.5, 0.5)
        xy = np.asarray(self.centre) + unit * self.side
        return np.concatenate((xy, np.full(xy.shape[:-1] + (1,), self.z + lift)), axis=-1)

    def scale(self) -> float:
        """Scene length of one radian."""
        return self.side / (2 * math.pi)


def square_beside(reach: float, clear_of: float | None = None) -> Square:
    """The square to the right of a workspace of radius `reach` (the base at the origin), level with it; with
    `clear_of`, its left edge past x = clear_of too (the ground grid's edge: a square over the grid is hard to read)."""
    left = (1 + GAP) * reach if clear_of is None else max((1 + GAP) * reach, clear_of + 0.5 * GAP * reach)
    return Square(centre=(left + SIDE / 2 * reach, 0.0), side=SIDE * reach, z=0.0)


def camera_over_both(reach: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera above the workspace and the square together, as camera_fit frames one."""
    left, right = -reach, (1 + GAP + SIDE) * reach
    half, middle = (right - left) / 2, (right + left) / 2
    distance = 1.55 * half  # camera.camera_fit's framing of a radius-`half` disc
    return (middle, -1e-3 * distance, distance), (middle, 0.0, 0.0)


def frame_segments(square: Square) -> tuple[np.ndarray, np.ndarray]:
    """The square's border and its lines at multiples of pi/2, (M, 2, 3); and which are the border or zero (M,)."""
    ticks = np.array([-math.pi, -math.pi / 2, 0.0, math.pi / 2, math.pi])
    ends = np.array([-math.pi, math.pi])
    segments, strong = [], []
    for tick in ticks:
        for line in ((np.full(2, tick), ends), (ends, np.full(2, tick))):
            angles = np.stack(line, axis=-1)  # (2, 2): the line's two ends
            unit = (angles + math.pi) / (2 * math.pi) - 0.5  # no wrap: pi is the far edge here
            xy = np.asarray(square.centre) + unit * square.side
            segments.append(np.concatenate((xy, np.full((2, 1), square.z)), axis=-1))
            strong.append(tick in (-math.pi, 0.0, math.pi))
    return np.stack(segments), np.array(strong)


def arrow_segments(square: Square, starts: np.ndarray, arrows: np.ndarray, count: int, lift: float) -> np.ndarray:
    """Short arrows from `starts` (M, 2) along `arrows` (M, 2), radians, as shaft and two head strokes (3M, 2, 3).

    Lengths are to scale with one another: an arrow of length pi fills ARROW_CELL_FILL of a grid cell
    of a count x count grid, and none is drawn longer than a cell, so arrows never cross.
    """
    cell = 2 * math.pi / count
    drawn = np.asarray(arrows, dtype=np.float64) * (ARROW_CELL_FILL * cell / math.pi)  # (M, 2) radians
    length = np.linalg.norm(drawn, axis=-1, keepdims=True)
    drawn = np.where(length > cell, drawn * cell / np.maximum(length, 1e-12), drawn)
    length = np.minimum(length, cell)
    base = square.place(starts)[:, :2]
    tip = base + drawn * square.scale()  # not wrapped: the arrow's tip may reach a little past the edge
    direction = drawn / np.maximum(length, 1e-12)  # (M, 2)
    head = np.maximum(ARROW_HEAD * length, ARROW_MIN_HEAD * cell) * square.scale()  # (M, 1)
    strokes = []
    for side in (1.0, -1.0):
        cos, sin = math.cos(ARROW_HEAD_ANGLE), side * math.sin(ARROW_HEAD_ANGLE)
        turned = (cos * direction[:, 0] - sin * direction[:, 1], sin * direction[:, 0] + cos * direction[:, 1])
        back = -np.stack(turned, axis=-1)  # the arrow's direction turned by +-ARROW_HEAD_ANGLE, reversed
        strokes.append(np.stack((tip, tip + head * back), axis=1))
    shafts = np.stack((base, tip), axis=1)  # (M, 2, 2)
    segments = np.stack((shafts, *strokes), axis=1).reshape(-1, 2, 2)  # per arrow: shaft, head, head
    return np.concatenate((segments, np.full(segments.shape[:-1] + (1,), square.z + lift)), axis=-1)


def cross_segments(square: Square, points: np.ndarray, lift: float) -> np.ndarray:
    """A diagonal cross on each point (P, 2) radians, (2P, 2, 3): the target's mark, in joint space."""
    centres = square.place(np.asarray(points, dtype=np.float64).reshape(-1, 2), lift)  # (P, 3)
    arm = CROSS_CELLS * square.side
    strokes = [np.stack((centres - offset, centres + offset), axis=1) for offset in ((arm, arm, 0), (arm, -arm, 0))]
    segments = np.stack(strokes, axis=1).reshape(-1, 2, 3)
    (cx, cy), half = square.centre, square.side / 2  # a cross on an edge is cut there, not spilled outside
    segments[..., 0] = np.clip(segments[..., 0], cx - half, cx + half)
    segments[..., 1] = np.clip(segments[..., 1], cy - half, cy + half)
    return segments


def curve_segments(square: Square, curve: np.ndarray, lift: float) -> np.ndarray:
    """A closed curve of angles (C, 2) as segments (M, 2, 3), cut where it crosses the square's seam."""
    curve = wrap_to_square(curve)
    following = np.roll(curve, -1, axis=0)
    jumps = np.abs(following - curve).max(axis=-1) > math.pi  # the next point is across an edge
    ends = np.stack((curve, following), axis=1)[~jumps]  # (M, 2, 2)
    return square.place(ends, lift)


# Everything drawn in the scene, as components: the arm view and the side views beside it, and the one camera.
class Stage:
    """The arm view, the side views and the camera over them; written by the drawing loop only."""

    def __init__(self, server, panel, solver, target: np.ndarray, gizmo_update):
        self.server = server
        # No environment map: its reflections wash dark materials out to grey; the default lights stay.
        server.scene.configure_environment_map(hdri=None)
        # No shadow maps: nothing here casts one, and software WebGL drew the empty page at 16-26 frames/s with
        # them, 27-29 without
        server.scene.configure_default_lights(cast_shadow=False)
        self.view = arm_view(server, solver, target, gizmo_update)
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
