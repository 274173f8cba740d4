"""The viewer's Constraints folder: a partial target, lock joints, drop and drag obstacles, stay near, follow.

Controls live in their own folder of the panel; the app reads `constraints()` into each
solve request and hands each finished solve to `after_solve`. Every handler runs on the drawing
loop's thread (`on_loop`, the scene writer's `run`): the loop alone changes the obstacles, writes
their nodes, the overlay and the folder's own controls, so nothing here needs a lock; `constraints()`
only reads (a copy of the list, whole values), from whichever thread asks for a solve.

- target (pose models only): the full pose, the position only (ikdp.PositionOnly: the gizmo's
  rotation rings are hidden), or the hand free to turn about its x, y or z axis (ikdp.FreeAxis:
  the axis drawn through the target, with a ring about it); the readouts then measure that;
- lock: a checkbox and a value per joint (absolute headings on a planar arm);
- add obstacle: a sphere (a disc on a planar arm) with a gizmo to drag it, between the base
  and the target; its radius is the panel's at the time it is dropped;
- stay near the last pose: every solve is pulled toward the pose last kept (ikdp.NearPose);
- follow: ikdp.tracking's step from the last pose kept (solver.track's, one target at a time): dragging
  the target keeps the arm on one continuous solution; the readout gives the largest joint jump so far;
- colour by constraint: the highlighted sample at every state of the reverse process, green
  where the constraints hold and red where not (constraint_scene.py), and every sample on screen
  by the same rule at the state shown (the scene writer's `constraint_tints`).
"""

from __future__ import annotations

import numpy as np
import viser

from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.camera import camera_fit_3d
from ikdp_viz.constraint_scene import (
    LINK_CLEARANCE,
    TARGET_KINDS,
    beside_the_arm,
    build_constraints,
    holds,
    overlay_segments,
    readout_text,
)
from ikdp_viz.planar_scene import line_colors
from ikdp_viz.style import FREE_AXIS_COLOR, OBSTACLE

FREE_AXIS_LENGTH = 0.35  # the free axis drawn through the target, either way, in reach radii
FREE_AXIS_RING = 0.12  # the ring about it (the turn left free), radius in reach radii: outside the gizmo's arrows


