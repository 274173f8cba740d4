"""The Constraints panel's arrays: constraints from its settings, each state's violation, the coloured overlay.

No viser here. The overlay draws one sample's pose at every state of the reverse process,
green where the constraints hold (to HOLDS_TOLERANCE) and red where they do not, so the user
sees at which step the constraint takes hold; `sample_tints` colours every sample at every
state the same way, for the K poses on screen. A pose model's target may be
partial (TARGET_KINDS): the position only, or the hand free to turn about one of its axes.
"""

from __future__ import annotations

import numpy as np

import ikdp
from ikdp.guidance import ConstraintSet
from ikdp_viz.style import HOLDS, HOLDS_FAINT, HOLDS_OTHERS, VIOLATES, VIOLATES_FAINT, VIOLATES_OTHERS

HOLDS_TOLERANCE = 0.01  # summed violation (radians of a locked joint, depth in the arm's unit) drawn as holding
NEAR_WEIGHT = 0.6  # the pull toward the last pose (ikdp.tracking: 0.6 kept a Panda circle's jumps under 0.02 rad)


# What a pose model's target asks for: the panel's choices, each with the free axis (end-effector frame) or None
TARGET_KINDS = {
    "full pose": None,
    "position only": None,
    "free x axis": (1.0, 0.0, 0.0),
    "free y axis": (0.0, 1.0, 0.0),
    "free z axis": (0.0, 0.0, 1.0),
}
PARTIAL_NAMES = ("position_only", "free_axis")  # the ikdp constraints that make a target partial


def target_constraint(kind: str):
    """The panel's target kind as an ikdp constraint: None (full pose), PositionOnly or FreeAxis."""
    if kind not in TARGET_KINDS:
        raise ValueError(f"target kind: expected one of {tuple(TARGET_KINDS)}, got {kind!r}")
    if kind == "full pose":
        return None
    axis = TARGET_KINDS[kind]
    return ikdp.PositionOnly() if axis is None else ikdp.FreeAxis(axis=axis)


def partial_target(constraints) -> object | None:
    """The partial target among a solve's constraints (PositionOnly or FreeAxis), or None."""
    return next((item for item in constraints if item.name in PARTIAL_NAMES), None)


def checkable(constraints) -> bool:
    """Whether any constraint can hold or fail on a pose: a partial target is measured by the errors instead."""
    return any(item.name not in PARTIAL_NAMES for item in constraints)


def build_constraints(
    locks: dict[int, float],
    obstacles: list[tuple[np.ndarray, float]],
    near_pose: np.ndarray | None,
    *,
    planar: bool,
    target_kind: str = "full pose",
) -> tuple:
    """The panel's settings as ikdp constraints: locked joints, obstacles (discs, planar), a pose to stay near,
    a partial target (pose models)."""
    partial = target_constraint(target_kind)
    if partial is not None and planar:
        raise ValueError(f"target kind: a planar arm's targets are points, got {target_kind!r}")
    constraints = []
    if locks:
        constraints.append(ikdp.LockedJoints({index: float(value) for index, value in locks.items()}))
    if obstacles:
        dim = 2 if planar else 3
        centers = np.array([np.asarray(center, dtype=np.float64)[:dim] for center, _ in obstacles])
        constraints.append(ikdp.Obstacles(centers, [float(radius) for _, radius in obstacles]))
    if near_pose is not None:
        constraints.append(ikdp.NearPose(np.asarray(near_pose, dtype=np.float64), weight=NEAR_WEIGHT))
    if partial is not None:
        constraints.append(partial)
    return tuple(constraints)


LINK_CLEARANCE = 0.07  # a robot's links' half-thickness about its joint origins' line, in reach radii (the
# Panda's meshes are about 6 cm about it): a dropped sphere clears the shown robot's meshes by this


