"""The robot denoiser's condition for a few targets without gradients: what depends on the timestep looked up.

`ChainFiLMDenoiser.condition` embeds t, concatenates the target's features, runs the two-layer condition network
and builds the features' row; for one target's solve on a CPU those dozen small operations cost more than the
network's arithmetic. The first layer splits into a timestep's part and a target's part, W [time; target] + b =
(W_time time + b) + W_target target, and the timestep's part, like the features' row, depends on t alone: both
are computed once for every t up to the largest asked, by the denoiser's own code, and looked up. FiLM's "1 +"
on the scales rides in the second layer's bias. The same numbers up to float rounding (the first layer's sum in
two parts).

The table is rebuilt when a weight changes (a parameter's version counter moves at every in-place update) or a
larger t is asked for.
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.embeddings import sinusoidal_embedding


class ConditionTable:
    """Per-timestep parts of a `ChainFiLMDenoiser`'s condition (module docstring), for its float weights."""

    def __init__(self):
        self.key = None
        self.count = 0
        self.parameters: list[torch.Tensor] | None = None

    def condition(self, denoiser, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t (M,), target (M, target_dim) -> `ChainFiLMDenoiser.condition` (M, blocks + 1, 2, hidden)."""
        if self.parameters is None:
            self.parameters = list(denoiser.parameters())  # walking the modules for them took 20 us a call
        key = (t.device, tuple(parameter._version for parameter in self.parameters))
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
        self.count = count
