"""What each part of a playing frame costs the viewer's page, interleaved in one page: ms a frame, medians.

    python benchmarks/viz_frame_costs.py                  # planar ikdp_n4, K = 16, 8 rounds of 3 s per variant

benchmarks/viz_frames.py counts the frames of whole animations, one setting per run, and
this shared 2-core machine moves those counts by a fifth from one run to the next. Here one
page stays open, its canvas at a device pixel ratio of 1 throughout (viser's `fixedDpr`), and
the server writes a state of the K = 16 denoising 20 times a second, as an animation does
(states 40 to 80 in a loop, the frame a playing animation draws), while
the variants below take turns in a new order each round, `--rounds` times: one 3 s count
swings by 10 ms a frame here, so only medians over many rounds resolve a few ms.

  as shipped          the playing frame of the view the command line opens on (no trail, the highlighted sample
                      followed); the slider and readout with every state, the chart and schedule plot standing
                      (a playing frame marks no state on them)
  chart every state   the chart's and schedule plot's markers moved with every state too
  trail shown         "show trail" on: the followed sample's last 6 states
  half-length grid    a grid line every half bone length, not every bone length (a hidden node, swapped in)
  80-face spheres     the joints and tips as 80-face spheres, not the shipped 20 (an extra hidden node each, swapped in)
  nothing written     the last frame stands; only a tiny message keeps the page drawing
  nothing drawn       every node hidden, the same tiny message: what the page costs with nothing of ours to draw
  bare WebGL canvas   not the viewer: a page of one canvas as large, cleared every frame, in the same browser

Prints a table and writes JSON.
"""

from __future__ import annotations

import contextlib
import io
import json
import random
import statistics
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path

VARIANTS = (
    "as shipped", "chart every state", "trail shown", "half-length grid", "80-face spheres", "nothing written",
    "nothing drawn",
)  # fmt: skip


@dataclass(frozen=True)
class CostsConfig:
    """Milliseconds a frame of the playing page, per variant, interleaved."""

    ckpt: str = "ikdp_n4"  # a planar shipped model's name or a checkpoint's path
    samples: int = 16  # K
    rounds: int = 8  # each variant is counted this many times, in turn with the others
    seconds: float = 3.0  # frames counted per turn
    seed: int = 0  # the turns' order, shuffled each round
    target: tuple[float, float] = (-0.010, 1.200)  # the target solved
    chromium: str = "/usr/bin/chromium"  # browser executable
    viewport: tuple[int, int] = (1280, 800)  # the page's width and height, pixels
    output: Path = Path("benchmarks/results/viz_frame_costs.json")  # JSON written here


