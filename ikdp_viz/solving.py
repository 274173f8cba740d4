"""One solve of the viewer: the session's model and target, the request as the panel set it, the core's solve, its
drawable arrays.

Every browser tab shares one session. Moves and model switches come from viser's event loop, its callback threads and
scripts at once; the session's lock makes each change of the target one step, so the order of the targets is the order
of the requests. A solve runs on the solve worker's thread (solve_worker.LatestWorker); a newer request stops a
running solve through the core's per-step callback: `stop_when` is the one place that knows how.
"""

from __future__ import annotations

import dataclasses
import random
import threading
import time
from dataclasses import dataclass

import numpy as np
import torch

import ikdp
from ikdp.constraint_base import joint_difference
from ikdp.samplers import SAMPLERS
from ikdp.tracking import TrackStep, track_step
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.chain_scene import METRES_PER_RADIAN, ChainView
from ikdp_viz.constraint_scene import NEAR_WEIGHT, checkable, final_violations, partial_target, state_violation
from ikdp_viz.frame import highlighted_sample
from ikdp_viz.joint_space import FieldAsk, SolveFields, solve_fields
from ikdp_viz.planar_scene import SolveView
from ikdp_viz.solve_worker import Cancelled
from ikdp_viz.student import (
    STUDENT,
    TEACHER,
    distillation_target,
    matched_its_teacher,
    sampler_label,
    solve_title,
    student_sampling,
    target_title,
)

NEAR_POSE = "near_pose"  # the pull toward the last pose (ikdp.NearPose)
PREVIEW_SAMPLER = ("dpmpp2m", 5)  # the fast solve a robot's drag shows first: 5 steps, about 40 ms here
REACH_FRACTION = 0.01  # a returned pose within this share of the arm's span reaches the target (1e-2: 0.04 bone
# lengths on ikdp_n4, 12 mm on the Panda; ikdp_n4 unpulled lands 0.010 away, a pull that lost the target 0.15)

RERUN_SEED_STRIDE = 1_000_003  # a prime: run r of seed s draws its step noise from s + r * stride, apart from s + 1


@dataclass(frozen=True)
class SolveRequest:
    """One solve, with the panel's settings as they were when it was asked for."""

    solver: ikdp.Solver
    target: np.ndarray  # inside the workspace: planar (2,), chain pose (7,) position m + wxyz
    num_samples: int  # K
    sampler: str  # a name of ikdp.samplers.SAMPLERS
    steps: int | None  # the sampler's number of steps; None: all T (and for samplers that always take T)
    refine_steps: int  # 0: no damped-least-squares polish
    seed: int  # of the solve's torch.Generator
    arrival: float  # time.perf_counter() when the move (or settings change) arrived
    animate: bool  # play the denoising once drawn; False while the gizmo is being dragged
    compare_sampler: str | None = None  # also solve with this sampler from the same x_T (compare_view.py); None: not
    compare_steps: int | None = None  # its number of steps (None: all T)
    compare_spacing: str | None = None  # its timestep grid (None: the model's default for it)
    constraints: tuple = ()  # ikdp constraints from the Constraints panel (constraint_controls.py)
    compare_solver: ikdp.Solver | None = None  # the model the comparison runs (student.py); None: `solver`
    compare_note: str | None = None  # why no comparison runs though one was chosen (the readout says it)
    student: ikdp.Solver | None = None  # the few-step student in sight (student.py): a drag's preview runs it
    teacher: ikdp.Solver | None = None  # the session's model when `solver` is its student; None: `solver` is it
    follow_from: np.ndarray | None = None  # follow mode: the pose kept last, from which ikdp.tracking's step goes
    target_clamped: bool = False  # the point asked for lay outside the workspace (a robot's reach ball): `target` is
    # the nearest point inside it
    rerun: int = 0  # again from the same x_T: run r > 0 keeps the seed's x_T and reseeds the step noise (teaching.py)
    joint_space: FieldAsk | None = None  # the joint-space view is shown: the solve brings its fields; None: it is off

    @property
    def model(self) -> ikdp.Solver:
        """The session's model this solve belongs to (a solve of a replaced model is not drawn)."""
        return self.solver if self.teacher is None else self.teacher

    @property
    def compared_by(self) -> ikdp.Solver:
        return self.solver if self.compare_solver is None else self.compare_solver

    def title(self, steps: int) -> str:
        """The label over this solve's arms: its sampler in `steps` steps, and whose network, with a student."""
        return solve_title(self.solver, self.student, self.sampler, steps)

    def compare_title(self, steps: int) -> str:
        if self.solver is self.student and self.compare_spacing is not None:  # the run it was distilled from
            return target_title(str(self.compare_sampler), steps, matched_its_teacher(self.student))
        return solve_title(self.compared_by, self.student, str(self.compare_sampler), steps)

    @property
    def sampler_label(self) -> str:
        """The sampler as the readouts name it ("student's ddim" with a student in sight)."""
        return sampler_label(self.solver, self.student, self.sampler)


