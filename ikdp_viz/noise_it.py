"""Noise it: the forward process of the poses on screen, drawn on the same t slider as the denoising.

Training noises a pose and the network learns to undo it; "noise it" shows that direction. The K final
poses of the solve on screen are mixed with one held noise eps at every t (ikdp.forward_process), and
the result is handed to the drawing loop as a solve like any other, its states ordered as a reverse
run's (t = T first, t = 0 last): the slider, the trail, the chart and the readouts all read it as they
read a denoising, and playing it from t = 0 toward T takes the pose to pure noise. Planar arms only:
a robot's pose error also has a rotation, which this view does not rank.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from ikdp.forward_process import forward_trajectory
from ikdp.solve_result import SolveResult
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.solving import Solved

FORWARD = "forward process (noise it)"  # the readouts' sampler name for a noised solve


def forward_solved(solved: Solved, seed: int) -> Solved:
    """The forward process of `solved`'s returned poses with noise eps drawn from `seed`, as a Solved of T+1 states.

    Its state s is x at t = T - s: state 0 the noisiest, the last the poses themselves.
    """
    request = solved.request
    solver = request.solver
    if solver.arm.kind != "planar":
        raise ValueError(f"solved: expected a planar arm's solve to noise, got a {solver.arm.kind!r} arm")
    if solved.final_angles is None:
        raise ValueError("solved: expected a solve with its returned poses (final_angles), got None")
    model = solver.model
    clean = torch.as_tensor(np.asarray(solved.final_angles), dtype=torch.float32)  # (K, J)
    generator = torch.Generator().manual_seed(int(seed))
    noise = torch.randn((clean.shape[0], model.representation.dim), generator=generator)  # (K, D) one eps per sample
    states = forward_trajectory(model.schedule, model.representation, clean, noise).flip(0)  # (T+1, K, J) t = T first
    tip_error = torch.as_tensor(np.asarray(solved.view.final_tip_error), dtype=torch.float32)[None]  # (1, K)
    result = SolveResult(
        angles=clean[None], tip_error=tip_error, trajectory=states[:, None], reachable=None,
        timesteps=list(range(solver.timesteps - 1, -1, -1)), raw_angles=clean[None], raw_tip_error=tip_error,
    )  # fmt: skip
    view, trail = arm_kind(solver).drawable(result, solver, request.target)
    forward_request = dataclasses.replace(request, sampler=FORWARD, steps=None, animate=False, compare_sampler=None)
    return Solved(forward_request, view, trail, 0.0, final_angles=solved.final_angles, forward=True)


def is_forward(solved: Solved | None) -> bool:
    """`solved` is a forward process made by `forward_solved`, not a denoising."""
    return solved is not None and solved.forward
