"""Our default denoiser: a kinematics-aware residual MLP conditioned by FiLM.

Why this shape (measured by benchmarks/denoiser_choice.py; docs/paper.md, "Where we differ from the paper"):
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

Solving runs `denoise` 80 times on a handful of rows, where each tensor op's fixed
cost outweighs its arithmetic. `workspace(rows, like)` returns a FiLMWorkspace: the
same ops, call for call, written into buffers allocated once per solve, so a step
allocates nothing; the two paths give bit-identical results (a test checks it).
"""

from __future__ import annotations

import torch
from torch import nn

from ikdp.denoisers.config import DenoiserConfig, require_feature_width
from ikdp.denoisers.embeddings import sinusoidal_embedding
from ikdp.denoisers.film_compiled import CompiledFiLMWorkspace, compiled_workspace
from ikdp.denoisers.film_trunk import condition_network
from ikdp.refine import planar_dls_step
from ikdp.representation import SCALED_BY_LIMITS, AngleRepresentation

DLS_DAMPING = 0.05  # lambda of the DLS step feature, in units of the reach


class FiLMDenoiser(nn.Module):
    def __init__(self, config: DenoiserConfig, representation: AngleRepresentation, arm):
        super().__init__()
        if arm.kind != "planar" or representation.kind in SCALED_BY_LIMITS:
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
        require_feature_width("film", hidden, feature_dim)
        self.input = nn.Linear(feature_dim, hidden)
        self.condition_net = condition_network(config.time_dim, 2, hidden, config.blocks)  # target (x, y)
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
        # written into one buffer: a stack and a cat copied every row twice more (4 KB a row for a
        # 128-wide, 3-block model: 10 ms of a 57 ms batch solve of 500 targets)
        blocks = self.config.blocks
        out = torch.empty(len(t), blocks + 1, 2, self.config.hidden, dtype=film.dtype, device=film.device)
        out[:, :blocks, 0] = 1 + film[:, :, 0]
        out[:, :blocks, 1] = film[:, :, 1]
        out[:, blocks].zero_()  # not `= 0`, which makes a tensor of the host scalar first (CUDA-graph capture)
        out[:, blocks, 0, : feature_scale.shape[1]] = feature_scale
        return out

    def features(self, x: torch.Tensor, unit: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """(M, D) noisy sample, its (M, N, 2) unit bone directions, (M, 2) target -> (M, F).

        F is x_t, the tip's miss e and the damped least-squares step J^T (J J^T + lambda^2 I)^-1 e:
        the turn of each link a DLS solver would take (ikdp.refine.planar_dls_step, the
        refinement's step written from the bone vectors).
        """
        bones = unit * self.lengths[:, None]  # (M, N, 2)
        miss = target - bones.sum(dim=-2)  # (M, 2): target - tip
        step = planar_dls_step(bones, miss, self.damping_squared)  # (M, N)
        return torch.cat((x, miss, step), dim=-1)

    def workspace(
        self, rows: int, like: torch.Tensor, *, compiled: bool = True
    ) -> CompiledFiLMWorkspace | FiLMWorkspace | None:
        """Buffers for `denoise(..., workspace=)` on `rows` rows, or None where only the plain path applies.

        The compiled kernel (film_compiled.py) when it builds here and `compiled`, else the
        torch workspace, bit-identical to the plain path. The plain path stays for training
        (out= ops do not record gradients) and for the `angle` representation, whose turn is
        not a complex product.
        """
        if torch.is_grad_enabled() or self.representation.kind != "cossin":
            return None
        fast = compiled_workspace(self, rows, like) if compiled else None
        return fast if fast is not None else FiLMWorkspace(self, rows, like)

    def denoise(
        self,
        x: torch.Tensor,
        target: torch.Tensor,
        film: torch.Tensor,
        *,
        workspace: CompiledFiLMWorkspace | FiLMWorkspace | None = None,
    ) -> torch.Tensor:
        """x: (M, D), target: (M, 2), film: condition() rows -> the estimate of x_0, (M, D).

        The network outputs a turn of each link, and x_0 is x_t turned by it: a clean pose
        is on the circle of headings, so a turn can reach any of it, and near t = 0, where
        the pose is nearly right, the turn it needs is close to the DLS step it was given.
        With a `workspace` the result is its buffer, overwritten by the next call.
        """
        if workspace is not None:
            return workspace.denoise(x, target, film)
        unit = self.representation.unit_vectors(x)
        feature_scale = film[:, -1, 0, : self.input.in_features]
        h = self.input(self.features(x, unit, target) * feature_scale)
        for index, block in enumerate(self.blocks):
            h = h + block(nn.functional.silu(torch.addcmul(film[:, index, 1], h, film[:, index, 0])))
        return self.representation.turn(x, self.output(nn.functional.silu(h)), unit=unit)

    def forward(self, x: torch.Tensor, t: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return self.denoise(x, target, self.condition(t, target))


class FiLMWorkspace:
    """`FiLMDenoiser.denoise` for the cossin representation on M rows, into buffers allocated once.

    Every op below is the plain path's op on the same inputs with an `out=` (or in place),
    in the same order, so the results are bit-identical; keep the two in step when either changes.
    """

    def __init__(self, denoiser: FiLMDenoiser, rows: int, like: torch.Tensor):
        num_links, dim, hidden = denoiser.representation.num_links, denoiser.representation.dim, denoiser.config.hidden
        num_features = denoiser.input.in_features
        empty = lambda *shape: torch.empty(shape, dtype=like.dtype, device=like.device)  # noqa: E731
        self.denoiser = denoiser
        self.num_links = num_links
        self.num_features = num_features
        self.lengths = denoiser.lengths.to(like)[:, None]  # (N, 1)
        self.damping_squared = denoiser.damping_squared
        # the weights transposed once: F.linear(x, W, b) is addmm(b, x, W.t())
        self.input = (denoiser.input.bias, denoiser.input.weight.t())
        self.blocks = [(block.bias, block.weight.t()) for block in denoiser.blocks]
        self.output = (denoiser.output.bias, denoiser.output.weight.t())
        # features (M, F) = [x_t | miss | DLS step], each part a view
        self.features = empty(rows, num_features)
        self.sample_part, self.miss = self.features[:, :dim], self.features[:, dim : dim + 2]
        self.step = self.features[:, dim + 2 :]
        self.norm = empty(rows, num_links, 1)
        self.unit = empty(rows, num_links, 2)
        self.bones = empty(rows, num_links, 2)
        self.tip = empty(rows, 2)
        self.outer = empty(rows, num_links, 2, 2)
        self.adjugate = empty(rows, 2, 2)
        self.adjugate_diagonal = self.adjugate.diagonal(dim1=-2, dim2=-1)
        self.determinant = empty(rows)
        self.weighted = empty(rows, 2, 2)
        self.solved = empty(rows, 2)
        self.columns = empty(rows, num_links, 2)
        self.products = empty(rows, num_links, 2)
        self.hidden = empty(rows, hidden)
        self.modulated = empty(rows, hidden)
        self.block_output = empty(rows, hidden)
        self.turn = empty(rows, num_links)
        self.ones = torch.ones_like(self.turn)
        complex_dtype = torch.complex128 if like.dtype == torch.float64 else torch.complex64
        self.rotation = torch.empty((rows, num_links), dtype=complex_dtype, device=like.device)
        self.clean = empty(rows, dim)
        self.unit_complex = torch.view_as_complex(self.unit)
        self.clean_complex = torch.view_as_complex(self.clean.view(rows, num_links, 2))
        # the views the step reads, made once: each indexing is an op of its own at this size
        self.bones_x, self.bones_y = self.bones.unbind(-1)
        self.bones_column, self.bones_row = self.bones[..., :, None], self.bones[..., None, :]
        self.columns_x, self.columns_y = self.columns.unbind(-1)
        self.adjugate_xx, self.adjugate_yy = self.adjugate[:, 0, 0], self.adjugate[:, 1, 1]
        self.adjugate_xy = self.adjugate[:, 0, 1]
        self.miss_row = self.miss[:, None, :]
        self.determinant_column = self.determinant[:, None]
        self.solved_row = self.solved[:, None, :]

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """The plain `FiLMDenoiser.denoise`; returns the `clean` buffer (M, D)."""
        rows = film.unbind(1)  # (M, 2, hidden) each: the blocks' scale and shift, then the feature scales
        # representation.unit_vectors: F.normalize(pairs) = pairs / max(||pairs||, eps)
        pairs = x.view(x.shape[0], self.num_links, 2)
        torch.linalg.vector_norm(pairs, dim=-1, keepdim=True, out=self.norm)
        self.norm.clamp_min_(1e-12)
        torch.div(pairs, self.norm, out=self.unit)
        # features: x_t, the tip's miss and refine.planar_dls_step
        torch.mul(self.unit, self.lengths, out=self.bones)
        torch.sum(self.bones, dim=-2, out=self.tip)
        torch.sub(target, self.tip, out=self.miss)
        torch.mul(self.bones_column, self.bones_row, out=self.outer)
        torch.sum(self.outer, dim=-3, out=self.adjugate)
        self.adjugate_diagonal.add_(self.damping_squared)
        torch.mul(self.adjugate_xx, self.adjugate_yy, out=self.determinant)
        torch.addcmul(self.determinant, self.adjugate_xy, self.adjugate_xy, value=-1, out=self.determinant)
        torch.mul(self.adjugate, self.miss_row, out=self.weighted)
        torch.sum(self.weighted, dim=-1, out=self.solved)
        self.solved.div_(self.determinant_column)
        torch.neg(self.bones_y, out=self.columns_x)
        self.columns_y.copy_(self.bones_x)
        torch.mul(self.columns, self.solved_row, out=self.products)
        torch.sum(self.products, dim=-1, out=self.step)
        self.sample_part.copy_(x)
        self.features.mul_(rows[-1][:, 0, : self.num_features])
        # the network
        h = self.hidden
        torch.addmm(self.input[0], self.features, self.input[1], out=h)
        for (bias, weight), film_row in zip(self.blocks, rows, strict=False):
            scale, shift = film_row.unbind(1)
            torch.addcmul(shift, h, scale, out=self.modulated)
            nn.functional.silu(self.modulated, inplace=True)
            torch.addmm(bias, self.modulated, weight, out=self.block_output)
            h.add_(self.block_output)
        nn.functional.silu(h, inplace=True)
        torch.addmm(self.output[0], h, self.output[1], out=self.turn)
        # representation.turn: (cos, sin) times e^(i turn) as complex numbers
        torch.polar(self.ones, self.turn, out=self.rotation)
        torch.mul(self.unit_complex, self.rotation, out=self.clean_complex)
        return self.clean
