"""Neural IK (Bensadoun et al., ICML 2022), the paper's "IKNet", as we built it.

The pose is sampled joint after joint: p(theta) = prod_n p(theta^n | t, theta^<n).
Each factor is a mixture density network, here a mixture of von Mises distributions
on the absolute heading theta^n (the circle's own Gaussian, so no wrap at pi).

What we built and what we left out: Neural IK's hypernetwork, which emits the
weights of a separate small network per joint from the target, is replaced by one
shared network that takes the joint's index (one-hot) with its inputs. The inputs
are the target, the tip of the partial arm theta^<n, the gap between them and the
length still to come, all divided by the reach. Training maximises the likelihood
of poses from the prior, every joint at once by teacher forcing.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn
from tqdm import tqdm

from ikdp.arm import PlanarArm
from ikdp.kinematics import wrap_angle
from ikdp.priors import PosePrior

LOG_CONCENTRATION_RANGE = (-3.0, 11.0)  # kappa up to e^11 ~ 6e4: a spread of ~0.004 rad


@dataclass(frozen=True)
class NeuralIKConfig:
    num_links: int = 4  # N
    components: int = 8  # von Mises components per joint
    hidden: int = 256  # width of each hidden layer
    layers: int = 3  # hidden layers
    steps: int = 3000  # optimizer steps
    batch: int = 1024  # poses per step
    lr: float = 1e-3  # Adam learning rate, cosine decay to zero


def sample_von_mises(mean: torch.Tensor, concentration: torch.Tensor, generator: torch.Generator | None = None):
    """One draw per element (any shape). Best & Fisher (1979) rejection in float64; a wrapped
    normal N(mean, 1/kappa) above kappa = 200, where the two agree to far below our resolution."""
    shape = mean.shape
    mean, kappa = mean.double().flatten(), concentration.double().flatten()
    result = mean + torch.randn(mean.shape, generator=generator, dtype=torch.float64) / kappa.sqrt()
    todo = torch.nonzero(kappa <= 200).flatten()
    k = kappa[todo]
    tau = 1 + torch.sqrt(1 + 4 * k**2)
    rho = (tau - torch.sqrt(2 * tau)) / (2 * k)
    r = (1 + rho**2) / (2 * rho)
    while len(todo):
        u1, u2, u3 = torch.rand(3, len(todo), generator=generator, dtype=torch.float64)
        z = torch.cos(math.pi * u1)
        f = (1 + r * z) / (r + z)
        c = k * (r - f)
        accept = (c * (2 - c) - u2 > 0) | (torch.log(c / u2) + 1 - c >= 0)
        angle = torch.sign(u3 - 0.5) * torch.acos(f.clamp(-1, 1))
        result[todo[accept]] = mean[todo[accept]] + angle[accept]
        todo, k, r = todo[~accept], k[~accept], r[~accept]
    return wrap_angle(result).reshape(shape).float()


class NeuralIK(nn.Module):
    def __init__(self, config: NeuralIKConfig, lengths: torch.Tensor):
        super().__init__()
        self.config = config
        self.register_buffer("lengths", lengths.float().clone())
        self.arm = PlanarArm(lengths.tolist())
        inputs = 7 + config.num_links
        widths = [inputs] + [config.hidden] * config.layers
        blocks = [module for a, b in zip(widths, widths[1:], strict=False) for module in (nn.Linear(a, b), nn.SiLU())]
        self.net = nn.Sequential(*blocks, nn.Linear(config.hidden, 4 * config.components))

    def features(self, targets: torch.Tensor, partial_tips: torch.Tensor, joint: torch.Tensor) -> torch.Tensor:
        """targets (..., 2), partial tips (..., 2), joint index (...) -> (..., 7 + N)."""
        reach = self.lengths.sum()
        still_to_come = (reach - torch.cumsum(torch.nn.functional.pad(self.lengths, (1, 0)), 0)[joint]) / reach
        one_hot = torch.nn.functional.one_hot(joint, self.config.num_links).to(targets)
        return torch.cat(
            (
                targets / reach,
                partial_tips / reach,
                (targets - partial_tips) / reach,
                still_to_come[..., None],
                one_hot,
            ),
            dim=-1,
        )

    def mixture(self, features: torch.Tensor):
        """(..., F) -> log weights, mean headings, concentrations, each (..., M)."""
        logits, cos, sin, log_kappa = self.net(features).unflatten(-1, (4, self.config.components)).unbind(-2)
        kappa = log_kappa.clamp(*LOG_CONCENTRATION_RANGE).exp()
        return torch.log_softmax(logits, dim=-1), torch.atan2(sin, cos), kappa

    def log_likelihood(self, headings: torch.Tensor) -> torch.Tensor:
        """Poses (B, N) -> log p(theta | t) (B,), every joint's factor in one pass (teacher forcing)."""
        batch, num_links = headings.shape
        targets = self.arm.end_effector(headings)
        bones = torch.stack((torch.cos(headings), torch.sin(headings)), dim=-1) * self.lengths[:, None]
        partial_tips = torch.cumsum(bones, dim=1) - bones  # (B, N, 2): the tip of theta^<n
        joint = torch.arange(num_links).expand(batch, -1)
        log_weight, mean, kappa = self.mixture(
            self.features(targets[:, None].expand(-1, num_links, -1), partial_tips, joint)
        )
        # log I0(kappa) = log(i0e(kappa)) + kappa, stable for large kappa
        log_density = (
            kappa * (torch.cos(headings[..., None] - mean) - 1)
            - math.log(2 * math.pi)
            - torch.log(torch.special.i0e(kappa))
        )
        return torch.logsumexp(log_weight + log_density, dim=-1).sum(-1)

    @torch.inference_mode()
    def solve(self, targets: torch.Tensor, num_samples: int = 1, generator: torch.Generator | None = None):
        """targets (B, 2) -> (headings (B, K, N), tip_error (B, K)), sampled joint after joint."""
        rows = targets.repeat_interleave(num_samples, dim=0)  # (M, 2)
        partial_tip = torch.zeros_like(rows)
        headings = []
        for joint in range(self.config.num_links):
            index = torch.full((len(rows),), joint, dtype=torch.long)
            log_weight, mean, kappa = self.mixture(self.features(rows, partial_tip, index))
            component = torch.multinomial(log_weight.exp(), 1, generator=generator)  # (M, 1)
            heading = sample_von_mises(mean.gather(-1, component)[:, 0], kappa.gather(-1, component)[:, 0], generator)
            headings.append(heading)
            partial_tip = partial_tip + self.lengths[joint] * torch.stack((torch.cos(heading), torch.sin(heading)), -1)
        poses = torch.stack(headings, dim=-1).unflatten(0, (targets.shape[0], num_samples))
        return poses, self.arm.tip_error(poses, targets[:, None])


def train_neural_ik(config: NeuralIKConfig, prior: PosePrior, arm: PlanarArm, *, seed: int = 0, progress: bool = True):
    """Maximum likelihood on poses from the prior; returns the model (eval mode)."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    model = NeuralIK(config, torch.tensor(arm.lengths))
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, config.steps)
    for _ in tqdm(range(config.steps), desc=f"Neural IK N={config.num_links}", disable=not progress, leave=False):
        loss = -model.log_likelihood(prior.sample(config.batch, arm, generator=generator)).mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        optimizer.step()
        schedule.step()
    return model.eval()


def neural_ik_state(model: NeuralIK) -> dict:
    """A plain dict (weights + config) that loads with weights_only=True."""
    return {"kind": "neural_ik", "config": asdict(model.config), "state_dict": model.state_dict()}


def neural_ik_from_state(state: dict) -> NeuralIK:
    model = NeuralIK(NeuralIKConfig(**state["config"]), state["state_dict"]["lengths"])
    model.load_state_dict(state["state_dict"])
    return model.eval()