@dataclass(frozen=True)
class Solved:
    request: SolveRequest  # what was asked
    view: SolveView | ChainView  # what is drawn (arm_kinds picks which)
    trail_points: np.ndarray  # (S+1, K*N, 2, 3) every state's polylines, see scene.trail_points
    solve_seconds: float  # solver.solve alone
    compare: SolveView | ChainView | None = None  # the same noise through request.compare_sampler
    compare_trail: np.ndarray | None = None  # its trail points, as trail_points
    final_angles: np.ndarray | None = None  # (K, J) the returned joint values (refined when asked)
    state_violation: np.ndarray | None = None  # (S+1, K) each state's constraint violation (checkable ones: not
    # a partial target alone)
    pull_missed: float | None = None  # "stay near": the best error of the pulled samples, which all missed the
    # target, so the solve shown is the one without the pull; None: the pull was kept or off
    preview_of: str | None = None  # a fast solve shown while the full one with this sampler runs
    final_violations: tuple = ()  # ((constraint name, (K,) violation at t = 0), ...) one per checked constraint:
    # which one fails, for the readouts' "why none meets"
    followed: TrackStep | None = None  # follow mode: ikdp.tracking's step to this target
    followed_sample: int | None = None  # the sample whose returned pose is drawn as the pose that step kept
    forward: bool = False  # the forward process of a solve's poses (teaching.py), not a denoising
    reaches_unconstrained: bool | None = None  # where no pose reaches under locks or obstacles: whether the same
    # noise solved without them reaches (they cause the miss) or not (they do not); None: not asked
    fields: SolveFields | None = None  # the joint-space fields of its states, as request.joint_space asked; None:
    # not asked (the view was off), or another pair, grid or highlight is shown now (joint_space_view.py asks anew)

    @property
    def reaches(self) -> bool:
        """Some returned pose reaches the target (within REACH_FRACTION of the arm's span)."""
        return float(self.view.final_error.min()) <= REACH_FRACTION * self.request.solver.arm.span


def preview_request(request: SolveRequest) -> SolveRequest | None:
    """A fast solve to show first while `request` runs, or None: during a robot's drag (not animated), when the
    sampler takes many steps. The model's few-step student where there is one, else
    DPM-Solver++(2M) in 5 steps: in 10, a Panda solve took 12 ms unloaded (benchmarks/viz_robot_settings.py) but
    73 ms on a shared 2-core machine, against DDPM's 120-740 ms; so the arm follows the gizmo at once
    (benchmarks/viz_robot_drag.py)."""
    solver, (sampler, steps) = request.solver, PREVIEW_SAMPLER
    if request.student is not None:
        solver, (sampler, steps) = request.student, student_sampling(request.student)
    if request.animate or not arm_kind(request.solver).previews_drags or request.solver is request.student:
        return None
    same_model_and_sampler = solver is request.solver and request.sampler == sampler
    if same_model_and_sampler or (request.steps or request.solver.timesteps) <= steps:
        return None
    return dataclasses.replace(
        request, solver=solver, sampler=sampler, steps=steps, compare_sampler=None, compare_steps=None,
        compare_solver=None, teacher=request.model if solver is not request.solver else request.teacher,
    )  # fmt: skip


