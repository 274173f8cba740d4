"""The kinematics-aware FiLM denoiser for spatial chains with joint limits (a robot's).

The planar FiLM denoiser's idea carried to 3-D: besides x_t the network sees what
the robot does at x_t, the task error e (position miss, and the rotation error as
an axis-angle vector for pose targets) and the damped least-squares step
J^T (J J^T + lambda^2 I)^-1 e a numerical solver would take from there. Near
t = 0 denoising becomes "correct a nearly right pose", and the DLS step makes it
a short reach. It predicts x_0 as x_t plus a correction (zero at start).

With `dls_skip`, the DLS step also reaches the estimate directly, scaled by a gain per timestep
and coordinate: x̂0 = x_t + g(t) * step + correction. The gain starts at 1 at low noise and 0 at
high noise (`dls_skip_noise`) and the network learns a change to it. Through the residual MLP alone
the step is one feature among many: after 8 minutes of CPU training, x̂0 at t = 0 removed 7 % of
a 55 mm miss (xArm7). A gain learned from zero stayed at 0.3-0.9, because in training x_t at low
noise is already within a hair of its pose and the step there teaches little; hence the start.

The kinematic features can be switched off above a timestep (`kinematic_until`):
at the noisy steps, where the pose is decided, the network then sees only x_t
and the target, which keeps the samples faithful to the prior instead of
anchored to the nearest solution of the initial noise.
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.config import DenoiserConfig, require_feature_width
from ikdp.denoisers.embeddings import sinusoidal_embedding
from ikdp.denoisers.film_trunk import condition_network, film_residual_pass, normed_blocks, scale_and_shift
from ikdp.refine import dls_step
from ikdp.representation import SCALED_BY_LIMITS, AngleRepresentation

DLS_DAMPING = 0.05  # lambda of the DLS step feature, in units of the arm's span
MISS_SCALE = 10.0  # the position miss in tenths of the span: the last steps correct millimetres


class ChainFiLMDenoiser(nn.Module):
    def __init__(
        self, config: DenoiserConfig, representation: AngleRepresentation, arm, noise_levels: torch.Tensor | None = None
    ):
        """`noise_levels`: the schedule's sigma_t = sqrt((1 - abar_t) / abar_t), (T,), which dls_skip needs."""
        super().__init__()
        if representation.kind not in SCALED_BY_LIMITS:
            raise ValueError(f"denoiser 'chain_film': expected one of {SCALED_BY_LIMITS}, got {representation.kind!r}")
        self.config = config
        self.arm = arm
        self.representation = representation
        dim, hidden, joints = representation.dim, config.hidden, arm.num_joints
        error_dim = 3 if arm.target_dim == 3 else 6
        feature_dim = dim + error_dim + joints  # x_t, the task error, a DLS step per joint
        self.damping_squared = (DLS_DAMPING * arm.span) ** 2
        error_scale = torch.cat((torch.full((3,), MISS_SCALE / arm.span), torch.ones(error_dim - 3)))
        scale = torch.cat((torch.ones(dim), error_scale, torch.ones(joints)))
        self.register_buffer("feature_scale", scale, persistent=False)
        kinematic_mask = torch.cat(
            (torch.ones(dim, dtype=torch.bool), torch.zeros(error_dim + joints, dtype=torch.bool))
        )
        self.register_buffer("kinematic_mask", kinematic_mask, persistent=False)
        self.register_buffer("half_range", representation.half_range.clone(), persistent=False)
        require_feature_width("chain_film", hidden, feature_dim)
        self.input = nn.Linear(feature_dim, hidden)
        self.condition_net = condition_network(config.time_dim, arm.condition_dim, hidden, config.blocks)
        self.norms, self.blocks = normed_blocks(hidden, config.blocks)
        self.output = nn.Linear(hidden, dim)
        nn.init.zeros_(self.output.weight)  # start as the identity: predict x_0 = x_t
        nn.init.zeros_(self.output.bias)
        if config.dls_skip:
            require_feature_width("chain_film", hidden, dim)  # the gain rides in the condition's last row
            self.step_gain = nn.Linear(config.time_dim, dim)
            nn.init.zeros_(self.step_gain.weight)
            nn.init.zeros_(self.step_gain.bias)
            if noise_levels is None:
                raise ValueError("denoiser 'chain_film': dls_skip needs the schedule's noise levels")
            # the gain's start: 1 where the noise is small against the scale on which the arm looks
            # linear (there the mean clean pose is x_t moved onto the solutions, a DLS step), 0 where large
            start = 1 / (1 + (noise_levels.double() / config.dls_skip_noise) ** 2)
            self.register_buffer("step_gain_start", start.float(), persistent=False)

    def condition(self, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """t: (M,), target: (M, target_dim) -> (M, blocks + 1, 2, hidden).

        Rows 0..blocks-1: each block's FiLM scale and shift. The last row carries in [0, :F]
        the scale of each input feature at this t (kinematic features off at t >= kinematic_until),
        and with `dls_skip` in [1, :D] the gain of the DLS step added to the estimate.
        """
        time = sinusoidal_embedding(t, self.config.time_dim)
        embedded = torch.cat((time, self.arm.target_features(target)), dim=-1)
        film = self.condition_net(embedded).unflatten(-1, (self.config.blocks, 2, self.config.hidden))
        feature_scale = self.feature_scale.expand(len(t), -1)
        if self.config.kinematic_until > 0:
            feature_scale = feature_scale * (self.kinematic_mask | (t < self.config.kinematic_until)[:, None])
        feature_row = torch.zeros(len(t), 1, 2, self.config.hidden, dtype=film.dtype, device=film.device)
        feature_row[:, 0, 0, : feature_scale.shape[1]] = feature_scale
        if self.config.dls_skip:
            gain = self.step_gain_start[t][:, None] + self.step_gain(time)
            if self.config.kinematic_until > 0:  # no step where the features are off
                gain = gain * (t < self.config.kinematic_until)[:, None]
            feature_row[:, 0, 1, : gain.shape[1]] = gain
        return torch.cat((scale_and_shift(film), feature_row), dim=1)

    def features_and_step(self, x: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(M, D) noisy sample, (M, target_dim) target -> the input features (M, F): x_t, the task error and the
        DLS step in x units; and that step in radians per joint, (M, J), for the skip."""
        joints = self.representation.decode(x, clamp=not self.config.kinematics_past_limits)
        error = self.arm.task_error(joints, target)  # (M, E)
        jacobian = self.arm.jacobian(joints)
        step = dls_step(jacobian, error, self.damping_squared)
        if self.config.limit_aware_step:
            blocked = self.arm.blocked_by_limits(joints, step)
            held = dls_step(jacobian * ~blocked[..., None, :], error, self.damping_squared)  # without those joints
            step = torch.where(blocked.any(-1, keepdim=True), held, step)
        return torch.cat((x, error, step / self.half_range), dim=-1), step  # the feature in x units

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """x: (M, D), target: (M, target_dim), film: condition() rows -> the estimate of x_0, (M, D)."""
        rows = film.unbind(1)  # once: each index of film would fill a zero gradient of its whole size
        feature_scale, step_gain = rows[-1].unbind(1)
        features, step = self.features_and_step(x, target)
        h = self.input(features * feature_scale[:, : self.input.in_features])
        h = film_residual_pass(h, rows, self.norms, self.blocks)
        estimate = x + self.output(nn.functional.silu(h))
        if self.config.dls_skip:
            # the step in x's coordinates: where x lands after it, less x (continuous joints as (cos, sin) too)
            moved = self.representation.encode(self.representation.decode(x, clamp=False) + step) - x
            estimate = estimate + step_gain[:, : x.shape[1]] * moved
        return estimate

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))
