"""Int8 weights for sampling on a CPU: the robot denoiser's wide layers as dynamically quantized linears.

Why: on a CPU a batch solve of the Panda's 512 x 4 network (1000 targets x 16 samples) spends most of
its time in the residual blocks' 512 x 512 products and the condition network's 512 x 4096 one. With
the weights in int8 (one scale per output channel) and each input quantized on the fly, fbgemm does
those products 2.5-3 x faster than float32 on an AVX2 CPU; a layer's output moves by about 2 % of its
size. What that costs in accuracy is measured, never assumed: `python -m benchmarks.few_step --precisions
float32 int8` (benchmarks/results/few_step_int8_per_row.json); docs/benchmarks.md's fastest CPU pipeline uses it.

Only the layers whose inputs and outputs are both wide are quantized: the input layer (the kinematic
features, a few dozen wide) and the output (the correction, the sample's precision) stay in float32.
Sampling only; training and gradients never see these weights.
"""

from __future__ import annotations

import threading
import warnings

import torch
from torch import nn

QUANTIZED_WIDTH = 64  # a linear is quantized when both its widths are at least this


class Int8Linear(nn.Module):
    """`linear(x)` with per-channel int8 weights and float32 inputs and outputs (fbgemm's dynamic linear).

    fbgemm quantizes its input with one scale for the whole batch: a row beside a larger one lost
    precision, and a target's pose depended on the others solved with it (one-step Panda student, 100
    targets: poses 0.2 rad apart median, raw 67 mm median in a batch against 58 mm alone). So each row is
    divided by its own largest magnitude first and two constant inputs, +1 and -1 (zero weights), pin the
    batch's range to [-1, 1]: every row is quantized on the same scale whatever its neighbours, and the
    output is multiplied back by the row's magnitude before the bias (kept in float32) is added.
    """

    def __init__(self, linear: nn.Linear):
        super().__init__()
        weight = linear.weight.detach().float()
        weight = torch.cat([weight, torch.zeros(weight.shape[0], 2)], dim=1)  # the +1 and -1 inputs: no effect
        scales = (weight.abs().amax(dim=1).clamp_min(1e-12) / 127).double()
        zero_points = torch.zeros(weight.shape[0], dtype=torch.long)
        with warnings.catch_warnings():  # torch marks its quantized tensors deprecated; the op is what we use
            warnings.simplefilter("ignore")
            quantized = torch.quantize_per_channel(weight, scales, zero_points, 0, torch.qint8)
            self.packed = torch.ops.quantized.linear_prepack(quantized, None)
        self.bias = linear.bias.detach().float()
        self.out_features = linear.out_features

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        flat = x.reshape(-1, x.shape[-1]).float()
        inputs = input_rows(*flat.shape)
        magnitude = flat.abs().amax(dim=1, keepdim=True).clamp_min(1e-30)
        torch.div(flat, magnitude, out=inputs[:, :-2])
        # reduce_range: 7-bit inputs, so that AVX2's 16-bit pair sums cannot overflow
        out = torch.ops.quantized.linear_dynamic(inputs, self.packed, True)
        return torch.addcmul(self.bias, out, magnitude, out=out).view(*x.shape[:-1], self.out_features)


INPUTS = threading.local()  # per thread, per input width: one buffer of rows that only grows, shared by the layers


def input_rows(rows: int, width: int) -> torch.Tensor:
    """A (rows, width + 2) buffer whose last two columns hold +1 and -1; a layer fills the rest, then the product
    reads it before the next layer writes it (one thread's layers run one at a time)."""
    buffers = INPUTS.__dict__.setdefault("by_width", {})
    buffer = buffers.get(width)
    if buffer is None or len(buffer) < rows:
        buffer = buffers[width] = torch.empty(rows, width + 2)
        buffer[:, -2], buffer[:, -1] = 1.0, -1.0
    return buffer[:rows]


def quantized(layer: nn.Module):
    """The layer as sampling runs it: an Int8Linear when it is a wide linear, else itself."""
    wide = isinstance(layer, nn.Linear) and min(layer.in_features, layer.out_features) >= QUANTIZED_WIDTH
    return Int8Linear(layer) if wide else layer


class Int8Weights:
    """A chain_film denoiser's residual blocks and condition network with their wide layers in int8."""

    def __init__(self, denoiser):
        self.blocks = [quantized(block) for block in denoiser.blocks]
        self.condition_net = nn.Sequential(*(quantized(layer) for layer in denoiser.condition_net))


def int8_available() -> str | None:
    """None when this torch build can run Int8Linear here, else why not (one line)."""
    try:
        Int8Linear(nn.Linear(QUANTIZED_WIDTH, QUANTIZED_WIDTH))(torch.zeros(1, QUANTIZED_WIDTH))
    except (RuntimeError, AttributeError, NotImplementedError) as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        return f"this torch build cannot run int8 linears on this CPU ({first_line})"
    return None
