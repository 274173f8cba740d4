"""A robot's drag: time from a target change to the first new frame on screen.

    python -m benchmarks.viz_robot_drag                  # ikdp_panda, 30 moves, one torch thread
    python -m benchmarks.viz_robot_drag --moves 5        # a smoke run
    python -m benchmarks.viz_robot_drag --setups         # with its student: every setup below in one run
    python -m benchmarks.viz_robot_drag --setups --models ikdp_panda ikdp_n4   # each model's, one run

`--setups` measures, in one process on the same moves, the viewer as it opens the Panda
(`student`: its distilled few-step student as the sampler, drag updates and released moves that
animate) beside the teacher's DDPM with the student's preview, with the DPM-Solver++(2M)-5 preview
of a model without a student, and with no preview.

The Panda viewer as a user meets it (K = 16, DDPM, all 100 steps), the solve on one CPU
thread. Each move is a drag update (the gizmo's "update" phase, not animated) 3 cm from the
last, made once the previous one is drawn; measured from the move's arrival to the end of the
`server.atomic()` block of the first solve drawn for it (`app.latencies`: a fast preview when
the viewer makes one, else the full solve), and to the full solve. Works against an older
checkout of the viewer too (it reads only VizApp's public `move_target` and `latencies`), so
`--label` names the run and the table goes to benchmarks/results/viz_robot_drag.json beside
the runs already there.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch
import viser

import ikdp
from ikdp.evaluation.machine import cpu_model, machine_description
from ikdp.shipped import shipped_checkpoint
from ikdp_viz.app import VizApp
from ikdp_viz.student import STUDENT

RESULTS = Path(__file__).resolve().parent / "results" / "viz_robot_drag.json"


def measure(
    moves: int,
    *,
    previews: bool | None,
    student=None,
    sampler: str | None = None,
    drag: bool = True,
    model: str = "ikdp_panda",
) -> dict:
    """Per move: ms to the first frame drawn and to the full solve drawn, for the shipped robot model `model`."""
    torch.set_num_threads(1)
    solver = ikdp.load(shipped_checkpoint(model))
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    options = {} if previews is None else {"previews": previews}
    if student is not None:  # an older checkout's VizApp takes no student
        options["student"] = student
    app = VizApp(server, solver, animation_seconds=0.0, **options)
    if sampler is not None:
        app.panel.sampler.value = sampler
    try:
        assert app.wait_until_still(120), "the first solve did not finish"
        start = np.array(app.target, dtype=np.float64)
        first, full = [], []
        for index in range(moves):
            target = start.copy()
            target[:3] += 0.03 * np.array([np.cos(index), np.sin(index), 0.0])  # 3 cm around the first target
            arrival = time.perf_counter()
            app.move_target(target, arrival=arrival, from_gizmo=True, dragging=drag)
            assert app.wait_until_still(120), "a solve did not finish"
            drawn = sorted(when for came, when, _ in app.latencies if came == arrival)
            first.append(1000 * (drawn[0] - arrival))
            full.append(1000 * (drawn[-1] - arrival))
        return {"first_frame_ms": first, "full_solve_ms": full}
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()


def summary(values: list[float]) -> dict[str, float]:
    array = np.asarray(values)
    return {"median": float(np.median(array)), "p95": float(np.percentile(array, 95)), "max": float(array.max())}


def setups(moves: int, student_path: str | None = None, model: str = "ikdp_panda") -> dict[str, dict]:
    """Every setup of `--setups` for the shipped robot model `model`, in one run: label -> measure()'s lists.
    `student_path`: a student of `model` to use instead of the shipped one."""
    if student_path is not None:
        student = ikdp.load(student_path)
    else:
        student = ikdp.load(shipped_checkpoint(model)).student
    if student is None:
        raise SystemExit(f"viz_robot_drag: the shipped {model} holds no student (python -m ikdp.ship --student)")
    prefix = "" if model == "ikdp_panda" else f"{model}: "  # the rows measured before this option keep their labels
    return {
        f"{prefix}student, drag updates": measure(moves, previews=None, student=student, sampler=STUDENT, model=model),
        f"{prefix}student, released moves (animated)": measure(
            moves, previews=None, student=student, sampler=STUDENT, drag=False, model=model
        ),  # fmt: skip
        f"{prefix}teacher DDPM-100 + the student's preview": measure(
            moves, previews=None, student=student, sampler="ddpm", model=model
        ),  # fmt: skip
        f"{prefix}teacher DDPM-100 + DPM-Solver++(2M)-5 preview (no student)": measure(
            moves, previews=None, sampler="ddpm", model=model
        ),  # fmt: skip
        f"{prefix}teacher DDPM-100, no preview": measure(moves, previews=False, sampler="ddpm", model=model),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--moves", type=int, default=30)
    parser.add_argument("--label", default="this checkout")
    parser.add_argument("--no-previews", action="store_true", help="the full solve alone (this checkout's switch)")
    parser.add_argument("--setups", action="store_true", help="the student and the teacher's setups, one run")
    parser.add_argument("--student", default=None, help="with --setups: this student of the model, not the shipped")
    parser.add_argument("--models", nargs="+", default=["ikdp_panda"], help="with --setups: these shipped models")
    args = parser.parse_args()
    if args.setups:
        results = {}
        for model in args.models:
            results |= setups(args.moves, args.student, model)
    else:
        results = {args.label: measure(args.moves, previews=False if args.no_previews else None)}
    print(f"Panda drag, K = 16, one torch thread, {args.moves} moves ({cpu_model()})")
    print("| setup | first frame median / p95 ms | full solve median / p95 ms |")
    print("|---|---|---|")
    runs = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for label, result in results.items():
        row = {name: summary(values) for name, values in result.items()}
        first, full = row["first_frame_ms"], row["full_solve_ms"]
        print(f"| {label} | {first['median']:.0f} / {first['p95']:.0f} | {full['median']:.0f} / {full['p95']:.0f} |")
        runs[label] = {**row, "moves": args.moves, "cpu": cpu_model(), "python": platform.python_version(),
                       "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}  # fmt: skip
    runs["machine"] = machine_description(1)  # the latest run's, its load average included
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(runs, indent=2) + "\n")


if __name__ == "__main__":
    main()
