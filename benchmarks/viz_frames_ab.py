r"""Frames per second of K = 16 animating in software WebGL, two code trees alternated in one run, and the
server's messages and bytes per state drawn (which do not depend on the CPU).

    OMP_NUM_THREADS=1 python benchmarks/viz_frames_ab.py --base /tmp/base --rounds 3
    # /tmp/base: the tree to compare with, e.g. `git worktree add /tmp/base HEAD~1`

Views: "before" (the base tree's app as a script opens it), "default" (this tree's, the same way)
and "full trail" (this tree with 'trail of: all samples'); `--views before default` for a plain
A/B. Each round runs every view once, in a new process with that tree on
PYTHONPATH (`--child`), in turn: the shipped ikdp_n4, target (-0.010, 1.200), K = 16, seed 0,
DDPM, a 4 s animation played `repeats` times in Debian's chromium (flags in
ikdp_viz/screenshot.py, 1280 x 800). The page counts its requestAnimationFrame callbacks while
it plays; the server counts the messages it queues (viser's `queue_message`) and their encoded
bytes (msgpack plus binary arrays) per state the writer draws. Prints a table of medians and
writes JSON.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

VIEWS = {"before": ("base", None), "default": ("this", None), "full trail": ("this", "all samples"),
         "default, no grid": ("this", None), "default, section grid": ("this", None)}  # fmt: skip
PROBES = {
    "default, no grid": "no grid",
    "default, section grid": "section grid",
}  # a view measured with a part hidden, to see what it costs
HERE = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class AbConfig:
    base: Path = Path("/tmp/base")  # the tree measured as "before"
    rounds: int = 3  # each view once per round, alternated
    repeats: int = 2  # animations per run (the run's median)
    seconds: float = 4.0  # the animation's duration
    samples: int = 16  # K
    views: tuple[str, ...] = ("before", "default", "full trail")  # which of VIEWS to measure
    chromium: str = "/usr/bin/chromium"
    output: Path = field(default=HERE / "benchmarks" / "results" / "viz_frames_ab.json")


def child(trail_of: str | None, samples: int, seconds: float, repeats: int, chromium: str, probe: str = "") -> dict:
    """One run in this process, with whichever tree is on sys.path: frames/s and messages per state."""
    import contextlib
    import io

    import msgspec
    import torch
    import viser
    from playwright.sync_api import sync_playwright

    import ikdp
    from ikdp_viz.app import VizApp
    from ikdp_viz.screenshot import COUNT_FRAMES, open_viewer_page

    torch.set_num_threads(1)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = VizApp(server, ikdp.load("ikdp_n4"), solve_now=False, animation_seconds=0.0, target=(-0.010, 1.200))
    app.panel.samples.value = samples
    if trail_of is not None:
        app.panel.learn.trail_of.value = trail_of
    app.move_target(app.target)
    assert app.wait_until_still(120)
    grid = getattr(app.writer, "view", app.writer)._static_nodes[0]  # the ground grid, the first static node
    if probe == "no grid":
        grid.visible = False
    elif probe == "section grid":  # its lines every mean bone length only, not every half
        from ikdp_viz.style import GRID_SECTION

        sections = (grid.colors[:, 0] == GRID_SECTION).all(axis=-1)
        grid.points, grid.colors = grid.points[sections], grid.colors[sections]
    sent = {"messages": 0, "bytes": 0}
    websock = server._websock_server
    queue = websock.queue_message

    def counting(message) -> None:
        buffers: list = []
        encoded = msgspec.msgpack.encode(message.as_serializable_dict(buffers))
        sent["messages"] += 1
        sent["bytes"] += len(encoded) + sum(memoryview(buffer).nbytes for buffer in buffers)
        queue(message)

    writer = app.writer
    draw, drawn = writer._draw_state, [0]

    def counting_draw(state: int) -> None:
        drawn[0] += 1
        draw(state)

    writer._draw_state = counting_draw
    fps, per_state_messages, per_state_bytes = [], [], []
    try:
        with sync_playwright() as playwright:
            browser, page = open_viewer_page(playwright, server, chromium=chromium, viewport=(1280, 800))
            page.evaluate(COUNT_FRAMES, 2.0)  # the page takes in the scene first
            for _ in range(repeats):
                app.panel.duration.value = seconds
                sent.update(messages=0, bytes=0)
                drawn[0] = 0
                websock.queue_message = counting
                app.toggle_play()
                frames, elapsed = page.evaluate(COUNT_FRAMES, seconds)
                assert app.wait_until_still(120)
                websock.queue_message = queue
                fps.append(frames / elapsed)
                per_state_messages.append(sent["messages"] / max(drawn[0], 1))
                per_state_bytes.append(sent["bytes"] / max(drawn[0], 1))
                app.panel.duration.value = 0.0
            browser.close()
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    return {
        "fps": statistics.median(fps),
        "messages_per_state": statistics.median(per_state_messages),
        "bytes_per_state": statistics.median(per_state_bytes),
        "states_drawn": drawn[0],
    }


def main() -> None:
    import tyro

    if sys.argv[1:2] == ["--child"]:
        trail_of = None if sys.argv[2] == "-" else sys.argv[2]
        samples, seconds, repeats, chromium = int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
        probe = sys.argv[7] if len(sys.argv) > 7 else ""
        print("RESULT " + json.dumps(child(trail_of, samples, seconds, repeats, chromium, probe)), flush=True)
        return
    config = tyro.cli(AbConfig)
    trees = {"base": config.base.resolve(), "this": HERE}
    runs: dict[str, list[dict]] = {view: [] for view in config.views}
    loads = []
    for round_number in range(config.rounds):
        for view in config.views:
            tree, trail_of = VIEWS[view]
            environment = {**os.environ, "PYTHONPATH": str(trees[tree]), "OMP_NUM_THREADS": "1"}
            command = [sys.executable, __file__, "--child", trail_of or "-", str(config.samples), str(config.seconds),
                       str(config.repeats), config.chromium, PROBES.get(view, "")]  # fmt: skip
            output = subprocess.run(command, env=environment, cwd=trees[tree], capture_output=True, text=True)
            line = next((line for line in output.stdout.splitlines() if line.startswith("RESULT ")), None)
            if line is None:
                raise SystemExit(f"{view}: the run failed\n{output.stderr[-2000:]}")
            runs[view].append(json.loads(line[len("RESULT ") :]))
            loads.append(Path("/proc/loadavg").read_text().split()[0])
            print(f"round {round_number + 1}, {view}: {runs[view][-1]}", flush=True)
    print(f"\nK = {config.samples}, ikdp_n4 DDPM, {config.seconds:g} s animation; per view the runs in order, median")
    print("| view | frames/s animating (runs) | median | messages / state | bytes / state |")
    print("|---|---|---|---|---|")
    table = {}
    for view, results in runs.items():
        fps = [result["fps"] for result in results]
        table[view] = {
            "fps_runs": fps,
            "fps_median": statistics.median(fps),
            "messages_per_state": statistics.median(result["messages_per_state"] for result in results),
            "bytes_per_state": statistics.median(result["bytes_per_state"] for result in results),
        }
        row = table[view]
        print(f"| {view} | {', '.join(f'{value:.1f}' for value in fps)} | {row['fps_median']:.1f} | "
              f"{row['messages_per_state']:.1f} | {row['bytes_per_state']:,.0f} |")  # fmt: skip
    base_commit = subprocess.run(["git", "-C", str(trees["base"]), "rev-parse", "--short", "HEAD"],
                                 capture_output=True, text=True).stdout.strip()  # fmt: skip
    this_commit = subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"],
                                 capture_output=True, text=True).stdout.strip()  # fmt: skip
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), "unknown")  # fmt: skip
    payload = {"config": {"rounds": config.rounds, "repeats": config.repeats, "seconds": config.seconds,
                          "samples": config.samples}, "base": base_commit, "this": this_commit, "cpu": cpu,
               "load_average_after_each_run": loads, "views": table, "runs": runs, "time": time.ctime()}  # fmt: skip
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {config.output}")


if __name__ == "__main__":
    main()
