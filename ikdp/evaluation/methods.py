"""Every solver in the comparison behind one signature.

A Method solves (targets (B, 2), K, generator) -> (headings (B, K, N), tip_error (B, K)),
and carries as typed fields what the tables and the experiments ask of it (its family,
its refinement steps), so nothing reads them back out of its printed name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

from ikdp.arm import PlanarArm
from ikdp.baselines.ccd import ccd
from ikdp.baselines.closed_form import solve_two_link
from ikdp.baselines.fabrik import fabrik
from ikdp.baselines.random_starts import Polish, dls_polish, solve_from_random_starts
from ikdp.priors import PosePrior

DLS_ITERATIONS = 10
CCD_SWEEPS = 20
FABRIK_ITERATIONS = 20
REFINE_STEPS = 5


@dataclass(frozen=True)
class Method:
    name: str  # as printed in the tables
    family: str  # ikdp, learned, classical or reference
    solve: Callable  # (targets (B, 2), num_samples, generator) -> (headings (B, K, N), tip_error (B, K))
    settings: str  # steps / iterations, in words
    several: bool = True  # gives distinct solutions when K > 1
    refine_steps: int = 0  # DLS steps after an IKDP sampler; 0 for raw samples and for every other family


def ikdp_method(name: str, solver, *, sampler: str = "ddpm", steps: int | None = None, refine: int = 0) -> Method:
    def solve(targets, num_samples, generator):
        out = solver.solve(
            targets, num_samples=num_samples, sampler=sampler, steps=steps, refine_steps=refine, generator=generator
        )
        return out.angles, out.tip_error

    count = solver.timesteps if steps is None else steps
    settings = f"{sampler.upper()} {count} steps (T={solver.timesteps})" + (f" + {refine} DLS steps" if refine else "")
    return Method(name, "ikdp", solve, settings, refine_steps=refine)


def ikdp_variants(prefix: str, solver) -> list[Method]:
    """Raw and refined, DDPM and DDIM (T/4 steps) of one checkpoint, in that order."""
    ddim_steps = max(1, solver.timesteps // 4)
    ddim = f"{prefix}, DDIM {ddim_steps}"
    return [
        ikdp_method(f"{prefix}, DDPM", solver),
        ikdp_method(f"{prefix}, DDPM + DLS", solver, refine=REFINE_STEPS),
        ikdp_method(ddim, solver, sampler="ddim", steps=ddim_steps),
        ikdp_method(f"{ddim} + DLS", solver, sampler="ddim", steps=ddim_steps, refine=REFINE_STEPS),
    ]


def learned_method(name: str, model, settings: str, *, several: bool) -> Method:
    return Method(name, "learned", lambda targets, k, generator: model.solve(targets, k, generator), settings, several)


def dls_from_prior(prior: PosePrior, arm: PlanarArm, iterations: int = DLS_ITERATIONS) -> Method:
    """DLS started from poses of a known prior: what a numerical solver does when it is told the prior."""
    polish = dls_polish(iterations=iterations)

    def solve(targets, num_samples, generator):
        starts = prior.sample(targets.shape[0] * num_samples, arm, generator=generator)
        starts = starts.unflatten(0, (targets.shape[0], num_samples))  # (B, K, N)
        goals = targets[:, None].expand(-1, num_samples, -1)
        headings = polish(starts, goals, arm)
        return headings, arm.tip_error(headings, goals)

    return Method("DLS, starts from the prior (told the prior)", "classical", solve, f"{iterations} iterations")


def random_pose(arm: PlanarArm) -> Method:
    """No solver at all: uniformly random headings. The floor every number above should beat."""

    def solve(targets, num_samples, generator):
        headings = arm.random_poses(targets.shape[0] * num_samples, generator=generator)
        headings = headings.unflatten(0, (targets.shape[0], num_samples))  # (B, K, N)
        return headings, arm.tip_error(headings, targets[:, None])

    return Method("Random pose (no solver)", "reference", solve, "uniform headings", several=False)


def _from_random_starts(polish: Polish, arm: PlanarArm, targets, num_samples, generator):
    return solve_from_random_starts(polish, targets, arm, restarts=num_samples, generator=generator)


def random_start_methods(arm: PlanarArm) -> list[Method]:
    """DLS, CCD and FABRIK, each from uniformly random starts (one start per sample)."""
    polishes = [
        ("DLS, random starts", dls_polish(iterations=DLS_ITERATIONS), f"{DLS_ITERATIONS} iterations, damping 1e-3"),
        ("CCD, random starts", partial(ccd, sweeps=CCD_SWEEPS), f"{CCD_SWEEPS} sweeps"),
        ("FABRIK, random starts", partial(fabrik, iterations=FABRIK_ITERATIONS), f"{FABRIK_ITERATIONS} iterations"),
    ]
    return [
        Method(name, "classical", partial(_from_random_starts, polish, arm), settings)
        for name, polish, settings in polishes
    ]


def classical_methods(arm: PlanarArm) -> list[Method]:
    """The random-start solvers, and for N = 2 the closed form."""
    methods = random_start_methods(arm)
    if arm.num_joints == 2:
        methods.append(
            Method(
                "Closed form (exact)",
                "classical",
                lambda targets, k, generator: solve_two_link(targets, arm, num_samples=k),
                "law of cosines; samples alternate the two elbows",
            )
        )
    return methods
