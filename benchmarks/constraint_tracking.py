"""Panda, tracking circles: part 3 of benchmarks/constraints.py, `--parts tracking`.

Circles of `track_radius` in a horizontal plane through a start pose's hand, `track_points`
targets at that hand's fixed orientation, followed from the start pose: the largest joint jump
between consecutive solutions and the share of targets solved within 1 mm and 1 degree, beside
pytorch_kinematics PseudoInverseIK warm-started from the previous solution.

A circle is only a test of tracking if the arm can reach all of it, so every circle is first
certified by a check that is not IKDP: PseudoInverseIK from `CERTIFY_STARTS` uniform random
starts per target must put some start within 1 mm and 1 degree of every target, within the joint
limits. The first circle starts from Franka's ready pose; then random starts away from the limits
are drawn until `track_circles` circles are certified, and the rejected draws are counted. The
first rejected circle is kept as a separate stress row: part of it is out of reach at that
orientation, its certified share is the ceiling any tracker can reach, and it measures what a
tracker does across the unreachable stretch, apart from the certified circles the tracking target is judged on.
"""

from __future__ import annotations

import math
import os

import torch

from benchmarks.constraint_common import ConstraintBenchmarkConfig, run_pseudo_inverse, timed, within_pose_tolerance
from benchmarks.robot_benchmark import parse_sampler
from ikdp.tracking import branch_switches, needed_jumps

READY_POSE = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)  # Franka's "ready" configuration
CERTIFY_STARTS = 64  # uniform random starts per target of the independent reachability check
CERTIFY_ITERATIONS = 100  # PseudoInverseIK iterations of that check (the tracked baseline gets pk_iterations)
CERTIFY_ATTEMPTS = 3  # fresh start sets tried when PseudoInverseIK meets a singular matrix
MAX_DRAWS = 100  # random circles drawn at most before the benchmark gives up finding certified ones
JUMP_BOUND = 0.1  # radians: the largest joint jump a tracked path may take between consecutive solutions


