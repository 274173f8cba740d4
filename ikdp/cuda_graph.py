"""The reverse loop on CUDA, captured once per shape as a CUDA graph and replayed (optional).

On a GPU one solve is a few thousand tiny kernels, so its time is launch overhead,
not arithmetic. A CUDA graph records the kernels of one run of the loop for a fixed
shape (sampler, steps, B, K) and replays them with a single launch. The eager loop
(ikdp.sampling.run_reverse_diffusion) stays the reference and the CPU path: this
module only captures that same function, so both give the same samples for the
same seed (tests/test_cuda_graph.py checks it where CUDA exists).

    graphed = CapturedReverseDiffusion(solver.model, batch=1, num_samples=16)
    out = graphed(targets, seed=0)       # a Trajectory; its tensors are overwritten by the next call

A whole batch solve (sampling, refinement, the restarts' fallback, the errors) is captured the same way by
CapturedSolve (`solver.capture(batch, ...)`): its body, `solve_without_sync`, asks the device nothing and keeps
every shape fixed, so it runs eagerly on a CPU too (tests/test_cuda_graph.py checks that it makes no host sync).
"""

from __future__ import annotations

import importlib.util

import torch

from ikdp.refine import damped_least_squares, sync_free_iteration
from ikdp.restarts import restart_every_target, within_tolerances
from ikdp.samplers import Sampler, make_sampler
from ikdp.sampling import Trajectory, run_reverse_diffusion, step_conditions
from ikdp.solve_result import SolveResult, is_integer


def capture(run, generator: torch.Generator):
    """`run()` recorded as a CUDA graph drawing from `generator` -> (graph, run's output, overwritten by replays).

    A warm-up run on a side stream first makes what a capture may not (cuBLAS handles, the per-device constants
    of the arm and the sampler, the allocator's pools).
    """
    side = torch.cuda.Stream()
    side.wait_stream(torch.cuda.current_stream())
    with torch.cuda.stream(side), torch.inference_mode():
        run()
    torch.cuda.current_stream().wait_stream(side)
    graph = torch.cuda.CUDAGraph()
    graph.register_generator_state(generator)
    with torch.cuda.graph(graph), torch.inference_mode():
        output = run()
    return graph, output


class CapturedReverseDiffusion:
    """One shape's reverse loop as a CUDA graph: static target and condition buffers in, a Trajectory out."""

    def __init__(
        self,
        model,
        *,
        batch: int,
        num_samples: int,
        sampler: str = "ddpm",
        steps: int | None = None,
        spacing: str = "uniform",
    ):
        device = next(model.parameters()).device
        if device.type != "cuda":
            raise ValueError(f"model: expected a model on a CUDA device, got one on {device}")
        if batch < 1 or num_samples < 1:
            raise ValueError(f"batch, num_samples: expected positive integers, got {batch}, {num_samples}")
        self.model = model
        self.num_samples = num_samples
        # a sampler of its own: its noise buffers live in the graph's memory, not in the model's shared cache
        self.sampler = make_sampler(sampler, model.schedule, steps, spacing)
        self.targets = torch.zeros((batch, model.arm.target_dim), device=device)
        self.conditions = self._conditions(self.targets)
        self.generator = torch.Generator(device=device)
        self.graph, self.output = capture(self._run, self.generator)

    def _conditions(self, targets: torch.Tensor) -> torch.Tensor:
        conditions = step_conditions(self.model.denoiser, self.sampler.timesteps, targets, self.num_samples)
        if conditions is None:
            raise ValueError("batch, num_samples: too large for the conditions of every step to be precomputed")
        return conditions

    def _run(self) -> Trajectory:
        return run_reverse_diffusion(
            self.model.denoiser,
            self.model.schedule,
            self.model.representation,
            self.sampler,
            self.targets,
            num_samples=self.num_samples,
            prediction=self.model.config.prediction,
            generator=self.generator,
            return_trajectory=True,
            conditions=self.conditions,
        )

    @torch.inference_mode()
    def __call__(self, targets: torch.Tensor, *, seed: int) -> Trajectory:
        """targets (B, C), already clamped to the workspace as `solve` does -> the run's Trajectory.

        The same as run_reverse_diffusion with `generator=torch.Generator("cuda").manual_seed(seed)`.
        """
        if targets.shape != self.targets.shape:
            raise ValueError(f"targets: expected shape {tuple(self.targets.shape)}, got {tuple(targets.shape)}")
        self.targets.copy_(targets)
        self.conditions.copy_(self._conditions(self.targets))  # eager: it copies timesteps from the host
        self.generator.manual_seed(seed)
        self.graph.replay()
        return self.output


