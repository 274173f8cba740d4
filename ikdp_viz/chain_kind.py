"""A robot's kind (a chain from a URDF): its maths, texts, colours and legend; its nodes are robot_view.py's.

No viser here. `arm_kinds.arm_kind(solver)` picks this or planar_kind.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ikdp_viz import chain_scene, readouts
from ikdp_viz.chain_scene import ghost_colors
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
    """A robot from a URDF (ikdp.chain_arm.ChainArm): pose targets (7,) position m + wxyz, a reach ball."""

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
    def sample_path(view, sample: int) -> np.ndarray:
        """(S, J+1, 3) one sample's joint origins at every state: the constraint overlay's polyline."""
        return view.points[:, sample]

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

    def configure_panel(self, panel) -> None:
        """The panel's controls as a robot starts: the hands' trail off, the planar-only views hidden."""
        # Off at start: near t = T the hands jump across the whole reach ball, and their paths cage the robots.
        panel.show_trail.value = False
        panel.joint_space.folder.visible = False  # the joint space view draws planar arms only

    def initial_target(self, solver, target=None) -> np.ndarray:
        """(target_dim,) `target` pulled into reach; the hand at mid-limits (surely reachable) when None."""
        if target is None or np.asarray(target).size != solver.arm.target_dim:
            return chain_scene.initial_pose_target(solver.arm)[: solver.arm.target_dim]
        return self.clamp(solver, target)[0]

    def clamp(self, solver, point) -> tuple[np.ndarray, bool]:
        """A target (7,) (or (3,) for position targets) with its position pulled onto the reach ball, and
        whether it moved. A pose's quaternion comes back normalised with w >= 0."""
        size = solver.arm.target_dim
        point = np.asarray(point, dtype=np.float64).reshape(-1)
        if point.shape != (size,) or not np.isfinite(point).all():
            what = "x, y, z, w, qx, qy, qz" if size == 7 else "x, y, z"
            raise ValueError(f"point: expected {size} finite numbers ({what}), got {point.tolist()}")
        target = chain_scene.pose_target(point[:3], point[3:]) if size == 7 else point
        inside = solver.arm.clamp_to_workspace(torch.as_tensor(target)).numpy()
        return inside, not np.allclose(inside[:3], target[:3], rtol=0.0, atol=1e-12)

    def gizmo_target(self, solver, gizmo) -> np.ndarray:
        """The target a dragged 6-DoF gizmo asks for: position then wxyz (7,), or the position alone."""
        pose = np.concatenate((np.asarray(gizmo.position, np.float64), np.asarray(gizmo.wxyz, np.float64)))
        return pose[: solver.arm.target_dim]

    def drawable(self, result, solver, target, partial=None) -> tuple[chain_scene.ChainView, np.ndarray]:
        """A solve's view and its trail: the K hands' paths, (S+1, K, 2, 3). `partial`: the solve's partial
        target (ikdp.PositionOnly or FreeAxis), whose residual the errors then measure; None: the full pose."""
        view = chain_scene.build_chain_view(result, solver.arm, target, partial=partial)
        return view, chain_scene.hand_paths(view.points)

    def model_text(self, solver) -> str:
        return readouts.chain_model_text(solver.arm, solver.timesteps, solver.metadata)

    def target_text(self, solver, target: np.ndarray, clamped: bool) -> str:
        note = "  \n(out of reach: moved onto the reach ball, which bounds every pose the arm reaches)"
        return readouts.pose_text(target) + (note if clamped else "")

    def target_words(self, target: np.ndarray) -> str:
        """The target in a recording's label."""
        x, y, z = 1000 * np.asarray(target[:3])
        return f"target x = {x:+.0f}, y = {y:+.0f}, z = {z:+.0f} mm"

    def typed_numbers(self, inputs, arm) -> tuple[float, ...]:
        """The numbers typed in the panel's Target folder: metres from the mm fields, then roll pitch yaw."""
        position = tuple(float(value) / 1000 for value in inputs.position_mm.value)
        return position + (tuple(inputs.rotation_deg.value) if arm.target_dim == 7 else ())

    def write_typed_fields(self, inputs, target: np.ndarray) -> None:
        """The typed-target fields show the target solved: position in mm, rotation as roll pitch yaw in degrees."""
        from ikdp_viz.typed_target import roll_pitch_yaw_degrees  # here: it imports viser's SO3 helper

        inputs.show_fields(point=False, rotation=len(target) == 7)
        inputs.position_mm.value = tuple(round(1000 * float(value), 1) for value in target[:3])
        if len(target) == 7:
            inputs.rotation_deg.value = tuple(round(float(value), 1) for value in roll_pitch_yaw_degrees(target[3:7]))

    def flat_picture(self, solved) -> tuple[np.ndarray, np.ndarray, float | None, np.ndarray]:
        """What the exported files draw: the skeletons (S+1, K, J+1, 2) and the target's position (2,) projected
        (orthographically) as the viewer's camera sees them, no workspace circle."""
        from ikdp_viz.camera import camera_fit_3d

        view = solved.view
        center = np.asarray(view.points[0, 0, 0], dtype=np.float64)  # the base: any point of the view's axis
        position, look_at = camera_fit_3d(center, 1.0)
        forward = (look_at - position) / np.linalg.norm(look_at - position)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        basis = np.stack([right, up], axis=-1)  # (3, 2)
        return view.points @ basis, np.asarray(view.target[:3]) @ basis, None, None

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
            lines=lines, skeletons=trail_colors(lines, view.num_joints), trail=trail_colors(ramp, 1), ghosts=ghosts,
            ghost_opacities=opacities,
        )  # fmt: skip

    def solve_text(self, solved, state: int, highlight: int, reason: str, error: str | None) -> str:
        request = solved.request
        text = readouts.chain_solve_text(
            solved.view, state, highlight, sampler=request.sampler_label, seed=request.seed,
            refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds, reason=reason,
        )  # fmt: skip
        miss = readouts.miss_text(solved.view, request.solver.arm, beyond_reach=request.target_clamped)
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
                Entry(
                    Swatch(OTHERS_FINAL if follows else DARK, faint=FAINT), "skeletons: joint origins to the hand", True
                ),  # fmt: skip
            ]
        trail = "trail (show trail): the highlighted hand's path" if follows else "trail (show trail): the hands' paths"
        if settings.recording:  # no panel to turn it on or off
            trail = trail.replace(" (show trail)", "")
        hand = Entry(Swatch(HAND_RED), "hand frame of the highlighted robot: x red, y green, z blue")
        ramp = Swatch(ACCENT_DARK, faint=ACCENT_FAINT) if follows else Swatch(DARK, faint=FAINT)
        trail_entry = Entry(ramp, trail, True)
        if settings.recording:  # a static page: what it draws alone, the target a frame no one can drag
            target = Entry(Swatch(TARGET_RED), "target: the frame at the target pose, x red, y green, z blue")
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
            Entry(Swatch(TARGET_RED), "target: the gizmo's pose (drag its arrows and rings)"),
            *(frame_beside if compared else []),
        ]
        measure = getattr(view, "rotation_measure", "rotation") if view is not None else "rotation"
        if measure not in ("rotation", "none"):
            entries.append(Entry(Swatch(FREE_AXIS_COLOR), f"the hand's free {measure}: any turn about it counts"))
        return entries
