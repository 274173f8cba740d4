"""Constraints at sampling time, measured: obstacles, locked joints, tracking, a planar disc.

    OMP_NUM_THREADS=1 python -m benchmarks.constraints --targets 1000

One run, one torch thread, every method on the same targets in the same run:
1. Panda, obstacles: held-out pose targets (FK of joint values uniform within the limits),
   each with 2 spheres of radius 5-10 cm centred within 3 cm of the straight segments between
   the elbow joints of that valid solution (joints 3 to 6), so that solution is blocked; spheres
   touching the links the target pins down (base, shoulder, wrist, hand) are drawn again, and a
   pair is kept only if an independent 64-start DLS search has a solution 1 cm clear of it (every
   target feasible; `--no-certified-placement`: the first pair, feasible or not).
   Share of targets with a collision-free solution within 1 mm and 1 degree, valid solutions
   per target and time per target: IKDP K=16 + refinement (guided with DPM-Solver++ and DDPM, and
   unguided with the same filter), 16 uniform random starts with the same constrained refinement, and pytorch_kinematics
   PseudoInverseIK (16 retries, 30 iterations) with the same collision filter (the link spheres of
   ikdp/link_spheres.py). "Solved by any method" bounds how many targets the spheres leave open.
   One more IKDP row takes solve's `restart_steps` (`--restart-steps`, 0: no such row).
2. Panda, joints 1 and 7 locked at the valid solution's values: share solved, locked joints moved
   (with the same restarts row).
3. Panda, tracking (benchmarks/constraint_tracking.py): circles of `track_radius` in a horizontal
   plane, `track_points` targets at a fixed orientation, each certified reachable all the way round
   by PseudoInverseIK from many random starts (plus one partly unreachable stress circle): largest
   joint jump between consecutive solutions and share solved; beside pytorch_kinematics warm-started
   from the previous solution.
4. Panda, partial targets (position only; the hand's z axis free): share within 1 mm (and 1 degree
   of the axis), beside random starts refined on the same partial residual.
5. Planar N=4 (ikdp_n4) with one disc over a valid solution's middle bones, clear of the base and
   the target (a pose folded so that no disc fits is drawn again): the same shares as 1.
Prints tables and writes benchmarks/results/constraints.json.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict

import torch
import tyro

import ikdp
from benchmarks.constraint_common import (
    ConstraintBenchmarkConfig,
    row,
    run_pseudo_inverse,
    timed,
    within_pose_tolerance,
)
from benchmarks.constraint_tracking import print_tracking, tracking_part
from benchmarks.robot_benchmark import parse_sampler
from ikdp.evaluation.machine import machine_description
from ikdp.guidance import ConstraintSet
from ikdp.link_spheres import link_spheres
from ikdp.refine import damped_least_squares

PLACEMENT_ATTEMPTS = 100  # disc placements tried on one planar pose before the pose is drawn again
PINNED_LINKS = ("panda_link0", "panda_link1", "panda_link6", "panda_link7", "panda_hand")  # fixed by the target
WITNESS_STARTS = 64  # random starts per target of the independent solve that certifies a free solution exists
WITNESS_STEPS = 30  # its unconstrained DLS steps
PLACEMENT_DRAWS = 32  # sphere pairs drawn per target; the first one that leaves a certified free solution is kept
CANDIDATES = 8 * PLACEMENT_DRAWS  # single spheres drawn per target (those touching a pinned link are dropped)
WITNESS_CLEARANCE = 0.01  # metres a certifying solution keeps from every sphere: not a knife-edge feasibility


def refined_random_starts(arm, goals: torch.Tensor, dls_steps: int, task) -> tuple[float, torch.Tensor]:
    """K uniform random starts per target (goals (B, K, C)), then `dls_steps` constrained DLS steps: timed."""
    starts = arm.random_poses(goals.shape[0] * goals.shape[1], generator=torch.Generator().manual_seed(3))
    starts = starts.unflatten(0, tuple(goals.shape[:2]))
    return timed(lambda: damped_least_squares(arm, starts, goals, steps=dls_steps, task=task))


def free_solution_pool(arm, targets: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """(B, W, J) solutions of every target from `WITNESS_STARTS` uniform starts + unconstrained DLS; NaN where missed.

    Not IKDP and not any benchmarked row: a larger random-restart search, run once, so the
    spheres can be placed where some solution stays free (a witness that the target is feasible).
    """
    starts = arm.random_poses(len(targets) * WITNESS_STARTS, generator=generator).unflatten(0, (len(targets), -1))
    goals = targets[:, None].expand(-1, WITNESS_STARTS, -1)
    solutions = damped_least_squares(arm, starts, goals, steps=WITNESS_STEPS)
    reached = within_pose_tolerance(arm, solutions, targets)
    return torch.where(reached[..., None], solutions, torch.nan)


def candidate_spheres(arm, truth: torch.Tensor, generator: torch.Generator):
    """(B, C, 3) centres, (B, C) radii near each valid solution's elbow segments, (B, C) clear of the pinned links."""
    spheres = link_spheres(arm)
    world = spheres.world_centers(arm, truth)  # (B, S, 3)
    radii = torch.tensor(spheres.radii)
    pinned = torch.tensor([arm.link_names[index] in PINNED_LINKS for index in spheres.link_indices])
    joints = arm.forward_kinematics(truth)[:, 2:6]  # (B, 4, 3) joints 3..6: the upper arm and forearm
    count = (len(truth), CANDIDATES)
    segment = torch.randint(3, count, generator=generator)
    along = torch.rand(count, generator=generator)[..., None]
    start = joints.gather(1, segment[..., None].expand(-1, -1, 3))
    end = joints.gather(1, (segment + 1)[..., None].expand(-1, -1, 3))
    centers = start + along * (end - start) + (torch.rand(*count, 3, generator=generator) * 2 - 1) * 0.03
    sizes = 0.05 + 0.05 * torch.rand(count, generator=generator)
    gap = (world[:, None, pinned] - centers[:, :, None]).norm(dim=-1) - radii[pinned] - sizes[..., None]
    return centers, sizes, (gap > 0).all(dim=-1)