class ConstraintControls:
    """The Constraints folder and its scene nodes for one model; `rebuild` for another."""

    def __init__(self, server: viser.ViserServer, solver, on_loop, on_change, on_loop_thread):
        self.server = server
        self.on_loop = on_loop  # the scene writer's run(function, wait=): on the drawing loop's thread
        self.on_loop_thread = on_loop_thread  # True on the drawing loop's own thread
        self.on_change = on_change  # ask for a new solve
        self.obstacles: list[dict] = []  # {"position": (3,), "radius": float, "nodes": [...]}
        self.last_pose: np.ndarray | None = None  # the pose kept from the last solve
        self.largest_jump, self.branch_switches = 0.0, 0  # follow mode's, since it was turned on (ikdp.tracking's)
        self.highlight_set: tuple | None = None  # (panel, number) follow mode wrote into the highlight dropdown
        self.overlay = self.target_marks = None  # the coloured states; the free axis and its ring (target's child)
        self._overlay_of: tuple | None = None  # (solve, sample, on) the overlay was drawn for
        self.build(solver)

    # ------------------------------------------------------------------ the folder

    def build(self, solver) -> None:
        self.solver = solver
        arm = solver.arm
        kind = arm_kind(solver)
        gui = self.server.gui
        self.fields = arm_kind(solver).lock_fields(arm)
        self.folder = gui.add_folder("Constraints", expand_by_default=False)
        with self.folder:
            self.target_kind = None  # a planar arm's target is a point: nothing to leave free
            if kind.pose_targets and arm.target_dim == 7:
                self.target_kind = gui.add_dropdown(
                    "target", tuple(TARGET_KINDS), initial_value="full pose",
                    hint="What the hand must reach: the whole pose, its position only, or the pose up to a turn "
                    "about one of the hand's axes",
                )  # fmt: skip
            note = kind.partial_target_note  # why there is no "target" dropdown, where that needs saying
            if note is not None:
                gui.add_markdown(note)
            self.lock_boxes, self.lock_values = [], []
            for field in self.fields:
                box = gui.add_checkbox(f"lock {field.name}", False)
                value = gui.add_number(
                    field.label, field.initial, min=field.low, max=field.high, step=0.1, disabled=True,
                    hint="any angle: it wraps into (-180°, 180°]" if field.wraps else "within the joint's limits",
                )  # fmt: skip
                on_lock = lambda _, box=box, value=value: self._on_lock(box, value)
                box.on_update(lambda event, on_lock=on_lock: self._loop(event, on_lock))
                value.on_update(lambda _: self.on_change())
                self.lock_boxes.append(box)
                self.lock_values.append(value)
            span = arm.span
            self.radius = gui.add_number("obstacle radius", kind.obstacle_radius(arm), min=0.01, max=span, step=0.01)
            self.add_button = gui.add_button("Add obstacle", hint="A sphere (a disc) no link may touch; drag it")
            self.clear_button = gui.add_button("Clear obstacles")
            self.stay_near = gui.add_checkbox("stay near the last pose", False, hint="Pull every solve toward it")
            self.follow = gui.add_checkbox(
                "follow (one continuous solution)", False,
                hint="Each target from the last pose as solver.track goes: the nearest pose that reaches it",
            )  # fmt: skip
            self.color_states = gui.add_checkbox(
                "colour poses by constraint",
                True,
                hint="Every sample at the step shown, and the highlighted one's past steps (faint): green where "
                "the constraints hold, red where not",
            )
            self.readout = gui.add_markdown("No constraint.")
        self.add_button.on_click(lambda _: self.add_obstacle())
        self.clear_button.on_click(lambda _: self.clear_obstacles())
        for toggle in (self.stay_near, self.follow):
            toggle.on_update(lambda event: self._loop(event, lambda _: self._on_near()))
        self.color_states.on_update(lambda event: self._loop(event, self._on_color_states))
        if self.target_kind is not None:
            self.target_kind.on_update(lambda event: self._loop(event, self._on_target_kind))

    def _loop(self, event, handler) -> None:
        """handler(writer) on the drawing loop; a value set from Python waits for it. A control the loop itself
        wrote asks nothing (the loop does what follows from it)."""
        if self.on_loop_thread():
            return
        self.on_loop(handler, wait=event.client is None)

    def _on_color_states(self, writer) -> None:
        """Writer thread: the overlay and every sample's colours follow the checkbox (the frame redrawn draws both)."""
        writer.set_constraint_colors(self.color_states.value)

    def _on_target_kind(self, writer) -> None:
        self._draw_target_marks(writer, str(self.target_kind.value))
        self.on_change()

    def rebuild(self, solver, writer) -> None:
        """Drawing loop's thread: another model, a fresh folder for its joints, no obstacles, no last pose."""
        self._clear(writer, ask=False)
        self._remove_overlay()
        self._draw_target_marks(writer, "full pose")
        self.folder.remove()
        self.last_pose, self.largest_jump, self.branch_switches = None, 0.0, 0
        self.build(solver)

    def _on_lock(self, box, value) -> None:
        value.disabled = not box.value
        self.on_change()

    def _on_near(self) -> None:
        if not (self.stay_near.value or self.follow.value):
            self.largest_jump, self.branch_switches = 0.0, 0
        if not self.follow.value and self.highlight_set is not None:
            # follow mode had set the highlight to the sample it kept: give "best" back, unless the
            # user chose another sample since
            panel, number = self.highlight_set
            self.highlight_set = None
            if panel.highlight.value == number:
                panel.highlight.value = "best"
        self.on_change()

    # ------------------------------------------------------------------ what a solve asks for

    def constraints(self) -> tuple:
        """The panel's constraints now, as ikdp constraint objects (any thread: it only reads)."""
        locks = self.locks()[0]
        obstacles = [(entry["position"], entry["radius"]) for entry in tuple(self.obstacles)]  # the loop may add one
        near = self.last_pose if (self.stay_near.value and not self.follow.value) else None  # follow: track's own
        kind = "full pose" if self.target_kind is None else str(self.target_kind.value)
        return build_constraints(locks, obstacles, near, planar=arm_kind(self.solver).flat, target_kind=kind)

    def follow_from(self) -> np.ndarray | None:
        """The pose follow mode's next step goes from (any thread: it only reads); None while not following."""
        return self.last_pose if self.follow.value else None

    def locks(self) -> tuple[dict[int, float], list[str]]:
        """The locked joints' values (rad or m) from the fields, and a note per value wrapped or clamped."""
        locks, notes = {}, []
        for index, (field, box, value) in enumerate(zip(self.fields, self.lock_boxes, self.lock_values, strict=True)):
            if box.value:
                locks[index], note = field.joint_value(value.value)
                notes += [note] if note else []
        return locks, notes

    # ------------------------------------------------------------------ what the target asks for, in the scene

    def _draw_target_marks(self, writer, kind: str) -> None:
        """Writer thread: position only hides the gizmo's rotation rings (its rotation asks nothing); a free axis
        is drawn through the target, along the hand's axis, with a ring about it for the turn left free."""
        if self.target_marks is not None:
            self.target_marks.remove()
            self.target_marks = None
        if self.target_kind is None:
            return
        writer.view.gizmo.disable_rotations = kind == "position only"
        axis = TARGET_KINDS.get(kind)
        if kind == "full pose" or axis is None:
            return
        self.target_marks = self.server.scene.add_line_segments(
            "/target/free_axis", free_axis_segments(np.asarray(axis), writer.view.reach), FREE_AXIS_COLOR,
            thickness=4.0, thickness_units="screen",
        )  # fmt: skip

    # ------------------------------------------------------------------ obstacles

    def add_obstacle(self, position=None, radius: float | None = None) -> int:
        """Drop an obstacle (where `obstacle_drop` puts it when no position is given); returns its index. Any
        thread: it runs on the drawing loop and waits for it."""
        added: list[int] = []
        self.on_loop(lambda writer: (added.append(self._add_obstacle(position, radius)), self._said(writer)), wait=True)
        return added[0]

    def _add_obstacle(self, position, radius: float | None) -> int:
        radius = float(self.radius.value if radius is None else radius)
        if position is None:
            position = obstacle_drop(self.solver.arm, self.last_pose, radius, arm_kind(self.solver))
        entry = {"position": np.asarray(position, dtype=np.float64), "radius": radius, "nodes": []}
        index = len(self.obstacles)
        entry["nodes"] = obstacle_nodes(self.server, index, entry, planar=arm_kind(self.solver).flat,
                                        moved=self.move_obstacle)  # fmt: skip
        self.obstacles = [*self.obstacles, entry]  # a new list: a solve request may be copying the old one
        self.on_change()
        return index

    def _said(self, writer) -> None:
        """The legend lists the obstacles while any is drawn (drawing loop's thread)."""
        writer.show_obstacles(len(self.obstacles))

    def move_obstacle(self, index: int, position) -> None:
        """The obstacle's gizmo callback: the loop moves it and asks for a solve."""
        position = np.asarray(position, dtype=np.float64)

        def move(_) -> None:
            if index < len(self.obstacles):  # a drag's last event may come after Clear
                self.obstacles[index]["position"] = position
                self.on_change()

        self.on_loop(move, wait=False)

    def clear_obstacles(self, ask: bool = True) -> None:
        """Remove every obstacle (any thread but the drawing loop's: it runs there and waits)."""
        self.on_loop(lambda writer: self._clear(writer, ask), wait=True)

    def _clear(self, writer, ask: bool) -> None:
        removed, self.obstacles = self.obstacles, []
        for entry in removed:
            for node in entry["nodes"]:
                node.remove()
        self._said(writer)
        if ask:
            self.on_change()

    # ------------------------------------------------------------------ after a solve

    def after_solve(self, solved, panel, writer) -> None:
        """Drawing loop's thread, as a solve goes on screen: keep the pose (follow: the one tracking's step kept,
        highlighted), write the readouts."""
        writer.followed = bool(self.follow.value)
        if solved.final_angles is not None and solved.request.model is self.solver:  # not a replaced model's
            self._after_solve(solved, panel)

    def _after_solve(self, solved, panel) -> None:
        view = solved.view
        errors = view.final_error  # a robot's counts the rotation (or a free axis's angle): a turned hand is a miss
        if solved.state_violation is not None and holds(solved.state_violation[-1]).any():
            errors = np.where(holds(solved.state_violation[-1]), errors, np.inf)  # a sample through an obstacle
            # is no candidate
        following = bool(self.follow.value)
        choice, jump, switched = int(np.argmin(errors)), 0.0, False  # the first pose followed: the best
        if following and solved.followed is not None:  # tracking's step: its pose, jump and branch switch
            choice = solved.followed_sample
            jump = float(solved.followed.kept.joint_jumps[0])
            switched = bool(solved.followed.kept.branch_switches[0])
            self.branch_switches += int(switched)
        if following:
            self.largest_jump = max(self.largest_jump, jump)
            panel.highlight.value = str(choice + 1)
            self.highlight_set = (panel, str(choice + 1))
        elif panel.highlight.value != "best":
            choice = min(int(panel.highlight.value), len(errors)) - 1
        self.last_pose = solved.final_angles[choice].copy()
        self.readout.content = readout_text(
            solved,
            choice,
            jump if following else None,
            self.largest_jump,
            self.locks()[1],
            reaches=solved.reaches,
            switches=self.branch_switches,
            switched=switched,
        )

    def _remove_overlay(self) -> None:
        if self.overlay is not None:
            self.overlay.remove()
            self.overlay = None
        self._overlay_of = None

    def draw_overlay(self, frame) -> None:
        """Drawing loop, inside the frame's `server.atomic()`: the frame's highlighted sample at every state,
        coloured by whether its constraints hold; written again only when the solve, the sample or the checkbox
        changed, so it never shows another sample than the frame's."""
        solved = frame.solved
        shown = solved.state_violation is not None and solved.request.model is self.solver and self.color_states.value
        drawn = self._overlay_of
        if drawn is not None and drawn[0] is solved and drawn[1:] == (frame.highlight, shown):
            return
        self._remove_overlay()
        self._overlay_of = (solved, frame.highlight, shown)
        if not shown:
            return
        path, polylines = arm_kind(self.solver).sample_path(solved.view, frame.highlight)
        segments, colors = overlay_segments(path, solved.state_violation[:, frame.highlight], polylines)
        self.overlay = self.server.scene.add_line_segments(
            "/constraints/states", segments, line_colors(colors), thickness=2.0, thickness_units="screen"
        )


