"""The reverse loop on CUDA, captured once per shape as a CUDA graph and replayed (optional).

On a GPU one solve is a few thousand tiny kernels, so its time is launch overhead,
not arithmetic. A CUDA graph records the kernels of one run of the loop for a fixed
shape (sampler, steps, B, K) and replays them with a single launch. The eager loop
(ikdp.sampling.run_reverse_diffusion) stays the reference and the CPU path: this
module only captures that same function, so both give the same samples for the
same seed (tests/test_cuda_graph.py checks it where CUDA exists).

    graphed = CapturedReverseDiffusion(solver.model, batch=1, num_samples=16)
    out = graphed(targets, seed=0)       # a Trajectory; its tensors are overwritten by the next call

Not yet run on GPU hardware: the project's machine has none.
"""

from __future__ import annotations

import torch

from ikdp.samplers import make_sampler
from ikdp.sampling import Trajectory, run_reverse_diffusion, step_conditions


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
        # warm up on a side stream (cuBLAS handles, allocator), then capture the same call
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side), torch.inference_mode():
            self._run()
        torch.cuda.current_stream().wait_stream(side)
        self.graph = torch.cuda.CUDAGraph()
        self.graph.register_generator_state(self.generator)
        with torch.cuda.graph(self.graph), torch.inference_mode():
            self.output = self._run()

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
