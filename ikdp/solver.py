"""The public solver: load a checkpoint, solve IK for a batch of targets.

solver = ikdp.load("checkpoints/ikdp_n4.pt")
out = solver.solve(targets, num_samples=16)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from ikdp.checkpoint import CheckpointError, read_checkpoint
from ikdp.kinematics import project_to_workspace, reach, tip_position
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior
from ikdp.refine import damped_least_squares
from ikdp.sampling import SAMPLERS


@dataclass
class SolveResult:
    angles: torch.Tensor  # (B, K, N) absolute link headings, radians in (-pi, pi]; refined when refine_steps > 0
    tip_error: torch.Tensor  # (B, K) distance from the tip of `angles` to the target, bone-length units
    trajectory: torch.Tensor | None  # (S+1, B, K, N) raw sampler states from noise to final, when asked
    timesteps: list[int]  # the S diffusion timesteps the sampler visited, noisiest first
    reachable: torch.Tensor  # (B,) False where the target lies outside the arm's reach
    raw_angles: torch.Tensor  # (B, K, N) the sampler's output before refinement
    raw_tip_error: torch.Tensor  # (B, K) tip error of `raw_angles`


def validate_targets(targets) -> torch.Tensor:
    """Array-like (B, 2) or (2,) -> float32 tensor (B, 2); ValueError naming the problem otherwise."""
    try:
        tensor = torch.as_tensor(targets, dtype=torch.float32)
    except (TypeError, ValueError, RuntimeError) as error:
        raise ValueError(f"targets: expected numbers of shape (B, 2), could not read them ({error})") from None
    if tensor.ndim == 1 and tensor.shape[0] == 2:
        tensor = tensor[None]
    if tensor.ndim != 2 or tensor.shape[1] != 2 or tensor.shape[0] == 0:
        raise ValueError(f"targets: expected shape (B, 2) with B >= 1, got {tuple(tensor.shape)}")
    bad_rows = torch.nonzero(~torch.isfinite(tensor).all(dim=1)).flatten()
    if len(bad_rows):
        row = int(bad_rows[0])
        raise ValueError(f"targets: row {row} is {tensor[row].tolist()}, NaN or inf is not a target")
    return tensor


class Solver:
    """A trained IKDP model, ready to solve. Build it with `ikdp.load(path)`."""

    def __init__(self, model: IKDiffusion, prior: PosePrior, metadata: dict, device: str | torch.device = "cpu"):
        self.device = torch.device(device)
        self.model = model.to(self.device).eval()
        self.prior = prior
        self.metadata = metadata  # model config, training config, metrics at save, source path

    @property
    def num_links(self) -> int:
        return self.model.config.num_links

    @property
    def lengths(self) -> tuple[float, ...]:
        return self.model.config.lengths

    @property
    def timesteps(self) -> int:
        return self.model.schedule.num_timesteps

    @property
    def reach(self) -> tuple[float, float]:
        """(inner, outer) radius of the reachable annulus."""
        return reach(self.lengths)

    def solve(
        self,
        targets,
        *,
        num_samples: int = 16,
        sampler: str = "ddpm",
        steps: int | None = None,
        refine_steps: int = 0,
        generator: torch.Generator | None = None,
        return_trajectory: bool = False,
    ) -> SolveResult:
        """K poses for each of B targets.

        An unreachable target is not an error: the model is asked for the nearest
        reachable point (its training never saw farther targets), so the arm reaches
        toward the target as far as it can; `reachable` is False and `tip_error` is the
        distance to the target as asked.
        """
        targets = validate_targets(targets).to(self.device)
        if not isinstance(num_samples, int) or num_samples < 1:
            raise ValueError(f"num_samples: expected a positive integer, got {num_samples!r}")
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler: expected one of {SAMPLERS}, got {sampler!r}")
        if not isinstance(refine_steps, int) or refine_steps < 0:
            raise ValueError(f"refine_steps: expected a non-negative integer, got {refine_steps!r}")
        lengths = self.model.lengths
        inner, outer = self.reach
        radius = targets.norm(dim=-1)
        reachable = (radius <= outer + 1e-6) & (radius >= inner - 1e-6)
        conditions = project_to_workspace(targets, self.lengths)
        result = self.model.sample(
            conditions,
            num_samples=num_samples,
            sampler=sampler,
            steps=steps,
            generator=generator,
            return_trajectory=return_trajectory,
        )
        raw = result.headings  # (B, K, N)
        raw_error = (tip_position(raw, lengths) - targets[:, None]).norm(dim=-1)
        if refine_steps:
            # aim at the nearest reachable point: for a target beyond reach that is the stretched arm
            goals = conditions[:, None].expand(-1, num_samples, -1)
            refined = damped_least_squares(raw, goals, lengths, steps=refine_steps)
            refined_error = (tip_position(refined.double(), lengths.double()) - targets[:, None].double()).norm(dim=-1)
            angles, error = refined, refined_error.float()
        else:
            angles, error = raw, raw_error
        return SolveResult(
            angles=angles,
            tip_error=error,
            trajectory=result.states,
            timesteps=result.timesteps,
            reachable=reachable,
            raw_angles=raw,
            raw_tip_error=raw_error,
        )


def model_from_checkpoint(payload: dict, source: str = "<memory>") -> IKDiffusion:
    """Rebuild the model a checkpoint describes and load its weights; CheckpointError if they disagree."""
    try:
        config = ModelConfig.from_dict(payload["model"])
        model = IKDiffusion(config)
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{source}: invalid model description in checkpoint ({error})") from None
    state = payload["state_dict"]
    if not isinstance(state, dict) or not all(isinstance(value, torch.Tensor) for value in state.values()):
        raise CheckpointError(f"{source}: state_dict is not a dict of tensors")
    try:
        model.load_state_dict(state, strict=True)
    except RuntimeError as error:
        raise CheckpointError(f"{source}: weights do not match the model ({str(error).splitlines()[0]})") from None
    return model


def load(path: str | Path, device: str | torch.device = "cpu") -> Solver:
    """Load an IKDP checkpoint as a Solver. Refuses anything but a valid IKDP checkpoint (CheckpointError)."""
    payload = read_checkpoint(path)
    model = model_from_checkpoint(payload, str(path))
    try:
        prior = PosePrior.from_config(payload["prior"])
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: invalid prior in checkpoint ({error})") from None
    metadata = {
        "path": str(path),
        "model": payload["model"],
        "train": payload["train"],
        "metrics": payload["metrics"],
    }
    return Solver(model, prior, metadata, device)
