"""Drawable arrays for a spatial chain (a robot from a URDF): ghost skeletons, their colours, mesh and gizmo poses.

The 3-D counterpart of `planar_scene.py`, with the same rule: no viser here, only numpy
(and the arm's own kinematics), so everything the chain viewer draws is built and
tested without a server. Positions are metres in the robot's base frame; rotations
are unit quaternions (w, x, y, z), the convention of the arm's pose targets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ikdp.rotations import matrix_to_quaternion
from ikdp.solver import SolveResult
from ikdp_viz.planar_scene import fade_colors, state_labels
from ikdp_viz.style import ACCENT_DARK, ACCENT_FAINT, GHOST_DARK, GHOST_FAINT

METRES_PER_RADIAN = 0.1  # ranks returned poses: a degree of rotation error counts as 1.7 mm of position

__all__ = [
    "ChainView",
    "build_chain_view",
    "ghost_colors",
    "gizmo_pose",
    "hand_paths",
    "initial_pose_target",
    "mesh_poses",
    "pose_target",
    "skeleton_segments",
]


@dataclass(frozen=True)
class ChainView:
    """Every state of one chain solve, as joint values and joint origins, with the errors the readouts show."""

    target: np.ndarray  # (7,) position (m) + unit quaternion (w, x, y, z) the hand was asked to reach
    labels: np.ndarray  # (S+1,) diffusion time of each state, T (pure noise) down to 0
    joint_values: np.ndarray  # (S+1, K, J) every sample's joint values at every state (radians / metres)
    points: np.ndarray  # (S+1, K, J+1, 3) joint origins then the end effector, per state and sample
    position_error: np.ndarray  # (S+1, K) metres from each state's end effector to the target position
    rotation_error: np.ndarray  # (S+1, K) radians between each state's hand rotation and the target's
    # (a free axis: between the axis as reached and as asked; position only: zeros, not measured)
    final_joint_values: np.ndarray  # (K, J) the poses the solver returned (refined when `refined`)
    final_points: np.ndarray  # (K, J+1, 3) their joint origins
    final_position_error: np.ndarray  # (K,) metres, of the returned poses
    final_rotation_error: np.ndarray  # (K,) radians, of the returned poses
    refined: bool  # the returned poses are the damped-least-squares polish of the last state
    estimate_points: np.ndarray | None = None  # (S, K, J+1, 3) the denoiser's x̂0 at the step into state s+1
    rotation_measure: str = "rotation"  # what rotation_error measures: "rotation", "none" (position only), "z axis"
    # Several end effectors (a tree, E of them): `points` holds one polyline per end effector, base to hand, one after
    # another (`polylines` their point counts), and the errors above are the worst hand's; each hand's own follow.
    # One end effector: one polyline, each hand error the one above.
    effector_names: tuple[str, ...] = ("hand",)  # the end effectors' link names, in the target's order
    polylines: tuple[int, ...] = ()  # points per end effector's polyline; () one polyline of every point
    effector_position_error: np.ndarray | None = None  # (S+1, K, E) metres, each hand's; None: position_error
    effector_rotation_error: np.ndarray | None = None  # (S+1, K, E) radians, each hand's
    final_effector_position_error: np.ndarray | None = None  # (K, E) of the returned poses
    final_effector_rotation_error: np.ndarray | None = None  # (K, E)
    effector_targets: np.ndarray | None = None  # (E, 7) each hand's target pose (or (E, 3) position); None: `target`

    @property
    def num_states(self) -> int:
        return self.points.shape[0]

    @property
    def num_samples(self) -> int:
        return self.points.shape[1]

    @property
    def num_joints(self) -> int:
        return self.joint_values.shape[2]

    @property
    def num_effectors(self) -> int:
        return len(self.effector_names)

    @property
    def point_counts(self) -> tuple[int, ...]:
        """Points per polyline: one per end effector (a chain's one: every point)."""
        return self.polylines or (self.points.shape[2],)

    @property
    def target_poses(self) -> np.ndarray:
        """(E, 7) or (E, 3): each end effector's target, one row per hand."""
        return self.target[None] if self.effector_targets is None else self.effector_targets

    @property
    def num_segments(self) -> int:
        """Skeleton segments per sample: a chain's J, a tree's points less one per polyline."""
        return self.points.shape[2] - len(self.point_counts)

    @property
    def hand_indices(self) -> np.ndarray:
        """(E,) where each end effector's hand sits among `points`' points: the last of its polyline."""
        return np.cumsum(self.point_counts) - 1

    def hand_errors(self, state: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each hand's (position m, rotation rad), (K, E) each: at state `state`, or of the returned poses (None)."""
        if state is None:
            position, rotation = self.final_effector_position_error, self.final_effector_rotation_error
            if position is None:
                return self.final_position_error[:, None], self.final_rotation_error[:, None]
            return position, rotation
        if self.effector_position_error is None:
            return self.position_error[state][:, None], self.rotation_error[state][:, None]
        return self.effector_position_error[state], self.effector_rotation_error[state]

    @property
    def tip_error(self) -> np.ndarray:
        """(S+1, K) metres: the planar view's name for the hand's position error, read by the shared plot."""
        return self.position_error

    @property
    def final_error(self) -> np.ndarray:
        """(K,) how far each returned pose lands: position in metres plus rotation at 0.1 m per radian."""
        return self.final_position_error + METRES_PER_RADIAN * self.final_rotation_error

    def best_sample(self) -> int:
        """The sample whose returned pose lands closest (`final_error`)."""
        return int(np.argmin(self.final_error))

    def estimate_at(self, state: int) -> np.ndarray | None:
        """(K, J+1, 3) the denoiser's x̂0 when it made state `state`; None when not recorded, at t = T (no guess yet)
        and at t = 0, where the guess is the final pose itself, hidden under it."""
        if self.estimate_points is None or state < 1 or state >= self.num_states - 1:
            return None
        return self.estimate_points[state - 1]

    def pose_at(self, state: int, sample: int) -> np.ndarray:
        """(J,) the joint values to draw the robot's meshes at: the returned pose at the last state."""
        if state >= self.num_states - 1:
            return self.final_joint_values[sample]
        return self.joint_values[state, sample]


def pose_target(position, wxyz) -> np.ndarray:
    """A pose target (7,) from a position (3,) and a quaternion (4,) (w, x, y, z), normalised; w >= 0."""
    position = np.asarray(position, dtype=np.float64).reshape(-1)
    wxyz = np.asarray(wxyz, dtype=np.float64).reshape(-1)
    if position.shape != (3,):
        raise ValueError(f"position: expected 3 numbers, got shape {position.shape}")
    if wxyz.shape != (4,):
        raise ValueError(f"wxyz: expected a quaternion of 4 numbers (w, x, y, z), got shape {wxyz.shape}")
    norm = np.linalg.norm(wxyz)
    if not np.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"wxyz: expected a non-zero quaternion, got {wxyz.tolist()}")
    wxyz = wxyz / norm
    return np.concatenate((position, wxyz if wxyz[0] >= 0 else -wxyz))


def gizmo_pose(arm, joint_values) -> tuple[np.ndarray, np.ndarray]:
    """Where the gizmo goes for joint values (J,): the end effector's position (3,) and wxyz (4,)."""
    pose = arm.end_effector_pose(torch.as_tensor(np.asarray(joint_values), dtype=torch.float64)).numpy()
    return pose[:3], pose[3:]


def initial_pose_target(arm) -> np.ndarray:
    """(7,) the hand's pose with every joint at the middle of its limits: a pose the arm surely reaches."""
    middle = arm.joint_limits.double().mean(dim=-1)  # (J,)
    position, wxyz = gizmo_pose(arm, middle.numpy())
    return pose_target(position, wxyz)


def mesh_poses(arm, joint_values, link_index: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (..., M, 3) and wxyz (..., M, 4) of M meshes at joint values (..., J).

    Mesh m hangs from link `link_index[m]` (an index into `arm.link_names`) with the 4x4
    offset `offsets[m]` (the URDF geometry's origin, scale not included).
    """
    links = arm.link_poses(torch.as_tensor(np.asarray(joint_values), dtype=torch.float64))  # (..., L, 4, 4)
    index = torch.as_tensor(np.asarray(link_index), dtype=torch.long)
    frames = links[..., index, :, :] @ torch.as_tensor(np.asarray(offsets), dtype=torch.float64)  # (..., M, 4, 4)
    return frames[..., :3, 3].numpy(), matrix_to_quaternion(frames[..., :3, :3]).numpy()


def skeleton_segments(points: np.ndarray, polylines: tuple[int, ...] = ()) -> np.ndarray:
    """Polylines (..., P, 3) -> their segments (M, 2, 3) in order, M = prod(...) * (P - E).

    `polylines`: the point counts of the E polylines laid one after another along P (a tree's chains, which
    share no segment: the last point of one is no joint of the next); () one polyline of all P points."""
    points = np.asarray(points)
    segments = np.stack((points[..., :-1, :], points[..., 1:, :]), axis=-2)  # (..., P-1, 2, 3)
    if len(polylines) > 1:
        joins = np.cumsum(polylines)[:-1] - 1  # a segment from one polyline's last point to the next's first
        segments = np.delete(segments, joins, axis=-3)
    return segments.reshape(-1, 2, 3)


def hand_paths(points: np.ndarray, hands: np.ndarray | None = None) -> np.ndarray:
    """Each sample's hands from state to state, (S+1, K*E, 2, 3) float32, sample-major: state s holds the step from
    s-1 to s (state 0 a point). `hands` (E,): which points are hands; None: the last. The trail of a robot: K
    skeletons per state would hide the robots in a 3-D view. Laid out as scene.trail_points (E segments per
    sample), so the shared `scene.trail_until` cuts it."""
    points = np.asarray(points)
    hands = points[:, :, [-1] if hands is None else list(hands)]  # (S+1, K, E, 3)
    before = np.concatenate((hands[:1], hands[:-1]))
    paths = np.stack((before, hands), axis=-2)  # (S+1, K, E, 2, 3)
    return paths.reshape(points.shape[0], -1, 2, 3).astype(np.float32)


def ghost_colors(num_states: int, num_samples: int, highlight: int | None) -> np.ndarray:
    """(S+1, K, 3) uint8 for the robots' meshes: faint to mid-grey (shaded meshes in the skeletons' near-black
    read as one dark blob), the accent ramp for the highlighted sample."""
    colors = np.repeat(fade_colors(num_states, GHOST_FAINT, GHOST_DARK)[:, None], num_samples, axis=1)
    if highlight is not None:
        colors[:, highlight] = fade_colors(num_states, ACCENT_FAINT, ACCENT_DARK)
    return colors


def rotation_measure(partial) -> str:
    """What a partial target's rotation error measures: "rotation" (None: the full pose), "none", "x axis"..."""
    if partial is None:
        return "rotation"
    if partial.name == "position_only":
        return "none"
    axis = np.asarray(partial.axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    for index, name in enumerate("xyz"):
        if abs(axis[index]) > 1 - 1e-9:
            return f"{name} axis"
    return "axis ({:.2f}, {:.2f}, {:.2f})".format(*axis)


def build_chain_view(result: SolveResult, arm, target, kind, partial=None) -> ChainView:
    """The drawable arrays of the first target of a chain `solver.solve(..., return_trajectory=True)` result.

    `partial` (ikdp.PositionOnly or FreeAxis, the solve's partial target): the rotation errors measure its
    residual, nothing for position only, the free axis's angle for a free axis. `kind`: the arm kind
    (chain_kind.ChainKind or TreeKind) that names the end effectors and measures each one's errors."""
    if result.trajectory is None:
        raise ValueError("result: solve with return_trajectory=True, the viewer draws every state")
    target = np.asarray(target, dtype=np.float64).reshape(-1)
    if target.shape != (arm.target_dim,):
        raise ValueError(f"target: expected {arm.target_dim} numbers, got shape {target.shape}")
    goal = torch.as_tensor(target, dtype=torch.float64)
    trajectory = result.trajectory[:, 0].detach().cpu().double()  # (S+1, K, J)
    final = result.angles[0].detach().cpu().double()  # (K, J)

    measure = rotation_measure(partial)
    bound = None if partial is None else partial.bind(arm, 1, 1)
    position, rotation = kind.effector_errors(arm, trajectory, goal, bound, measure)  # (S+1, K, E) each
    final_position, final_rotation = kind.effector_errors(arm, final, goal, bound, measure)  # (K, E) each
    several = position.shape[-1] > 1
    estimates = None if result.estimates is None else result.estimates[:, 0].detach().cpu().double()
    return ChainView(
        target=target,
        labels=state_labels(result.timesteps),
        joint_values=trajectory.numpy(),
        points=arm.forward_kinematics(trajectory).numpy(),
        position_error=position.max(-1),
        rotation_error=rotation.max(-1),
        final_joint_values=final.numpy(),
        final_points=arm.forward_kinematics(final).numpy(),
        final_position_error=final_position.max(-1),
        final_rotation_error=final_rotation.max(-1),
        refined=not torch.equal(result.angles, result.raw_angles),
        estimate_points=None if estimates is None else arm.forward_kinematics(estimates).numpy(),
        rotation_measure=measure,
        effector_names=kind.effector_names(arm),
        polylines=kind.polylines(arm),
        effector_position_error=position if several else None,
        effector_rotation_error=rotation if several else None,
        final_effector_position_error=final_position if several else None,
        final_effector_rotation_error=final_rotation if several else None,
        effector_targets=kind.pose_rows(arm, target) if several else None,
    )