class CapturedSolve:
    """One shape's whole `solve` on CUDA as one CUDA graph: targets in, a SolveResult out (no constraints).

        captured = solver.capture(1000, num_samples=16, sampler="ddim", steps=1, refine_steps=8)
        result = captured(targets, seed=0)  # its tensors are overwritten by the next call

    The poses are `solve`'s for the same seed except the restarts: theirs come from every target's fresh
    starts drawn on the GPU (`restart_every_target`), where solve draws only the unreached ones' on the CPU.
    `fused=True`: each refinement step and the error check (a float64 kinematics pass) are compiled first
    (torch.compile fuses their hundreds of small kernels into a few; needs Triton, and the first capture of a
    shape takes seconds longer).
    """

    def __init__(
        self,
        solver,
        *,
        batch: int,
        num_samples: int = 16,
        sampler: str = "ddpm",
        steps: int | None = None,
        spacing: str | None = None,
        refine_steps: int = 0,
        restart_steps: int = 0,
        fused: bool = False,
    ):
        if not is_integer(batch) or batch < 1:
            raise ValueError(
                f"batch: expected a positive integer (the number of targets a replay takes), got {batch!r}"
            )
        spacing = solver.default_spacing(sampler, steps) if spacing is None else spacing
        solver.check_options(batch, num_samples, sampler, steps, spacing, refine_steps, None, None)
        if not is_integer(restart_steps) or restart_steps < 0:
            raise ValueError(f"restart_steps: expected a non-negative integer, got {restart_steps!r}")
        if fused and importlib.util.find_spec("triton") is None:
            raise ValueError("fused: torch.compile needs Triton on a GPU, which is not installed; capture unfused")
        if solver.device.type != "cuda":
            raise ValueError(f"solver: expected one loaded on a CUDA device, got one on {solver.device}")
        self.solver = solver
        self.options = dict(num_samples=num_samples, refine_steps=refine_steps, restart_steps=restart_steps)
        if fused:  # compiled once per shape by the warm-up run, before the capture
            self.options["iteration"] = torch.compile(sync_free_iteration, dynamic=False)
            self.options["errors"] = torch.compile(solver.arm.tip_and_rotation_errors, dynamic=False)
        self.sampler = make_sampler(sampler, solver.model.schedule, steps, spacing)  # its buffers: the graph's
        self.asked = torch.zeros((batch, solver.arm.target_dim), device=solver.device)
        self.generator = torch.Generator(device=solver.device)
        self.graph, self.output = capture(self._run, self.generator)

    def _run(self):
        return solve_without_sync(self.solver, self.sampler, self.asked, generator=self.generator, **self.options)

    @torch.inference_mode()
    def __call__(self, targets, *, seed: int):
        """targets as `solve` takes them ((B, target_dim); a tree's (B, E, 7) or (B, E, 3)) -> the SolveResult of
        `solve(targets, ..., generator=torch.Generator("cuda").manual_seed(seed))` (restarts aside, above)."""
        targets = self.solver.arm.validate_targets(targets).to(self.asked.device)
        if targets.shape != self.asked.shape:
            raise ValueError(f"targets: expected shape {tuple(self.asked.shape)}, got {tuple(targets.shape)}")
        self.asked.copy_(targets)
        self.generator.manual_seed(seed)
        self.graph.replay()
        return self.output


@torch.inference_mode()
def solve_without_sync(
    solver,
    sampler: Sampler,
    targets: torch.Tensor,
    *,
    num_samples: int,
    refine_steps: int,
    restart_steps: int,
    generator: torch.Generator | None,
    iteration=None,
    errors=None,
):
    """`Solver.solve` for validated targets (B, target_dim), without constraints, callbacks or trajectories, and
    with nothing that waits for the device or sizes a tensor by its data: what a CUDA graph can hold.
    `iteration`, `errors`: the refinement's step and `arm.tip_and_rotation_errors`, compiled (CapturedSolve's
    `fused`); None: sync_free_iteration and the arm's method."""
    arm, model = solver.arm, solver.model
    conditions = arm.clamp_to_workspace(targets)
    result = run_reverse_diffusion(
        model.denoiser,
        model.schedule,
        model.representation,
        sampler,
        conditions,
        num_samples=num_samples,
        prediction=model.config.prediction,
        generator=generator,
    )
    raw = result.headings
    goals = conditions[:, None].expand(-1, num_samples, -1)
    refine = dict(sync_free=True, iteration=iteration)
    angles = damped_least_squares(arm, raw, goals, steps=refine_steps, **refine) if refine_steps else raw
    restarted = None
    if restart_steps:
        restarted = ~within_tolerances(arm, angles, goals, errors=errors).any(dim=-1)
        angles = restart_every_target(arm, angles, goals, restarted, restart_steps, generator, iteration, errors)
    per_sample_targets = targets[:, None].expand(-1, num_samples, -1)
    errors = arm.tip_and_rotation_errors if errors is None else errors
    by_effector = arm.errors_by_effector(angles, per_sample_targets)  # a tree's, each (B, K, E); else None
    if by_effector is None:
        error, rotation_error = errors(angles, per_sample_targets)
    else:  # the worst end effector's, from the same kinematics pass
        error = by_effector[0].amax(dim=-1)
        rotation_error = None if by_effector[1] is None else by_effector[1].amax(dim=-1)
    return SolveResult(
        angles=angles,
        tip_error=error,
        trajectory=None,
        timesteps=result.timesteps,
        reachable=arm.is_reachable(targets),
        raw_angles=raw,
        raw_tip_error=error if angles is raw else errors(raw, per_sample_targets)[0],
        rotation_error=rotation_error,
        network_evaluations=result.network_evaluations,
        restarted=restarted,
        tip_error_by_effector=None if by_effector is None else by_effector[0],
        rotation_error_by_effector=None if by_effector is None else by_effector[1],
    )
