"""A robot's kind (a chain from a URDF, or a tree of chains): its maths, texts, colours and legend; its nodes are
robot_view.py's.

A chain is a tree with one end effector: ChainKind handles E end effectors (a target is E poses, one gizmo, hand
frame, trail and readout per hand); TreeKind only says how a tree's arm lays them out (ikdp.tree_arm.TreeArm: a
flat target row, every position then every quaternion; one polyline of points per chain). No viser here.
`arm_kinds.arm_kind(solver)` picks one of them or planar_kind.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ikdp_viz import chain_scene, readouts
from ikdp_viz.chain_scene import ghost_colors, pose_target
from ikdp_viz.constraint_scene import holds, sample_tints
from ikdp_viz.planar_kind import PLAYING_FOLLOWED_STATES, PLAYING_TRAIL_STATES, shown_layers
from ikdp_viz.planar_scene import emphasis_colors, follows_one, trail_colors
from ikdp_viz.style import (
    ACCENT_DARK,
    ACCENT_FAINT,
    DARK,
    FAINT,
    FRAME_Y_GREEN,
    FREE_AXIS_COLOR,
    GHOST_DARK,
    GHOST_FAINT,
    HAND_RED,
    HIGHLIGHTED_ROBOT,
    HOLDS,
    OTHERS_FINAL,
    TARGET_RED,
    VIOLATES,
    Entry,
    Swatch,
)

# darkens a mesh and the Panda's links are near black in their own shadows
GHOST_OPACITY = 0.15  # the samples not highlighted: seen through, so the highlighted robot stays readable
# a see-through robot that breaks a constraint at the step shown: at 0.15 its red read as a pale pink beside the
# greens, so the ones in collision are drawn denser (viser multiplies each robot's factor into the node's opacity)
VIOLATING_GHOST_OPACITY = 0.45


def ghost_opacities(holding: np.ndarray) -> np.ndarray:
    """(..., K) whether each see-through robot meets the constraints -> (..., K) float32 factors of the ghosts'
    node opacity (VIOLATING_GHOST_OPACITY): the usual GHOST_OPACITY where it holds, the full node opacity where not."""
    return np.where(holding, GHOST_OPACITY / VIOLATING_GHOST_OPACITY, 1.0).astype(np.float32)


@dataclass(frozen=True)
class ChainPalette:
    """The colours of one robot solve with one sample highlighted, every state at once."""

    lines: np.ndarray  # (S+1, K, 3) uint8 each skeleton's colour at each state
    skeletons: np.ndarray  # (S+1, K*J, 2, 3) uint8 per skeleton segment
    trail: np.ndarray  # (S+1, K, 2, 3) uint8 each hand step's colour
    ghosts: np.ndarray  # (S+1, K, 3) uint8 each robot's mesh colour (the highlighted one's: the opaque robot)
    ghost_opacities: np.ndarray  # (S+1, K) float32 factors of the ghosts' opacity


class ChainKind:
    """A robot from a URDF (ikdp.chain_arm.ChainArm): pose targets (7,) position m + wxyz, a reach ball.

    Written for E end effectors, E = 1 here: the methods from `effector_names` to `mesh_chains` are all
    that tell a chain's arm from a tree's (TreeKind)."""

    name = "chain"
    # The paper's DDPM, as for the planar arm: for the shipped Panda (20 targets, K = 16) the samples' median
    # error is 9.8 mm / 3.0 deg against DPM-Solver++(2M)-10's 24.4 mm / 8.6 deg, for 210 ms a solve instead of
    # 12 (benchmarks/viz_robot_settings.py); the steps apply when the user picks a sampler that skips some.
    default_sampler = ("ddpm", 10)
    # A robot's model with a distilled student opens on it: a new target's first frame after
    # a few network evaluations, the teacher's full DDPM one click away (student.py)
    opens_on_student = True
    opens_with_trail = False  # a robot's hand paths cage it near t = T

    @staticmethod
    def sample_path(view, sample: int) -> tuple[np.ndarray, tuple[int, ...]]:
        """(S, J+1, 3) one sample's joint origins at every state: the constraint overlay's polylines, and their
        point counts along J+1 (chain_scene.skeleton_segments' `polylines`)."""
        return view.points[:, sample], view.polylines

    chart_error, chart_unit, chart_scale = "hand position error", "mm", 1000.0  # view.tip_error is in metres
    holds_text = "constraints hold at the step shown"
    flat = False
    pose_targets = True  # the Constraints folder offers a partial target: the position only, a turn left free
    teaches = False  # the tour and "noise it" are the planar arm's
    previews_drags = True  # a fast solve drawn first while a drag goes on (solving.preview_request)
    draws_joint_space = False

    @staticmethod
    def target_from_numbers(values, solver, current) -> np.ndarray:
        """The typed numbers as a target, not yet pulled into reach (typed_target.py)."""
        from ikdp_viz.typed_target import pose_from_numbers  # here: the kinds import no viser

        return pose_from_numbers(values, target_dim=solver.arm.target_dim, current=current)

    @staticmethod
    def lock_fields(arm) -> list:
        from ikdp_viz.typed_target import joint_lock_fields

        return joint_lock_fields(arm)

    @staticmethod
    def obstacle_radius(arm) -> float:
        return 0.08  # metres: a ball about a hand's size

    violates_text = "constraints fail at the step shown (those see-through robots denser)"

    # -------------------------------------------------------------- the end effectors of the arm

    def effector_names(self, arm) -> tuple[str, ...]:
        """The end effectors' link names, in the order of the target's rows."""
        return (arm.ee_link,)

    def polylines(self, arm) -> tuple[int, ...]:
        """Point counts of the polylines `arm.forward_kinematics` lays one after another; (): a chain's one."""
        return ()

    def pose_rows(self, arm, target) -> np.ndarray:
        """The flat target (target_dim,) -> one row per end effector, (E, 7) or (E, 3)."""
        return np.asarray(target, dtype=np.float64).reshape(1, -1)

    def flat_target(self, arm, rows) -> np.ndarray:
        """One row per end effector (E, 7 or 3) -> the flat target the solver takes (target_dim,)."""
        return np.asarray(rows, dtype=np.float64).reshape(-1)

    def hand_poses(self, arm, joint_values) -> tuple[np.ndarray, np.ndarray]:
        """Each end effector's position (E, 3) and wxyz (E, 4) at joint values (J,)."""
        position, wxyz = chain_scene.gizmo_pose(arm, joint_values)
        return position[None], wxyz[None]

    def effector_errors(self, arm, joints: torch.Tensor, goal: torch.Tensor, bound, measure: str):
        """Each end effector's position error (..., E), metres, and rotation error (..., E), radians, of joints (..., J)
        against the flat `goal`; `bound` the partial target's bound constraint (None: the full pose), `measure` what
        its rotation error measures (chain_scene.rotation_measure)."""
        position = arm.position_error(joints, goal).double().numpy()
        if arm.target_dim != 7 or measure == "none":
            return position[..., None], np.zeros(position.shape + (1,))
        goals = goal.expand(*joints.shape[:-1], 7)
        rotation = arm.rotation_error(joints, goals) if bound is None else bound.rotation_error(joints, goals)
        return position[..., None], rotation.double().numpy()[..., None]

    def reach_center(self, arm) -> np.ndarray:
        """(3,) the point the floor and the camera centre on: the base of the reach ball."""
        return arm.reach_center.double().numpy()

    def reach_centers(self, arm) -> np.ndarray:
        """(E, 3) the centre of each end effector's reach ball."""
        return self.reach_center(arm)[None]

    def reach_radii(self, arm) -> np.ndarray:
        """(E,) the radius of each end effector's reach ball."""
        return np.array([float(arm.reach[1])])

    def mesh_chains(self, arm) -> list:
        """The chains (ikdp.chain_arm.ChainArm) whose URDF's link meshes are drawn."""
        return [arm]

    # -------------------------------------------------------------- texts every end effector shares

    partial_target_note = None  # the Constraints folder's "target" dropdown offers a chain's partial targets
    hand_frame_text = "hand frame of the highlighted robot: x red, y green, z blue"
    skeleton_text = "skeletons: joint origins to the hand"
    gizmo_text = "target: the gizmo's pose (drag its arrows and rings)"
    recorded_target_text = "target: the frame at the target pose, x red, y green, z blue"
    followed_trail_text = "the highlighted hand's path"

    def gizmo_names(self, arm) -> tuple[str, ...]:
        """The scene names of the target gizmos, one per end effector."""
        return ("/target",)

    def beyond_reach(self, arm, target, clamped: bool) -> np.ndarray:
        """(E,) bool: the end effectors whose target position was moved onto their reach ball (`clamped`: the
        target as asked was moved)."""
        if not clamped:
            return np.zeros(len(self.effector_names(arm)), bool)
        return self.on_reach_ball(arm, target)

    def on_reach_ball(self, arm, target) -> np.ndarray:
        """(E,) bool: the end effectors whose target position lies on (or past) their reach ball's surface, where
        `clamp` puts a position asked for beyond it."""
        distance = np.linalg.norm(self.pose_rows(arm, target)[:, :3] - self.reach_centers(arm), axis=-1)
        return distance >= self.reach_radii(arm) * (1 - 1e-6)

    def configure_panel(self, panel) -> None:
        """The panel's controls as a robot starts: the hands' trail off, the planar-only views hidden."""
        # Off at start: near t = T the hands jump across the whole reach ball, and their paths cage the robots.
        panel.show_trail.value = False
        panel.joint_space.folder.visible = False  # the joint space view draws planar arms only
        panel.teach.noise_it.visible = False  # the forward process is drawn for a planar arm's poses only

    def initial_target(self, solver, target=None) -> np.ndarray:
        """(target_dim,) `target` pulled into reach; the hands at mid-limits (surely reachable) when None."""
        arm = solver.arm
        if target is None or np.asarray(target).size != arm.target_dim:
            middle = arm.joint_limits.double().mean(dim=-1).numpy()  # (J,)
            positions, wxyzs = self.hand_poses(arm, middle)
            rows = np.stack([pose_target(position, wxyz) for position, wxyz in zip(positions, wxyzs, strict=True)])
            return self.flat_target(arm, rows[:, : arm.target_dim // len(rows)])
        return self.clamp(solver, target)[0]

    def target_layout(self, arm) -> str:
        """The numbers of a target, for an error message."""
        return "x, y, z, w, qx, qy, qz" if arm.target_dim == 7 else "x, y, z"

    def clamp(self, solver, point) -> tuple[np.ndarray, bool]:
        """A target (target_dim,) with each hand's position pulled onto its reach ball, and whether one moved.
        A pose's quaternions come back normalised with w >= 0."""
        arm = solver.arm
        size = arm.target_dim
        point = np.asarray(point, dtype=np.float64).reshape(-1)
        if point.shape != (size,) or not np.isfinite(point).all():
            raise ValueError(f"point: expected {size} finite numbers ({self.target_layout(arm)}), got {point.tolist()}")
        rows = self.pose_rows(arm, point)
        if rows.shape[1] == 7:
            rows = np.stack([pose_target(row[:3], row[3:]) for row in rows])
        inside = arm.clamp_to_workspace(torch.as_tensor(self.flat_target(arm, rows))).numpy()
        moved = not np.allclose(self.pose_rows(arm, inside)[:, :3], rows[:, :3], rtol=0.0, atol=1e-12)
        return inside, moved

    def gizmo_target(self, solver, gizmo, current) -> np.ndarray:
        """The target a dragged 6-DoF gizmo asks for: its hand's row its position then wxyz (or the position alone),
        every other hand's row that of `current`, the target before the drag."""
        arm = solver.arm
        rows = self.pose_rows(arm, current).copy()
        hand = self.gizmo_names(arm).index(gizmo.name)
        pose = np.concatenate((np.asarray(gizmo.position, np.float64), np.asarray(gizmo.wxyz, np.float64)))
        rows[hand] = pose[: rows.shape[1]]
        return self.flat_target(arm, rows)

    def drawable(self, result, solver, target, partial=None) -> tuple[chain_scene.ChainView, np.ndarray]:
        """A solve's view and its trail: the K hands' paths, (S+1, K, 2, 3). `partial`: the solve's partial
        target (ikdp.PositionOnly or FreeAxis), whose residual the errors then measure; None: the full pose."""
        view = chain_scene.build_chain_view(result, solver.arm, target, self, partial=partial)
        return view, chain_scene.hand_paths(view.points, view.hand_indices)

    def model_text(self, solver) -> str:
        arm = solver.arm
        return readouts.chain_model_text(
            arm, solver.timesteps, solver.metadata, effectors=self.effector_names(arm), chains=self.mesh_chains(arm)
        )

    def target_text(self, solver, target: np.ndarray, clamped: bool) -> str:
        arm = solver.arm
        names = self.effector_names(arm)
        rows = self.pose_rows(arm, target)
        beyond = self.beyond_reach(arm, target, clamped)
        if len(names) == 1:
            note = "  \n(out of reach: moved onto the reach ball, which bounds every pose the arm reaches)"
            return readouts.pose_text(target) + (note if clamped else "")
        lines = [readouts.pose_text(row, f"Target {name}") for name, row in zip(names, rows, strict=True)]
        if beyond.any():
            hands = ", ".join(name for name, far in zip(names, beyond, strict=True) if far)
            lines.append(f"(out of reach: {hands} moved onto its arm's reach ball, which bounds every pose it reaches)")
        return "  \n".join(lines)

    def target_words(self, target: np.ndarray, arm) -> str:
        """The target in a recording's label and an export's title: each hand's position, in mm."""
        rows = 1000 * self.pose_rows(arm, target)[:, :3]
        if len(rows) == 1:
            x, y, z = rows[0]
            return f"target x = {x:+.0f}, y = {y:+.0f}, z = {z:+.0f} mm"
        # several hands: (x, y, z) each, short enough for an export's title line
        return "targets " + ", ".join("({:+.0f}, {:+.0f}, {:+.0f})".format(*row) for row in rows) + " mm"

    def typed_numbers(self, inputs, arm) -> tuple[float, ...]:
        """The numbers typed in the panel's Target folder: metres from the mm fields, then roll pitch yaw."""
        position = tuple(float(value) / 1000 for value in inputs.position_mm.value)
        return position + (tuple(inputs.rotation_deg.value) if arm.target_dim == 7 else ())

    def write_typed_fields(self, inputs, target: np.ndarray) -> None:
        """The typed-target fields show the target solved: position in mm, rotation as roll pitch yaw in degrees."""
        from ikdp_viz.typed_target import roll_pitch_yaw_degrees  # here: it imports viser's SO3 helper

        inputs.show_fields(point=False, rotation=len(target) == 7)
        inputs.go.visible = True
        inputs.position_mm.value = tuple(round(1000 * float(value), 1) for value in target[:3])
        if len(target) == 7:
            inputs.rotation_deg.value = tuple(round(float(value), 1) for value in roll_pitch_yaw_degrees(target[3:7]))

    def flat_picture(self, solved) -> tuple[np.ndarray, np.ndarray, float | None, np.ndarray]:
        """What the exported files draw: the skeletons (S+1, K, J+1, 2) and the target's position (2,) projected
        (orthographically) as the viewer's camera sees them, no workspace circle. Several end effectors: each
        chain's polyline ends with a NaN point (so no line joins one hand to the next chain's base) and the targets
        are (E, 2)."""
        from ikdp_viz.camera import camera_fit_3d

        view = solved.view
        center = np.asarray(view.points[0, 0, 0], dtype=np.float64)  # the base: any point of the view's axis
        position, look_at = camera_fit_3d(center, 1.0)
        forward = (look_at - position) / np.linalg.norm(look_at - position)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        basis = np.stack([right, up], axis=-1)  # (3, 2)
        flat = view.points @ basis  # (S+1, K, P, 2)
        targets = np.asarray(view.target_poses[:, :3]) @ basis  # (E, 2)
        if view.num_effectors == 1:
            return flat, targets[0], None, None
        breaks = np.cumsum(view.point_counts)[:-1]  # a NaN after each polyline but the last: matplotlib stops there
        return np.insert(flat, breaks, np.nan, axis=2), targets, None, None

    def arm_colors(self, palette) -> np.ndarray:
        """(S+1, K, 3) each sample's line colour at each state, from this kind's palette: the skeletons'."""
        return palette.lines

    def light_trail_states(self, trail_of: str) -> int:
        return PLAYING_FOLLOWED_STATES if follows_one(trail_of) else PLAYING_TRAIL_STATES

    def palette(self, solved, highlight: int, trail_of: str, constraint_colors: bool) -> ChainPalette:
        view = solved.view
        # (S+1, K, 3) each: following one sample (the default), its skeleton blue and the others' light grey
        lines, ramp = emphasis_colors(view.num_states, view.num_samples, highlight, trail_of)
        ghosts = ghost_colors(view.num_states, view.num_samples, highlight)
        if follows_one(trail_of):
            ghosts[:, highlight] = HIGHLIGHTED_ROBOT  # the followed robot stands out at every step
        opacities = ghost_opacities(np.ones((view.num_states, view.num_samples), bool))
        if constraint_colors:  # every robot and skeleton green where its constraints hold, red where not, in full
            # colour: at the ghosts' opacity, and as thin lines sent as is (lighter on the page), the lighter tints
            # of the planar arms read as grey; the highlighted robot is the opaque one
            lines = ghosts = sample_tints(solved.state_violation, highlight, others_full=True)
            opacities = ghost_opacities(holds(solved.state_violation))
        return ChainPalette(
            lines=lines, skeletons=trail_colors(lines, view.num_segments), trail=trail_colors(ramp, view.num_effectors),
            ghosts=ghosts,
            ghost_opacities=opacities,
        )  # fmt: skip

    def solve_text(self, solved, state: int, highlight: int, reason: str, error: str | None) -> str:
        request = solved.request
        text = readouts.chain_solve_text(
            solved.view, state, highlight, sampler=request.sampler_label, seed=request.seed,
            refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds, reason=reason,
        )  # fmt: skip
        arm = request.solver.arm
        beyond = self.beyond_reach(arm, request.target, request.target_clamped)
        miss = readouts.miss_text(solved.view, arm, beyond_reach=beyond)
        text += "" if miss is None else "  \n" + miss
        return text + (f"  \n**Newest solve failed** {error}" if error else "")

    def legend_entries(self, settings, *, constraint_colors: bool, view, solved, state=None) -> list[Entry]:
        """What each colour of the 3-D scene means now, for the panel's legend (and a recording's)."""
        follows = follows_one(settings.trail_of)
        if constraint_colors:  # robots and skeletons green or red, the highlighted robot too
            robots = [Entry(Swatch(HOLDS), self.holds_text, True), Entry(Swatch(VIOLATES), self.violates_text, True)]
        else:
            robots = [
                Entry(
                    Swatch(HIGHLIGHTED_ROBOT if follows else ACCENT_DARK),
                    "highlighted robot (opaque), at the step shown",
                    True,
                ),  # fmt: skip
                Entry(Swatch(GHOST_DARK, faint=GHOST_FAINT), "the other robots (see-through), t = T → 0"),
                Entry(Swatch(OTHERS_FINAL if follows else DARK, faint=FAINT), self.skeleton_text, True),  # fmt: skip
            ]
        trail = "trail (show trail): " + (self.followed_trail_text if follows else "the hands' paths")
        if settings.recording:  # no panel to turn it on or off
            trail = trail.replace(" (show trail)", "")
        hand = Entry(Swatch(HAND_RED), self.hand_frame_text)
        ramp = Swatch(ACCENT_DARK, faint=ACCENT_FAINT) if follows else Swatch(DARK, faint=FAINT)
        trail_entry = Entry(ramp, trail, True)
        if settings.recording:  # a static page: what it draws alone, the target a frame no one can drag
            target = Entry(Swatch(TARGET_RED), self.recorded_target_text)
            return [*robots, *([trail_entry] if settings.show_trail else []), hand,
                    *shown_layers(settings, solved, state), target]  # fmt: skip
        # a comparison draws the same target beside as a frame (viser's axes) with a red origin: its green and
        # blue axes get a swatch of their own
        compared = getattr(solved, "compare", None) is not None
        frame_beside = [Entry(Swatch(FRAME_Y_GREEN), "beside: the target's frame, x red, y green, z blue")]
        entries = [
            *robots,
            *([trail_entry] if settings.show_trail else []),  # listed only while drawn, as every layer
            hand,
            *shown_layers(settings, solved, state),
            # the 3-D target is the gizmo, no red cross (the legend must not list one)
            Entry(Swatch(TARGET_RED), self.gizmo_text),
            *(frame_beside if compared else []),
        ]
        measure = getattr(view, "rotation_measure", "rotation") if view is not None else "rotation"
        if measure not in ("rotation", "none"):
            entries.append(Entry(Swatch(FREE_AXIS_COLOR), f"the hand's free {measure}: any turn about it counts"))
        return entries


class TreeKind(ChainKind):
    """A robot with several end effectors (ikdp.tree_arm.TreeArm, the G1's two hands on one waist): a target is
    one pose per hand, laid out flat (every position, then every quaternion); one gizmo, hand frame, trail and
    readout per hand. Reached: every hand within the arm's tolerances."""

    name = "tree"
    chart_error = "worst hand's position error"  # view.tip_error: the worst hand's, as the tree arm's own errors

    def effector_names(self, arm) -> tuple[str, ...]:
        return tuple(arm.ee_links)

    def polylines(self, arm) -> tuple[int, ...]:
        return tuple(chain.num_joints + 1 for chain in arm.chains)

    def pose_rows(self, arm, target) -> np.ndarray:
        flat = torch.as_tensor(np.asarray(target, dtype=np.float64).reshape(-1))
        return arm.stacked_targets(flat).numpy()

    def flat_target(self, arm, rows) -> np.ndarray:
        return arm.flat_targets(torch.as_tensor(np.asarray(rows, dtype=np.float64))).numpy()

    def hand_poses(self, arm, joint_values) -> tuple[np.ndarray, np.ndarray]:
        poses = arm.end_effector_pose(torch.as_tensor(np.asarray(joint_values), dtype=torch.float64)).numpy()
        return poses[:, :3], poses[:, 3:]

    def effector_errors(self, arm, joints: torch.Tensor, goal: torch.Tensor, bound, measure: str):
        goals = goal.expand(*joints.shape[:-1], arm.target_dim)
        position, rotation = (arm if bound is None else bound).errors_by_effector(joints, goals)
        position = position.double().numpy()
        if rotation is None or measure == "none":
            return position, np.zeros_like(position)
        return position, rotation.double().numpy()

    def reach_center(self, arm) -> np.ndarray:
        return self.reach_centers(arm).mean(axis=0)

    def reach_centers(self, arm) -> np.ndarray:
        return np.stack([chain.reach_center.double().numpy() for chain in arm.chains])

    def reach_radii(self, arm) -> np.ndarray:
        return np.array([float(chain.reach[1]) for chain in arm.chains])

    def mesh_chains(self, arm) -> list:
        return list(arm.chains)

    def target_layout(self, arm) -> str:
        width = "x, y, z" if arm.per_effector_dim == 3 else "x, y, z of each hand, then w, qx, qy, qz of each hand"
        return f"{width}; hands {list(arm.ee_links)}"

    partial_target_note = (  # the Constraints folder's line where a chain's "target" dropdown stands
        "target: each hand's full pose (a tree's partial targets, `ikdp.PositionOnly(effectors=...)` per hand, are "
        "the library's)"
    )
    hand_frame_text = "hand frames of the highlighted robot, one per hand: x red, y green, z blue"
    skeleton_text = "skeletons: joint origins, base to each hand"
    gizmo_text = "targets: one gizmo per hand, labelled with its link (drag one: that hand's target alone moves)"
    recorded_target_text = "targets: a frame at each hand's target pose, x red, y green, z blue"
    followed_trail_text = "the highlighted robot's hands' paths"

    def gizmo_names(self, arm) -> tuple[str, ...]:
        return tuple(f"/targets/{name}" for name in arm.ee_links)

    def beyond_reach(self, arm, target, clamped: bool) -> np.ndarray:
        """Each hand on its reach ball, whichever move put it there: `clamped` says only whether the last move
        pulled some hand in, and a drag of the other hand keeps this one's target where it was pulled."""
        return self.on_reach_ball(arm, target)

    pose_targets = False  # a tree's partial target is per hand (`partial_target_note`), not the folder's dropdown

    @staticmethod
    def target_from_numbers(values, solver, current) -> np.ndarray:
        """Every number of the target (the command line's `--target`): each hand's position, then each hand's
        w x y z; no shorthand names one hand of them."""
        from ikdp_viz.typed_target import finite_numbers  # here: the kinds import no viser

        values, size = finite_numbers(values), solver.arm.target_dim
        if values.size != size:
            raise ValueError(
                f"target: this model's target is {size} numbers (every hand's position, then every hand's w x y z), "
                f"got {values.size} numbers"
            )
        return values

    def typed_numbers(self, inputs, arm) -> tuple[float, ...]:
        """None typed: the fields take one hand's pose, and a tree's hands are set by their gizmos."""
        return ()

    def write_typed_fields(self, inputs, target: np.ndarray) -> None:
        """The typed-target fields hidden (`target_text` says why): they hold one hand's pose."""
        for field in (inputs.xy, inputs.position_mm, inputs.rotation_deg, inputs.go):
            field.visible = False

    def target_text(self, solver, target: np.ndarray, clamped: bool) -> str:
        return (super().target_text(solver, target, clamped) + "  \n*Drag each hand's gizmo*: the typed fields take "
                "one hand's pose, so a tree's targets are set in the scene")  # fmt: skip