def collides(arm, joints: torch.Tensor, centers: torch.Tensor, radii: torch.Tensor, margin: float) -> torch.Tensor:
    """joints (B, W, J) against spheres (B, O, 3), (B, O) -> (B, W) whether any link sphere comes within `margin`."""
    spheres = link_spheres(arm)
    world = spheres.world_centers(arm, joints.nan_to_num())[:, :, :, None]  # (B, W, S, 1, 3)
    distance = (world - centers[:, None, None]).norm(dim=-1)  # (B, W, S, O)
    return (distance < spheres.radii_like(joints)[:, None] + radii[:, None, None] + margin).flatten(2).any(dim=-1)


def place_spheres(arm, truth: torch.Tensor, generator: torch.Generator, certified: bool = True) -> dict:
    """Two spheres per target blocking its valid solution `truth` (B, J), placed so another solution stays free.

    Spheres (5-10 cm) are centred within 3 cm of the elbow segments of `truth`, clear of the
    links the target pins (base, shoulder, wrist, hand). Of `PLACEMENT_DRAWS` pairs the first
    that leaves one solution of an independent random-restart search clear of both spheres by
    `WITNESS_CLEARANCE` is kept; a target with none is drawn again. So every target is feasible,
    with room to spare, as a >= 99 % target needs. `certified=False` keeps every first pair (the
    rule before: some targets then have no free solution at all), the certificate only measured.
    """
    truth = truth.clone()
    centers, radii = torch.zeros(len(truth), 2, 3), torch.zeros(len(truth), 2)
    witnesses = torch.full_like(truth, torch.nan)  # the certifying solution of each target (NaN: uncertified)
    first_draw_feasible, redrawn, pending = None, 0, torch.arange(len(truth))
    while len(pending):
        targets = arm.end_effector(truth[pending])
        pool = free_solution_pool(arm, targets, generator)
        candidates, sizes, clear = candidate_spheres(arm, truth[pending], generator)
        pairs = torch.full((len(pending), PLACEMENT_DRAWS, 2), -1)
        for row_index, allowed in enumerate(clear):  # consecutive pairs of allowed candidates
            usable = allowed.nonzero()[:, 0][: 2 * PLACEMENT_DRAWS]
            usable = usable[: len(usable) // 2 * 2].view(-1, 2)
            pairs[row_index, : len(usable)] = usable
        feasible = torch.zeros(len(pending), PLACEMENT_DRAWS, dtype=torch.bool)
        witness = torch.zeros(len(pending), PLACEMENT_DRAWS, dtype=torch.long)  # its index in the pool
        for draw in range(PLACEMENT_DRAWS):
            index = pairs[:, draw].clamp_min(0)
            draw_centers = candidates.gather(1, index[..., None].expand(-1, -1, 3))
            draw_radii = sizes.gather(1, index)
            free = ~collides(arm, pool, draw_centers, draw_radii, WITNESS_CLEARANCE) & ~pool.isnan().any(dim=-1)
            feasible[:, draw] = free.any(dim=-1) & (pairs[:, draw, 0] >= 0)
            witness[:, draw] = free.double().argmax(dim=-1)
        if first_draw_feasible is None:
            first_draw_feasible = float(feasible[:, 0].double().mean())
        if not certified:
            feasible[:, 0] = pairs[:, 0, 0] >= 0
        found = feasible.any(dim=1)
        chosen = feasible.double().argmax(dim=1)
        for row_index in found.nonzero()[:, 0].tolist():
            pair = pairs[row_index, chosen[row_index]]
            centers[pending[row_index]], radii[pending[row_index]] = candidates[row_index, pair], sizes[row_index, pair]
            if certified:
                witnesses[pending[row_index]] = pool[row_index, witness[row_index, chosen[row_index]]]
        pending = pending[~found]
        redrawn += len(pending)
        truth[pending] = arm.random_poses(len(pending), generator=generator)
    return {
        "truth": truth,
        "centers": centers,
        "radii": radii,
        "witnesses": witnesses,
        "first_draw_feasible_share": first_draw_feasible,
        "targets_redrawn": redrawn,
    }


def obstacles_part(solver, config: ConstraintBenchmarkConfig) -> dict:
    arm = solver.arm
    generator = torch.Generator().manual_seed(config.seed)
    placement = place_spheres(
        arm, arm.random_poses(config.targets, generator=generator), generator, config.certified_placement
    )
    truth = placement["truth"]
    targets = arm.end_effector(truth)
    obstacle = ikdp.Obstacles(placement["centers"], placement["radii"])
    check = ConstraintSet(arm, [obstacle], len(targets), config.samples)
    name, steps = parse_sampler(config.sampler)
    options = {"num_samples": config.samples, "sampler": name, "steps": steps, "refine_steps": config.refine_steps}
    rows, solved = {}, {}

    def record(label: str, seconds: float, joints: torch.Tensor) -> None:
        valid = within_pose_tolerance(arm, joints, targets) & (check.violation(joints) == 0)
        rows[label] = row(valid, seconds)
        solved[label] = valid.any(dim=1)

    runs = [(text, 0) for text in (config.sampler, *config.obstacle_extra_samplers)]
    runs += [(config.sampler, config.restart_steps)] if config.restart_steps else []
    for text, restart_steps in runs:
        name, steps = parse_sampler(text)
        guided = {**options, "sampler": name, "steps": steps, "restart_steps": restart_steps}
        label = f"IKDP {text}, K={config.samples}, guided + {config.refine_steps} constrained DLS steps"
        label += f", restarts + {restart_steps}" if restart_steps else ""
        seconds, out = timed(
            lambda guided=guided: solver.solve(
                targets, constraints=[obstacle], generator=torch.Generator().manual_seed(1), **guided
            )
        )
        record(label, seconds, out.angles)
    label = f"IKDP {config.sampler}, K={config.samples}, unguided + {config.refine_steps} DLS steps, filtered"
    seconds, out = timed(lambda: solver.solve(targets, generator=torch.Generator().manual_seed(1), **options))
    record(label, seconds, out.angles)
    goals = targets[:, None].expand(-1, config.samples, -1)
    for dls_steps in config.random_start_steps:
        seconds, joints = refined_random_starts(arm, goals, dls_steps, check.refine_task())
        record(f"{config.samples} uniform random starts + {dls_steps} constrained DLS steps", seconds, joints)
    try:
        retry = arm.random_poses(config.pk_retries, generator=torch.Generator().manual_seed(config.seed + 9))
        seconds, joints = run_pseudo_inverse(arm, targets, retry, config.pk_iterations)
        label = f"pytorch_kinematics PseudoInverseIK, {config.pk_retries} retries, {config.pk_iterations} iterations"
        valid = within_pose_tolerance(arm, joints, targets)
        valid &= ConstraintSet(arm, [obstacle], len(targets), joints.shape[1]).violation(joints) == 0
        rows[label] = row(valid, seconds)
        solved[label] = valid.any(dim=1)
    except ImportError:
        pass
    any_method = torch.stack(list(solved.values())).any(dim=0)
    return {
        "targets": len(targets),
        "rows": rows,
        "solved_by_any_method": float(any_method.double().mean()),
        "first_draw_feasible_share": placement["first_draw_feasible_share"],
        "targets_redrawn_for_want_of_a_free_solution": placement["targets_redrawn"],
        "blocked_ground_truth_share": float(
            (ConstraintSet(arm, [obstacle], len(targets), 1).violation(truth[:, None]) > 0).double().mean()
        ),
    }


def locked_part(solver, config: ConstraintBenchmarkConfig) -> dict:
    arm = solver.arm
    truth = arm.random_poses(config.targets, generator=torch.Generator().manual_seed(config.seed + 1))
    targets = arm.end_effector(truth)
    values = {"panda_joint1": truth[:, 0].tolist(), "panda_joint7": truth[:, 6].tolist()}
    name, steps = parse_sampler(config.sampler)
    options = {"num_samples": config.samples, "sampler": name, "steps": steps, "refine_steps": config.refine_steps}
    rows = {}

    def moved(joints: torch.Tensor) -> float:
        return float((joints[..., [0, 6]] - truth[:, None, [0, 6]]).abs().max())

    runs = [(True, 0), (False, 0)] + ([(True, config.restart_steps)] if config.restart_steps else [])
    for repaint, restart_steps in runs:
        lock = ikdp.LockedJoints(values, repaint=repaint)
        seconds, out = timed(
            lambda lock=lock, restart_steps=restart_steps: solver.solve(
                targets, constraints=[lock], generator=torch.Generator().manual_seed(1), **options,
                restart_steps=restart_steps,
            )
        )  # fmt: skip
        label = f"IKDP {config.sampler}, K={config.samples}, " + (
            "inpainted (x̂0 and states, RePaint)" if repaint else "inpainted (x̂0 only)"
        )
        label += f", restarts + {restart_steps}" if restart_steps else ""
        valid = within_pose_tolerance(arm, out.angles, targets)
        rows[label] = row(valid, seconds, locked_joints_moved_rad=moved(out.angles))
    check = ConstraintSet(arm, [ikdp.LockedJoints(values)], len(targets), config.samples)
    goals = targets[:, None].expand(-1, config.samples, -1)
    for dls_steps in config.random_start_steps:
        starts = arm.random_poses(len(targets) * config.samples, generator=torch.Generator().manual_seed(3))
        starts = check.hold(starts.unflatten(0, (len(targets), config.samples)))
        seconds, joints = timed(
            lambda starts=starts, dls_steps=dls_steps: damped_least_squares(
                arm, starts, goals, steps=dls_steps, task=check.refine_task()
            )
        )
        label = f"{config.samples} uniform random starts (locked joints set) + {dls_steps} DLS steps, locked columns"
        rows[label] = row(within_pose_tolerance(arm, joints, targets), seconds, locked_joints_moved_rad=moved(joints))
    return {"targets": len(targets), "rows": rows}


def partial_part(solver, config: ConstraintBenchmarkConfig) -> dict:
    """Position only and a free hand z axis: IKDP against random starts with the same partial refinement."""
    arm = solver.arm
    truth = arm.random_poses(config.targets, generator=torch.Generator().manual_seed(config.seed + 4))
    targets = arm.end_effector(truth)
    name, steps = parse_sampler(config.sampler)
    options = {"num_samples": config.samples, "sampler": name, "steps": steps, "refine_steps": config.refine_steps}
    parts = {}
    for constraint in (ikdp.PositionOnly(), ikdp.FreeAxis(axis=(0.0, 0.0, 1.0))):
        bound = constraint.bind(arm, len(targets), config.samples)

        def valid_of(joints, bound=bound):
            goals = targets[:, None].expand(-1, joints.shape[1], -1)
            valid = arm.position_error(joints, goals) < 1e-3
            axis_error = bound.rotation_error(joints, goals)
            return valid if axis_error is None else valid & (axis_error < math.radians(1))

        rows = {}
        seconds, out = timed(
            lambda constraint=constraint: solver.solve(
                targets, constraints=[constraint], generator=torch.Generator().manual_seed(1), **options
            )
        )
        rows[f"IKDP {config.sampler}, K={config.samples}, partial conditions + {config.refine_steps} DLS steps"] = row(
            valid_of(out.angles), seconds
        )
        task = ConstraintSet(arm, [constraint], len(targets), config.samples).refine_task()
        goals = targets[:, None].expand(-1, config.samples, -1)
        for dls_steps in config.random_start_steps:
            starts = arm.random_poses(len(targets) * config.samples, generator=torch.Generator().manual_seed(3))
            starts = starts.unflatten(0, (len(targets), config.samples))
            seconds, joints = timed(
                lambda starts=starts, dls_steps=dls_steps, task=task, goals=goals: damped_least_squares(
                    arm, starts, goals, steps=dls_steps, task=task
                )
            )
            label = f"{config.samples} uniform random starts + {dls_steps} DLS steps on the partial residual"
            rows[label] = row(valid_of(joints), seconds)
        parts[constraint.name] = {"targets": len(targets), "rows": rows}
    return parts


def planar_part(config: ConstraintBenchmarkConfig) -> dict:
    solver = ikdp.load(config.planar_checkpoint)
    arm = solver.arm
    generator = torch.Generator().manual_seed(config.seed + 3)
    truth = solver.prior.sample(config.planar_targets, arm.num_joints, generator=generator)
    centers, radii, redrawn = torch.zeros(len(truth), 1, 2), torch.zeros(len(truth), 1), 0
    for index in range(len(truth)):  # a disc over bone 2 or 3, clear of the base and of the target
        for attempt in range(PLACEMENT_ATTEMPTS * 10):
            if attempt and attempt % PLACEMENT_ATTEMPTS == 0:  # this pose leaves no room (folded near the base)
                truth[index] = solver.prior.sample(1, arm.num_joints, generator=generator)[0]
                redrawn += 1
            points, target = arm.forward_kinematics(truth[index]), arm.end_effector(truth[index])
            bone = int(torch.randint(1, 3, (1,), generator=generator))
            center = points[bone : bone + 2].mean(dim=0) + (torch.rand(2, generator=generator) * 2 - 1) * 0.1
            radius = 0.3 + 0.3 * torch.rand((), generator=generator)
            if center.norm() > radius + 0.1 and (target - center).norm() > radius + 0.1:
                centers[index, 0], radii[index, 0] = center, radius
                break
        else:
            raise RuntimeError(f"planar target {index}: no disc placement found")
    targets = arm.end_effector(truth)
    obstacle = ikdp.Obstacles(centers, radii)
    check = ConstraintSet(arm, [obstacle], len(targets), config.samples)
    tolerance = 1e-3  # bone lengths

    def valid_of(joints):
        return (arm.tip_error(joints, targets[:, None]) < tolerance) & (check.violation(joints) == 0)

    rows, solved = {}, {}
    for text in (config.planar_sampler, "ddpm"):
        name, steps = parse_sampler(text)
        options = {"num_samples": config.samples, "sampler": name, "steps": steps, "refine_steps": config.refine_steps}
        for guided in (True, False):
            constraints = [obstacle] if guided else []
            seconds, out = timed(
                lambda constraints=constraints, options=options: solver.solve(
                    targets, constraints=constraints, generator=torch.Generator().manual_seed(1), **options
                )
            )
            label = f"IKDP {text}, K={config.samples}, " + (
                f"guided + {config.refine_steps} constrained DLS steps"
                if guided
                else f"unguided + {config.refine_steps} DLS steps, filtered"
            )
            valid = valid_of(out.angles)
            rows[label], solved[label] = row(valid, seconds), valid.any(dim=1)
    goals = targets[:, None].expand(-1, config.samples, -1)
    for dls_steps in config.random_start_steps:
        seconds, joints = refined_random_starts(arm, goals, dls_steps, check.refine_task())
        label = f"{config.samples} uniform random starts + {dls_steps} constrained DLS steps"
        valid = valid_of(joints)
        rows[label], solved[label] = row(valid, seconds), valid.any(dim=1)
    any_method = torch.stack(list(solved.values())).any(dim=0)
    return {
        "targets": len(targets),
        "tolerance_bone_lengths": tolerance,
        "poses_redrawn_for_want_of_room": redrawn,
        "rows": rows,
        "solved_by_any_method": float(any_method.double().mean()),
    }


def print_rows(title: str, part: dict) -> None:
    print(f"\n{title} ({part['targets']} targets)")
    print("| method | solved | valid of K | ms per target |")
    print("|---|---|---|---|")
    for label, values in part["rows"].items():
        extra = (
            f" (locked joints moved {values['locked_joints_moved_rad']:.3g} rad)"
            if "locked_joints_moved_rad" in values
            else ""
        )
        print(
            f"| {label}{extra} | {100 * values['success_share']:.1f} % | {values['valid_per_target']:.1f} "
            f"| {values['ms_per_target']:.2f} |"
        )
    if "solved_by_any_method" in part:
        print(f"solved by any method: {100 * part['solved_by_any_method']:.1f} %")
    if "first_draw_feasible_share" in part:
        print(
            f"first sphere pair drawn left a certified free solution: {100 * part['first_draw_feasible_share']:.1f} %; "
            f"targets drawn again for want of one: {part['targets_redrawn_for_want_of_a_free_solution']}"
        )


def main(config: ConstraintBenchmarkConfig) -> dict:
    torch.set_num_threads(1)
    unknown = sorted(set(config.parts) - {"obstacles", "locked", "tracking", "partial", "planar"})
    if unknown:
        raise ValueError(f"parts: unknown {unknown}, expected obstacles, locked, tracking, partial, planar")
    results: dict = {
        "config": {**asdict(config), "output": str(config.output)},
        "machine": machine_description(threads=1),
    }
    solver = ikdp.load(config.checkpoint) if set(config.parts) - {"planar"} else None
    started = time.perf_counter()
    if "obstacles" in config.parts:
        results["obstacles"] = obstacles_part(solver, config)
        print_rows("Panda, 2 spheres blocking a valid solution", results["obstacles"])
    if "locked" in config.parts:
        results["locked"] = locked_part(solver, config)
        print_rows("Panda, joints 1 and 7 locked", results["locked"])
    if "tracking" in config.parts:
        results["tracking"] = tracking_part(solver, config)
        print_tracking(results["tracking"])
    if "partial" in config.parts:
        results["partial"] = partial_part(solver, config)
        for kind, part in results["partial"].items():
            print_rows(f"Panda, partial target: {kind}", part)
    if "planar" in config.parts:
        results["planar"] = planar_part(config)
        print_rows(f"planar N=4 ({config.planar_checkpoint}), one disc over a valid solution", results["planar"])
    results["wall_seconds"] = time.perf_counter() - started
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main(tyro.cli(ConstraintBenchmarkConfig, description=__doc__.splitlines()[0]))
