"""The robot denoiser for a few targets without gradients: its condition's per-timestep parts looked up, and its
trunk's weights transposed once.

`ChainFiLMDenoiser.condition` embeds t, concatenates the target's features, runs the two-layer condition network
and builds the features' row; for one target's solve on a CPU those dozen small operations cost more than the
network's arithmetic. The first layer splits into a timestep's part and a target's part, W [time; target] + b =
(W_time time + b) + W_target target, and the timestep's part, like the features' row, depends on t alone: both
are computed once for every t up to the largest asked, by the denoiser's own code, and looked up. FiLM's "1 +"
on the scales rides in the second layer's bias. The same numbers up to float rounding (the first layer's sum in
two parts).

The trunk (the input layer, the residual blocks, the output layer) runs as `torch.addmm` on 2-D rows with each
weight transposed and laid out once: `nn.Linear` on a target's (1, K, hidden) rows took twice the time of that
product for K = 16 on one Xeon thread (copies and checks around the same arithmetic), a fifth of a Panda solve.

The table is rebuilt when a weight changes (a parameter's version counter moves at every in-place update) or a
larger t is asked for.
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.embeddings import sinusoidal_embedding


class ConditionTable:
    """Per-timestep parts of a `ChainFiLMDenoiser`'s condition and its trunk's weights transposed (module
    docstring), for its float weights."""

    def __init__(self):
        self.key = None
        self.count = 0
        self.parameters: list[torch.Tensor] | None = None
        self.layers: list[tuple[torch.Tensor, torch.Tensor]] = []  # (bias, weight.T): input, blocks, output

    def current_key(self, denoiser, device: torch.device) -> tuple:
        if self.parameters is None:
            self.parameters = list(denoiser.parameters())  # walking the modules for them took 20 us a call
        return (device, tuple(parameter._version for parameter in self.parameters))

    def condition(self, denoiser, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t (M,), target (M, target_dim) -> `ChainFiLMDenoiser.condition` (M, blocks + 1, 2, hidden)."""
        key = self.current_key(denoiser, t.device)
        largest = int(t.max())
        if key != self.key or largest >= self.count:
            self.build(denoiser, max(largest + 1, self.count if key == self.key else 0), t.device)
            self.key = key
        features = denoiser.arm.small_batch_kinematics().target_features(target)
        hidden = nn.functional.silu(torch.addmm(self.time_part[t], features, self.target_weight))
        film = torch.addmm(self.second_bias, hidden, self.second_weight)
        config = denoiser.config
        return torch.cat((film.view(len(t), config.blocks, 2, config.hidden), self.feature_rows[t]), dim=1)

    def build(self, denoiser, count: int, device: torch.device) -> None:
        config = denoiser.config
        first, second = denoiser.condition_net[0], denoiser.condition_net[2]
        with torch.no_grad():
            steps = torch.arange(count, device=device)
            time = sinusoidal_embedding(steps, config.time_dim)
            self.time_part = torch.addmm(first.bias, time, first.weight[:, : config.time_dim].T)  # (T, hidden)
            self.target_weight = first.weight[:, config.time_dim :].T.contiguous()  # (condition_dim, hidden)
            self.second_weight = second.weight.T.contiguous()  # (hidden, blocks * 2 * hidden)
            ones = torch.zeros(config.blocks, 2, config.hidden, device=device)
            ones[:, 0] = 1  # FiLM's scale is 1 + the network's output (film_trunk.scale_and_shift)
            self.second_bias = second.bias + ones.reshape(-1)
            self.feature_rows = denoiser.feature_row(steps, time)  # (T, 1, 2, hidden)
            linears = [denoiser.input, *denoiser.blocks, denoiser.output]
            self.layers = [(layer.bias, layer.weight.T.contiguous()) for layer in linears]
        self.count = count

    def trunk(self, denoiser, features: torch.Tensor, rows, targets: int) -> torch.Tensor | None:
        """The network's output (M, D) from the scaled input features (M, F) and the condition's rows, `film[:, :, :,
        None].unbind(1)` of a condition (B, blocks + 1, 2, hidden) whose each row serves K = M / B consecutive rows:
        `ChainFiLMDenoiser.denoise_rows`'s trunk as 2-D products. None when the weights changed since the table was
        built (the caller's own path then)."""
        if self.key != self.current_key(denoiser, features.device):
            return None
        (input_bias, input_weight), *blocks, (output_bias, output_weight) = self.layers
        hidden = torch.addmm(input_bias, features, input_weight)  # (M, hidden)
        grouped = (targets, len(features) // targets, hidden.shape[1])
        for (bias, weight), row, norm in zip(blocks, rows, denoiser.norms, strict=False):
            scale, shift = row.unbind(1)  # (B, 1, hidden): over a target's K rows
            normed = torch.layer_norm(hidden, norm.normalized_shape, None, None, norm.eps).view(grouped)
            modulated = nn.functional.silu(torch.addcmul(shift, normed, scale), inplace=True).view_as(hidden)
            hidden = torch.addmm(hidden, modulated, weight).add_(bias)
        return torch.addmm(output_bias, nn.functional.silu(hidden, inplace=True), output_weight)
