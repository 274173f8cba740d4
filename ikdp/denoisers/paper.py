"""The paper's denoiser (section "Model Architecture", Fig. "model").

theta_t tokens -> transformer encoder -> features, concatenated with the time
embedding plus the target condition -> a few MLP layers -> transformer decoder
(attending to the encoder's tokens) -> per-token output + the residual of theta_t.
It predicts the clean pose, as the paper's Algorithm 1 trains it (MSE on theta).
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.config import DenoiserConfig
from ikdp.denoisers.embeddings import sinusoidal_embedding
from ikdp.representation import AngleRepresentation


class PaperDenoiser(nn.Module):
    def __init__(self, config: DenoiserConfig, representation: AngleRepresentation, arm):
        super().__init__()
        self.config = config
        self.num_links = representation.num_links
        self.token_size = representation.dim // self.num_links  # 1 for angle, 2 for cossin
        width = config.model_dim
        self.arm = arm
        self.token_in = nn.Linear(self.token_size, width)
        self.position = nn.Parameter(torch.randn(self.num_links, width) * 0.02)

        def layer_kwargs():
            return dict(d_model=width, nhead=config.heads, dim_feedforward=2 * width, dropout=0.0, batch_first=True)

        self.encoder = nn.TransformerEncoder(
            nn.TransformerEncoderLayer(**layer_kwargs()), config.layers, enable_nested_tensor=False
        )
        self.decoder = nn.TransformerDecoder(nn.TransformerDecoderLayer(**layer_kwargs()), config.layers)
        # "the target (t_x, t_y) is added to the time embedding"
        self.time_mlp = nn.Sequential(nn.Linear(config.time_dim, config.time_dim), nn.SiLU())
        self.target_in = nn.Linear(arm.condition_dim, config.time_dim)
        flat = self.num_links * width
        self.mlp = nn.Sequential(
            nn.Linear(flat + config.time_dim, config.mlp_hidden),
            nn.SiLU(),
            nn.Linear(config.mlp_hidden, config.mlp_hidden),
            nn.SiLU(),
            nn.Linear(config.mlp_hidden, flat),
        )
        self.token_out = nn.Linear(width, self.token_size)

    def condition(self, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t: (M,), target: (M, target_dim) -> (M, time_dim)."""
        time = self.time_mlp(sinusoidal_embedding(t, self.config.time_dim))
        return time + self.target_in(self.arm.target_features(target))

    def denoise(self, x: torch.Tensor, target: torch.Tensor, condition: torch.Tensor) -> torch.Tensor:
        """x: (M, D) -> the estimate of x_0, (M, D). `target` is already inside `condition`."""
        tokens = x.unflatten(-1, (self.num_links, self.token_size))  # (M, N, token)
        encoded = self.encoder(self.token_in(tokens) + self.position)  # (M, N, width)
        condition = condition.expand(x.shape[0], -1)  # a single target's condition serves all K rows
        mixed = self.mlp(torch.cat((encoded.flatten(1), condition), dim=-1)).unflatten(-1, (self.num_links, -1))
        decoded = self.decoder(mixed, encoded)
        return x + self.token_out(decoded).flatten(1)

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))
