"""Following a path of targets with one continuous solution: `solver.track(path, start_pose)`.

Each target is solved with a pull toward the previous solution (`NearPose`: every step's x̂0
is moved part of the way to it), so the K samples gather on the branch the arm is already
on; of those that reach the target (and meet the other constraints), the one nearest the
previous pose is kept. Nearest is by the Euclidean joint distance, as the pseudo-inverse's
minimum-norm step: by the largest joint change alone, the other joints are free to drift along a
redundant arm's self-motion, and on one Panda circle the path drifted into a stretch near a
singularity that needed a 0.115 rad jump (0.043 by the Euclidean distance; `python -m benchmarks.constraint_tracking`).
The previous solution refined toward the target is one more candidate (`warm_start`).

A path the branch cannot follow (it runs into a joint limit) makes the arm switch branch: a jump of
several radians between targets millimetres apart, which a user executing the path must know of.
`TrackResult.branch_switches` flags each such target: its joint jump is larger than
BRANCH_SWITCH_FLOOR and BRANCH_SWITCH_RATIO times the joint move the path step needs (the
minimum-norm step J⁺ e from the pose before, e the task error toward the target).

A path may leave the arm's reach (at a fixed orientation, part of a circle often does) and come
back. Two rules keep the arm sound across such a stretch:
- `hold_step`: where no candidate reaches a target, the arm holds its branch and stretches toward
  the target (the previous pose refined toward it, each joint moved at most `hold_step`), rather
  than taking whichever sample lies nearest, which may sit on another branch;
- `look_ahead`: where the targets come back into reach, the reaching candidates are on different
  branches, and the nearest may be one that loses the path again a few targets on. The target is
  then also solved without the pull (the pull gathers the samples on the branch the arm held, the
  one that lost the path), each reaching candidate is followed over the next `look_ahead` targets
  by warm-started refinement, and the one that keeps reaching the longest is kept (the nearest
  among equals).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ikdp.constraint_base import joint_difference
from ikdp.fused_chain import small_batch
from ikdp.guidance import ConstraintSet, checked
from ikdp.joint_constraints import NearPose

WARM_START_STEPS = 10  # DLS steps of the warm-started candidate (at least the solve's refine_steps)
BRANCH_SWITCH_RATIO = 10.0  # a jump this many times the move the path step needs ...
BRANCH_SWITCH_FLOOR = 0.1  # ... and above this many radians (the tracking target's bound) switches branch


@dataclass
class TrackResult:
    angles: torch.Tensor  # (P, J) one solution per target, in path order
    position_error: torch.Tensor  # (P,) distance to each target's position (arm's length unit)
    rotation_error: torch.Tensor | None  # (P,) radians, for pose targets
    reached: torch.Tensor  # (P,) True within the arm's tolerances (robots: 1 mm and 1°) and every constraint
    joint_jumps: torch.Tensor  # (P,) largest joint change from the previous solution (the start pose first)
    needed_jumps: torch.Tensor  # (P,) the largest joint change the path step needs there (J⁺ e, module docstring)
    branch_switches: torch.Tensor  # (P,) True where the jump is a change of branch, not a move along the path

    @property
    def largest_jump(self) -> float:
        return float(self.joint_jumps.max())

    @property
    def switch_indices(self) -> list[int]:
        """The targets at which the arm switched branch, in path order."""
        return torch.nonzero(self.branch_switches).flatten().tolist()


def needed_jumps(arm, path: torch.Tensor, start_pose: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """(P,) the largest joint change of the minimum-norm step J⁺ e from each pose before (the start pose first)
    toward its target: what moving along the path asks of the joints, to first order."""
    before = torch.cat([start_pose[None], angles[:-1]]).double()  # (P, J)
    error = arm.task_error(before, path.double())  # (P, E)
    step = torch.linalg.pinv(arm.jacobian(before).double()) @ error[..., None]  # (P, J, 1)
    return step[..., 0].abs().amax(dim=-1).float()


def branch_switches(joint_jumps: torch.Tensor, needed: torch.Tensor) -> torch.Tensor:
    """(P,) True where a jump is above BRANCH_SWITCH_FLOOR and BRANCH_SWITCH_RATIO times what the step needs."""
    return (joint_jumps > BRANCH_SWITCH_FLOOR) & (joint_jumps > BRANCH_SWITCH_RATIO * needed)


@dataclass
class Candidates:
    """The poses one target may keep, with what decides between them."""

    angles: torch.Tensor  # (C, J)
    position_error: torch.Tensor  # (C,)
    rotation_error: torch.Tensor | None  # (C,) for pose targets
    met: torch.Tensor  # (C,) True where every constraint holds

    @classmethod
    def of_solve(cls, out) -> Candidates:
        """A one-target solve's K samples."""
        met = out.constraints_met[0] if out.constraints_met is not None else None
        return cls(
            angles=out.angles[0],
            position_error=out.position_error[0],
            rotation_error=None if out.rotation_error is None else out.rotation_error[0],
            met=torch.ones(len(out.angles[0]), dtype=torch.bool) if met is None else met,
        )

    def __add__(self, other: Candidates) -> Candidates:
        rotation = None if self.rotation_error is None else torch.cat([self.rotation_error, other.rotation_error])
        return Candidates(
            angles=torch.cat([self.angles, other.angles]),
            position_error=torch.cat([self.position_error, other.position_error]),
            rotation_error=rotation,
            met=torch.cat([self.met, other.met]),
        )