def segment_distances(point: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(P-1,) the distance from `point` (3,) to each segment of the polyline `points` (P, 3)."""
    start, end = points[:-1], points[1:]
    along = end - start
    length2 = np.maximum((along * along).sum(axis=-1), 1e-12)
    fraction = np.clip(((point - start) * along).sum(axis=-1) / length2, 0.0, 1.0)
    return np.linalg.norm(start + fraction[:, None] * along - point, axis=-1)


def beside_the_arm(points: np.ndarray, radius: float, camera: np.ndarray, clearance: float) -> np.ndarray:
    """(3,) where a dropped 3-D sphere of `radius` is seen: from the middle joint of the pose shown, toward the
    camera until it clears every link by `clearance`. Dropped on the middle joint itself it sat inside the opaque
    robot and could not be seen; here it stands just in front of it, one drag away."""
    points = np.asarray(points, dtype=np.float64)
    middle = points[len(points) // 2]
    toward = np.asarray(camera, dtype=np.float64) - middle
    toward /= max(np.linalg.norm(toward), 1e-12)
    needed = radius + clearance
    for steps in range(200):  # in quarter radii: the first place clear of every link
        where = middle + toward * (needed + 0.25 * radius * steps)
        if segment_distances(where, points).min() >= needed:
            return where
    return where


def state_violation(solver, constraints, result) -> np.ndarray:
    """(S+1, K) each state's summed violation of the solve's constraints (one target)."""
    trajectory = result.trajectory[:, 0]  # (S+1, K, J)
    checked = ConstraintSet(solver.arm, list(constraints), 1, trajectory.shape[1])
    return np.stack([checked.violation(state[None])[0].numpy() for state in trajectory])


def final_violations(solver, constraints, result) -> tuple:
    """((name, (K,) violation of the last state), ...) for each checkable constraint alone: which one fails."""
    last = result.trajectory[-1, 0][None]  # (1, K, J)
    return tuple(
        (item.name, ConstraintSet(solver.arm, [item], 1, last.shape[1]).violation(last)[0].numpy())
        for item in constraints
        if checkable([item])
    )


def holds(violation: np.ndarray) -> np.ndarray:
    return violation <= HOLDS_TOLERANCE


def sample_tints(violation: np.ndarray, highlight: int, *, others_full: bool = False) -> np.ndarray:
    """(S+1, K) every sample's violation at every state -> (S+1, K, 3) uint8: green where it holds, red where not;
    the highlighted sample in full colour, the others lighter (`others_full`: in full colour too, for see-through
    robots whose opacity lightens them already)."""
    holding = holds(np.asarray(violation))[..., None]
    if others_full:
        return np.where(holding, np.array(HOLDS), np.array(VIOLATES)).astype(np.uint8)
    colors = np.where(holding, np.array(HOLDS_OTHERS), np.array(VIOLATES_OTHERS))
    colors[:, highlight] = np.where(holding[:, highlight], np.array(HOLDS), np.array(VIOLATES))
    return colors.astype(np.uint8)


def met_text(violation: np.ndarray, state: int, *, colored: bool) -> str:
    """The readout line for the state shown: how many of the K samples meet the constraints there."""
    met = int(holds(np.asarray(violation)[state]).sum())
    text = f"**Constraints hold** for {met} of {violation.shape[1]} samples at this step"
    return text + (" (green; red: not)" if colored else "")


def first_holding_state(violation: np.ndarray) -> int | None:
    """(S+1,) one sample's violations -> the first state from which every later state holds; None if the last fails."""
    holding = holds(violation)
    if not holding[-1]:
        return None
    failing = np.flatnonzero(~holding)
    return int(failing[-1]) + 1 if len(failing) else 0


def overlay_segments(
    points: np.ndarray, violation: np.ndarray, polylines: tuple[int, ...] = ()
) -> tuple[np.ndarray, np.ndarray]:
    """One sample's joint positions at every state (S+1, P, 2 or 3) and violations (S+1,) -> line segments
    (S * (P-1)... , 2, 3) and their colours (same, uint8): faint green where the state holds, faint red where not.
    `polylines`: the point counts of the polylines along P (a tree's chains: none joined); () one polyline."""
    points = np.asarray(points, dtype=np.float32)
    if points.shape[-1] == 2:
        points = np.concatenate([points, np.zeros((*points.shape[:-1], 1), np.float32)], axis=-1)
    segments = np.stack([points[:, :-1], points[:, 1:]], axis=-2)  # (S+1, P-1, 2, 3)
    if len(polylines) > 1:
        segments = np.delete(segments, np.cumsum(polylines)[:-1] - 1, axis=1)  # one polyline's end to the next's start
    colors = np.where(holds(violation)[:, None, None, None], np.array(HOLDS_FAINT), np.array(VIOLATES_FAINT))
    colors = np.broadcast_to(colors, segments.shape).astype(np.uint8)
    return segments.reshape(-1, 2, 3), colors.reshape(-1, 2, 3)


# The Constraints folder's readout after a solve (markdown), from plain values: no viser here.
def readout_text(solved, choice: int, jump: float | None, largest_jump: float, lock_notes: list[str], *,
                 reaches: bool, switches: int = 0, switched: bool = False) -> str:  # fmt: skip
    """The readout for `solved` with sample `choice` kept; `reaches`: some returned pose reaches the target;
    `switched`: follow mode's kept pose changed branch at this target, `switches` times so far."""
    lines = []
    measure = getattr(solved.view, "rotation_measure", "rotation")
    if measure == "none":
        lines.append("target: **position only**, any hand rotation")
    elif measure != "rotation":
        lines.append(f"target: the hand's **{measure} free**, any turn about it")
    lines += [f"lock: {note}" for note in lock_notes]
    if solved.state_violation is not None:
        count = len(solved.state_violation[-1])
        met = int(holds(solved.state_violation[-1]).sum())
        first = first_holding_state(solved.state_violation[:, choice])
        states = len(solved.state_violation) - 1
        held = "never" if first is None else f"from state {first} of {states} (t = {solved.view.labels[first]})"
        lines.append(f"constraints met by {met} of {count} raw samples")
        lines.append(f"sample {choice + 1}: holds {held}")
    lines += unmet_reasons(solved, reaches=reaches)
    if solved.pull_missed is not None:
        lines.append(
            f"**stay near: every pulled sample missed the target** (best {solved.pull_missed:.3g} away); "
            "shown: the same noise solved without the pull"
        )
    if jump is not None and solved.followed is not None:
        lines.append(followed_text(solved.followed, choice))
    if jump is not None:
        lines.append(f"joint jump {jump:.3f} rad, largest so far **{largest_jump:.3f} rad**")
        if switched:
            lines.append("**branch switch**: no sample continues the last pose; the arm jumps to another solution here")
        if switches:
            lines.append(f"branch switches so far: {switches}")
    return "  \n".join(lines) if lines else "No constraint."


def followed_text(step, choice: int) -> str:
    """What follow mode (ikdp.tracking's step) kept for this target."""
    if not bool(step.kept.reached[0]):
        return ("**follow: no pose reaches the target**; the arm stays on its branch, stretched toward it "
                f"(sample {choice + 1}'s returned pose)")  # fmt: skip
    if step.sample is None:
        return (f"follow: kept the last pose moved onto the target, nearer than every sample (drawn as sample "
                f"{choice + 1}'s returned pose)")  # fmt: skip
    return f"follow: kept sample {choice + 1}, the nearest of those that reach the target"


# what each checked constraint's failure means to a user, and what to do (ikdp constraint name -> words)
FAILING_WORDS = {
    "obstacles": ("touches an obstacle", "move it, or make it smaller"),
    "locked_joints": ("is off a locked joint's value", "unlock it or change its value"),
}


def unmet_reasons(solved, *, reaches: bool | None = None) -> list[str]:
    """Why no sample meets the constraints, or reaches the target, in words: which constraint fails in how many
    of the K raw samples at t = 0, and whether the locks keep the hand from the target. [] when
    some sample meets them and reaches. Both readouts say it: the main one and the Constraints folder's."""
    names = {item.name for item in solved.request.constraints}
    if not names:
        return []
    reaches = solved.reaches if reaches is None else reaches
    lines = []
    if solved.state_violation is not None and not holds(solved.state_violation[-1]).any():
        count = solved.state_violation.shape[1]
        why = []
        for name, violation in solved.final_violations:
            failing = int((~holds(violation)).sum())
            if failing:
                failure, remedy = FAILING_WORDS.get(name, (f"fails {name.replace('_', ' ')}", "relax it"))
                who = "every sample" if failing == count else f"{failing} of {count} samples"
                why.append(f"{who} {failure}: {remedy}")
        if not why and "obstacles" in names:  # no per-constraint split (an older solve): the obstacle is the one
            failure, remedy = FAILING_WORDS["obstacles"]
            why.append(f"every one {failure}: {remedy}")
        lines.append(f"**no sample meets the constraints**: {'; '.join(why) or 'try more samples (K)'}")
    caused = not reaches and bool(solved.reaches_unconstrained)  # the same noise, freed, reaches
    if caused and "locked_joints" in names:
        lines.append("**no sample reaches the target with these locks**: the locked joints keep the hand from it; "
                     "unlock one or change its value")  # fmt: skip
    elif caused and "obstacles" in names:
        lines.append("**no sample reaches the target past the obstacles**: move them, or make them smaller")
    return lines
