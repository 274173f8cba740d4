"""Our default denoiser: a kinematics-aware residual MLP conditioned by FiLM.

Why this shape (measured in docs/DENOISER_CHOICE.md):
- The network sees what the arm *does* at x_t, not only the numbers of x_t:
  the tip's miss vector e = target - tip, and J^T e per link (the direction a
  Jacobian-transpose step would turn each link). Near
  t = 0 denoising becomes "correct a nearly right pose", and these features
  make that a short reach for an MLP.
- The target and timestep enter by FiLM (scale and shift of every block), as
  in diffusion_policy, so the condition modulates all layers, not just the input.
- The condition is computed apart from the noisy sample (`condition`), so a
  sampler can embed all timesteps of a solve at once.
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.config import DenoiserConfig
from ikdp.denoisers.embeddings import sinusoidal_embedding
from ikdp.representation import AngleRepresentation


class FiLMDenoiser(nn.Module):
    def __init__(self, config: DenoiserConfig, representation: AngleRepresentation, lengths: torch.Tensor):
        super().__init__()
        self.config = config
        self.representation = representation
        num_links, dim, hidden = representation.num_links, representation.dim, config.hidden
        self.register_buffer("lengths", lengths.float().clone(), persistent=False)
        self.reach = float(lengths.sum())
        feature_dim = dim + 2 + num_links  # x_t, the tip's miss vector, J^T e per link
        # One matrix maps unit bone directions (M, 2N) to [bone vectors (2N), tip (2)].
        bone_vectors = torch.kron(torch.diag(lengths.float()), torch.eye(2))  # (2N, 2N)
        tip = torch.kron(lengths[:, None].float(), torch.eye(2))  # (2N, 2)
        self.register_buffer("kinematics", torch.cat((bone_vectors, tip), dim=1), persistent=False)
        self.register_buffer("perpendicular", torch.tensor([[0.0, -1.0], [1.0, 0.0]]), persistent=False)
        scale = torch.cat((torch.ones(dim), torch.full((2,), 1 / self.reach), torch.full((num_links,), 1 / self.reach**2)))
        self.register_buffer("feature_scale", scale, persistent=False)  # lengths in units of the reach
        self.input = nn.Linear(feature_dim, hidden)
        self.condition_net = nn.Sequential(
            nn.Linear(config.time_dim + 2, hidden),
            nn.SiLU(),
            nn.Linear(hidden, config.blocks * 2 * hidden),
        )
        self.blocks = nn.ModuleList(nn.Linear(hidden, hidden) for _ in range(config.blocks))
        self.output = nn.Linear(hidden, dim)
        nn.init.zeros_(self.output.weight)  # start as the identity: predict x_0 = x_t
        nn.init.zeros_(self.output.bias)

    def condition(self, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t: (M,), target: (M, 2) -> FiLM parameters (M, blocks, 2, hidden): scale and shift."""
        embedded = torch.cat((sinusoidal_embedding(t, self.config.time_dim), target / self.reach), dim=-1)
        film = self.condition_net(embedded).unflatten(-1, (self.config.blocks, 2, self.config.hidden))
        return torch.stack((1 + film[:, :, 0], film[:, :, 1]), dim=2)

    def features(self, x: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """(M, D) noisy sample, (M, 2) target -> (M, F): x_t, the tip's miss vector and J^T e.

        Written with few tensor ops: at sampling time each op's fixed cost, not its
        arithmetic, is what a step pays.
        """
        num_links = self.representation.num_links
        bones = self.representation.unit_vectors(x).flatten(-2)  # (M, 2N) unit direction per bone
        vectors_and_tip = bones @ self.kinematics  # (M, 2N + 2)
        miss = target - vectors_and_tip[:, -2:]  # (M, 2): target - tip
        bone_vectors = vectors_and_tip[:, :-2].unflatten(-1, (num_links, 2))  # (M, N, 2)
        # J^T e: column n of the tip Jacobian (w.r.t. absolute headings) is bone n turned by 90 degrees
        jacobian_t_miss = (bone_vectors * (miss @ self.perpendicular)[:, None]).sum(-1)  # (M, N)
        return torch.cat((x, miss, jacobian_t_miss), dim=-1) * self.feature_scale

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """x: (M, D), target: (M, 2), film: (M, blocks, 2, hidden) -> the estimate of x_0, (M, D)."""
        h = self.input(self.features(x, target))
        for index, block in enumerate(self.blocks):
            h = h + block(nn.functional.silu(torch.addcmul(film[:, index, 1], h, film[:, index, 0])))
        return x + self.output(nn.functional.silu(h))  # residual to the input, as in the paper

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))
