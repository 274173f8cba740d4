"""The public solver: load a checkpoint, solve IK for a batch of targets.

solver = ikdp.load("checkpoints/ikdp_n4.pt")
out = solver.solve(targets, num_samples=16)
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch

from ikdp.checkpoint import CheckpointError, read_checkpoint
from ikdp.constraint_base import Constraint
from ikdp.denoisers.int8 import Int8Weights, int8_available
from ikdp.device import available_bytes, checked_device
from ikdp.fused_chain import small_batch
from ikdp.guidance import ConstraintSet, checked
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior
from ikdp.restarts import restart_unreached
from ikdp.samplers import SAMPLERS, sampler_names
from ikdp.sampling import StepCallback
from ikdp.schedule import TIMESTEP_SPACINGS
from ikdp.shipped import shipped_checkpoint
from ikdp.solve_result import SolveResult, is_integer
from ikdp.stream import PoseStream
from ikdp.tracking import TrackResult, track

# Peak memory of one sample row while sampling, measured on one CPU thread (a Panda model of hidden 512: 9.6 kB;
# of hidden 256: 5.3 kB; refinement adds nothing to the peak): about 1 kB + 17 bytes per unit width.
ROW_BYTES_FIXED = 1024
ROW_BYTES_PER_WIDTH = 17
MEMORY_CHECK_FROM = 2**28  # bytes: solves that need less are not checked against the free memory
STUDENT = "student"  # solve's sampler name for a model's distilled few-step student (the one folded into its file)


class Solver:
    """A trained IKDP model, ready to solve. Build it with `ikdp.load(path or shipped name)`."""

    def __init__(
        self,
        model: IKDiffusion,
        prior: PosePrior,
        metadata: dict,
        device: str | torch.device = "cpu",
        student: Solver | None = None,
    ):
        self.device = checked_device(device)
        self.model = model.to(self.device).eval()
        self.arm = model.arm
        self.prior = prior
        self.metadata = metadata  # model config, training config, metrics at save, source path
        # the few-step student folded into this model's file (ikdp/ship.py): what solve(sampler="student") runs
        self.student = student

    @property
    def num_links(self) -> int:
        return self.arm.num_joints

    @property
    def lengths(self) -> tuple[float, ...]:
        """Bone lengths of a planar arm."""
        return self.arm.lengths

    @property
    def noise_dim(self) -> int:
        """D, the size of one sample's noise x_T (the pose in the model's representation)."""
        return self.model.representation.dim

    @property
    def timesteps(self) -> int:
        return self.model.schedule.num_timesteps

    @property
    def reach(self) -> tuple[float, float]:
        """(inner, outer) radius of a planar arm's reachable annulus."""
        return self.arm.reach

    def default_spacing(self, sampler: str, steps: int | None) -> str:
        """The timestep spacing a solve uses when it names none.

        A distilled student's own (sampler, steps) use the grid it was trained on; a robot's few-step
        solves use the grid packed near t = 0, which measured better at 4 to 16 evaluations on both shipped
        Panda models (docs/benchmarks.md); a planar arm's keep the evenly spaced grid.
        """
        student = self.metadata.get("distill") or {}
        if (sampler, steps) == (student.get("sampler"), student.get("steps")):
            return student["spacing"]
        return "uniform" if self.arm.kind == "planar" else "quadratic"

    def solve(
        self,
        targets,
        *,
        num_samples: int = 16,
        sampler: str = "ddpm",
        steps: int | None = None,
        spacing: str | None = None,
        refine_steps: int = 0,
        restart_steps: int = 0,
        stop_when_reached: bool = False,
        generator: torch.Generator | None = None,
        return_trajectory: bool = False,
        return_estimates: bool = False,
        callback: StepCallback | None = None,
        initial_noise: torch.Tensor | None = None,
        constraints: Sequence[Constraint] = (),
    ) -> SolveResult:
        """K poses for each of B targets, (B, target_dim) -> (B, K, J); several end effectors (`arm.ee_links`):
        targets (B, E, 7) or (B, E, 3), and each one's errors in `tip_error_by_effector` (B, K, E).

        An unreachable target is not an error: the model is asked for the nearest
        reachable point (its training never saw farther targets), so the arm reaches
        toward the target as far as it can; `reachable` is False and `tip_error` is the
        distance to the target as asked.

        `callback(step_index, timestep, state, estimate)` is called after every reverse
        step with the state and the denoiser's x̂0 as joint values (B, K, J); returning
        True stops the solve at once (`stopped` is then True and no refinement runs).

        `spacing`: how the sampler's `steps` timesteps spread over [0, T-1]: "uniform" or "quadratic"
        (packed near t = 0); None: `default_spacing(sampler, steps)`.
        `initial_noise`: the pure noise x_T the samplers start from, (B, K, D) with D =
        `solver.noise_dim`; the same x_T given to DDPM and to DDIM compares the two on equal
        terms. None draws it from `generator` (as the first thing drawn).
        `constraints` (ikdp.constraint_names(): locked joints, a pose to stay near, obstacles,
        partial targets) bend the reverse process toward them and are kept by the refinement;
        `constraint_violation` then says where they hold (docs/library.md, "Constraints"). A tree whose
        links can meet keeps its branches apart unless given `ikdp.SelfCollision(enabled=False)`.
        `restart_steps`: a numerical fallback. The targets none of whose K refined poses is within the arm's
        tolerances (1 mm and 1 degree on a robot) get K fresh uniform starts within the limits, refined that
        many DLS steps (ikdp/restarts.py); `restarted` (B,) says which. With constraints, reaching also means
        meeting them, and the fresh starts keep the locked joints and are refined by the constrained task (a pose
        to stay near, a soft pull on the diffusion, does not steer them).
        `stop_when_reached`: the refinement stops before a step once every target has one of its K poses within the
        tolerances (without constraints): the best answer in fewer steps (a Panda target's K = 16 one-step samples
        mostly after 2 of 4), the other poses refined less.
        """
        if sampler == STUDENT:
            student, sampler, steps, spacing = self.student_sampling(steps, spacing)
            return student.solve(
                targets,
                num_samples=num_samples,
                sampler=sampler,
                steps=steps,
                spacing=spacing,
                refine_steps=refine_steps,
                restart_steps=restart_steps,
                stop_when_reached=stop_when_reached,
                generator=generator,
                return_trajectory=return_trajectory,
                return_estimates=return_estimates,
                callback=callback,
                initial_noise=initial_noise,
                constraints=constraints,
            )
        arm = self.arm
        constraints = arm.with_default_constraints(checked(constraints))  # a tree: its self-collision check
        targets = ConstraintSet.validate_targets(arm, targets, constraints).to(self.device)
        spacing = self.default_spacing(sampler, steps) if spacing is None else spacing
        self.check_options(len(targets), num_samples, sampler, steps, spacing, refine_steps, generator, initial_noise)
        if not is_integer(restart_steps) or restart_steps < 0:
            raise ValueError(f"restart_steps: expected a non-negative integer, got {restart_steps!r}")
        if not isinstance(stop_when_reached, bool):
            raise ValueError(f"stop_when_reached: expected True or False, got {stop_when_reached!r}")
        self.check_memory(len(targets) * num_samples, sampler, steps, return_trajectory, return_estimates)
        reachable = arm.is_reachable(targets)
        conditions = arm.clamp_to_workspace(targets)
        batch = len(targets)
        bound = ConstraintSet(arm, constraints, batch, num_samples) if constraints else None
        sample_targets, per_target = conditions, num_samples
        if bound is not None and bound.partial is not None:  # each sample its own full pose to aim at
            sample_targets, per_target = bound.partial.conditions(conditions, num_samples, generator), 1
            if callback is not None:
                callback = regroup_callback(callback, batch, num_samples)
        guidance = None
        if bound is not None:
            rows = sample_targets.repeat_interleave(per_target, dim=0)
            guidance = bound.guidance(self.model.representation, self.model.sampler(sampler, steps, spacing), rows)
        result = self.model.sample(
            sample_targets,
            num_samples=per_target,
            sampler=sampler,
            steps=steps,
            spacing=spacing,
            generator=generator,
            return_trajectory=return_trajectory,
            return_estimates=return_estimates,
            callback=callback,
            # a partial target gives each sample a row of its own: x_T (B, K, D) as (B * K, 1, D)
            initial_noise=initial_noise
            if initial_noise is None or per_target == num_samples
            else initial_noise.reshape(batch * num_samples, 1, -1),
            guidance=guidance,
        )
        raw = result.headings.reshape(batch, num_samples, -1)  # (B, K, J)
        if bound is not None:
            raw = bound.hold(raw)
        per_sample_targets = targets[:, None].expand(-1, num_samples, -1)
        angles = raw
        # refinement and restarts aim at the nearest reachable point: for a target beyond reach, the stretched arm
        goals = sample_targets.reshape(batch, num_samples, -1) if per_target == 1 else conditions[:, None]
        goals = goals.expand(-1, num_samples, -1)
        # a few poses on a CPU (one target's K): the arm's kinematics, errors and, without constraints, refinement as
        # a few fused operations (ikdp/fused_chain.py), the same numbers to rounding; a batch keeps the arm's own
        fused = small_batch(raw.numel() // arm.num_joints, raw.device)
        kinematics = arm.small_batch_kinematics() if fused else arm
        scores = None  # the errors the fused refinement measured on its way, where they are the solve's own
        if refine_steps and not result.stopped:
            task = None if bound is None else bound.refine_task()
            if task is None:
                angles, scores = kinematics.refine_scored(
                    raw, goals, steps=refine_steps, until_reached=stop_when_reached
                )
                if scores is not None and (bound is not None or not torch.equal(goals, per_sample_targets)):
                    # measured against the nearest reachable point, not the target as asked, or blind to constraints
                    scores = None
            else:
                angles = kinematics.refine(raw, goals, steps=refine_steps, task=task)
        restarted = None
        if restart_steps and not result.stopped:
            within = None if scores is None else scores.within(arm)
            angles, restarted = restart_unreached(kinematics, angles, goals, restart_steps, generator, bound, within)
        measure = kinematics if bound is None or bound.partial is None else bound.partial  # partial: the parts asked
        if scores is not None and measure is kinematics and (restarted is None or not bool(restarted.any())):
            error, rotation_error, raw_error = scores.position, scores.rotation, scores.first_position
        else:
            error, rotation_error = measure.tip_and_rotation_errors(angles, per_sample_targets)  # one kinematics pass
            raw_error = error if angles is raw else measure.tip_and_rotation_errors(raw, per_sample_targets)[0]
        # a tree's, each (B, K, E); else None
        by_effector = (arm if measure is kinematics else measure).errors_by_effector(angles, per_sample_targets)
        states, estimates = result.states, result.estimates
        if per_target == 1:  # (S, B * K, 1, J) -> (S, B, K, J)
            states = None if states is None else states.reshape(states.shape[0], batch, num_samples, -1)
            estimates = None if estimates is None else estimates.reshape(estimates.shape[0], batch, num_samples, -1)
        return SolveResult(
            angles=angles,
            tip_error=error,
            trajectory=states,
            timesteps=result.timesteps,
            reachable=reachable,
            raw_angles=raw,
            raw_tip_error=raw_error,
            estimates=estimates,
            stopped=result.stopped,
            rotation_error=rotation_error,
            constraint_violation=None if bound is None else bound.violation(angles),
            network_evaluations=result.network_evaluations,
            restarted=restarted,
            tip_error_by_effector=None if by_effector is None else by_effector[0],
            rotation_error_by_effector=None if by_effector is None else by_effector[1],
        )

    def student_sampling(self, steps: int | None, spacing: str | None) -> tuple[Solver, str, int, str]:
        """(student, sampler, steps, spacing) that sampler="student" runs: the folded student on the grid it was
        distilled for (a student's own file: itself); ValueError when this model has none or the call asks for
        another grid."""
        student = self.student if self.student is not None else (self if self.metadata.get("distill") else None)
        if student is None:
            name = Path(str(self.metadata.get("path", "this model"))).stem
            raise ValueError(
                f"sampler: {name!r} has no distilled student to run as 'student'; its samplers: {sampler_names()}"
            )
        record = student.metadata["distill"]
        own = (int(record["steps"]), str(record["spacing"]))
        if (steps, spacing) not in ((None, None), own):
            raise ValueError(
                f"steps, spacing: the student runs the {own[0]} steps ({own[1]}) it was distilled for; got steps="
                f"{steps!r}, spacing={spacing!r} (leave both None)"
            )
        return student, str(record["sampler"]), own[0], own[1]

    def stream(self, start_pose, **options) -> PoseStream:
        """Targets one at a time, as a control loop asks: `stream = solver.stream(start_pose)`, then
        `pose = stream(target)` (target_dim,) -> (J,) at every tick, each warm-started from the last answer by a
        few fused damped least-squares steps, a tracking solve where they do not reach (ikdp/stream.py).
        `options`: max_steps, max_jump, and `track`'s for that fallback."""
        return PoseStream(self, start_pose, **options)

    def capture(self, batch: int, **options):
        """This solve for `batch` targets as one CUDA graph (a solver on a GPU; ikdp/cuda_graph.py):
        `captured = solver.capture(1000, num_samples=16, sampler="ddim", steps=1, refine_steps=8)`, then
        `captured(targets, seed=0)` replays it from one launch. `options`: solve's num_samples, sampler, steps,
        spacing, refine_steps and restart_steps (constraints, a tree's self-collision check among them, callbacks and
        trajectories stay eager); `fused=True`
        compiles each refinement step first (torch.compile; Triton)."""
        from ikdp.cuda_graph import CapturedSolve  # CUDA-only machinery, loaded when asked for

        if options.get("sampler") == STUDENT:
            student, sampler, steps, spacing = self.student_sampling(options.get("steps"), options.get("spacing"))
            return CapturedSolve(
                student, batch=batch, **{**options, "sampler": sampler, "steps": steps, "spacing": spacing}
            )
        return CapturedSolve(self, batch=batch, **options)

    def check_options(
        self, batch, num_samples, sampler, steps, spacing, refine_steps, generator, initial_noise
    ) -> None:
        """ValueError naming the first of solve's options that cannot run, before any work starts."""
        if not is_integer(num_samples) or num_samples < 1:
            raise ValueError(f"num_samples: expected a positive integer, got {num_samples!r}")
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler: expected one of {sampler_names()} or {STUDENT!r}, got {sampler!r}")
        if spacing not in TIMESTEP_SPACINGS:
            raise ValueError(f"spacing: expected one of {TIMESTEP_SPACINGS} or None, got {spacing!r}")
        if steps is not None and (not is_integer(steps) or steps < 1):
            raise ValueError(f"steps: expected None or a positive integer, got {steps!r}")
        if not is_integer(refine_steps) or refine_steps < 0:
            raise ValueError(f"refine_steps: expected a non-negative integer, got {refine_steps!r}")
        if generator is not None and not isinstance(generator, torch.Generator):
            raise ValueError(f"generator: expected None or a torch.Generator, got {generator!r}")
        if initial_noise is not None:
            if not isinstance(initial_noise, torch.Tensor):
                raise ValueError(f"initial_noise: expected a tensor x_T, got {type(initial_noise).__name__}")
            expected = (batch, num_samples, self.noise_dim)
            if tuple(initial_noise.shape) != expected:
                raise ValueError(f"initial_noise: expected x_T of shape {expected}, got {tuple(initial_noise.shape)}")
            if not bool(torch.isfinite(initial_noise).all()):
                raise ValueError("initial_noise: holds NaN or inf; x_T must be finite")

    def sampling_bytes(self, rows: int, sampler: str, steps: int | None, trajectory: bool, estimates: bool) -> int:
        """About how much memory sampling `rows` = B x K samples takes at its peak, in bytes (ROW_BYTES_*)."""
        per_row = ROW_BYTES_FIXED + ROW_BYTES_PER_WIDTH * self.model.config.denoiser.hidden
        num_steps = self.model.sampler(sampler, steps).num_steps
        per_row += 4 * self.noise_dim * ((num_steps + 1) * trajectory + num_steps * estimates)  # float32 states
        return rows * per_row

    def check_memory(self, rows: int, sampler: str, steps: int | None, trajectory: bool, estimates: bool) -> None:
        """ValueError, with the memory it would need, when B x K samples cannot fit in the device's free memory."""
        needed = self.sampling_bytes(rows, sampler, steps, trajectory, estimates)
        if needed < MEMORY_CHECK_FROM:
            return  # no need to read the free memory (a file read on a CPU) at every small solve
        available = available_bytes(self.device)
        if available is not None and needed > available:
            fits = max(1, rows * available // needed)
            raise ValueError(
                f"num_samples: {rows} samples (targets x num_samples) need about {needed / 1e9:.1f} GB to sample, "
                f"more than the {available / 1e9:.1f} GB free on {self.device}; solve at most about {fits} at a time"
            )

    def track(self, path, start_pose, **options) -> TrackResult:
        """One continuous solution per target of a path (P, target_dim), starting from `start_pose` (J,).

        Each target is solved with a pull toward the previous solution and the nearest sample that
        reaches it is kept; out of reach the arm holds its branch, stretched toward the target
        (ikdp/tracking.py). `options`: weight, tolerances, constraints, warm_start, hold_step,
        look_ahead and solve's.
        """
        return track(self, path, start_pose, **options)


def regroup_callback(callback: StepCallback, batch: int, num_samples: int) -> StepCallback:
    """A callback written for (B, K, J) states, called by a loop that runs B * K targets of one sample."""

    def regrouped(index, t, state, estimate):
        return callback(index, t, state.reshape(batch, num_samples, -1), estimate.reshape(batch, num_samples, -1))

    return regrouped


def model_from_checkpoint(payload: dict, source: str = "<memory>") -> IKDiffusion:
    """Rebuild the model a checkpoint describes and load its weights; CheckpointError if they disagree."""
    try:
        config = ModelConfig.from_dict(payload["model"])
        model = IKDiffusion(config)
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{source}: invalid model description in checkpoint ({error})") from None
    state = payload["state_dict"]
    if not isinstance(state, dict) or not all(isinstance(value, torch.Tensor) for value in state.values()):
        raise CheckpointError(f"{source}: state_dict is not a dict of tensors")
    problems = weight_differences(model.state_dict(), state)
    if problems:
        raise CheckpointError(f"{source}: weights do not match the model: {problems}")
    model.load_state_dict(state, strict=True)
    return model


def weight_differences(expected: dict, state: dict) -> str:
    """Where `state` does not fit a model whose state_dict is `expected`: the first difference named (and how many
    more), or "" when every key is there with its shape."""
    problems = [f"missing key {name!r}" for name in expected if name not in state]
    problems += [f"unexpected key {name!r}" for name in state if name not in expected]
    problems += [
        f"key {name!r} has shape {tuple(state[name].shape)}, the model's {tuple(expected[name].shape)}"
        for name in expected
        if name in state and state[name].shape != expected[name].shape
    ]
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    return f"{problems[0]}{more}" if problems else ""


def resolve_checkpoint(path_or_name: str | Path) -> Path:
    """A path as given when it exists or looks like a path; else a shipped model's name (`ikdp_n4`)."""
    path = Path(path_or_name)
    if path.exists() or path.suffix or len(path.parts) > 1:
        return path
    try:
        return shipped_checkpoint(str(path_or_name))
    except ValueError as error:
        raise CheckpointError(f"{path_or_name}: no such file, and {error}") from None


PRECISIONS = ("float32", "int8")


def load(path: str | Path, device: str | torch.device = "cpu", precision: str = "float32") -> Solver:
    """Load an IKDP checkpoint (a path, or a shipped model's name) as a Solver.

    `precision="int8"`: the robot denoiser's wide layers sample with int8 weights (CPU only; faster
    batch solves, the raw samples a little less precise: ikdp/denoisers/int8.py).

    Refuses anything but a valid IKDP checkpoint (CheckpointError, one line), and a device that is not
    here or a precision it cannot run (ValueError), before reading anything (int8 for a model without the
    robot denoiser: once its file says so).
    """
    device = checked_device(device)
    if precision not in PRECISIONS:
        raise ValueError(f"precision: expected one of {PRECISIONS}, got {precision!r}")
    if precision == "int8":
        if device.type != "cpu":
            raise ValueError(f"precision 'int8' runs on the CPU only, not on {device}")
        unavailable = int8_available()
        if unavailable:
            raise ValueError(f"precision 'int8': {unavailable}")
    path = resolve_checkpoint(path)
    payload = read_checkpoint(path)
    student_payload = folded_student(payload, path)
    model = model_from_checkpoint(payload, str(path))
    kind = model.config.denoiser.kind
    if precision == "int8" and kind != "chain_film":
        raise ValueError(f"precision 'int8' is built for the robots' 'chain_film' denoiser; {path.name} has {kind!r}")
    try:
        prior = PosePrior.from_config(payload["prior"])
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: invalid prior in checkpoint ({error})") from None
    student = None
    if student_payload is not None:
        student_model = model_from_checkpoint(student_payload, f"{path} (its student)")
        student = solver_of(student_model, prior, student_payload, path, precision, device)
    return solver_of(model, prior, payload, path, precision, device, student)


def solver_of(model, prior, payload: dict, path: Path, precision: str, device, student: Solver | None = None):
    """The Solver of a model read from `payload` (a file's, or the student folded into it)."""
    metadata = {
        "path": str(path),
        "model": payload["model"],
        "train": payload["train"],
        "metrics": payload["metrics"],
        "distill": payload.get("distill"),  # a student of ikdp.distill: its teacher and its own sampler
        "precision": precision,
    }
    solver = Solver(model, prior, metadata, device, student)
    if precision == "int8":
        solver.model.denoiser.int8 = Int8Weights(solver.model.denoiser)
    return solver


STUDENT_KEYS = ("model", "train", "metrics", "distill", "state_dict")


def folded_student(payload: dict, path: Path) -> dict | None:
    """The student payload folded into a checkpoint (ikdp/ship.py), checked for what a Solver needs; None if none."""
    student = payload.get(STUDENT)
    if student is None:
        return None
    if not isinstance(student, dict):
        raise CheckpointError(f"{path}: its student is not a dict but {type(student).__name__}")
    missing = [key for key in STUDENT_KEYS if key not in student]
    if missing:
        raise CheckpointError(f"{path}: its student is incomplete, missing {', '.join(missing)}")
    record = student["distill"]
    if not isinstance(record, dict) or any(key not in record for key in ("sampler", "steps", "spacing")):
        raise CheckpointError(f"{path}: its student's distill record lacks its sampler, steps or spacing")
    return student
