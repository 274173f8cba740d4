r"""Frames per second the viewer's page renders in headless chromium while the denoising plays, at K = 1, 16, 64.

    python benchmarks/viz_frames.py                      # the shipped ikdp_n4, a 4 s animation
    python benchmarks/viz_frames.py --samples 16 --seconds 2
    python benchmarks/viz_frames.py --ckpt ikdp_panda --sampler ddpm --samples 1 16 \
        --output benchmarks/results/viz_frames_panda.json

The app runs in-process on a free port; Debian's chromium (software WebGL, the
flags in ikdp_viz/screenshot.py) opens it. For each K the page counts its
requestAnimationFrame callbacks over the animation, and, as the baseline timed in
the same run, over as long a time with the final pose standing still. The server
side counts the states it wrote. Prints a table and writes JSON (medians of
`--repeats` runs). The target: >= 30 frames/s while K = 16 animates on a quiet machine, so that the denoising
reads as smooth motion.
"""

from __future__ import annotations

import contextlib
import io
import json
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

TARGET_FPS = 30.0  # K = 16 playing, software WebGL, a quiet machine


@dataclass(frozen=True)
class FramesConfig:
    """Frames per second of the viewer's page while the denoising plays."""

    ckpt: str = "ikdp_n4"  # a shipped model's name or a checkpoint's path
    samples: tuple[int, ...] = (1, 16, 64)  # the K to measure
    seconds: float = 4.0  # animation duration (the viewer's default)
    # the panel's sampler (None: the one the command line opens on; a robot's distilled student plays 5 states in 4 s
    # and the page idles between them, so "ddpm", 101 states, is the robot's hard case)
    sampler: str | None = None
    repeats: int = 3  # runs per K; the table gives medians
    target: tuple[float, ...] | None = (-0.010, 1.200)  # the target solved (a robot: None, its first target)
    show_trail: bool = False  # the panel's "show trail": off in the view `python -m ikdp_viz` opens on (the tour's
    # first step); the docs' table gives both
    chromium: str = "/usr/bin/chromium"  # browser executable
    viewport: tuple[int, int] = (1280, 800)  # the page's width and height, pixels
    output: Path = Path("benchmarks/results/viz_frames.json")  # JSON written here


@dataclass(frozen=True)
class Row:
    samples: int  # K
    animating_fps: float  # page frames per second while the denoising plays (median)
    still_fps: float  # page frames per second with the final pose standing (median): the baseline
    states_per_second: float  # states the server wrote per second of animation (median)
    states: int  # states in one solve (S + 1)


def measure(config: FramesConfig) -> list[Row]:
    import torch
    import viser
    from playwright.sync_api import sync_playwright

    import ikdp
    from ikdp.shipped import shipped_dir
    from ikdp_viz.app import VizApp
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.screenshot import COUNT_FRAMES, open_viewer_page
    from ikdp_viz.student import opening_sampler

    torch.set_num_threads(1)
    solver = ikdp.load(config.ckpt)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    # the shipped models' folder: a robot opens on its distilled student, as `python -m ikdp_viz` opens it
    app = VizApp(server, solver, solve_now=False, animation_seconds=0.0, target=config.target,
                 checkpoint_folder=shipped_dir())  # fmt: skip
    sampler, steps = opening_sampler(arm_kind(app.solver), app.session.student, app.asked_for_student)
    app.panel.sampler.value = config.sampler or sampler  # None: the sampler the command line opens on
    if config.sampler is None:
        app.panel.steps.value = min(steps, app.panel.steps.max)
    app.panel.show_trail.value = config.show_trail
    target = app.target.copy()  # config.target pulled into the workspace, or the arm's first target
    rows = []
    try:
        with sync_playwright() as playwright:
            browser, page = open_viewer_page(playwright, server, chromium=config.chromium, viewport=config.viewport)
            for samples in config.samples:
                app.panel.samples.value = samples
                app.move_target(target)
                assert app.wait_until_still(120), "the solve did not finish"
                page.evaluate(COUNT_FRAMES, 2.0)  # let the page take in the new nodes first
                animating, still, written = [], [], []
                for _ in range(config.repeats):
                    frames, elapsed = page.evaluate(COUNT_FRAMES, config.seconds)
                    still.append(frames / elapsed)
                    app.panel.duration.value = config.seconds
                    drawn = count_states(app)
                    app.toggle_play()  # at the end: plays from t = T
                    frames, elapsed = page.evaluate(COUNT_FRAMES, config.seconds)
                    animating.append(frames / elapsed)
                    assert app.wait_until_still(120)
                    written.append((count_states(app) - drawn) / config.seconds)
                    app.panel.duration.value = 0.0
                rows.append(
                    Row(samples, statistics.median(animating), statistics.median(still),
                        statistics.median(written), app.solved.view.num_states)
                )  # fmt: skip
                print(f"K={samples}: {rows[-1]}", flush=True)
            browser.close()
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    return rows


def count_states(app) -> int:
    """How many states the writer has drawn so far (a counter the benchmark installs on first use)."""
    writer = app.writer
    if not hasattr(writer, "_frames_drawn"):
        draw = writer._draw_state
        writer._frames_drawn = 0

        def counting(state: int) -> None:
            writer._frames_drawn += 1
            draw(state)

        writer._draw_state = counting
    return writer._frames_drawn


def main(argv: list[str] | None = None) -> None:
    import tyro

    config = tyro.cli(FramesConfig, args=argv)
    started = time.time()
    rows = measure(config)
    print(f"\n{'K':>4} {'animating fps':>14} {'still fps':>10} {'states/s':>9} {'states':>7}")
    for row in rows:
        print(
            f"{row.samples:>4} {row.animating_fps:>14.1f} {row.still_fps:>10.1f} "
            f"{row.states_per_second:>9.1f} {row.states:>7}"
        )
    from ikdp.evaluation.machine import machine_description

    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    result = {
        "config": {key: str(value) if isinstance(value, Path) else value for key, value in asdict(config).items()},
        "rows": [asdict(row) for row in rows],
        "machine": {**machine_description(1), "load_average": load},
        "seconds": round(time.time() - started, 1),
        "median_of": config.repeats,
        "target_fps_at_16": TARGET_FPS,
        "met_at_16": bool(np.any([row.animating_fps >= TARGET_FPS for row in rows if row.samples == 16])),
    }
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {config.output}")


if __name__ == "__main__":
    main()