def landing_error(result) -> float:
    """The best returned pose's miss of a one-target solve: its tip error (a robot: plus its rotation, ranked as
    the chain view ranks samples)."""
    error = result.tip_error[0]  # (K,)
    if result.rotation_error is not None:
        error = error + METRES_PER_RADIAN * result.rotation_error[0]
    return float(error.min())


def stop_when(cancel: threading.Event):
    """The solve's per-step callback: stop after the step under way once `cancel` is set."""
    return lambda step_index, timestep, state, estimate: cancel.is_set()


def solve(request: SolveRequest, cancel: threading.Event | None = None, preview=None) -> Solved:
    """Run the reverse diffusion for one request and build its drawable arrays (worker thread).

    Raises Cancelled, part-way, once `cancel` is set: a newer request has arrived. `preview(solved)`, when
    given, receives a fast solve of the same target first where `preview_request` makes one.
    """
    cancel = cancel if cancel is not None else threading.Event()
    if cancel.is_set():
        raise Cancelled
    fast = None if preview is None else preview_request(request)
    if fast is not None:
        preview(dataclasses.replace(solve(fast, cancel), preview_of=request.sampler_label))
    generator = torch.Generator(device=request.solver.device).manual_seed(request.seed)
    started = time.perf_counter()
    solver = request.solver
    # x_T drawn as the solve itself would draw it first: the main solve is the same with or without a comparison
    noise = torch.randn((1, request.num_samples, solver.noise_dim), generator=generator, device=solver.device)
    if request.rerun:  # the same x_T, new noise for every step after it: only a stochastic sampler changes
        generator.manual_seed(rerun_seed(request.seed, request.rerun))
    after_noise = generator.get_state()

    def run(constraints) -> ikdp.SolveResult:
        generator.set_state(after_noise)  # a second run (without the pull) draws the same sampling noise
        result = solver.solve(
            request.target[None],  # (1, target_dim): one target
            num_samples=request.num_samples,
            sampler=request.sampler,
            steps=request.steps,
            refine_steps=request.refine_steps,
            generator=generator,
            return_trajectory=True,
            return_estimates=True,
            callback=stop_when(cancel),
            initial_noise=noise,
            constraints=list(constraints),
        )
        if result.stopped:
            raise Cancelled
        return result

    followed = followed_sample = None
    if request.follow_from is not None:
        # follow mode is ikdp.tracking's step itself (the pulled solve, the previous pose refined onto the target as
        # one more candidate, the nearest that reaches kept, or the branch held), so the viewer keeps what
        # solver.track keeps
        generator.set_state(after_noise)
        followed = track_step(
            solver, request.target, request.follow_from, weight=NEAR_WEIGHT, constraints=list(request.constraints),
            num_samples=request.num_samples, sampler=request.sampler, steps=request.steps,
            refine_steps=request.refine_steps, generator=generator, return_trajectory=True, return_estimates=True,
            callback=stop_when(cancel), initial_noise=noise,
        )  # fmt: skip
        if followed.solve.stopped:
            raise Cancelled
        result, followed_sample = kept_in_its_sample(solver.arm, followed)
    else:
        result = run(request.constraints)
    pull_missed = None
    if any(item.name == NEAR_POSE for item in request.constraints):
        # As ikdp.track does: a pull toward the last pose that leaves every sample short of the target is not
        # kept; the same noise solved without it reaches, and the readouts say which is shown.
        best = landing_error(result)
        if best > REACH_FRACTION * solver.arm.span:
            unpulled = run(tuple(item for item in request.constraints if item.name != NEAR_POSE))
            if landing_error(unpulled) < best:
                result, pull_missed = unpulled, best
    # a pull is no constraint that holds or fails (it was counted as holding for every sample), nor is a
    # partial target, which the errors measure
    checked = tuple(item for item in request.constraints if item.name != NEAR_POSE)
    # A miss is blamed on the locks or obstacles only where they cause it: the same noise solved without them
    # reaches. The comparison costs a second solve, made only when no pose reaches.
    reaches_unconstrained = None
    if checkable(checked) and landing_error(result) > REACH_FRACTION * solver.arm.span:
        free = run(tuple(item for item in checked if not checkable([item])))  # a partial target stays
        reaches_unconstrained = landing_error(free) <= REACH_FRACTION * solver.arm.span
    solve_seconds = time.perf_counter() - started
    partial = partial_target(request.constraints)  # the errors measure what the target asks (position only, ...)
    view, trail = arm_kind(request.solver).drawable(result, request.solver, request.target, partial=partial)
    compare = compare_trail = None
    if request.compare_sampler is not None:
        compare_seed = request.seed + 1 if not request.rerun else rerun_seed(request.seed + 1, request.rerun)
        other = request.compared_by.solve(
            request.target[None], num_samples=request.num_samples, sampler=request.compare_sampler,
            steps=request.compare_steps, spacing=request.compare_spacing, return_trajectory=True,
            generator=torch.Generator(device=solver.device).manual_seed(compare_seed), initial_noise=noise,
            callback=stop_when(cancel),
        )  # fmt: skip
        if other.stopped:
            raise Cancelled
        compare, compare_trail = arm_kind(solver).drawable(other, solver, request.target)
    violation = state_violation(request.solver, checked, result) if checkable(checked) else None
    final = final_violations(request.solver, checked, result) if violation is not None else ()
    solved = Solved(
        request,
        view,
        trail,
        solve_seconds,
        compare,
        compare_trail,
        result.angles[0].numpy(),
        violation,
        pull_missed,
        final_violations=final,
        followed=followed,
        followed_sample=followed_sample,
        reaches_unconstrained=reaches_unconstrained,
    )
    if request.joint_space is None:
        return solved
    return dataclasses.replace(solved, fields=asked_fields(solved, request.joint_space, cancel))


