"""Every solver in the comparison behind one signature.

A Method solves (targets (B, 2), K, generator) -> (headings (B, K, N), tip_error (B, K)),
and says in words how many samples, steps and iterations it ran.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from ikdp.arm import PlanarArm
from ikdp.baselines.ccd import solve_ccd
from ikdp.baselines.closed_form import solve_two_link
from ikdp.baselines.dls_restarts import solve_dls_restarts
from ikdp.baselines.fabrik import solve_fabrik
from ikdp.kinematics import tip_position
from ikdp.priors import PosePrior
from ikdp.refine import damped_least_squares

DLS_ITERATIONS = 10
CCD_SWEEPS = 20
FABRIK_ITERATIONS = 20
REFINE_STEPS = 5


@dataclass
class Method:
    name: str  # as printed in the tables
    family: str  # ikdp, learned or classical
    solve: Callable  # (targets (B, 2), num_samples, generator) -> (headings (B, K, N), tip_error (B, K))
    settings: str  # steps / iterations, in words
    several: bool = True  # gives distinct solutions when K > 1


def ikdp_method(name: str, solver, *, sampler: str = "ddpm", steps: int | None = None, refine: int = 0) -> Method:
    def solve(targets, num_samples, generator):
        out = solver.solve(
            targets, num_samples=num_samples, sampler=sampler, steps=steps, refine_steps=refine, generator=generator
        )
        return out.angles, out.tip_error

    count = solver.timesteps if steps is None else steps
    settings = f"{sampler.upper()} {count} steps (T={solver.timesteps})" + (f" + {refine} DLS steps" if refine else "")
    return Method(name, "ikdp", solve, settings)


def learned_method(name: str, model, settings: str, *, several: bool) -> Method:
    return Method(name, "learned", lambda targets, k, generator: model.solve(targets, k, generator), settings, several)


def dls_from_prior(prior: PosePrior, lengths: torch.Tensor, iterations: int = DLS_ITERATIONS) -> Callable:
    """DLS started from poses of a known prior: what a numerical solver does when it is told the prior."""

    def solve(targets, num_samples, generator):
        starts = prior.sample(targets.shape[0] * num_samples, lengths.shape[0], generator=generator)
        starts = starts.unflatten(0, (targets.shape[0], num_samples))
        goals = targets[:, None].expand(-1, num_samples, -1)
        headings = damped_least_squares(PlanarArm(lengths.tolist()), starts, goals, steps=iterations)
        error = (tip_position(headings.double(), lengths.double()) - goals.double()).norm(dim=-1).float()
        return headings, error

    return solve


def random_pose(lengths: torch.Tensor) -> Method:
    """No solver at all: uniformly random headings. The floor every number above should beat."""

    def solve(targets, num_samples, generator):
        headings = (torch.rand(targets.shape[0], num_samples, lengths.shape[0], generator=generator) * 2 - 1) * torch.pi
        return headings, (tip_position(headings, lengths) - targets[:, None]).norm(dim=-1)

    return Method("Random pose (no solver)", "reference", solve, "uniform headings", several=False)


def classical_methods(lengths: torch.Tensor) -> list[Method]:
    """DLS, CCD and FABRIK from uniformly random starts (one start per sample), and the N = 2 closed form."""
    methods = [
        Method(
            "DLS, random starts",
            "classical",
            lambda targets, k, generator: solve_dls_restarts(
                targets, lengths, restarts=k, iterations=DLS_ITERATIONS, generator=generator
            ),
            f"{DLS_ITERATIONS} iterations, damping 1e-3",
        ),
        Method(
            "CCD, random starts",
            "classical",
            lambda targets, k, generator: solve_ccd(
                targets, lengths, restarts=k, sweeps=CCD_SWEEPS, generator=generator
            ),
            f"{CCD_SWEEPS} sweeps",
        ),
        Method(
            "FABRIK, random starts",
            "classical",
            lambda targets, k, generator: solve_fabrik(
                targets, lengths, restarts=k, iterations=FABRIK_ITERATIONS, generator=generator
            ),
            f"{FABRIK_ITERATIONS} iterations",
        ),
    ]
    if lengths.shape[0] == 2:
        methods.append(
            Method(
                "Closed form (exact)",
                "classical",
                lambda targets, k, generator: solve_two_link(targets, lengths, num_samples=k),
                "law of cosines; samples alternate the two elbows",
            )
        )
    return methods
