"""The docs' benchmark tables, rendered from benchmarks/results/*.json: the one place a figure enters the docs.

    python benchmarks/render_docs_tables.py           # rewrite every table between its markers in docs/*.md
    python benchmarks/render_docs_tables.py --check   # exit 1 if a committed page differs from the JSON (CI)

A page holds `<!-- table:NAME -->` ... `<!-- /table:NAME -->`; everything between is replaced by the table NAME
of TABLES, followed by the command that wrote its JSON and the machine it ran on (read from the JSON).
"""

from __future__ import annotations

import argparse
import functools
import json
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"
DOCS = REPO / "docs"

# The file each figure was measured on -> the name it ships under (the same weights, consolidated)
SHIPPED_AS = {
    "ikdp_panda_gpu": "ikdp_panda",
    "ikdp_panda_gpu_4step": 'ikdp_panda, sampler="student"',
    "ikdp_panda_1step": "ikdp_panda_fast",
    "ikdp_n4_relaxed_mlp": "ikdp_n4_relaxed",
}


def shipped(text: str) -> str:
    for old in sorted(SHIPPED_AS, key=len, reverse=True):
        text = re.sub(rf"\b{old}\b", SHIPPED_AS[old], text)
    return text


@dataclass(frozen=True)
class Table:
    source: str  # a file of benchmarks/results/
    command: str  # the command that wrote it
    rows: Callable[[dict], tuple[list[str], list[list[str]]]]  # the JSON -> (header, rows)
    note: str = ""  # what a reader must know that the JSON does not say


def machine(data: dict) -> str:
    """The machine a result names: a GPU and torch, or a CPU, its torch threads and torch."""
    if "gpu" in data:
        return f"{data['gpu']}, torch {data['torch']}"
    found = data.get("machine") or data.get("environment") or {}
    if isinstance(found, str) and "thread" in found:  # a script that names the CPU and its threads itself
        return found
    if isinstance(found, str):  # the oldest scripts wrote only the architecture
        return f"{found}, {data.get('threads', '?')} torch thread(s), torch {data.get('torch', '?')}"
    cpu = found.get("cpu") or found.get("cpu_model") or found.get("platform", "?")
    threads = found.get("torch_threads") or found.get("threads") or "?"
    return f"{cpu}, {threads} torch thread(s), torch {found.get('torch', '?')}"


