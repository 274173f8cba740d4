"""Every benchmark script starts: its imports and its command line hold as the library moves.

The benchmarks run for minutes, so the suite never runs them; but a script that no longer
imports (as core_benchmark did when ikdp._cli was removed) is only found the day someone
needs its numbers. `--help` imports everything and builds the command line, in seconds.
"""

import subprocess
import sys
from pathlib import Path

import pytest
import torch

REPO = Path(__file__).resolve().parents[1]
HELPERS = {
    "pk_chain",
    "constraint_tracking",
    "constraint_common",
    "pinocchio_clik",
}  # run or imported by another script, not a command of its own
SCRIPTS = sorted(path.stem for path in (REPO / "benchmarks").glob("*.py") if path.stem not in HELPERS)


def test_the_benchmarks_are_found():
    assert {"core_benchmark", "robot_benchmark", "fidelity", "viz_frames"} <= set(SCRIPTS)


@pytest.mark.slow
@pytest.mark.parametrize("name", SCRIPTS)
def test_a_benchmark_script_starts(name):
    result = subprocess.run(
        [sys.executable, "-m", f"benchmarks.{name}", "--help"], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-1500:]
    assert "usage" in result.stdout.lower()


def test_the_robot_benchmark_names_its_results_after_the_checkpoint():
    from benchmarks.robot_benchmark import default_output

    assert default_output("/any/checkpoints/ikdp_panda.pt").name == "robot_panda.json"  # the Panda's file, as before
    assert default_output("runs/my_arm.pt") == REPO / "benchmarks" / "results" / "robot_my_arm.json"


def test_the_obstacle_benchmark_blocks_each_valid_solution_and_certifies_another_one_free():
    import torch

    import ikdp
    from benchmarks.constraints import WITNESS_CLEARANCE, place_spheres, within_pose_tolerance
    from ikdp.guidance import ConstraintSet

    arm = ikdp.load_robot("panda")
    generator = torch.Generator().manual_seed(0)
    placement = place_spheres(arm, arm.random_poses(6, generator=generator), generator)
    truth, witnesses = placement["truth"], placement["witnesses"]
    targets = arm.end_effector(truth)
    blocking = ConstraintSet(arm, [ikdp.Obstacles(placement["centers"], placement["radii"])], 6, 1)
    assert bool((blocking.violation(truth[:, None]) > 0).all())  # the easy solution is blocked
    assert bool(within_pose_tolerance(arm, witnesses[:, None], targets).all())  # another one reaches the target
    grown = ikdp.Obstacles(placement["centers"], placement["radii"] + WITNESS_CLEARANCE - 1e-6)
    assert bool((ConstraintSet(arm, [grown], 6, 1).violation(witnesses[:, None]) == 0).all())  # and is 1 cm clear


