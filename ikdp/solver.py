"""The public solver: load a checkpoint, solve IK for a batch of targets.

solver = ikdp.load("checkpoints/ikdp_n4.pt")
out = solver.solve(targets, num_samples=16)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from ikdp.checkpoint import CheckpointError, read_checkpoint
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior
from ikdp.refine import damped_least_squares
from ikdp.samplers import SAMPLERS, sampler_names
from ikdp.sampling import StepCallback
from ikdp.shipped import shipped_checkpoint


@dataclass
class SolveResult:
    angles: torch.Tensor  # (B, K, J) joint values (planar: absolute link headings in (-pi, pi]); refined if asked
    tip_error: torch.Tensor  # (B, K) distance from the end effector of `angles` to the target (arm's length unit)
    trajectory: torch.Tensor | None  # (S+1, B, K, J) raw sampler states from noise to final, when asked
    timesteps: list[int]  # the S diffusion timesteps of the sampler, noisiest first
    reachable: torch.Tensor | None  # (B,) False where the target lies outside the arm's reach; None if unknown
    raw_angles: torch.Tensor  # (B, K, J) the sampler's output before refinement
    raw_tip_error: torch.Tensor  # (B, K) tip error of `raw_angles`
    estimates: torch.Tensor | None = None  # (S, B, K, J) the denoiser's x̂0 at each step, when asked
    stopped: bool = False  # True when the callback stopped the solve; the poses are the state reached then
    rotation_error: torch.Tensor | None = None  # (B, K) radians, for pose targets of spatial arms

    @property
    def position_error(self) -> torch.Tensor:
        """(B, K) the end effector's distance to the target position (= tip_error)."""
        return self.tip_error


class Solver:
    """A trained IKDP model, ready to solve. Build it with `ikdp.load(path or shipped name)`."""

    def __init__(self, model: IKDiffusion, prior: PosePrior, metadata: dict, device: str | torch.device = "cpu"):
        self.device = torch.device(device)
        self.model = model.to(self.device).eval()
        self.arm = model.arm
        self.prior = prior
        self.metadata = metadata  # model config, training config, metrics at save, source path

    @property
    def num_links(self) -> int:
        return self.arm.num_joints

    @property
    def lengths(self) -> tuple[float, ...]:
        """Bone lengths of a planar arm."""
        return self.arm.lengths

    @property
    def noise_dim(self) -> int:
        """D, the size of one sample's noise x_T (the pose in the model's representation)."""
        return self.model.representation.dim

    @property
    def timesteps(self) -> int:
        return self.model.schedule.num_timesteps

    @property
    def reach(self) -> tuple[float, float]:
        """(inner, outer) radius of a planar arm's reachable annulus."""
        return self.arm.reach

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
        return_estimates: bool = False,
        callback: StepCallback | None = None,
        initial_noise: torch.Tensor | None = None,
    ) -> SolveResult:
        """K poses for each of B targets, (B, target_dim) -> (B, K, J).

        An unreachable target is not an error: the model is asked for the nearest
        reachable point (its training never saw farther targets), so the arm reaches
        toward the target as far as it can; `reachable` is False and `tip_error` is the
        distance to the target as asked.

        `callback(step_index, timestep, state, estimate)` is called after every reverse
        step with the state and the denoiser's x̂0 as joint values (B, K, J); returning
        True stops the solve at once (`stopped` is then True and no refinement runs).

        `initial_noise`: the pure noise x_T the samplers start from, (B, K, D) with D =
        `solver.noise_dim`; the same x_T given to DDPM and to DDIM compares the two on equal
        terms. None draws it from `generator` (as the first thing drawn).
        """
        arm = self.arm
        targets = arm.validate_targets(targets).to(self.device)
        if not isinstance(num_samples, int) or num_samples < 1:
            raise ValueError(f"num_samples: expected a positive integer, got {num_samples!r}")
        if sampler not in SAMPLERS:
            raise ValueError(f"sampler: expected one of {sampler_names()}, got {sampler!r}")
        if not isinstance(refine_steps, int) or refine_steps < 0:
            raise ValueError(f"refine_steps: expected a non-negative integer, got {refine_steps!r}")
        reachable = arm.is_reachable(targets)
        conditions = arm.clamp_to_workspace(targets)
        result = self.model.sample(
            conditions,
            num_samples=num_samples,
            sampler=sampler,
            steps=steps,
            generator=generator,
            return_trajectory=return_trajectory,
            return_estimates=return_estimates,
            callback=callback,
            initial_noise=initial_noise,
        )
        raw = result.headings  # (B, K, J)
        per_sample_targets = targets[:, None].expand(-1, num_samples, -1)
        raw_error = arm.tip_error(raw, per_sample_targets)
        angles, error = raw, raw_error
        if refine_steps and not result.stopped:
            # aim at the nearest reachable point: for a target beyond reach that is the stretched arm
            goals = conditions[:, None].expand(-1, num_samples, -1)
            angles = damped_least_squares(arm, raw, goals, steps=refine_steps)
            error = arm.tip_error(angles, per_sample_targets)
        rotation_error = arm.rotation_error(angles, per_sample_targets) if arm.target_dim == 7 else None
        return SolveResult(
            angles=angles,
            tip_error=error,
            trajectory=result.states,
            timesteps=result.timesteps,
            reachable=reachable,
            raw_angles=raw,
            raw_tip_error=raw_error,
            estimates=result.estimates,
            stopped=result.stopped,
            rotation_error=rotation_error,
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


def resolve_checkpoint(path_or_name: str | Path) -> Path:
    """A path as given when it exists or looks like a path; else a shipped model's name (`ikdp_n4`)."""
    path = Path(path_or_name)
    if path.exists() or path.suffix or len(path.parts) > 1:
        return path
    try:
        return shipped_checkpoint(str(path_or_name))
    except ValueError as error:
        raise CheckpointError(f"{path_or_name}: no such file, and {error}") from None


def load(path: str | Path, device: str | torch.device = "cpu") -> Solver:
    """Load an IKDP checkpoint (a path, or a shipped model's name) as a Solver.

    Refuses anything but a valid IKDP checkpoint (CheckpointError, one line).
    """
    path = resolve_checkpoint(path)
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