def asked_fields(solved: Solved, ask: FieldAsk, cancel: threading.Event | None = None) -> SolveFields:
    """The joint-space fields that `ask` names of the states `solved` will show (worker thread): every state of a
    solve to animate, the final one of a drag's (drawn at once; a scrub asks for the others, joint_space_view.py).
    The held pose is the sample the frame will highlight: follow mode's kept one, else the dropdown's choice;
    the network is the session's model's, as the view names it."""
    highlight = solved.followed_sample
    if highlight is None:
        highlight = highlighted_sample(ask.highlight, solved)
    states = None if solved.request.animate else [solved.view.num_states - 1]
    return solve_fields(solved.request.model, solved.view, ask.joints, highlight, ask.count, cancel, states)


def kept_in_its_sample(arm, step: TrackStep) -> tuple[ikdp.SolveResult, int]:
    """The step's solve with the pose it kept as one sample's returned pose, and that sample: the kept sample
    itself, or, where the kept pose is the previous one moved onto the target, the sample nearest it (its
    denoising drawn, the kept pose drawn where the returned poses are)."""
    result = step.solve
    if step.sample is not None:
        return result, step.sample
    kept = step.kept.angles[0]
    slot = int(joint_difference(arm, result.angles[0], kept).norm(dim=-1).argmin())
    angles, tip_error = result.angles.clone(), result.tip_error.clone()
    angles[0, slot], tip_error[0, slot] = kept, step.kept.position_error[0]
    rotation_error = result.rotation_error
    if rotation_error is not None:
        rotation_error = rotation_error.clone()
        rotation_error[0, slot] = step.kept.rotation_error[0]
    return dataclasses.replace(result, angles=angles, tip_error=tip_error, rotation_error=rotation_error), slot


def rerun_seed(seed: int, run: int) -> int:
    """The seed of run `run`'s step noise (run 0: the solve's own generator goes on; this is never asked)."""
    if run < 1:
        raise ValueError(f"run: expected a rerun numbered from 1, got {run}")
    return (int(seed) + int(run) * RERUN_SEED_STRIDE) % 2**63


def initial_target(solver: ikdp.Solver, target=None) -> np.ndarray:
    """`target` clamped into the solver's workspace, or the arm kind's first target when None."""
    return arm_kind(solver).initial_target(solver, target)


