"""A screenshot of the viewer in headless chromium: `python -m ikdp_viz.screenshot --output docs/screenshot.png`.

Starts the app in-process on a free local port, solves one target, opens the
page in Debian's chromium (Playwright, software WebGL) and saves the picture
once the final pose is drawn. Needs the test extras (playwright) and chromium.
"""

from __future__ import annotations

import contextlib
import io
import time
from dataclasses import dataclass
from pathlib import Path

from ikdp.shipped import DEFAULT_MODEL

# Debian's chromium with software WebGL, no GPU needed; the browser tests and the frame benchmarks use these too
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--disable-background-networking",
]
# The page counts its own requestAnimationFrame callbacks for `seconds`: [frames, elapsed seconds]
# (benchmarks/viz_frames.py, viz_frame_costs.py)
COUNT_FRAMES = """(seconds) => new Promise((done) => {
  let frames = 0; const start = performance.now();
  const tick = (now) => { frames += 1; if (now - start < seconds * 1000) requestAnimationFrame(tick);
                          else done([frames, (now - start) / 1000]); };
  requestAnimationFrame(tick);
})"""
# viser fades its canvas in with a CSS transition that software rendering advances slowly
NO_FADE_CSS = "canvas { opacity: 1 !important; transition: none !important; }"


def open_viewer_page(playwright, server, *, chromium: str, viewport: tuple[int, int]):
    """Debian's chromium (software WebGL) on the viewer that `server` serves, once connected: (browser, page)."""
    browser = playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
    page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
    page.goto(f"http://127.0.0.1:{server.get_port()}")
    page.get_by_text("Connected", exact=True).wait_for(timeout=120_000)
    return browser, page


@dataclass(frozen=True)
class ScreenshotConfig:
    """A screenshot of the viewer in headless chromium, for the docs."""

    output: Path  # PNG to write
    ckpt: str = DEFAULT_MODEL  # a shipped model's name or a checkpoint's path
    target: tuple[float, ...] | None = (1.9, 1.5)  # target x y (a robot: x y z w qx qy qz; None: its first target)
    samples: int = 16  # samples K
    seed: int = 3  # sampling seed
    chromium: str = "/usr/bin/chromium"  # browser executable
    size: tuple[int, int] = (1400, 900)  # viewport width height


def main(argv: list[str] | None = None) -> None:
    import tyro

    args = tyro.cli(ScreenshotConfig, args=argv)

    import torch
    import viser
    from playwright.sync_api import sync_playwright

    import ikdp
    from ikdp.shipped import shipped_dir
    from ikdp_viz.__main__ import checkpoint_path
    from ikdp_viz.app import VizApp, list_checkpoints

    torch.set_num_threads(1)
    path = checkpoint_path(args.ckpt)
    solver = ikdp.load(path)
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    checkpoints = list_checkpoints(shipped_dir(), path)
    app = VizApp(
        server,
        solver,
        checkpoints=checkpoints,
        solve_now=False,
        animation_seconds=0.0,
        target=args.target and tuple(args.target),
    )
    app.panel.samples.value = args.samples
    app.panel.seed.value = args.seed
    app.move_target(app.target)  # args.target pulled into the workspace, or the arm's first target
    app.wait_until_still(60)
    try:
        with sync_playwright() as playwright:
            browser, page = open_viewer_page(playwright, server, chromium=args.chromium, viewport=args.size)
            page.add_style_tag(content=NO_FADE_CSS)
            with contextlib.suppress(Exception):  # the software-rendering notice covers a corner of the scene
                page.locator(".mantine-Notification-closeButton").first.click(timeout=5_000)
            page.get_by_text("Sampling", exact=True).click()  # fold it, so the readouts and the plot show
            time.sleep(5.0)  # software WebGL: let a few frames render
            args.output.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(args.output))
            browser.close()
    finally:
        app.close()
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
