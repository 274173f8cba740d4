"""How `ikdp.train` takes one optimizer step: eagerly, or replayed from one CUDA graph (the default on a GPU).

A step draws a batch of poses from the prior (on the generator's device: a GPU's data is made there, nothing is
copied per step), computes the loss, clips the gradient, steps AdamW and updates the weights' moving average.
On a GPU these small networks make a step a few hundred tiny kernels, so its time is their launches, not their
arithmetic. GraphedSteps records one whole step once and replays it with a single launch: the step reads its
learning rate from a tensor set before each replay, draws from a generator the graph advances, asks the device
nothing (tests/test_train_steps.py checks the step's body on a CPU) and keeps every shape fixed.

Both are called the same way, `steps(lr) -> (the batch drawn, the losses)`, and take the same steps: on a CPU,
GraphedSteps with an eager recorder gives EagerSteps' weights (a test). On an H100 the graph took the Panda's
GPU recipe from 41.7 to 144.8 steps a second and the planar N = 4 recipe from 147 to 1181 (docs/training.md,
"On a GPU"), so `ikdp.train` replays one wherever it applies (`graph_applies`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import torch

Step = Callable[[], tuple[torch.Tensor, dict[str, torch.Tensor]]]  # one whole step: (batch, losses)
Recorder = Callable[[Step, torch.Generator], Step]  # a step -> its replay


def graph_applies(graph: bool, device: torch.device, world_size: int) -> bool:
    """Whether a training asking for graphed steps (`--graph`, the default) gets them: on a CUDA device, in one
    process (DDP's gradient averaging is not recorded here). Elsewhere it takes eager steps, the same steps."""
    return graph and device.type == "cuda" and world_size == 1


def take_step(
    loss: torch.nn.Module, draw: Callable[[], torch.Tensor], generator: torch.Generator, optimizer
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """One optimizer step on a batch drawn now, at the rate the optimizer holds -> (the batch, the losses).

    The gradients are dropped first: a recorded backward then writes them rather than adding to them. Under DDP
    the backward pass averages them over the processes. The losses come back detached: a caller holding them
    would otherwise keep the autograd graph, and with it the weights' gradient accumulators made on the last
    step's stream, alive into the next (torch warns that this may break a capture)."""
    optimizer.zero_grad(set_to_none=True)
    headings = draw()
    losses = loss(headings, generator)
    losses["loss"].backward()
    torch.nn.utils.clip_grad_norm_(loss.parameters(), 1.0)
    optimizer.step()
    return headings, {name: value.detach() for name, value in losses.items()}


class EagerSteps:
    """Each step run op by op from Python: every device, and several processes (DDP).

    `loss`: the model's loss as a module (DDP may wrap it); `model`: the weights `averaged` follows, if given."""

    def __init__(self, loss, model, draw: Callable[[], torch.Tensor], generator, optimizer, averaged=None):
        self.loss, self.model, self.draw, self.generator = loss, model, draw, generator
        self.optimizer, self.averaged = optimizer, averaged
        for group in optimizer.param_groups:  # a checkpoint written by GraphedSteps is resumed here too
            group["capturable"] = False

    def __call__(self, lr: float) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        headings, losses = take_step(self.loss, self.draw, self.generator, self.optimizer)
        if self.averaged is not None:
            self.averaged.update_parameters(self.model)
        return headings, losses


def record_cuda_graph(step: Step, generator: torch.Generator) -> Step:
    """`step` recorded as a CUDA graph drawing from `generator` -> its replay (the same output tensors, rewritten).

    Recording runs nothing: the step the graph holds is first taken by the replay."""
    graph = torch.cuda.CUDAGraph()
    graph.register_generator_state(generator)
    with torch.cuda.graph(graph):
        output = step()

    def replay():
        graph.replay()
        return output

    return replay


class GraphedSteps:
    """Each step replayed from one recorded graph (a CUDA graph on a GPU; `record` says how to record).

    The first WARM_UP steps run eagerly, on a side stream on a GPU as a capture needs: they make AdamW's state,
    cuBLAS's workspace and autograd's buffers, which a recording may not allocate. Every call takes one step.
    """

    WARM_UP = 3

    def __init__(
        self,
        loss,
        model,
        draw: Callable[[], torch.Tensor],
        generator: torch.Generator,
        optimizer: torch.optim.Optimizer,
        averaged=None,
        *,
        ema: float = 0.0,
        record: Recorder = record_cuda_graph,
    ):
        self.loss, self.model, self.draw, self.generator = loss, model, draw, generator
        self.optimizer, self.averaged = optimizer, averaged
        self.ema, self.record = ema, record
        self.device = next(model.parameters()).device
        self.lr = torch.zeros((), device=self.device)  # the rate a replay reads, set before each
        capturable = self.device.type == "cuda"  # AdamW's step count then lives on the GPU, read by the graph
        for group in optimizer.param_groups:
            group["lr"], group["capturable"] = self.lr, capturable
        for state in optimizer.state.values():  # a resumed optimizer's counts come from the checkpoint, on the CPU
            if "step" in state and capturable:
                state["step"] = state["step"].to(self.device, torch.float32)
        self.taken = 0
        self.replay: Step | None = None
        self.warm_up_stream = torch.cuda.Stream(self.device) if self.device.type == "cuda" else None

    def __call__(self, lr: float) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        self.lr.fill_(lr)
        self.taken += 1
        if self.replay is not None:
            return self.replay()
        if self.taken <= self.WARM_UP:
            with self.side_stream():
                output = self.step(average=self.update_average)
            return output
        self.replay = self.record(lambda: self.step(average=self.lerp_average), self.generator)
        return self.replay()

    def step(self, average: Callable[[], None]) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """The whole step, the moving average's update included; no host sync and fixed shapes, so it records."""
        headings, losses = take_step(self.loss, self.draw, self.generator, self.optimizer)
        average()
        return headings, losses

    def update_average(self) -> None:
        """The eager steps' average: AveragedModel's own update (its first copies the weights, a host check)."""
        if self.averaged is not None:
            self.averaged.update_parameters(self.model)

    def lerp_average(self) -> None:
        """The recorded steps' average: AveragedModel's EMA update itself, without its host-side count."""
        if self.averaged is not None:
            ema_update = torch.optim.swa_utils.get_ema_multi_avg_fn(self.ema)
            ema_update(list(self.averaged.module.parameters()), list(self.model.parameters()), None)

    def side_stream(self):
        """The warm-up steps' stream, one for all of them (as torch's CUDA-graph recipe warms up)."""
        if self.warm_up_stream is None:
            return contextlib.nullcontext()
        self.warm_up_stream.wait_stream(torch.cuda.current_stream(self.device))
        return _on_stream_then_join(self.warm_up_stream, self.device)


@contextlib.contextmanager
def _on_stream_then_join(stream, device):
    with torch.cuda.stream(stream):
        yield
    torch.cuda.current_stream(device).wait_stream(stream)


def plain_optimizer_state(optimizer: torch.optim.Optimizer) -> dict:
    """The optimizer's state for a checkpoint with plain hyper-parameters (GraphedSteps' rate is a tensor, its
    AdamW capturable): either kind of step resumes it."""
    state = optimizer.state_dict()
    for group in state["param_groups"]:
        group["lr"], group["capturable"] = float(group["lr"]), False
    return state