def number(value, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def percent(share: float) -> str:
    return f"{100 * share:.1f} %"


def robot_raw(data: dict, published: bool = True):
    header = ["sampler", "position median / mean (mm)", "rotation median / mean (°)", "outside limits"]
    rows = [
        [
            sampler,
            f"{number(r['position_mm_median'])} / {number(r['position_mm_mean'])}",
            f"{number(r['rotation_deg_median'], 2)} / {number(r['rotation_deg_mean'], 2)}",
            str(r["limit_violations"]),
        ]
        for sampler, r in data["raw_k1"].items()
    ]
    for name, (mm, deg) in (data["published_mean_mm_deg"] if published else {}).items():
        rows.append([f"{name}, published mean", f"- / {number(mm, 2)}", f"- / {number(deg, 2)}", "-"])
    return header, rows


def robot_pipelines(data: dict):
    header = ["pipeline (16 samples a target)", "ms a target", "solved (1 mm, 1°)", "valid of 16", "spread (rad)"]
    rows = [
        [
            name,
            number(1000 * r["seconds_per_target"], 2),
            percent(r["success_share"]),
            number(r["valid_per_target"]),
            number(r["diversity_rad"], 2),
        ]
        for name, r in data["pipelines"].items()
    ]
    return header, rows


def few_step_pipeline(data: dict):
    header = ["pipeline (16 samples a target)", "ms a target (median)", "solved (1 mm, 1°)", "valid of 16"]
    rows = []
    for model, found in data["models"].items():
        for name, r in found["rows"].items():
            rows.append(
                [
                    shipped(f"{name} ({model})" if name.startswith("IKDP") else name),
                    number(r["ms_per_target"], 2),
                    percent(r["success_share"]),
                    number(r["valid_per_target"]),
                ]
            )
    return header, rows


GONE = {"ikdp_panda_4step", "ikdp_panda_cpu", "ikdp_n4_relaxed", "ikdp_n4_2step"}  # superseded: no rows


def few_step_samplers(data: dict):
    header = [
        "model",
        "sampler",
        "network evaluations",
        "position median / mean (mm)",
        "rotation median (°)",
        "spread vs its DDPM",
    ]
    rows = []
    for model, found in data["models"].items():
        if model in GONE:
            continue
        student = model.endswith(".pt")  # the run that shipped as the model's student
        label = shipped(data["config"]["checkpoints"][0]) + ", its student" if student else shipped(model)
        for sampler, r in found["rows"].items():
            if student and sampler == "ddpm":  # a student is distilled for its own few steps
                continue
            rows.append(
                [
                    label,
                    sampler,
                    str(r["network_evaluations"]),
                    f"{number(r['position_median'])} / {number(r['position_mean'])}",
                    number(r["rotation_deg_median"], 2),
                    number(r["diversity_vs_ddpm"], 2),
                ]
            )
    return header, rows


def gpu_batch(data: dict):
    header = ["solve, K = 16", "eager (ms)", "one CUDA graph (ms)", "fused graph (ms)", "solved (1 mm, 1°)"]
    rows = []
    for name, r in data["rows"].items():
        if "ms" in r:  # the baseline, on the same GPU, in its own eager loop
            rows.append([name, number(r["ms"]), "-", "-", percent(r["success"])])
            continue
        solved = r.get("fused") or r.get("graph") or {}
        rows.append(
            [
                shipped(name),
                number(r.get("eager_ms")),
                number(r.get("graph_ms")),
                number(r.get("fused_ms")),
                percent(solved["success"]) if "success" in solved else "-",
            ]
        )
    return header, rows


def gpu_train(data: dict):
    header = ["training loop", "batch", "width", "optimizer steps a second"]
    rows = [
        [name, str(r["batch"]), str(r["hidden"]), number(r["steps_per_second"])]
        for name, r in data["rows"].items()
        if "steps_per_second" in r
    ]
    return header, rows


def minutes_to_accuracy(data: dict):
    header = [
        "arm, after `--minutes 8`",
        "CPU minutes",
        "steps",
        "raw median / mean (mm)",
        "raw median (°)",
        "raw over 50 mm",
        "16 samples + 5 DLS: solved (1 mm, 1°)",
        "valid of 16",
    ]
    rows = []
    for run in data["runs"].values():
        raw, refined = run["raw_k1"], run["k16_refined_5"]
        rows.append(
            [
                run["arm"],
                number(run["cpu_minutes"]),
                str(run["steps"]),
                f"{number(raw['position_mm_median'])} / {number(raw['position_mm_mean'])}",
                number(raw["rotation_deg_median"], 2),
                percent(raw["over_50mm_share"]),
                percent(refined["success_share"]),
                number(refined["valid_per_target"]),
            ]
        )
    return header, rows


def constraint_part(data: dict, keys: str):
    """One part of benchmarks/constraints.py: its rows (share solved, valid poses, time) at data's path `keys`."""
    for key in keys.split("/"):
        data = data[key]
    header = ["method, 16 samples a target", "solved", "valid of 16", "ms a target"]
    rows = [
        [name, percent(r["success_share"]), number(r["valid_per_target"]), number(r["ms_per_target"], 2)]
        for name, r in data["rows"].items()
    ]
    return header, rows


def paper_table1(data: dict):
    header = [
        "links N",
        "paper: angle dist. / target dist.",
        "paper's denoiser here: angle dist. (rad)",
        "its target dist. median (bone lengths)",
        "our default: angle dist. (rad)",
        "its target dist. median",
    ]
    rows = []
    for joints, (angle, target) in data["paper"]["table1"].items():
        variant = data["variants"][f"n{joints}_T80"]
        ours = data["arms"][joints]["methods"]["IKDP ours, DDPM"]["fk_uniform"]
        rows.append(
            [
                joints,
                f"{angle} / {target}",
                number(variant["angle_distance"]["mean"], 2),
                f"{variant['target_distance']['median']:.3f}",
                number(ours["angle_distance"]["mean"], 2),
                f"{ours['target_distance']['median']:.4f}",
            ]
        )
    return header, rows


def paper_methods(data: dict):
    header = [
        "method (N = 4)",
        "settings",
        "tip miss median / mean (bone lengths)",
        "within 0.01",
        "one target (ms)",
        "a target in a batch of 1000 (ms)",
    ]
    runtime = data["runtime"]["methods"]
    rows = []
    for name, found in data["arms"]["4"]["methods"].items():
        miss, time = found["fk_uniform"]["target_distance"], runtime.get(name, {})
        rows.append(
            [
                name,
                found["settings"],
                f"{miss['median']:.2g} / {miss['mean']:.2g}",
                percent(miss["success@0.01"]),
                number(time.get("single_target_ms"), 2),
                number(time.get("per_target_in_batch_ms"), 3),
            ]
        )
    return header, rows


def planar_accuracy(data: dict):
    header = ["model", "links", "raw DDPM median / p95 (bone lengths)", "+ 5 DLS steps: within 1e-4"]
    rows = [
        [
            name,
            str(r["checkpoint"]["num_links"]),
            f"{r['raw_ddpm']['median']:.4f} / {r['raw_ddpm']['p95']:.4f}",
            percent(r["refined"]["share_within_tolerance"]),
        ]
        for name, r in data["accuracy"].items()
    ]
    return header, rows


def planar_goals(data: dict):
    return ["goal", "measured", "met"], [[g["goal"], g["measured"], "yes" if g["met"] else "no"] for g in data["goals"]]


def chain_fk(data: dict):
    header = ["forward kinematics of 100,000 Panda poses", "median (ms)", "times pytorch_kinematics"]
    return header, [[r["method"], number(r["median_ms"]), number(r["speedup"], 1)] for r in data["rows"]]


def tree_seeds(data: dict):
    """benchmarks/tree_seeds.py: per DLS budget, the share solved from each kind of start, in one run."""
    names = {
        "ikdp": "IKDP samples + DLS",
        "uniform": "uniform random starts + DLS",
        "pinocchio_clik": "Pinocchio CLIK from the same uniform starts",
    }
    header = [f"starts (K = {data['num_samples']} per target)", "steps", "solved (every hand 1 mm, 1°)", "refine (s)"]
    rows = [
        [names[r["seeds"]], str(r["dls_steps"]), percent(r["solved"]), number(r["refine_seconds"], 2)]
        for r in data["rows"]
    ]
    return header, rows


def tree_self_collision(data: dict):
    """benchmarks/tree_self_collision.py: the same targets solved with the self-collision check and without."""
    names = {"self_collision_on": "on (the default)", "self_collision_off": "off, `SelfCollision(enabled=False)`"}
    header = ["self-collision check", "poses in self-collision", "raw samples in it", "solved, apart", "solved", "s"]
    rows = [
        [
            names[r["setting"]],
            percent(r["poses_in_self_collision"]),
            percent(r["raw_samples_in_self_collision"]),
            percent(r["solved_free_of_collision"]),
            percent(r["solved_any"]),
            number(r["median_seconds"], 1),
        ]
        for r in data["rows"]
    ]
    return header, rows


def viz_frames(data: dict):
    header = ["samples K", "frames/s while the denoising plays", "frames/s standing still", "states drawn a second"]
    rows = [
        [str(r["samples"]), number(r["animating_fps"]), number(r["still_fps"]), number(r["states_per_second"])]
        for r in data["rows"]
    ]
    return header, rows


def viz_frame_costs(data: dict):
    """Each variant of the playing frame against the shipped one, interleaved in one page."""
    header = ["variant", "ms a frame", "frames/s", "against as shipped, ms"]
    rows = [
        [r["variant"], number(r["ms_per_frame"]), number(r["frames_per_second"]), f"{r['ms_more_than_shipped']:+.1f}"]
        for r in data["rows"]
    ]
    return header, rows


def one_target(data: dict):
    """Per model: each row of benchmarks/one_target_latency.py, one call per target (or per stream step)."""
    header = ["model", "row", "median ms", "p10 ms", "p90 ms", "solved", "valid / 16", "largest jump (rad)"]
    rows = []
    for model in data["config"]["models"]:
        for row, r in data[model].items():
            if row == "pipeline" or "median_ms" not in r:
                continue
            valid = r.get("valid_per_target")
            jump = r.get("largest_jump_rad")
            rows.append(
                [
                    shipped(model) if row == next(k for k in data[model] if k != "pipeline") else "",
                    row,
                    f"{r['median_ms']:.3g}",
                    number(r.get("p10_ms"), 2),
                    number(r.get("p90_ms"), 2),
                    percent(r["success_share"]) if "success_share" in r else "-",
                    number(valid),
                    number(jump, 4),
                ]
            )
    return header, rows


def viz_robot_drag(data: dict):
    """Per setup of benchmarks/viz_robot_drag.py: a Panda drag's server share, to the first frame and the full solve."""
    header = ["setup", "first frame median / p95 ms", "full solve median / p95 ms", "moves"]
    rows = []
    for setup, row in data.items():
        if setup == "machine":
            continue
        first, full = row["first_frame_ms"], row["full_solve_ms"]
        rows.append(
            [
                setup,
                f"{first['median']:.0f} / {first['p95']:.0f}",
                f"{full['median']:.0f} / {full['p95']:.0f}",
                str(row["moves"]),
            ]
        )
    return header, rows


def viz_page_latency(data: dict):
    """Per model: pointer move -> new pixels in the page, the server's share, and the way back to the pixels."""
    found = data["machine"]

    def spread(row: dict) -> str:
        return f"{row['median']:.0f} ({row['p10']:.0f}-{row['p90']:.0f})" if row["n"] else "-"

    header = [
        "model",
        "in the page: pointer move → new pixels, ms",
        "in the server: update's arrival → drawn, ms",
        "server's draw → new pixels, ms",
        "moves",
        f"load average ({found['cores']} cores)",
    ]
    load = f"{found['load_average_at_start'][0]:.1f}"
    rows = [
        [
            shipped(f"`{model}`"),
            spread(row["page_ms"]),
            spread(row["server_ms"]),
            spread(row["from_server_ms"]),
            str(row["page_ms"]["n"]),
            load,
        ]  # fmt: skip
        for model, row in data["summary"].items()
    ]
    return header, rows


EARLIER_PANDA = (
    "Measured on the earlier Panda model (raw DDPM-100 4.9 / 10.2 mm median / mean), which `ikdp_panda` replaced; "
    "the command measures today's."
)

TABLES = {
    "robot_raw": Table(
        "robot_panda_gpu.json", "python -m benchmarks.robot_benchmark --checkpoint ikdp_panda", robot_raw
    ),
    "robot_pipelines": Table(
        "robot_panda_gpu.json", "python -m benchmarks.robot_benchmark --checkpoint ikdp_panda", robot_pipelines
    ),
    "z1_raw": Table(
        "robot_z1.json",
        "python -m benchmarks.robot_benchmark --checkpoint ikdp_z1",
        functools.partial(robot_raw, published=False),
    ),
    "panda_student": Table(
        "few_step_panda_gpu_student.json",
        "python -m benchmarks.few_step --checkpoints ikdp_panda --samplers ddpm ddim:4 --spacings quadratic",
        few_step_samplers,
    ),
    "fast_pipeline": Table(
        "few_step_pipeline_restarts_shipped.json",
        "python -m benchmarks.few_step_pipeline --checkpoints ikdp_panda_fast --pipelines ddim:1:quadratic+3r20/int8 "
        "ddim:1:quadratic+4r20/int8 ddim:1:quadratic+4r10/int8 ddim:1:quadratic+8/int8 ddim:1:quadratic+4r20 "
        "--random-start-steps 20 15 10r20 8r20 6r20 6r10 --rounds 7",
        few_step_pipeline,
    ),
    "one_target": Table(
        "one_target_latency.json",
        "OMP_NUM_THREADS=1 python -m benchmarks.one_target_latency",
        one_target,
        "Solves alternate with the fused path switched off (general), target by target, so load hits both alike. "
        "Solved: a pose within 1 mm and 1° (planar: 1e-3 of the reach).",
    ),
    "gpu_batch": Table("gpu_batch_graph_h100_fused.json", "python -m benchmarks.gpu.batch_graph PANDA_URDF", gpu_batch),
    "gpu_train": Table("gpu_train_graph_h100.json", "python -m benchmarks.gpu.train_graph PANDA_URDF", gpu_train),
    "minutes_xarm7": Table(
        "minutes_to_accuracy_xarm7_limit_aware_quiet.json",
        "python -m ikdp.train --urdf xarm7.urdf --ee-link link_eef --minutes 8 --threads 1 --output runs/xarm7.pt; "
        "python -m benchmarks.minutes_to_accuracy --checkpoints runs/xarm7.pt",
        minutes_to_accuracy,
    ),
    "minutes_kinova_so101": Table(
        "minutes_to_accuracy_kinova_so101_limit_aware.json",
        "python -m ikdp.train --urdf <kinova.urdf | so101.urdf> --ee-link <its hand> --minutes 8 --threads 1; "
        "python -m benchmarks.minutes_to_accuracy --checkpoints runs/kinova.pt runs/so101.pt",
        minutes_to_accuracy,
    ),
    "constraints_obstacles": Table(
        "constraints_obstacles.json",
        "python -m benchmarks.constraints --parts obstacles --targets 1000",
        functools.partial(constraint_part, keys="obstacles"),
        EARLIER_PANDA,
    ),
    "constraints_locked": Table(
        "constraints.json",
        "python -m benchmarks.constraints --targets 1000 --planar-targets 1000",
        functools.partial(constraint_part, keys="locked"),
        EARLIER_PANDA,
    ),
    "constraints_free_axis": Table(
        "constraints.json",
        "python -m benchmarks.constraints --targets 1000 --planar-targets 1000",
        functools.partial(constraint_part, keys="partial/free_axis"),
        EARLIER_PANDA,
    ),
    "constraints_planar": Table(
        "constraints.json",
        "python -m benchmarks.constraints --targets 1000 --planar-targets 1000",
        functools.partial(constraint_part, keys="planar"),
        "Planar: `ikdp_n4`, one disc, a target within 1e-3 bone lengths.",
    ),
    "paper_table1": Table(
        "paper_evaluation.json", "python -m ikdp.evaluate --cache-dir .eval_cache --threads 1", paper_table1
    ),
    "paper_methods": Table(
        "paper_evaluation.json", "python -m ikdp.evaluate --cache-dir .eval_cache --threads 1", paper_methods
    ),
    "planar_accuracy": Table("solver.json", "python -m benchmarks.solver_benchmark", planar_accuracy),
    "planar_goals": Table("solver.json", "python -m benchmarks.solver_benchmark", planar_goals),
    "chain_fk": Table("chain_fk.json", "python benchmarks/chain_fk.py", chain_fk),
    "viz_frames": Table("viz_frames.json", "python benchmarks/viz_frames.py", viz_frames),
    "viz_frame_costs": Table("viz_frame_costs.json", "python benchmarks/viz_frame_costs.py", viz_frame_costs),
    "tree_seeds_pinocchio": Table(
        "tree_seeds_g1_shipped.json",
        "python -m benchmarks.tree_seeds --checkpoint checkpoints/ikdp_g1.pt --targets 500",
        tree_seeds,
        "500 held-out G1 targets (both hands' poses from poses uniform within the limits); the shipped `ikdp_g1`, "
        "trained `--minutes 8` on one CPU thread. Every row scored by the same rule through the same kinematics.",
    ),
    "tree_self_collision": Table(
        "tree_self_collision_g1_shipped.json",
        "python -m benchmarks.tree_self_collision --checkpoint checkpoints/ikdp_g1.pt --targets 200",
        tree_self_collision,
        "200 G1 targets from poses free of self-collision, K = 16 + 5 DLS steps, DDPM; solved: a pose with both "
        "hands within 1 mm and 1° (apart: and no overlap); s: the median wall time of 3 alternating rounds.",
    ),
    "viz_robot_drag": Table(
        "viz_robot_drag.json",
        "OMP_NUM_THREADS=1 python -m benchmarks.viz_robot_drag --setups",
        viz_robot_drag,
        "`ikdp_panda`, K = 16, 30 drag updates 3 cm apart, one torch thread: from the move's arrival in the server to "
        "the end of the drawing of its first frame (pointer to pixels in the page: docs/viewer.md). The viewer opens "
        "the Panda on its student (the first two rows).",
    ),
    "viz_page_latency": Table(
        "viz_page_latency.json",
        "python -m benchmarks.viz_page_latency",
        viz_page_latency,
        "Median (10th-90th percentile) of the moves. As the viewer opens them: K = 16, a planar arm on its DDPM, a "
        "robot on its student; chromium with software WebGL (no GPU).",
    ),
}


def render(name: str) -> str:
    table = TABLES[name]
    data = json.loads((RESULTS / table.source).read_text(encoding="utf-8"))
    header, rows = table.rows(data)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    lines += ["", f"`{table.command}` (`benchmarks/results/{table.source}`); {machine(data)}. {table.note}".rstrip()]
    return "\n".join(lines)


MARKED = re.compile(r"(<!-- table:(\w+) -->\n).*?(<!-- /table:\2 -->)", re.DOTALL)


def rendered_page(text: str) -> str:
    """The page with each marked table rendered anew; an unknown name is a ValueError."""

    def replace(match: re.Match) -> str:
        name = match.group(2)
        if name not in TABLES:
            raise ValueError(f"table: expected one of {sorted(TABLES)}, got {name!r}")
        return f"{match.group(1)}{render(name)}\n{match.group(3)}"

    return MARKED.sub(replace, text)


def stale_pages() -> dict[Path, str]:
    """Each docs page whose tables differ from the JSON, with its text as rendered now."""
    found = {}
    for page in sorted(DOCS.rglob("*.md")):
        text = page.read_text(encoding="utf-8")
        new = rendered_page(text)
        if new != text:
            found[page] = new
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a page differs from the JSON")
    args = parser.parse_args()
    stale = stale_pages()
    for page, text in stale.items():
        if args.check:
            print(f"{page.relative_to(REPO)}: its tables differ from benchmarks/results (run {Path(__file__).name})")
        else:
            page.write_text(text, encoding="utf-8")
            print(f"rewrote {page.relative_to(REPO)}")
    if args.check and stale:
        sys.exit(1)


if __name__ == "__main__":
    main()
