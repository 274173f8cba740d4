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

from ikdp.denoisers.condition_table import ConditionTable
from ikdp.denoisers.config import DenoiserConfig, require_feature_width
from ikdp.denoisers.embeddings import sinusoidal_embedding
from ikdp.denoisers.film_trunk import condition_network, film_residual_pass, normed_blocks, scale_and_shift
from ikdp.fused_chain import small_batch
from ikdp.refine import dls_step
from ikdp.representation import SCALED_BY_LIMITS, AngleRepresentation

DLS_DAMPING = 0.05  # lambda of the DLS step feature, in units of the arm's span
SAMPLING_CHUNK_ROWS = 1024  # rows a chunk of a large sampling batch: 2 MB per 512-wide activation (1024 measured
# 5-10 % faster than 2048 and 512, float32 and int8, on a 2-core AMD EPYC)
MISS_SCALE = 10.0  # the position miss in tenths of the span: the last steps correct millimetres


class ChainFiLMDenoiser(nn.Module):
    accepts_per_target_conditions = True  # denoise() broadcasts one condition over a target's K rows

    def __init__(
        self, config: DenoiserConfig, representation: AngleRepresentation, arm, noise_levels: torch.Tensor | None = None
    ):
        """`noise_levels`: the schedule's sigma_t = sqrt((1 - abar_t) / abar_t), (T,), which dls_skip needs."""
        super().__init__()
        if representation.kind not in SCALED_BY_LIMITS:
            raise ValueError(f"denoiser 'chain_film': expected one of {SCALED_BY_LIMITS}, got {representation.kind!r}")
        self.config = config
        self.arm = arm
        self.condition_table = None  # ConditionTable: a few targets' conditions without gradients, once asked for
        self.int8 = None  # Int8Weights (ikdp/denoisers/int8.py) when loaded with precision="int8": sampling only
        self.representation = representation
        dim, hidden, joints = representation.dim, config.hidden, arm.num_joints
        # the task error: the position misses (3 per end effector), then for poses as many rotation entries
        error_dim = arm.position_dim if arm.target_dim == arm.position_dim else 2 * arm.position_dim
        feature_dim = dim + error_dim + joints  # x_t, the task error, a DLS step per joint
        self.damping_squared = (DLS_DAMPING * arm.span) ** 2
        error_scale = torch.cat(
            (torch.full((arm.position_dim,), MISS_SCALE / arm.span), torch.ones(error_dim - arm.position_dim))
        )
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
        A few targets without gradients on a CPU (one target's solve) read what depends on t alone from a
        table (ikdp/denoisers/condition_table.py).
        """
        if self.int8 is None and not torch.is_grad_enabled() and small_batch(len(t), t.device):
            if self.condition_table is None:
                self.condition_table = ConditionTable()
            return self.condition_table.condition(self, t, target)
        time = sinusoidal_embedding(t, self.config.time_dim)
        embedded = torch.cat((time, self.arm.target_features(target)), dim=-1)
        condition_net = self.condition_net if self.int8 is None else self.int8.condition_net
        film = condition_net(embedded).unflatten(-1, (self.config.blocks, 2, self.config.hidden))
        return torch.cat((scale_and_shift(film), self.feature_row(t, time)), dim=1)

    def feature_row(self, t: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        """t (M,) and its embedding (M, time_dim) -> the condition's last row (M, 1, 2, hidden) (`condition`)."""
        feature_scale = self.feature_scale.expand(len(t), -1)
        if self.config.kinematic_until > 0:
            feature_scale = feature_scale * (self.kinematic_mask | (t < self.config.kinematic_until)[:, None])
        feature_row = torch.zeros(len(t), 1, 2, self.config.hidden, dtype=time.dtype, device=time.device)
        feature_row[:, 0, 0, : feature_scale.shape[1]] = feature_scale
        if self.config.dls_skip:
            gain = self.step_gain_start[t][:, None] + self.step_gain(time)
            if self.config.kinematic_until > 0:  # no step where the features are off
                gain = gain * (t < self.config.kinematic_until)[:, None]
            feature_row[:, 0, 1, : gain.shape[1]] = gain
        return feature_row

    def features_and_step(self, x: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(M, D) noisy sample, (M, target_dim) target -> the input features (M, F): x_t, the task error and the
        DLS step in x units; and that step in radians per joint, (M, J), for the skip."""
        joints = self.representation.decode(x, clamp=not self.config.kinematics_past_limits)
        # a few rows without gradients (one target's K on a CPU): the fused kinematics, the same numbers to float
        # rounding in a tenth of the time; training and large batches keep the arm's own
        fused = not torch.is_grad_enabled() and small_batch(len(joints), joints.device)
        if fused and not self.config.limit_aware_step:  # the error and the step alone, by NumPy's kernels
            error, step = self.arm.small_batch_kinematics().task_error_and_dls_step(
                joints, target, self.damping_squared
            )
            return torch.cat((x, error, step / self.half_range), dim=-1), step
        kinematics = self.arm.small_batch_kinematics() if fused else self.arm
        error, jacobian = kinematics.task_error_and_jacobian(joints, target)  # (M, E), (M, E, J)
        step = dls_step(jacobian, error, self.damping_squared)
        if self.config.limit_aware_step:
            blocked = self.arm.blocked_by_limits(joints, step)
            # every row, not only the blocked ones: picking rows by a mask syncs with the host, which a CUDA-graph
            # capture of the sampling loop (ikdp/cuda_graph.py) cannot do
            held = dls_step(jacobian * ~blocked[..., None, :], error, self.damping_squared)  # without those joints
            step = torch.where(blocked.any(-1, keepdim=True), held, step)
        return torch.cat((x, error, step / self.half_range), dim=-1), step  # the feature in x units

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """x: (M, D), target and film: one per row of x, (M, target_dim) and condition() rows (M, ...), or one per
        target, (B, ...), each shared by its K = M / B consecutive rows -> the estimate of x_0, (M, D).

        Per target, the condition is broadcast over a target's rows rather than copied to them: for
        1000 targets x 16 samples of the Panda's 512-wide network that copy was 330 MB a step, a
        quarter of a solve's time. Without gradients, a large batch runs in chunks of whole targets
        (SAMPLING_CHUNK_ROWS): each layer's activations then stay in the CPU's cache between the
        element-wise ops that read them.
        """
        rows, targets = x.shape[0], film.shape[0]
        if rows % targets or target.shape[0] not in (rows, targets):
            raise ValueError(f"denoise: {rows} rows cannot share {targets} conditions and {target.shape[0]} targets")
        per_target = rows // targets
        if target.shape[0] != rows:
            target = target[:, None].expand(-1, per_target, -1).reshape(rows, -1)
        if torch.is_grad_enabled() or rows <= SAMPLING_CHUNK_ROWS:
            return self.denoise_rows(x, target, film)
        chunk = max(1, SAMPLING_CHUNK_ROWS // per_target)  # targets a chunk
        return torch.cat(
            [
                self.denoise_rows(
                    x[first * per_target : (first + chunk) * per_target],
                    target[first * per_target : (first + chunk) * per_target],
                    film[first : first + chunk],
                )
                for first in range(0, targets, chunk)
            ]
        )

    def denoise_rows(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """`denoise` for one chunk: x and target (M, ...), film (B, ...) with B dividing M."""
        targets, per_target = film.shape[0], x.shape[0] // film.shape[0]
        grouped = lambda v: v.view(targets, per_target, v.shape[-1])  # noqa: E731  (M, C) -> (B, K, C)
        # once: each index of film would fill a zero gradient of its whole size; (B, 2, 1, H) broadcasts over K
        condition = film[:, :, :, None].unbind(1)
        feature_scale, step_gain = condition[-1].unbind(1)
        features, step = self.features_and_step(x, target)
        scaled = grouped(features) * feature_scale[..., : self.input.in_features]
        output = None
        table = self.condition_table
        if table is not None and self.int8 is None and not torch.is_grad_enabled() and small_batch(len(x), x.device):
            # a few rows (one target's K on a CPU), as the condition's table: the trunk with its weights laid out
            output = table.trunk(self, scaled.view_as(features), condition, targets)
        if output is None:
            h = film_residual_pass(self.input(scaled), condition, self.norms, self.trunk_layers())
            output = self.output(nn.functional.silu(h))
        estimate = x + output.view_as(x)
        if self.config.dls_skip:
            # the step in x's coordinates: where x lands after it, less x (continuous joints as (cos, sin) too)
            moved = self.representation.encode(self.representation.decode(x, clamp=False) + step) - x
            estimate = estimate + (step_gain[..., : x.shape[1]] * grouped(moved)).view_as(x)
        return estimate

    def trunk_layers(self):
        """The residual blocks' linear layers as sampling runs them: the float weights, or `int8` ones."""
        return self.blocks if self.int8 is None else self.int8.blocks

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))