class Session:
    """The model and the target; `lock` is held while either changes and its consequences are posted."""

    def __init__(self, solver: ikdp.Solver, target=None, student: ikdp.Solver | None = None):
        self.lock = threading.RLock()
        self.solver = solver  # the model the newest requests use
        self.student = student  # its few-step student, the sampler "student" (student.py); None: none here
        self.target = initial_target(solver, target)  # planar (2,), chain pose (7,); inside the workspace
        self.target_clamped = False  # the point asked for lay outside the workspace

    def move(self, point, *, from_gizmo: bool) -> tuple[np.ndarray, bool, bool]:
        """Clamp `point` into the workspace and make it the target: (target, clamped, changed). Hold `lock`."""
        target, clamped = arm_kind(self.solver).clamp(self.solver, point)
        changed = not np.array_equal(target, self.target)
        # A drag past the boundary ends on the boundary point the app put the gizmo at: still the clamped request.
        clamped = clamped or (not changed and from_gizmo and self.target_clamped)
        self.target, self.target_clamped = target, clamped
        return target, clamped, changed

    def request(
        self,
        panel,  # the viewer's Panel (panel.py), read for its sampling settings
        *,
        arrival: float | None = None,
        animate: bool = True,
        constraints: tuple = (),
        chosen_steps: int | None = None,
        follow_from: np.ndarray | None = None,
    ) -> SolveRequest:
        """A solve of the current target with the panel's settings (a new seed first, if the panel asks).

        `chosen_steps`: the steps the user chose for a sampler that can skip some, which the panel's slider
        does not show while DDPM runs (it shows T); None reads the slider.
        """
        # a new seed each solve when the panel asks (the app has the loop show it)
        seed = random.randrange(2**31) if panel.new_seed.value else int(panel.seed.value)
        choice = str(panel.sampler.value)
        solver, sampler, steps = self.sampling(choice, int(panel.steps.value))
        return SolveRequest(
            solver=solver,
            target=self.target.copy(),
            num_samples=int(panel.samples.value),
            sampler=sampler,
            steps=steps,
            refine_steps=int(panel.refine_steps.value) if panel.refine.value else 0,
            seed=seed,
            arrival=time.perf_counter() if arrival is None else arrival,
            animate=animate,
            **self.compare_settings(panel, choice, chosen_steps),
            constraints=tuple(constraints),
            student=self.student,
            teacher=None if solver is self.solver else self.solver,
            follow_from=follow_from,
            target_clamped=self.target_clamped,
        )

    def sampling(self, choice: str, steps: int | None) -> tuple[ikdp.Solver, str, int | None]:
        """The dropdown's `choice` as (model, sampler, steps): the student's own few steps, or the model's sampler
        with `steps` where it can skip some (None: all T)."""
        if choice == STUDENT and self.student is not None:
            return (self.student, *student_sampling(self.student))
        if choice not in SAMPLERS:
            raise ValueError(f"sampler: expected one of {tuple(SAMPLERS)}, got {choice!r}")
        return self.solver, choice, steps if SAMPLERS[choice].supports_steps else None

    def compare_settings(self, panel, choice: str, chosen_steps: int | None = None) -> dict:
        """The comparison the panel asks for: another sampler (or the student, or from it the teacher) from the
        same x_T, unless it is the sampler itself."""
        other = str(panel.learn.compare.value)
        if other == choice:  # nothing drawn beside it: said, or the choice looks broken
            return {"compare_note": f"compare with: **{other}** is the sampler shown: nothing to compare"}
        if other == "off" or (other not in SAMPLERS and other not in (STUDENT, TEACHER)):
            return {}
        if other in (STUDENT, TEACHER) and self.student is None:
            return {}
        if other == TEACHER:  # the teacher's run the student was distilled from, beside either
            sampler, steps, spacing = distillation_target(self.student)
            return {"compare_sampler": sampler, "compare_steps": steps, "compare_solver": self.solver,
                    "compare_spacing": spacing}  # fmt: skip
        steps = int(panel.steps.value) if chosen_steps is None else chosen_steps
        solver, sampler, steps = self.sampling(other, steps)
        return {"compare_sampler": sampler, "compare_steps": steps, "compare_solver": solver}
