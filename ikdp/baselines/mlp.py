"""The paper's MLP baseline: one network regresses a pose from the target.

target / reach -> MLP -> (cos theta, sin theta) per link -> atan2. The (cos, sin)
output spares it the wrap at pi, a kindness the paper's raw-theta regression does
not get. A regressor returns one pose per target: where the solutions form a
continuum it learns their average, which need not reach the target at all.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn
from tqdm import tqdm

from ikdp.arm import PlanarArm
from ikdp.priors import PosePrior


@dataclass(frozen=True)
class MLPConfig:
    num_links: int = 4  # N
    hidden: int = 256  # width of each hidden layer
    layers: int = 3  # hidden layers
    steps: int = 3000  # optimizer steps
    batch: int = 1024  # poses per step
    lr: float = 1e-3  # Adam learning rate, cosine decay to zero


class MLPRegressor(nn.Module):
    def __init__(self, config: MLPConfig, lengths: torch.Tensor):
        super().__init__()
        self.config = config
        self.register_buffer("lengths", lengths.float().clone())
        self.arm = PlanarArm(lengths.tolist())
        widths = [2] + [config.hidden] * config.layers
        blocks = [module for a, b in zip(widths, widths[1:], strict=False) for module in (nn.Linear(a, b), nn.SiLU())]
        self.net = nn.Sequential(*blocks, nn.Linear(config.hidden, 2 * config.num_links))

    def forward(self, targets: torch.Tensor) -> torch.Tensor:
        """targets (B, 2) -> (B, N, 2) unnormalised (cos, sin) per link."""
        return self.net(targets / self.lengths.sum()).unflatten(-1, (self.config.num_links, 2))

    @torch.inference_mode()
    def solve(self, targets: torch.Tensor, num_samples: int = 1, generator: torch.Generator | None = None):
        """targets (B, 2) -> (headings (B, K, N), tip_error (B, K)); the K copies are identical."""
        output = self(targets)
        headings = torch.atan2(output[..., 1], output[..., 0])[:, None].expand(-1, num_samples, -1)
        return headings, self.arm.tip_error(headings, targets[:, None])


def train_mlp(config: MLPConfig, prior: PosePrior, arm: PlanarArm, *, seed: int = 0, progress: bool = True):
    """Fit the regressor to poses from the prior and their FK targets; returns the model (eval mode)."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    model = MLPRegressor(config, torch.tensor(arm.lengths))
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, config.steps)
    for _ in tqdm(range(config.steps), desc=f"MLP N={config.num_links}", disable=not progress, leave=False):
        headings = prior.sample(config.batch, arm, generator=generator)
        truth = torch.stack((torch.cos(headings), torch.sin(headings)), dim=-1)
        loss = ((model(arm.end_effector(headings)) - truth) ** 2).mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        schedule.step()
    return model.eval()


def mlp_state(model: MLPRegressor) -> dict:
    """A plain dict (weights + config) that loads with weights_only=True."""
    return {"kind": "mlp", "config": asdict(model.config), "state_dict": model.state_dict()}


def mlp_from_state(state: dict) -> MLPRegressor:
    model = MLPRegressor(MLPConfig(**state["config"]), state["state_dict"]["lengths"])
    model.load_state_dict(state["state_dict"])
    return model.eval()