def track(
    solver,
    path,
    start_pose,
    *,
    weight: float = 0.6,
    position_tolerance: float | None = None,
    rotation_tolerance: float | None = None,
    constraints=(),
    warm_start: bool = True,
    hold_step: float | None = 0.05,
    look_ahead: int = 20,
    **solve_options,
) -> TrackResult:
    """path (P, target_dim), start_pose (J,) -> one solution per target, each near the one before.

    `weight`: NearPose's pull (0.3 let a Panda circle jump branches once, 3.6 rad; 0.6 kept every jump under 0.02
    rad; `python -m benchmarks.constraint_tracking`); the tolerances decide which samples count as reaching a
    target and `reached` (None: the arm's own, `arm.position_tolerance` and `arm.rotation_tolerance`: 1 mm and 1
    degree on a robot, 1e-3 of the reach on a planar arm); `solve_options` go to `solver.solve` (num_samples,
    sampler, steps, refine_steps, generator). `warm_start`: the previous solution refined toward the target
    (damped least squares, as a warm-started numerical solver would) is one more candidate.

    Out of reach (module docstring): `hold_step` (radians, or None) is the largest joint move per
    target while no candidate reaches, the arm stretched toward the target on its own branch; None
    keeps the candidate nearest the previous pose. `look_ahead` (targets, 0 for none): on coming
    back into reach, the reaching candidate that warm-started refinement keeps on the path for the
    most of the next `look_ahead` targets in a row is kept, not merely the nearest one. Neither acts
    while every target is reached (a path within reach is tracked exactly as without them), nor
    with a partial target (PositionOnly, FreeAxis), whose refinement aims elsewhere. On a
    Panda circle 53.5 % reachable (`python -m benchmarks.constraint_tracking`), with neither rule `track` reached 36.0 %
    (back in reach, the nearest candidate lost the path again 7 targets on) with 42 jumps over
    0.1 rad; either rule, or both, reached every reachable target (53.5 %): the look-ahead alone
    with 33 jumps over 0.1 rad (the arm wandering while out of reach), the hold with 2, both where
    the path comes back into reach (0.140 rad). While the arm holds, the look-ahead solves each
    target a second time (without the pull), to see whether another branch reaches it.
    """
    arm = solver.arm
    path = arm.validate_targets(path)
    start = previous = torch.as_tensor(start_pose, dtype=torch.float32)
    if previous.shape != (arm.num_joints,):
        raise ValueError(f"start_pose: expected shape ({arm.num_joints},), got {tuple(previous.shape)}")
    if hold_step is not None and not hold_step > 0:
        raise ValueError(f"hold_step: expected a positive number of radians or None, got {hold_step}")
    if not isinstance(look_ahead, int) or look_ahead < 0:
        raise ValueError(f"look_ahead: expected a number of targets >= 0, got {look_ahead!r}")
    position_tolerance = arm.position_tolerance if position_tolerance is None else position_tolerance
    rotation_tolerance = arm.rotation_tolerance if rotation_tolerance is None else rotation_tolerance
    constraints = arm.with_default_constraints(checked(constraints))  # a tree: its self-collision check, as solve's
    # a partial target is met by the solve's own residual; the refinement below aims at full targets
    full_targets = not any(hasattr(item, "validate_targets") for item in constraints)
    refine_task = ConstraintSet(arm, list(constraints), 1, 1).refine_task() if constraints else None
    refine_steps = max(int(solve_options.get("refine_steps", 0)), WARM_START_STEPS)

    def kinematics(rows: int):
        """The arm, or for a few poses on a CPU its kinematics as a few fused operations (the same numbers)."""
        return arm.small_batch_kinematics() if small_batch(rows, solver.device) else arm

    def refined(joints: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """joints (C, J) refined toward one target by warm-started damped least squares -> (C, J)."""
        goal = arm.clamp_to_workspace(target[None])[:, None].expand(1, len(joints), -1)
        return kinematics(len(joints)).refine(joints[None], goal, steps=refine_steps, task=refine_task)[0]

    def meets(joints: torch.Tensor) -> torch.Tensor:
        """joints (C, J) -> (C,) True where every constraint holds."""
        if not constraints:
            return torch.ones(len(joints), dtype=torch.bool)
        return ConstraintSet(arm, list(constraints), 1, len(joints)).violation(joints[None])[0] == 0

    def evaluated(joints: torch.Tensor, target: torch.Tensor) -> Candidates:
        """joints (C, J) as candidates for one target: their errors and whether they meet the constraints."""
        position, rotation = kinematics(len(joints)).tip_and_rotation_errors(joints, target[None])
        return Candidates(joints, position, rotation, meets(joints))

    def reaching(candidates: Candidates) -> torch.Tensor:
        """(C,) True where a candidate is within the tolerances and meets the constraints."""
        ok = candidates.position_error < position_tolerance
        if candidates.rotation_error is not None:
            ok &= candidates.rotation_error < rotation_tolerance
        return ok & candidates.met

    def run_ahead(joints: torch.Tensor, index: int) -> torch.Tensor:
        """joints (C, J) reaching target `index` -> (C,) how many targets after it warm-started refinement reaches
        in a row from each."""
        run = torch.zeros(len(joints), dtype=torch.long)
        alive = torch.ones(len(joints), dtype=torch.bool)
        for target in path[index + 1 : index + 1 + look_ahead]:
            joints = refined(joints, target)
            alive &= reaching(evaluated(joints, target))
            if not alive.any():
                break
            run += alive
        return run

    solutions, position_errors, rotation_errors, reached, jumps = [], [], [], [], []
    previous_reached = True
    for index, target in enumerate(path):
        near = NearPose(previous, weight=weight)
        candidates = Candidates.of_solve(solver.solve(target[None], constraints=[near, *constraints], **solve_options))
        coming_back = not previous_reached and full_targets and look_ahead > 0
        if coming_back:  # the pull gathers the samples on the branch that lost the path: add samples from every branch
            unpulled = solver.solve(target[None], constraints=list(constraints), **solve_options)
            candidates += Candidates.of_solve(unpulled)
        stretched = None  # (1, J) the previous pose refined toward the target
        if full_targets and (warm_start or hold_step is not None):
            stretched = refined(previous[None], target)
        if warm_start and stretched is not None:  # one more candidate
            candidates += evaluated(stretched, target)
        ok = reaching(candidates)
        # nearest by the Euclidean joint distance, as the pseudo-inverse's minimum-norm step: by the largest
        # joint change alone, the other joints drift freely along a redundant arm's self-motion
        distance = joint_difference(arm, candidates.angles, previous).norm(dim=-1)  # (C,)
        if ok.any():
            score = torch.where(ok, distance, math.inf)  # the nearest reaching candidate ...
            if coming_back and int(ok.sum()) > 1:
                run = torch.full((len(ok),), -1, dtype=torch.long)  # ... or, back in reach, the one that stays
                run[ok] = run_ahead(candidates.angles[ok], index)
                score = torch.where(run == run.max(), score, math.inf)
            pick = int(score.argmin())
        else:
            pick = int(torch.where(candidates.met, distance, distance + 1e6).argmin())  # nearest meeting constraints
        kept, at = candidates, pick
        if not ok.any() and hold_step is not None and stretched is not None:
            # hold the branch: toward the stretched pose, each joint at most hold_step (between two in-limit poses)
            step = joint_difference(arm, stretched[0], previous).clamp(-hold_step, hold_step)
            held = evaluated(arm.normalize_joints(previous + step)[None], target)
            if bool(held.met[0]):
                kept, at = held, 0
        chosen, chosen_reached = kept.angles[at], bool(reaching(kept)[at])
        solutions.append(chosen)
        position_errors.append(kept.position_error[at])
        if kept.rotation_error is not None:
            rotation_errors.append(kept.rotation_error[at])
        reached.append(chosen_reached)
        jumps.append(float(joint_difference(arm, chosen, previous).abs().max()))
        previous, previous_reached = chosen, chosen_reached
    angles, joint_jumps = torch.stack(solutions), torch.tensor(jumps)
    needed = needed_jumps(arm, path, start, angles)
    return TrackResult(
        angles=angles,
        position_error=torch.stack(position_errors),
        rotation_error=torch.stack(rotation_errors) if rotation_errors else None,
        reached=torch.tensor(reached),
        joint_jumps=joint_jumps,
        needed_jumps=needed,
        branch_switches=branch_switches(joint_jumps, needed),
    )


@dataclass
class TrackStep:
    """One target of `track`: the pulled solve of it and the pose kept."""

    solve: object  # the SolveResult of the target solved with the pull toward the previous pose (its K samples)
    kept: TrackResult  # one row: the pose kept, its errors, whether it reached, its jump, whether it switched branch
    sample: int | None  # which of the solve's K returned poses was kept; None: the previous pose moved onto the
    # target (the warm-started candidate, or the held stretch where nothing reaches)


def track_step(solver, target, previous_pose, **options) -> TrackStep:
    """target (target_dim,), previous_pose (J,) -> the step `track` takes to this target from `previous_pose`.

    It is `track` itself on the one-target path, so a caller that gets its targets one at a time (a
    dragged gizmo) keeps what `track` keeps; it cannot look ahead (it has no later targets). `options`
    as `track`'s; the solve options (return_trajectory, initial_noise, callback, ...) reach the solve
    returned as `solve`.
    """
    solves = []

    class Recorded:  # the solver itself (every attribute `track` reads), keeping the solve `track` makes
        def __getattr__(self, name):
            return getattr(solver, name)

        def solve(self, *args, **kwargs):
            solves.append(solver.solve(*args, **kwargs))
            return solves[-1]

    kept = track(Recorded(), torch.as_tensor(target)[None], previous_pose, **options)
    solved = solves[0]
    same = (solved.angles[0] == kept.angles[0]).all(dim=-1).nonzero().flatten()
    return TrackStep(solved, kept, int(same[0]) if len(same) else None)