def free_axis_segments(axis: np.ndarray, reach: float) -> np.ndarray:
    """(M, 2, 3) in the target's frame: the line along `axis` (3,) through it, and a ring of 32 segments about it."""
    axis = axis / np.linalg.norm(axis)
    line = np.stack([-axis, axis])[None] * FREE_AXIS_LENGTH * reach  # (1, 2, 3)
    across = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    across /= np.linalg.norm(across)
    other = np.cross(axis, across)
    angles = np.linspace(0.0, 2 * np.pi, 33)
    ring = FREE_AXIS_RING * reach * (np.cos(angles)[:, None] * across + np.sin(angles)[:, None] * other)  # (33, 3)
    return np.concatenate([line, np.stack([ring[:-1], ring[1:]], axis=1)]).astype(np.float32)


def obstacle_drop(arm, last_pose, radius: float, kind) -> np.ndarray:
    """(3,) where a new obstacle goes: on the middle of the arm as it stands, so the easy solution is blocked (a
    robot's just in front of it, toward the camera, or its opaque meshes hide the sphere)."""
    if last_pose is None:
        return np.array([0.3 * arm.span, 0.3 * arm.span, 0.0])
    points = arm.forward_kinematics(np.asarray(last_pose, dtype=np.float64)[None])[0].numpy()
    if points.shape[-1] == 3:
        reach = float(arm.reach[1])
        camera = camera_fit_3d(kind.reach_center(arm), reach)[0]
        return beside_the_arm(points, radius, camera, LINK_CLEARANCE * reach)
    return np.concatenate([points[len(points) // 2], [0.0]])


def obstacle_nodes(server, index: int, entry: dict, *, planar: bool, moved) -> list:
    """The obstacle's sphere and its gizmo (in the plane for a planar arm), the sphere a child that moves with it;
    `moved(index, position)` on each drag."""
    gizmo = server.scene.add_transform_controls(
        f"/constraints/obstacle_{index}", scale=max(2 * entry["radius"], 0.1), disable_rotations=True,
        active_axes=(True, True, not planar), position=tuple(entry["position"]),
    )  # fmt: skip
    sphere = server.scene.add_icosphere(
        f"/constraints/obstacle_{index}/sphere", radius=entry["radius"], color=OBSTACLE,
        # a robot's: denser and flat-lit, so it reads as a ball in front of the dark meshes
        opacity=0.45 if planar else 0.6, material="standard" if planar else "toon3",
        subdivisions=2, cast_shadow=False, receive_shadow=False,
    )  # fmt: skip
    gizmo.on_update(lambda event: moved(index, event.target.position))
    return [sphere, gizmo]