def refusal(module: str, *arguments: str) -> str:
    """The stderr of `python -m benchmarks.<module> <arguments>`, after checking that it refused (exit 1) without a
    traceback."""
    result = subprocess.run(
        [sys.executable, "-m", f"benchmarks.{module}", *arguments],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 1 and "Traceback" not in result.stderr
    return result.stderr


def test_the_seeded_fidelity_rows_are_read_or_refused_in_one_line():
    from benchmarks.fidelity_seeds import parse_row

    assert parse_row("ikdp_n4_relaxed@ddpm") == ("ikdp_n4_relaxed", "ddpm", None, None)
    assert parse_row("student.pt@ddim:4:quadratic") == ("student.pt", "ddim", 4, "quadratic")
    stderr = refusal("fidelity_seeds", "--rows", "m@ddim:four")
    assert "row 'm@ddim:four': expected checkpoint@sampler[:steps[:spacing]]" in stderr


def test_a_pipeline_row_names_its_sampler_refinement_and_precision():
    from benchmarks.few_step_pipeline import parse_pipeline

    assert parse_pipeline("ddim:3:quadratic+5") == ("ddim", 3, "quadratic", 5, 0, "float32")
    assert parse_pipeline("dpmpp2m:3:uniform+10/int8") == ("dpmpp2m", 3, "uniform", 10, 0, "int8")
    assert parse_pipeline("ddim:1:quadratic+8r20/int8") == ("ddim", 1, "quadratic", 8, 20, "int8")
    stderr = refusal("few_step_pipeline", "--random-start-steps", "10x20")
    assert "refinement '10x20': expected DLS steps, then optionally r and restart steps" in stderr
    for bad in ("ddim:3:quadratic", "ddim:three:quadratic+5", "ddim:3:quadratic+5r"):
        with pytest.raises(ValueError, match="expected"):
            parse_pipeline(bad)


def test_the_moonshot_line_names_only_rows_faster_than_random_starts_with_twice_their_valid_solutions():
    from benchmarks.few_step_pipeline import moonshot

    def row(ms, share, valid):
        return {"ms_per_target": ms, "success_share": share, "valid_per_target": valid}

    rows = {
        "IKDP fast and many": row(0.5, 0.997, 13.0),
        "IKDP fast, too few": row(0.5, 0.997, 12.0),
        "IKDP slow": row(0.9, 0.999, 14.0),
        "IKDP fast, unsolved": row(0.4, 0.990, 14.0),
        "random starts + 20 DLS": row(0.75, 0.997, 6.3),
    }
    assert moonshot(rows, "random starts + 20 DLS", 0.995) == {
        "baseline": "random starts + 20 DLS",
        "met_by": ["IKDP fast and many"],
    }
    assert moonshot(rows, None, 0.995) is None


def test_a_pipeline_row_records_the_share_of_targets_restarted_only_where_it_restarts(tiny_checkpoint):
    import ikdp
    from benchmarks.few_step_pipeline import Answer

    solver = ikdp.load(tiny_checkpoint)
    targets = torch.tensor([[1.0, 0.5], [0.2, -1.1], [-0.8, 0.9]])
    solved = solver.solve(targets, num_samples=4, sampler="ddim", steps=2, refine_steps=1, restart_steps=3)
    answer = Answer.of_solve(solved)
    assert answer.restarted_share() == float(solved.restarted.double().mean()) and answer.angles is solved.angles
    assert Answer.of_solve(solver.solve(targets, num_samples=4, sampler="ddim", steps=2)).restarted_share() is None
    assert Answer(solved.angles, torch.tensor([True, False, False, False])).restarted_share() == 0.25
    assert Answer(solved.angles, None).restarted_share() is None  # PseudoInverseIK, random starts without restarts


def test_the_tree_benchmarks_run_on_a_small_tree_with_pinocchio_beside_them(tmp_path, monkeypatch):
    """tree_seeds' rows (IKDP, uniform and, where pin is installed, Pinocchio's CLIK) and tree_self_collision's,
    end to end on a two-armed tree trained for a few steps."""
    from tree_helpers import BODIES_URDF

    from benchmarks.tree_seeds import TreeSeedsConfig
    from benchmarks.tree_seeds import main as tree_seeds
    from benchmarks.tree_self_collision import TreeSelfCollisionConfig
    from benchmarks.tree_self_collision import main as tree_self_collision
    from ikdp.train import main as train

    monkeypatch.setenv("IKDP_CACHE", str(tmp_path / "cache"))
    urdf = tmp_path / "bodies.urdf"
    urdf.write_text(BODIES_URDF)
    checkpoint = tmp_path / "bodies.pt"
    train(
        [
            *("--urdf", str(urdf), "--ee-link", "left_hand", "--ee-link", "right_hand", "--target", "position"),
            *("--steps", "3", "--batch", "16", "--hidden", "24", "--blocks", "1", "--timesteps", "8"),
            *("--eval-targets", "0", "--threads", "1", "--output", str(checkpoint), "--log-dir", str(tmp_path / "tb")),
        ]
    )
    seeds = tree_seeds(
        TreeSeedsConfig(str(checkpoint), targets=4, num_samples=2, dls_steps=(3,), output=tmp_path / "seeds.json")
    )
    expected = {"ikdp", "uniform"} | ({"pinocchio_clik"} if seeds["pinocchio"] else set())
    assert {row["seeds"] for row in seeds["rows"]} == expected
    assert all(0 <= row["solved"] <= 1 for row in seeds["rows"])
    apart = tree_self_collision(
        TreeSelfCollisionConfig(str(checkpoint), targets=4, num_samples=2, rounds=1, output=tmp_path / "apart.json")
    )
    assert [row["setting"] for row in apart["rows"]] == ["self_collision_on", "self_collision_off"]
    assert apart["pairs_checked"] > 0
