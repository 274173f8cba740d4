"""The conditional diffusion model of IK: an arm, a representation, a schedule and a denoiser.

Two verbs, as in diffusion_policy: `compute_loss(joints)` for training (paper
Algorithm 1) and `sample(targets)` for solving (Algorithm 2, or any sampler of
the registry in ikdp/samplers.py).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import torch
from torch import nn

from ikdp.arm import PlanarArm, arm_from_config
from ikdp.arm_inputs import drawing_device
from ikdp.denoisers import DenoiserConfig, build_denoiser
from ikdp.representation import SCALED_BY_LIMITS, AngleRepresentation
from ikdp.samplers import Sampler, make_sampler
from ikdp.sampling import Guidance, StepCallback, Trajectory, run_reverse_diffusion
from ikdp.schedule import PREDICTION_KINDS, DiffusionSchedule, ScheduleConfig

# The FK-consistency term weighs a rotation miss of 1 degree like a position miss of about 0.25 % of the
# span (3 mm on a Panda): ||R - R'||_F^2 ~ 2 angle^2, so 0.01 ||R - R'||^2 ~ (0.0025 / 0.0175)^2 angle^2.
ROTATION_LOSS_SCALE = 0.01


@dataclass(frozen=True)
class ModelConfig:
    lengths: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0)  # planar arm: bone lengths (their count is N); see `arm`
    representation: str = "cossin"  # what is diffused: angle (the paper's theta/pi), cossin (wrap-free) or limits
    prediction: str = "sample"  # what the denoiser predicts: sample (x_0, paper Alg. 1) or epsilon
    schedule: ScheduleConfig = field(default_factory=ScheduleConfig)
    denoiser: DenoiserConfig = field(default_factory=DenoiserConfig)
    arm: dict | None = None  # the arm's to_config(); None: a planar arm of `lengths`

    def __post_init__(self):
        if self.arm is None and (len(self.lengths) < 1 or any(not length > 0 for length in self.lengths)):
            raise ValueError(f"lengths: expected one or more positive bone lengths, got {self.lengths}")
        if self.prediction not in PREDICTION_KINDS:
            raise ValueError(f"prediction: expected one of {PREDICTION_KINDS}, got {self.prediction!r}")

    def build_arm(self):
        return PlanarArm(self.lengths) if self.arm is None else arm_from_config(self.arm)

    @property
    def num_links(self) -> int:
        return self.build_arm().num_joints

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> ModelConfig:
        return cls(
            lengths=tuple(float(length) for length in values["lengths"]),
            representation=values["representation"],
            prediction=values["prediction"],
            schedule=ScheduleConfig(**values["schedule"]),
            denoiser=DenoiserConfig(**values["denoiser"]),
            arm=values.get("arm"),  # checkpoints before the arm object describe a planar arm by `lengths`
        )


class IKDiffusion(nn.Module):
    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        self.arm = config.build_arm()
        if self.arm.kind == "planar":  # kept for callers that still read model.lengths
            self.register_buffer("lengths", torch.tensor(self.arm.lengths, dtype=torch.float32), persistent=False)
        robot = config.representation in SCALED_BY_LIMITS
        self.representation = AngleRepresentation(
            config.representation,
            self.arm.num_joints,
            limits=self.arm.joint_limits if robot else None,
            continuous=self.arm.continuous_joints if robot else None,
        )
        self.schedule = DiffusionSchedule(config.schedule)
        self.denoiser = build_denoiser(config.denoiser, self.representation, self.arm, self.schedule.noise_levels())
        self._samplers: dict[tuple[str, int | None, str], Sampler] = {}

    def compute_loss(
        self,
        joints: torch.Tensor,
        *,
        tip_loss_weight: float = 0.0,
        snr_gamma: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> dict[str, torch.Tensor]:
        """Paper Algorithm 1 on a batch of ground-truth poses, joints: (B, J).

        Returns `loss` (what is minimised), `theta_loss` (MSE on the diffused vector, the
        paper's loss) and `tip_distance` (mean ||t - t_hat|| of the predicted clean pose,
        the paper's second curve). A positive `tip_loss_weight` adds the squared tip miss
        of the prediction to the loss (for pose targets also its rotation miss): an FK-consistency
        term. A positive `snr_gamma`
        weights each sample by min(SNR_t, gamma) / gamma (Min-SNR, Hang et al. 2023): the
        noisiest steps, whose best answer is a blur, stop drowning out the last steps,
        where the pose's precision is decided.
        """
        batch = joints.shape[0]
        device = joints.device
        arm = self.arm
        targets = arm.end_effector(joints)  # (B, target_dim)
        clean = self.representation.encode(joints)  # (B, D)
        # drawn where the generator lives (the poses' device when training makes its data there), and nothing
        # read back: a GPU training step is captured whole as a CUDA graph (ikdp/train_steps.py)
        drawn_on = drawing_device(generator)
        t = torch.randint(self.schedule.num_timesteps, (batch,), generator=generator, device=drawn_on).to(device)
        noise = torch.randn(clean.shape, generator=generator, device=drawn_on).to(device)
        noisy = self.schedule.mix(clean, noise, t)
        output = self.denoiser(noisy, t, targets)
        signal, spread = self.schedule.levels_on(device)
        alpha, sigma = signal[t, None], spread[t, None]
        if self.config.prediction == "sample":
            squared_error = (output - clean) ** 2
            predicted_clean = output
        else:
            squared_error = (output - noise) ** 2
            predicted_clean = (noisy - sigma * output) / alpha
        weight = torch.ones(batch, device=device)
        if snr_gamma > 0:
            snr = (alpha / sigma).squeeze(-1) ** 2
            weight = snr.clamp(max=snr_gamma) / snr_gamma
        consistency, tip_miss = self.consistency_miss(predicted_clean, joints, targets)
        per_sample = squared_error.mean(-1) + tip_loss_weight * consistency
        loss = (weight * per_sample).mean()
        return {
            "loss": loss,
            "theta_loss": squared_error.mean().detach(),
            "tip_distance": tip_miss.detach().sqrt().mean(),
        }

    def consistency_miss(
        self, predicted_clean: torch.Tensor, joints: torch.Tensor, targets: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The FK-consistency term of a clean estimate (B, D) of poses `joints` (B, J) reaching `targets`.

        Returns (consistency, tip_miss), both (B,): the squared tip miss over the arm's span squared, plus
        for pose targets the rotation's squared Frobenius miss scaled by ROTATION_LOSS_SCALE; and the
        squared tip miss alone.
        """
        arm = self.arm
        # past a limit, a clamped joint would give the FK term no gradient to bring it back
        predicted_joints = self.representation.decode(
            predicted_clean, clamp=not self.config.denoiser.kinematics_past_limits
        )
        batch = joints.shape[0]
        # pose targets: the rotation must be consistent too, not only the position; a chain's frame is (B, 3, 3),
        # (B, 3), a tree's one per end effector, (B, E, 3, 3), (B, E, 3), its misses summed
        if arm.target_dim > arm.position_dim:
            predicted_rotation, predicted_tip = arm.end_effector_frame(predicted_joints)
            true_rotation, _ = arm.end_effector_frame(joints)
            rotation_miss = ((predicted_rotation - true_rotation) ** 2).reshape(batch, -1).sum(-1)  # ~ 2 angle^2
            predicted_tip = predicted_tip.reshape(batch, -1)
        else:
            predicted_tip = arm.end_effector(predicted_joints)[..., : arm.position_dim]
            rotation_miss = torch.zeros(batch, device=joints.device)
        tip_miss = ((predicted_tip - targets[..., : arm.position_dim]) ** 2).sum(-1)  # (B,)
        return tip_miss / arm.span**2 + ROTATION_LOSS_SCALE * rotation_miss, tip_miss

    def sampler(self, name: str = "ddpm", steps: int | None = None, spacing: str = "uniform") -> Sampler:
        """The sampler `name` with `steps` steps, built once per model: its coefficients depend on the schedule only."""
        key = (name, steps, spacing)
        if key not in self._samplers:
            self._samplers[key] = make_sampler(name, self.schedule, steps, spacing)
        return self._samplers[key]

    @torch.inference_mode()
    def sample(
        self,
        targets: torch.Tensor,
        *,
        num_samples: int = 1,
        sampler: str = "ddpm",
        steps: int | None = None,
        spacing: str = "uniform",
        generator: torch.Generator | None = None,
        return_trajectory: bool = False,
        return_estimates: bool = False,
        callback: StepCallback | None = None,
        initial_noise: torch.Tensor | None = None,
        guidance: Guidance | None = None,
    ) -> Trajectory:
        """Reverse diffusion, targets: (B, target_dim) -> K = num_samples poses per target, (B, K, J).

        `initial_noise`: x_T, (B, K, representation.dim); None draws it from `generator`.
        """
        return run_reverse_diffusion(
            self.denoiser,
            self.schedule,
            self.representation,
            self.sampler(sampler, steps, spacing),
            targets,
            num_samples=num_samples,
            prediction=self.config.prediction,
            generator=generator,
            return_trajectory=return_trajectory,
            return_estimates=return_estimates,
            callback=callback,
            initial_noise=None if initial_noise is None else initial_noise.to(targets),
            guidance=guidance,
        )