def reachable_targets(arm, path: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """path (P, 7) -> (P,) True where PseudoInverseIK from CERTIFY_STARTS random starts reaches the target."""
    for _ in range(CERTIFY_ATTEMPTS):
        starts = arm.random_poses(CERTIFY_STARTS, generator=generator)
        try:
            _, joints = run_pseudo_inverse(arm, path, starts, CERTIFY_ITERATIONS)
        except torch.linalg.LinAlgError:  # a start at a singular pose: draw the starts again
            continue
        return within_pose_tolerance(arm, joints, path).any(dim=1)
    raise RuntimeError(f"PseudoInverseIK met a singular matrix with {CERTIFY_ATTEMPTS} sets of random starts")


def circle_path(arm, start: torch.Tensor, points: int, radius: float) -> torch.Tensor:
    """A horizontal circle through the start pose's hand, at its orientation, (points, 7)."""
    pose = arm.end_effector(start)
    angles = torch.linspace(0, 2 * math.pi, points + 1)[:-1]
    center = pose[:3] - torch.tensor([radius, 0.0, 0.0])
    circle = center + radius * torch.stack([angles.cos(), angles.sin(), torch.zeros(points)], dim=-1)
    return torch.cat([circle, pose[3:].expand(points, 4)], dim=-1)


def draw_circles(arm, config: ConstraintBenchmarkConfig) -> dict:
    """The ready pose's circle, then random ones until `track_circles` are certified reachable all the way round.

    Returns {"circles": [(label, draw, start, path, reachable)], "stress": the first rejected one or None,
    "rejected": n}; `draw` numbers the circles in the order drawn (the ready pose is 0) and seeds IKDP on it.
    """
    draws = torch.Generator().manual_seed(config.seed + 2)
    certify = torch.Generator().manual_seed(config.seed + 5)
    circles, stress, rejected = [], None, 0
    candidates = [("ready pose", 0, torch.tensor(READY_POSE))]
    for draw in range(MAX_DRAWS):
        if len(circles) == config.track_circles:
            break
        if not candidates:  # a random start away from the limits, so that most of its circle is likely reachable
            limits = arm.joint_limits
            unit = 0.2 + 0.6 * torch.rand(arm.num_joints, generator=draws)
            candidates.append((f"random draw {draw}", draw, limits[:, 0] + unit * (limits[:, 1] - limits[:, 0])))
        label, index, start = candidates.pop()
        path = circle_path(arm, start, config.track_points, config.track_radius)
        reachable = reachable_targets(arm, path, certify)
        if bool(reachable.all()):
            circles.append((label, index, start, path, reachable))
        else:
            rejected += 1
            stress = stress or (label, index, start, path, reachable)
    if len(circles) < config.track_circles:
        raise RuntimeError(f"track_circles: only {len(circles)} of {MAX_DRAWS} drawn circles are reachable all round")
    return {"circles": circles, "stress": stress, "rejected": rejected}


def track_with_pseudo_inverse(arm, path: torch.Tensor, start: torch.Tensor, iterations: int) -> dict:
    """Warm-started PseudoInverseIK: each target from the previous solution, one start."""
    previous, solutions, seconds = start, [], 0.0
    for target in path:
        spent, joints = run_pseudo_inverse(arm, target[None], previous[None], iterations)
        seconds += spent
        previous = joints[0, 0]
        solutions.append(previous)
    return {"angles": torch.stack(solutions), "seconds": seconds}


def measured(arm, path: torch.Tensor, start: torch.Tensor, angles: torch.Tensor, seconds: float, reachable) -> dict:
    """One method's solutions `angles` (P, J) of a circle `path` (P, 7) followed from `start` (J,), against the
    certified `reachable` (P,); every method scored by the same rule (within_pose_tolerance: 1 mm and 1 degree,
    the rule of `track().reached`) and its branch switches flagged as `track` flags them."""
    reached = within_pose_tolerance(arm, angles[:, None], path)[:, 0]
    jumps = (angles - torch.cat([start[None], angles[:-1]])).abs().amax(dim=-1)  # the Panda has no continuous joint
    switches = branch_switches(jumps, needed_jumps(arm, path, start, angles))
    return {
        "solved_share": float(reached.double().mean()),
        "solved_share_of_reachable": float(reached[reachable].double().mean()),
        "largest_jump_rad": float(jumps.max()),
        "jumps_over_0.1_rad": int((jumps > JUMP_BOUND).sum()),
        "jumps_over_0.1_rad_onto_reachable_targets": int(((jumps > JUMP_BOUND) & reachable).sum()),
        "branch_switches": int(switches.sum()),
        "ms_per_target": 1000 * seconds / len(reached),
        "reached": reached.tolist(),
        "jumps_rad": jumps.tolist(),
    }


def track_variants(config: ConstraintBenchmarkConfig, stress: bool) -> dict:
    """label -> solver.track options of each IKDP variant; on the stress circle, also its out-of-reach rules apart."""
    weight = config.track_weight
    variants = {
        f"IKDP track, near-pose weight {weight}, + warm-started candidate": {"weight": weight, "warm_start": True},
        f"IKDP track, near-pose weight {weight}, samples only": {"weight": weight, "warm_start": False},
        "IKDP, no near-pose pull (nearest valid sample kept)": {"weight": 0.0, "warm_start": False},
    }
    if config.restart_steps:  # the unreached targets' restarts, which start from the previous solution (NearPose)
        label = f"IKDP track, near-pose weight {weight}, + warm-started candidate, restarts + {config.restart_steps}"
        variants[label] = {"weight": weight, "warm_start": True, "restart_steps": config.restart_steps}
    if stress:  # the default has both rules; they act only where some target is out of reach
        variants |= {
            "IKDP track, hold_step only (no look-ahead)": {"weight": weight, "look_ahead": 0},
            "IKDP track, look-ahead only (no hold_step)": {"weight": weight, "hold_step": None},
            "IKDP track, neither rule (the nearest candidate kept)": {
                "weight": weight,
                "hold_step": None,
                "look_ahead": 0,
            },
        }
    return variants


def track_circle(solver, config: ConstraintBenchmarkConfig, start, path, reachable, seed: int, stress=False) -> dict:
    """Every method on one circle: label -> measured."""
    name, steps = parse_sampler(config.sampler)
    methods = {}
    for label, options in track_variants(config, stress).items():
        seconds, result = timed(
            lambda options=options: solver.track(
                path,
                start,
                num_samples=config.samples,
                sampler=name,
                steps=steps,
                refine_steps=config.refine_steps,
                generator=torch.Generator().manual_seed(seed),
                **options,
            )
        )
        methods[label] = measured(solver.arm, path, start, result.angles, seconds, reachable)
        methods[label]["track_reached_agrees"] = result.reached.tolist() == methods[label]["reached"]
        methods[label]["track_branch_switches_agree"] = (
            int(result.branch_switches.sum()) == methods[label]["branch_switches"]
        )
    try:
        tracked = track_with_pseudo_inverse(solver.arm, path, start, config.pk_iterations)
    except ImportError:  # pytorch_kinematics is a benchmark dependency (benchmarks/requirements-bench.txt)
        return methods
    label = f"pytorch_kinematics PseudoInverseIK, warm-started, {config.pk_iterations} iterations"
    methods[label] = measured(solver.arm, path, start, tracked["angles"], tracked["seconds"], reachable)
    return methods


def circle_entry(label: str, start: torch.Tensor, reachable: torch.Tensor, methods: dict) -> dict:
    return {
        "label": label,
        "start_pose": start.tolist(),
        "reachable_share": float(reachable.double().mean()),
        "reachable": reachable.tolist(),
        "methods": methods,
    }


def tracking_part(solver, config: ConstraintBenchmarkConfig) -> dict:
    arm = solver.arm
    load_before = os.getloadavg()
    certify_seconds, drawn = timed(lambda: draw_circles(arm, config))
    circles = [
        circle_entry(label, start, reachable, track_circle(solver, config, start, path, reachable, seed))
        for label, seed, start, path, reachable in drawn["circles"]
    ]
    over_all = {}
    for label in circles[0]["methods"]:
        reached = [value for circle in circles for value in circle["methods"][label]["reached"]]
        jumps = torch.tensor([value for circle in circles for value in circle["methods"][label]["jumps_rad"]])
        over_all[label] = {
            "solved_share": sum(reached) / len(reached),
            "largest_jump_rad": float(jumps.max()),
            "jumps_over_0.1_rad": int((jumps > JUMP_BOUND).sum()),
            "branch_switches": sum(circle["methods"][label]["branch_switches"] for circle in circles),
            "ms_per_target": sum(circle["methods"][label]["ms_per_target"] for circle in circles) / len(circles),
            "meets_target": sum(reached) / len(reached) >= 0.99 and float(jumps.max()) <= JUMP_BOUND,
        }
    stress = None
    if drawn["stress"] is not None:
        label, seed, start, path, reachable = drawn["stress"]
        stress = circle_entry(
            label, start, reachable, track_circle(solver, config, start, path, reachable, seed, stress=True)
        )
    return {
        "points_per_circle": config.track_points,
        "radius_m": config.track_radius,
        "certification": {
            "method": f"pytorch_kinematics PseudoInverseIK, {CERTIFY_STARTS} uniform random starts per target, "
            f"{CERTIFY_ITERATIONS} iterations, 1 mm and 1 degree within the joint limits",
            "rejected_circles": drawn["rejected"],
            "seconds": certify_seconds,
        },
        "circles": circles,
        "all_reachable_circles": {"targets": len(circles) * config.track_points, "methods": over_all},
        "stress_circle": stress,
        "load_average": {"before": load_before, "after": os.getloadavg()},
    }


def print_tracking(part: dict) -> None:
    print(f"\nPanda, tracking circles of {part['radius_m']} m, {part['points_per_circle']} targets each")
    print(f"certified reachable by {part['certification']['method']}; rejected draws: ", end="")
    print(part["certification"]["rejected_circles"])
    print(
        "| circle | reachable | method | solved | of reachable | largest jump (rad) | jumps > 0.1 rad (onto reachable) "
        "| branch switches | ms/target |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    rows = [(f"{index} ({circle['label']})", circle) for index, circle in enumerate(part["circles"])]
    if part["stress_circle"] is not None:
        rows.append((f"stress ({part['stress_circle']['label']})", part["stress_circle"]))
    for name, circle in rows:
        for label, values in circle["methods"].items():
            print(
                f"| {name} | {100 * circle['reachable_share']:.1f} % | {label} | {100 * values['solved_share']:.1f} % "
                f"| {100 * values['solved_share_of_reachable']:.1f} % | {values['largest_jump_rad']:.3f} "
                f"| {values['jumps_over_0.1_rad']} ({values['jumps_over_0.1_rad_onto_reachable_targets']}) "
                f"| {values['branch_switches']} | {values['ms_per_target']:.1f} |"
            )
    summary = part["all_reachable_circles"]
    print(f"\nall certified circles together ({summary['targets']} targets)")
    print("| method | solved | largest jump (rad) | jumps > 0.1 rad | branch switches | ms/target | target met |")
    print("|---|---|---|---|---|---|---|")
    for label, values in summary["methods"].items():
        print(
            f"| {label} | {100 * values['solved_share']:.1f} % | {values['largest_jump_rad']:.3f} "
            f"| {values['jumps_over_0.1_rad']} | {values['branch_switches']} | {values['ms_per_target']:.1f} "
            f"| {values['meets_target']} |"
        )
