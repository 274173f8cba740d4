"""Our default denoiser: a kinematics-aware residual MLP conditioned by FiLM.

Why this shape (measured in docs/DENOISER_CHOICE.md):
- The network sees what the arm *does* at x_t, not only the numbers of x_t:
  the tip's miss vector e = target - tip, and the damped least-squares step
  per link (how a DLS solver would turn each link). Near t = 0 denoising
  becomes "correct a nearly right pose", and this makes it a short reach.
- It predicts x_0 as a turn of each link of x_t, so the correction near t = 0
  is nearly linear in the DLS feature, which an MLP learns precisely.
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
from ikdp.refine import dls_step
from ikdp.representation import AngleRepresentation

DLS_DAMPING = 0.05  # lambda of the DLS step feature, in units of the reach


class FiLMDenoiser(nn.Module):
    def __init__(self, config: DenoiserConfig, representation: AngleRepresentation, arm):
        super().__init__()
        if arm.kind != "planar" or representation.kind == "limits":
            raise ValueError(f"denoiser 'film': its features are a planar arm's; got a {arm.kind} arm, use 'mlp'")
        self.config = config
        self.representation = representation
        num_links, dim, hidden = representation.num_links, representation.dim, config.hidden
        self.register_buffer("lengths", torch.tensor(arm.lengths, dtype=torch.float32), persistent=False)
        self.reach = arm.span
        feature_dim = dim + 2 + num_links  # x_t, the tip's miss vector, a damped least-squares step per link
        self.damping_squared = (DLS_DAMPING * self.reach) ** 2
        # the miss in tenths of the reach: the last steps correct misses of a few thousandths
        scale = torch.cat((torch.ones(dim), torch.full((2,), 10 / self.reach), torch.ones(num_links)))
        self.register_buffer("feature_scale", scale, persistent=False)
        kinematic_mask = torch.cat((torch.ones(dim, dtype=torch.bool), torch.zeros(2 + num_links, dtype=torch.bool)))
        self.register_buffer("kinematic_mask", kinematic_mask, persistent=False)
        self.input = nn.Linear(feature_dim, hidden)
        self.condition_net = nn.Sequential(
            nn.Linear(config.time_dim + 2, hidden),
            nn.SiLU(),
            nn.Linear(hidden, config.blocks * 2 * hidden),
        )
        self.blocks = nn.ModuleList(nn.Linear(hidden, hidden) for _ in range(config.blocks))
        self.output = nn.Linear(hidden, num_links)  # a turn of each link: x_0 = x_t rotated
        nn.init.zeros_(self.output.weight)  # start as the identity: predict x_0 = x_t
        nn.init.zeros_(self.output.bias)

    @property
    def output_on_manifold(self) -> bool:
        """A turned unit pair is a unit pair: the sampler need not project this x_0 estimate again."""
        return self.representation.kind == "cossin"

    def condition(self, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t: (M,), target: (M, 2) -> (M, blocks + 1, 2, hidden).

        Rows 0..blocks-1 are the FiLM scale and shift of each block. The last row carries, in
        [0, :F], the scale of each input feature at this t: the kinematic features (the tip's
        miss and the DLS step) are switched off at t >= config.kinematic_until when that is set.
        """
        embedded = torch.cat((sinusoidal_embedding(t, self.config.time_dim), target / self.reach), dim=-1)
        film = self.condition_net(embedded).unflatten(-1, (self.config.blocks, 2, self.config.hidden))
        feature_scale = self.feature_scale.expand(len(t), -1)
        if self.config.kinematic_until > 0:
            keep = self.kinematic_mask | (t < self.config.kinematic_until)[:, None]
            feature_scale = feature_scale * keep
        feature_row = torch.zeros(len(t), 1, 2, self.config.hidden, dtype=film.dtype, device=film.device)
        feature_row[:, 0, 0, : feature_scale.shape[1]] = feature_scale
        return torch.cat((torch.stack((1 + film[:, :, 0], film[:, :, 1]), dim=2), feature_row), dim=1)

    def features(self, x: torch.Tensor, unit: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """(M, D) noisy sample, its (M, N, 2) unit bone directions, (M, 2) target -> (M, F).

        F is x_t, the tip's miss e and the damped least-squares step J^T (J J^T + lambda^2 I)^-1 e:
        the turn of each link a DLS solver would take (ikdp.refine.dls_step, the refinement's own
        step). Bone n's column of J is its bone vector turned by 90 degrees.
        """
        bones = unit * self.lengths[:, None]  # (M, N, 2)
        miss = target - bones.sum(dim=-2)  # (M, 2): target - tip
        jacobian = torch.stack((-bones[..., 1], bones[..., 0]), dim=-2)  # (M, 2, N)
        step = dls_step(jacobian, miss, self.damping_squared)  # (M, N)
        return torch.cat((x, miss, step), dim=-1)

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """x: (M, D), target: (M, 2), film: condition() rows -> the estimate of x_0, (M, D).

        The network outputs a turn of each link, and x_0 is x_t turned by it: a clean pose
        is on the circle of headings, so a turn can reach any of it, and near t = 0, where
        the pose is nearly right, the turn it needs is close to the DLS step it was given.
        """
        unit = self.representation.unit_vectors(x)
        feature_scale = film[:, -1, 0, : self.input.in_features]
        h = self.input(self.features(x, unit, target) * feature_scale)
        for index, block in enumerate(self.blocks):
            h = h + block(nn.functional.silu(torch.addcmul(film[:, index, 1], h, film[:, index, 0])))
        return self.representation.turn(x, self.output(nn.functional.silu(h)), unit=unit)

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))