def measure(config: CostsConfig) -> dict[str, list[float]]:
    import dataclasses

    import numpy as np
    import torch
    import trimesh
    import viser
    from playwright.sync_api import sync_playwright

    import ikdp
    from ikdp_viz.app import VizApp
    from ikdp_viz.frame import build_frame
    from ikdp_viz.planar_scene import grid_segments
    from ikdp_viz.screenshot import COUNT_FRAMES, open_viewer_page
    from ikdp_viz.style import GRID_CELL, GRID_SECTION

    torch.set_num_threads(1)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = VizApp(server, ikdp.load(config.ckpt), solve_now=False, animation_seconds=0.0, target=config.target)
    writer = app.writer
    chosen = {"variant": "nothing written"}
    keep_drawing = server.scene.add_icosphere("/keep_drawing", radius=1e-3, position=(50.0, 50.0, 0.0))
    dense: dict = {}  # the 80-face joints and tips, hidden but for their variant

    def write(state: int) -> None:
        """On the writer's thread: one state of the playing denoising, as the variant asks."""
        variant = chosen["variant"]
        with server.atomic():
            keep_drawing.position = (50.0 + 1e-3 * (state % 2), 50.0, 0.0)
            if variant.startswith("nothing"):
                return
            # every frame here is a playing one, its trail as the variant asks
            still = writer.make_frame(state)
            frame = build_frame(writer.kind, writer.solved, state, writer.settings(), palettes=writer._palettes,
                                animating_to=writer.solved.view.num_states - 1)  # fmt: skip
            settings = dataclasses.replace(frame.settings, show_trail=variant == "trail shown")
            frame = dataclasses.replace(frame, settings=settings)
            writer.view.update(frame)
            if variant == "80-face spheres":
                for name in ("joints", "tips"):
                    node = getattr(writer.view, name)
                    dense[name].batched_positions, dense[name].batched_colors = (
                        node.batched_positions,
                        node.batched_colors,
                    )
                    node.visible = False
            writer.output.frame(still if variant == "chart every state" else frame, writer.kind, writer.solver)

    def switch(variant: str) -> None:
        """On the writer's thread: from now on, draw `variant`."""
        chosen["variant"] = variant
        for node in dense.values():
            node.visible = variant == "80-face spheres"
        drawn = variant != "nothing drawn"
        arm = writer.view
        for node in (*arm._static_nodes, arm.cross, arm.trail, arm.links, arm.followed_links, arm.joints, arm.tips):
            node.visible = drawn
        half_grid.visible = variant == "half-length grid"
        arm._static_nodes[0].visible = drawn and variant != "half-length grid"

    stop = threading.Event()

    def twenty_states_a_second() -> None:
        step = 0
        while not stop.is_set():
            step += 1
            writer.run(lambda _, state=40 + step % 41: write(state), wait=False)
            time.sleep(0.05)

    results: dict[str, list[float]] = {variant: [] for variant in VARIANTS}  # and BARE's, last
    try:
        with sync_playwright() as playwright:
            # the resolution pinned: viser lowers it after slow frames, and the variants would inherit each other's
            browser, page = open_viewer_page(playwright, server, chromium=config.chromium, viewport=config.viewport,
                                             pixel_ratio=1.0)  # fmt: skip
            app.panel.samples.value = config.samples
            app.move_target(config.target)
            assert app.wait_until_still(120), "the solve did not finish"
            app.panel.show_trail.value = False  # as the tour's first step opens
            view = writer.view
            grid, sections = grid_segments(view.grid_half_width, view.unit / 2, view.unit, z=-0.02 * view.unit)
            colors = np.broadcast_to(np.where(sections[:, None, None], GRID_SECTION, GRID_CELL), grid.shape)
            half_grid = server.scene.add_line_segments(
                "/half_length_grid", grid, colors=colors.astype(np.uint8), thickness=1.0, thickness_units="screen",
                visible=False,
            )  # fmt: skip
            sphere = trimesh.creation.icosphere(subdivisions=1, radius=writer.view.sizes.joint)
            for name in ("joints", "tips"):
                node = getattr(writer.view, name)
                dense[name] = server.scene.add_batched_meshes_simple(
                    f"/dense_{name}", sphere.vertices, sphere.faces, node.batched_wxyzs, node.batched_positions,
                    batched_colors=node.batched_colors, lod="off", cast_shadow=False, receive_shadow=False,
                    visible=False,
                )  # fmt: skip
            threading.Thread(target=twenty_states_a_second, daemon=True).start()
            page.evaluate(COUNT_FRAMES, 2.0)
            order = random.Random(config.seed)
            for _ in range(config.rounds):
                # a new order each round: a variant always following the same one inherits its after-effects
                # (the first frames after "nothing drawn" shows every node again are slow)
                for variant in order.sample(VARIANTS, len(VARIANTS)):
                    writer.run(lambda _, variant=variant: switch(variant), wait=False)
                    writer.flush()
                    page.evaluate(COUNT_FRAMES, 1.0)  # let the switch reach the page, uncounted
                    frames, elapsed = page.evaluate(COUNT_FRAMES, config.seconds)
                    results[variant].append(1000.0 * elapsed / frames)
                    print(f"{variant}: {results[variant][-1]:.1f} ms a frame", flush=True)
            results[BARE] = bare_canvas_frames(page, config.seconds, config.rounds)
            browser.close()
    finally:
        stop.set()
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    return results


BARE = "bare WebGL canvas"
BARE_PAGE = """<body style="margin:0"><canvas style="width:100vw;height:100vh;display:block"></canvas><script>
const canvas = document.querySelector("canvas"); canvas.width = innerWidth; canvas.height = innerHeight;
const gl = canvas.getContext("webgl2", {antialias: true, preserveDrawingBuffer: true});
let frame = 0;
const draw = () => {
  frame += 1; gl.clearColor(frame % 2, 0.5, 0.5, 1); gl.clear(gl.COLOR_BUFFER_BIT); requestAnimationFrame(draw);
};
draw();
</script></body>"""


def bare_canvas_frames(page, seconds: float, rounds: int) -> list[float]:
    """ms a frame of a page that only clears a WebGL canvas the viewer's size (the browser's own floor)."""
    from ikdp_viz.screenshot import COUNT_FRAMES

    page.set_content(BARE_PAGE)
    page.evaluate(COUNT_FRAMES, 1.0)
    times = []
    for _ in range(rounds):
        frames, elapsed = page.evaluate(COUNT_FRAMES, seconds)
        times.append(1000.0 * elapsed / frames)
    return times


def main(argv: list[str] | None = None) -> None:
    import tyro

    config = tyro.cli(CostsConfig, args=argv)
    started = time.time()
    results = measure(config)
    shipped = statistics.median(results["as shipped"])
    medians = {variant: statistics.median(times) for variant, times in results.items()}
    rows = [
        {"variant": variant, "ms_per_frame": median, "frames_per_second": 1000 / median,
         "ms_more_than_shipped": median - shipped, "runs": results[variant]}
        for variant, median in medians.items()
    ]  # fmt: skip
    print(f"\n{'variant':<20} {'ms a frame':>10} {'frames/s':>9} {'vs shipped':>11}")
    for row in rows:
        print(f"{row['variant']:<20} {row['ms_per_frame']:>10.1f} {row['frames_per_second']:>9.1f} "
              f"{row['ms_more_than_shipped']:>+11.1f}")  # fmt: skip
    from ikdp.evaluation.machine import machine_description

    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    result = {
        "config": {key: str(value) if isinstance(value, Path) else value for key, value in asdict(config).items()},
        "rows": rows,
        "machine": {**machine_description(1), "load_average": load},
        "seconds": round(time.time() - started, 1),
    }
    config.output.parent.mkdir(parents=True, exist_ok=True)
    config.output.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {config.output}")


if __name__ == "__main__":
    main()
